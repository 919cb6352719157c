"""A seismic-gap study of a scene: for each of its records, the gap each facing floor pair needs (exact,
from a run without contact, against the combination rules and TBEC 2018's minimum), and how the two
buildings' response changes when the gap is shorter (response ratios adjacent / separated, against
gap / required gap: the paper's -4.27 % and -22.57 % peak displacement and +14.63 % peak acceleration).

Exact required gap of pair j: the largest u1j - u2j over the run without contact (displacements relative
to the table; building 1 left of building 2), from the closest-approach metric of a run whose gap
(SEPARATED_GAP_M) no motion closes; 0 when the floors never move toward each other. It is the
time-history truth the rules estimate, and the gap above which a contact run is the separated run,
bit for bit (no contact is ever made). Its sampling error is at most (w dt)^2 / 8 of the relative
displacement's amplitude. Harmonic runs start at rest: the start-up transient counts.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from pounding_sweep.engine import layout as L
from pounding_sweep.errors import ConfigError
from pounding_sweep.gaps.rules import (
    RULES,
    TBEC2018_RULE,
    combined_gap,
    cqc_correlation,
    floor_heights_m,
    frame_first_mode,
    tbec2018_minimum_gap_m,
)
from pounding_sweep.model.coupled import CoupledModel
from pounding_sweep.scene import Axis, Scene, validate
from pounding_sweep.scene.axes import setting_ks
from pounding_sweep.scene.parameters import CONTACT, names
from pounding_sweep.sweep.prepare import prepare

#: the gap of the runs "without contact": no building drifts 100 m (the divergence guard stops at 1 km)
SEPARATED_GAP_M = 100.0
#: gaps of the response-ratio ladder, as fractions of the governing required gap
RELATIVE_GAPS = (0.0, 0.05, 0.1, 0.2, 0.3, 0.5, 0.7, 0.85, 1.0, 1.2)


@dataclass(frozen=True)
class GapStudy:
    """required: one row per record and floor pair; ratios: one row per record, relative gap and building."""

    scene: str
    length_scale: float
    contact: dict  # the contact parameters of the ratio runs
    required: object  # pandas DataFrame
    ratios: object  # pandas DataFrame


def _records(scene: Scene) -> list:
    if scene.excitation.type != "record":
        return [None]
    return list(scene.axis_values("record")) or [scene.excitation.record]


def _point(scene: Scene, record, gaps, contact: dict) -> Scene:
    """The scene at one record and contact point, swept over `gaps` only."""
    c = dataclasses.replace(scene.contact, **contact)
    e = scene.excitation if record is None else dataclasses.replace(scene.excitation, record=record)
    out = dataclasses.replace(
        scene,
        contact=c,
        excitation=e,
        experiment=None,
        calibrate=None,
        sweep=(Axis("gap_m", tuple(gaps)),),
        output=dataclasses.replace(scene.output, histories=()),
    )
    validate(out)
    return out


def contact_used(scene: Scene, point: dict) -> dict:
    """The contact of the ratio runs in full (the scene's [contact] with the study's point applied, as _point
    applies it): the law and every setting of it."""
    return dataclasses.asdict(dataclasses.replace(scene.contact, **point))


def contact_point(scene: Scene, ks_ratio=None, ks_N_per_m=None, r=None) -> dict:
    """The contact parameters of the ratio runs: as given, else the scene's base point, else the first
    value of its sweep axis (a scene may sweep them and set no base value)."""
    out = {}
    if ks_ratio is not None or ks_N_per_m is not None:
        out.update(setting_ks("ks_ratio", ks_ratio) if ks_ratio is not None else setting_ks("ks_N_per_m", ks_N_per_m))
    elif scene.contact.ks_ratio is None and scene.contact.ks_N_per_m is None:
        for form in ("ks_ratio", "ks_N_per_m"):
            if scene.axis_values(form):
                out.update(setting_ks(form, scene.axis_values(form)[0]))
    if r is not None:
        out["r"] = float(r)
    elif scene.axis_values("r") and "r" not in out:
        out["r"] = scene.contact.r
    return out


def _metrics(scene: Scene, threads: int) -> dict:
    """Each grid point's metric row (columns by name), the scene's kernel (metrics only: the lane kernel)."""
    prep = prepare(scene)
    metrics, _, _, _, _ = prep.run(prep.grid.chunk(0, prep.grid.size), threads)
    names = L.metric_columns(prep.model.floors, prep.model.n_pairs)
    out = {n: metrics[:, i] for i, n in enumerate(names)}
    bad = (metrics[:, names.index("status_code")].astype(np.int64) & L.STATUS_NONFINITE) != 0
    if bad.any():
        raise ConfigError(f"[gap study] {scene.name}: a run diverged; the study needs finite runs")
    return out


def required_gaps(scene: Scene, length_scale: float | None = None, threads: int = 0, contact: dict | None = None):
    """One row per record and floor pair: the exact required gap against ABS, SRSS, DDC and TBEC 2018's
    minimum, at model scale [m] and, with a length scale, at full scale."""
    import pandas as pd

    model = CoupledModel.from_scene(scene)
    lam = float(length_scale if length_scale is not None else scene.excitation.length_scale)
    w1, z1 = frame_first_mode(model.b1)
    w2, z2 = frame_first_mode(model.b2)
    rho = cqc_correlation(w1, w2, z1, z2)
    h = scene.building1.story_heights()
    heights = floor_heights_m(h) if h else None
    rows = []
    for rec in _records(scene):
        # the separated run: any contact makes none at this gap, but the scene must be whole (contact: the study's
        # point, where [contact] leaves a setting to a sweep axis)
        m = _metrics(_point(scene, rec, (SEPARATED_GAP_M,), contact or {}), threads)
        for j in range(1, model.n_pairs + 1):
            closing = SEPARATED_GAP_M - m[f"closest_approach_f{j}_m"][0]  # the largest u1 - u2
            u1, u2 = m[f"peak_disp_b1f{j}_m"][0], m[f"peak_disp_b2f{j}_m"][0]
            row = {
                "record": _label(scene, rec),
                "pair": j,
                "height_m": np.nan if heights is None else float(heights[j - 1]),
                "exact_m": max(0.0, closing),
                "closing_time_s": m[f"closest_approach_time_f{j}_s"][0],
                "peak_disp_b1_m": u1,
                "peak_disp_b2_m": u2,
                "rho": rho,
            }
            for rule in RULES:
                row[f"{rule.lower()}_m"] = combined_gap(u1, u2, rule, rho)
            row["tbec2018_min_m"] = (
                tbec2018_minimum_gap_m(row["height_m"] * lam) / lam if heights is not None else np.nan
            )
            rows.append(row)
    df = pd.DataFrame(rows)
    df["length_scale"] = lam
    for col in ("exact_m", "abs_m", "srss_m", "ddc_m", "tbec2018_min_m", "height_m"):
        df[col[: -len("_m")] + "_full_scale_m"] = df[col] * lam
    for rule in ("abs", "srss", "ddc"):
        with np.errstate(divide="ignore", invalid="ignore"):
            df[f"{rule}_over_exact"] = df[f"{rule}_m"] / df["exact_m"]
    return df


def response_ratios(scene: Scene, required, relative_gaps=RELATIVE_GAPS, contact: dict | None = None, threads: int = 0):
    """Per record, relative gap and building: its peak responses with the gap relative_gap x the governing
    required gap (the largest over the floor pairs) over those of the separated run: the top floor's peak
    displacement, the largest story drift, the top floor's peak absolute acceleration."""
    import pandas as pd

    contact = contact or {}
    model = CoupledModel.from_scene(scene)
    rows = []
    for rec in _records(scene):
        name = _label(scene, rec)
        g_req = float(required[required.record == name].exact_m.max())
        rel = np.asarray(relative_gaps, dtype=float)
        m = _metrics(_point(scene, rec, tuple(rel * g_req) + (SEPARATED_GAP_M,), contact), threads)
        sep = len(rel)  # the last run: the separated one
        n_pairs = model.n_pairs
        for k, r in enumerate(rel):
            for b, nf in zip((1, 2), model.floors):
                top_d, top_a = f"peak_disp_b{b}f{nf}_m", f"peak_abs_acc_b{b}f{nf}_m_s2"
                drifts = [f"peak_drift_b{b}s{s}_m" for s in range(1, nf + 1)]
                drift, drift_sep = max(m[c][k] for c in drifts), max(m[c][sep] for c in drifts)
                rows.append(
                    {
                        "record": name,
                        "relative_gap": float(r),
                        "gap_m": float(r * g_req),
                        "required_gap_m": g_req,
                        "building": b,
                        "disp_ratio": m[top_d][k] / m[top_d][sep],
                        "drift_ratio": drift / drift_sep,
                        "acc_ratio": m[top_a][k] / m[top_a][sep],
                        "peak_disp_m": m[top_d][k],
                        "peak_drift_m": drift,
                        "peak_abs_acc_m_s2": m[top_a][k],
                        "impacts": int(sum(m[f"impacts_f{j}"][k] for j in range(1, n_pairs + 1))),
                        "peak_force_N": max(m[f"peak_force_f{j}_N"][k] for j in range(1, n_pairs + 1)),
                    }
                )
    return pd.DataFrame(rows)


def gap_study(
    scene: Scene, relative_gaps=RELATIVE_GAPS, length_scale: float | None = None, threads: int = 0, **contact
) -> GapStudy:
    """required_gaps and response_ratios of a scene (contact: ks_ratio, ks_N_per_m, r of the ratio runs). A [sweep]
    axis other than the records and the contact's is not studied (the study runs one excitation per record): said."""
    from pounding_sweep.errors import shown
    from pounding_sweep.warn import warn

    ignored = [a for a in scene.sweep if a.name not in STUDIED_AXES]
    if ignored:
        warn(
            "gaps_axis_ignored",
            "; ".join(f"[sweep] {a.name} = {shown(list(a.values))}" for a in ignored)
            + ": not studied: a gap study runs each motion once, at the scene's own value of these; run it once per "
            "value (set in its section), or `python -m pounding_sweep risk` for the probability of pounding over "
            "intensity levels or motions",
        )
    from pounding_sweep.sweep.checks import check_motion

    # what a sweep of the scene is told of its motions (a vertical component, a step coarser than the record's
    # samples); the study reads no experiment, nor any [sweep] axis but the records'
    motions = tuple(a for a in scene.sweep if a.name == "record")
    check_motion(prepare(dataclasses.replace(scene, experiment=None, calibrate=None, sweep=motions)))
    point = contact_point(scene, **contact)
    _say_contact_axes(scene, point, contact)
    req = required_gaps(scene, length_scale, threads, point)
    ratios = response_ratios(scene, req, relative_gaps, point, threads)
    lam = float(req.length_scale.iloc[0])
    return GapStudy(scene.name, lam, contact_used(scene, point), req, ratios)


def _say_contact_axes(scene: Scene, point: dict, given: dict) -> None:
    """A warning for each contact axis of several values that no option chose: the ratio runs take one point."""
    from pounding_sweep.errors import shown
    from pounding_sweep.warn import warn

    used = contact_used(scene, point)
    chosen = {k for k, v in given.items() if v is not None}
    if chosen & {"ks_ratio", "ks_N_per_m"}:
        chosen |= {"ks_ratio", "ks_N_per_m"}
    for a in scene.sweep:
        if a.name in CONTACT_AXES and a.name != "gap_m" and len(a.values) > 1 and a.name not in chosen:
            hint = f" (give --{a.name.replace('_', '-')} for another)" if a.name in ("ks_ratio", "r") else ""
            warn(
                "gaps_contact_point",
                f"[sweep] {a.name} = {shown(list(a.values))}: the study's response ratios take one contact point, "
                f"{a.name} = {used.get(a.name)!r}{hint}",
            )


#: what the study's table columns hold (written into their metadata)
COLUMN_DOCS = {
    "required_gaps": {
        "record": "the motion (record file's name, 'harmonic' or the stochastic seed)",
        "pair": "facing floor pair j (floor j of both buildings) [-]",
        "height_m": "the pair's height above the table [m]",
        "exact_m": "the gap this pair needs in this run: its largest closing relative displacement u1 - u2 [m]",
        "closing_time_s": "when it closes most [s]",
        "peak_disp_b1_m": "building 1's peak displacement at that floor [m]",
        "peak_disp_b2_m": "building 2's [m]",
        "rho": "Der Kiureghian's CQC correlation of the two first modes (DDC) [-]",
        "abs_m": "ABS rule: the sum of the two peaks [m]",
        "srss_m": "SRSS rule: the square root of the sum of their squares [m]",
        "ddc_m": "double-difference rule with rho [m]",
        "tbec2018_min_m": f"TBEC 2018 minimum: {TBEC2018_RULE} of the pair's full-scale height, back to model scale [m]",
        "length_scale": "model-to-full-scale length factor [-]",
        "abs_over_exact": "ABS / exact (likewise srss_, ddc_) [-]",
    },
    "response_ratios": {
        "relative_gap": "the run's gap over the exact required gap of the record [-]",
        "gap_m": "the run's gap [m]",
        "building": "building 1 or 2",
        "disp_ratio": "top floor peak displacement, this gap / separated (likewise drift_ratio, acc_ratio) [-]",
        "impacts": "contact phases over the pairs [-]",
        "peak_force_N": "largest pounding force [N]",
    },
}

#: the [sweep] axes a gap study takes: the records (one study each), the gaps (its own), the contact's (the ratio runs
#: take one point of them: _say_contact_axes)
CONTACT_AXES = tuple(names(CONTACT))  # gap_m among them
STUDIED_AXES = ("record", *CONTACT_AXES)


def _label(scene: Scene, record) -> str:
    """The motion's name in the tables: the record's, 'harmonic', or the stochastic realisation's seed."""
    if record is not None:
        return _name(record)
    return "harmonic" if scene.excitation.type == "harmonic" else f"stochastic seed {scene.stochastic.seed}"


def _name(path: str) -> str:
    from pathlib import Path

    return Path(path).stem
