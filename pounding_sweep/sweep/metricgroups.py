"""The metric groups a sweep computes (engine/layout.py GROUPS): the ones its scene's [output] metrics names, and
the ones a study that reads its results needs, whatever that key says. This is the one place that says which
reader needs which group, and why.

Who reads a group's columns (found with grep on the columns engine/layout.left_out_slots names):
- the risk study (risk/analysis.py) reads closest approach, story drift and the top floors' peak absolute
  accelerations; READERS below lists them;
- the no-contact warning (sweep/checks.py ContactTally) reads closest approach only to say how near the floors
  came: when the group is left out it says so rather than turning the group on (the warning's finding, that no
  run made contact, comes from impacts_f*, which is always computed);
- scoring, ranking, refinement and calibration read no group: the scores come from the kernel's score spec and
  the calibration fits histories, and the best table takes only parameters, scores and status. One exception:
  the scale check after a grid (sweep/checks.py check_scale) compares a scored acceleration channel's measured
  peak with the runs' peak absolute accelerations, so a scene scoring one computes accel (sweep_groups);
- one run in memory (simulate: the figures' captions read compression phases, the accuracy study the energy
  balance and its flag), the gap study and the benchmarks call prepare() without a mask: every group. (The gap
  study reads closest approach, drift and the top floors' peak accelerations of a dozen runs per record: leaving
  the other groups out would save a few per cent of seconds and cost a first compile of the lane kernel's other
  variant, engine/driver.py.)
"""

from __future__ import annotations

from pounding_sweep.engine import layout as L
from pounding_sweep.scene import Scene
from pounding_sweep.scene.channels import is_acceleration
from pounding_sweep.scene.groups import METRIC_GROUPS

#: reader -> (the groups it needs, why). A study asks for its readers' groups (study_metrics); the sweep then
#: computes them however its [output] metrics reads.
READERS = {
    "risk_demand": (
        ("closest",),
        "risk/analysis.py demand_table: a contact-free run's required gap is gaps.study.SEPARATED_GAP_M minus its "
        "closest approach (closest_approach_f*_m)",
    ),
    "risk_consequences": (
        ("drift", "accel"),
        "risk/analysis.py consequence_table: the largest story drift and the top floor's peak absolute "
        "acceleration of a contact run over the same motion's contact-free one (peak_drift_b*s*_m and "
        "peak_abs_acc_b*f*_m_s2 of both)",
    ),
}

#: the key that chooses the groups, as messages and the metadata name it
KEY = "[output] metrics"


def sweep_groups(scene: Scene) -> int:
    """The bit mask (engine/layout.py GROUP_*) of the groups a sweep of `scene` computes: those its [output]
    metrics names (default: all), and accel where the scene scores an acceleration channel (its scale check
    reads the runs' peak absolute accelerations)."""
    mask = L.groups_mask(scene.output.metrics or ("all",))
    x = scene.experiment
    if x is not None and any(is_acceleration(code) for code in (x.channels or {}).values()):
        mask |= L.GROUP_ACCEL
    return mask


def reader_groups(*readers: str) -> tuple[str, ...]:
    """The groups the READERS named need, in METRIC_GROUPS order."""
    need = {g for r in readers for g in READERS[r][0]}
    return tuple(g for g in METRIC_GROUPS if g in need)


def study_metrics(scene: Scene, *readers: str) -> tuple[str, ...]:
    """[output] metrics of a study's runs: the groups its `readers` need, and those the study's scene names
    beyond them ([output] metrics unset: none beyond them; the study pays only for what it reads)."""
    own = () if scene.output.metrics is None else scene.output.metrics
    names = set(reader_groups(*readers)) | set(L.group_names(L.groups_mask(own)))
    return tuple(g for g in METRIC_GROUPS if g in names) or ("none",)


def groups_facts(groups: int) -> dict:
    """The result metadata's account of the groups: computed, and left out (their columns NaN, their status
    flags never set)."""
    out = [g for g in METRIC_GROUPS if g not in L.group_names(groups)]
    return {"computed": L.group_names(groups), "left_out": out, "key": KEY}


def left_out_columns(groups: int, floors: tuple[int, int], n_pairs: int) -> list[str]:
    """The result columns of the groups not in `groups` (NaN in every row)."""
    names = L.metric_columns(floors, n_pairs)
    cols = [names[i] for i in L.left_out_slots(sum(floors), n_pairs, groups)]
    # the drift ratios (sweep/prepare.py drift_ratio_columns) are the drifts over the story heights: NaN with them
    return cols + [c.replace("peak_drift_", "peak_drift_ratio_").removesuffix("_m") for c in cols if "drift" in c]
