"""[output] metrics (issue 30): a sweep computes only the metric groups its scene names; the columns of the others
are NaN (nulls for the counts) in every row, the rest bit for bit a full run's; the metadata lists the groups and
says the left-out columns were not computed; the key is validated; what reads a group gets it (the risk study:
tests/risk/test_risk_groups.py), and scoring and calibration, which read none, give the same answer without any.

Why bit for bit, not to a tolerance: the mask (engine KernelOptions.groups) only skips the left-out groups' own
bookkeeping, which writes no other slot (engine/layout.py leave_out); the motion, and every kept metric, come from
the same operations on the same inputs in the same order, so the same IEEE 754 results. A difference of one ulp
would mean the mask changed the integration, which is the bug this test is for."""

from __future__ import annotations

import dataclasses
import fnmatch

import numpy as np
import pandas as pd
import pytest
from conftest import SWEEPS
from test_best_table import scored_scene

from pounding_sweep.engine import layout as L
from pounding_sweep.errors import ConfigError
from pounding_sweep.scene import load_scene, validate
from pounding_sweep.scene.groups import METRIC_GROUPS
from pounding_sweep.sweep.metricgroups import left_out_columns, sweep_groups
from pounding_sweep.sweep.results import COLUMN_DOCS, GROUP_FLAGS, read_metadata
from pounding_sweep.sweep.run import run_scene


def test_the_scene_knows_the_engines_groups():
    """The scene layer cannot import the engine: its list of group names is checked against the engine's here."""
    assert METRIC_GROUPS == tuple(L.GROUPS)


def test_a_scene_scoring_an_acceleration_computes_the_peak_accelerations():
    """The scale check after a grid (sweep/checks.py check_scale) reads the runs' peak absolute accelerations
    for a scored acceleration channel: such a scene computes accel whatever [output] metrics says."""
    for name, acc in (("real_northridge.toml", True), ("scored_6hz.toml", False)):
        s = load_scene(SWEEPS / name)
        for metrics in (("none",), ("drift",), None):
            s = dataclasses.replace(s, output=dataclasses.replace(s.output, metrics=metrics))
            asked = L.groups_mask(metrics or ("all",))
            assert sweep_groups(s) == (asked | L.GROUP_ACCEL if acc else asked), (name, metrics)


def test_the_accel_group_keeps_earlier_hashes_where_it_computes_what_they_did(tmp_path):
    """Every run computed the peak accelerations before accel was a group (6cae336): a scene computing it hashes
    [output] metrics as before (the groups then named: earlier results resume), one leaving it out is marked
    (earlier parts hold accelerations its new parts would not). Measured with the export of eaf6e55, the commit
    before: the 6 Hz scene with metrics ("drift",) hashed a8fb3dc5..., as ("drift", "accel") does here."""
    from pounding_sweep.scene.hashing import _output

    assert _output({"metrics": ("all",)}) == {"metrics": ["energy", "drift", "closest", "phases"]}
    assert _output({"metrics": ("drift", "accel")}) == {"metrics": ["drift"]}
    assert _output({"metrics": ("drift",)}) == {"metrics": ["drift", "no_accel"]}
    assert _output({"metrics": ("none",)}) == {"metrics": ["no_accel"]}
    assert _output({"metrics": None}) == {}
    h = {m: six_hz(tmp_path, m).config_hash() for m in (None, ("all",), ("drift", "accel"), ("drift",), ("none",))}
    assert len(set(h.values())) == len(h)


def six_hz(tmp_path, metrics, scheme: str = "event", name: str = "s"):
    """The paper's 6 Hz grid, 0.3 s of it (every pair pounds), with [output] metrics (None: not given)."""
    s = load_scene(SWEEPS / "paper_6hz.toml")
    s = dataclasses.replace(
        s,
        excitation=dataclasses.replace(s.excitation, duration_s=0.3),
        integration=dataclasses.replace(s.integration, scheme=scheme),
        output=dataclasses.replace(s.output, path=str(tmp_path / f"{name}.parquet"), metrics=metrics),
    )
    validate(s)
    return s


def rows(path) -> pd.DataFrame:
    return pd.read_parquet(path).drop(columns=["run_time_s"]).sort_values("run_id").reset_index(drop=True)


@pytest.fixture(scope="module")
def full(tmp_path_factory):
    """Every group, per scheme (the key left out: today's default)."""
    out = {}
    for scheme in ("event", "implicit"):
        s = six_hz(tmp_path_factory.mktemp(scheme), None, scheme)
        run_scene(s, threads=2)
        out[scheme] = rows(s.output.path)
    return out


@pytest.mark.parametrize("scheme", ["event", "implicit"])
@pytest.mark.parametrize("metrics", [("none",), ("energy", "closest"), ("drift", "phases")])
def test_left_out_groups_are_nan_and_the_rest_bit_for_bit(tmp_path, full, scheme, metrics):
    s = six_hz(tmp_path, metrics, scheme)
    run_scene(s, threads=2)
    sub, every = rows(s.output.path), full[scheme]
    kept = L.groups_mask(metrics)
    nan = [c for c in left_out_columns(kept, s.floors, 3) if c in every]
    assert nan and every[nan].notna().all().all()  # computed in the full run ...
    assert sub[nan].isna().all().all()  # ... and not at all here
    others = [c for c in every.columns if c not in nan and c != "status"]
    pd.testing.assert_frame_equal(sub[others], every[others], check_exact=True)  # same dtypes, same bits
    # the status: the full run's flags but those the left-out groups would set
    unset = {GROUP_FLAGS[g] for g in GROUP_FLAGS if not kept & L.GROUPS[g]}
    for a, b in zip(sub.status, every.status):
        words = [w for w in b.split("+") if w not in unset] or ["ok"]
        assert a == "+".join(words)
    md = read_metadata(s.output.path)
    assert md["metric_groups"]["computed"] == [g for g in METRIC_GROUPS if kept & L.GROUPS[g]]
    assert md["metric_groups"]["left_out"] == [g for g in METRIC_GROUPS if not kept & L.GROUPS[g]]
    for pattern, doc in md["columns"].items():  # exactly the left-out columns' patterns say "not computed"
        left = any(fnmatch.fnmatchcase(c, pattern) for c in nan)
        assert doc.startswith("not computed: [output] metrics") == left, pattern
        assert left or doc == COLUMN_DOCS[pattern] or pattern == "status"
    _, _, unchecked = md["columns"]["status"].partition("not checked here: ")
    for g, flag in GROUP_FLAGS.items():
        assert (flag in unchecked) == (not kept & L.GROUPS[g])


def test_the_default_computes_every_group_and_keeps_its_hash(tmp_path, full):
    """No key: every group (the metadata says so, the column docs are the plain ones), and the scene hashes as
    before the key existed; 'all' computes the same; the order of a list does not change the hash."""
    s = six_hz(tmp_path, None)
    assert "metrics" not in s.canonical()["output"]
    run_scene(s, threads=2)
    md = read_metadata(s.output.path)
    assert md["metric_groups"]["computed"] == list(METRIC_GROUPS) and md["metric_groups"]["left_out"] == []
    assert md["columns"] == COLUMN_DOCS
    every = six_hz(tmp_path, ("all",), name="all")
    run_scene(every, threads=2)
    pd.testing.assert_frame_equal(rows(every.output.path), full["event"], check_exact=True)
    a, b = six_hz(tmp_path, ("drift", "energy")), six_hz(tmp_path, ("energy", "drift"))
    assert a.config_hash() == b.config_hash() != s.config_hash()


def test_the_no_contact_warning_says_the_closest_approach_was_not_computed(tmp_path):
    """A grid that never pounds (gap 200 mm, the floors come a few mm nearer): computed, the closest approach shows
    the grid separated on purpose and nothing is said; left out, it is not read as a value (NaN would pass for
    "never approached"): the warning fires and says it does not know how near the floors came."""
    s = six_hz(tmp_path, ("energy",))
    s = dataclasses.replace(s, contact=dataclasses.replace(s.contact, gap_m=0.2))
    (msg,) = [w for w in run_scene(s, threads=2).warnings if w.startswith("no run made contact")]
    assert "not known ([output] metrics leaves out closest" in msg
    t = dataclasses.replace(s, output=dataclasses.replace(s.output, metrics=None, path=str(tmp_path / "b.parquet")))
    summary = run_scene(t, threads=2)
    assert summary.extremes["peak_force_N"] == 0 and not summary.warnings


@pytest.mark.parametrize(
    "value, fragment",
    [
        (("energyy",), "'energyy' is not a metric group"),
        (("drift", "drift"), "a group named twice"),
        (("all", "drift"), "'all' and 'none' stand alone"),
    ],
)
def test_a_bad_metrics_key_is_refused_naming_it(tmp_path, value, fragment):
    s = six_hz(tmp_path, None)
    bad = dataclasses.replace(s, output=dataclasses.replace(s.output, metrics=value))
    with pytest.raises(ConfigError, match="^\\[output\\] metrics = ") as e:
        validate(bad)
    assert fragment in str(e.value)


def test_scoring_and_calibration_read_no_group(tmp_path):
    """A scored, calibrated scene with every group left out ranks, refines and calibrates exactly as with all:
    the scores come from the kernel's score spec, the calibration fits histories (sweep/metricgroups.py)."""
    out = {}
    for metrics in ("none", "all"):
        path = scored_scene(tmp_path, name=f"{metrics}.toml")
        path.write_text(path.read_text().replace("[output]\n", f'[output]\nmetrics = "{metrics}"\n', 1))
        s = load_scene(path)
        assert s.output.metrics == (metrics,)
        s = dataclasses.replace(s, output=dataclasses.replace(s.output, path=str(tmp_path / f"{metrics}.parquet")))
        summary = run_scene(s, threads=2)
        out[metrics] = (rows(s.output.path), summary.best)
    (none, best_none), (every, best_every) = out["none"], out["all"]
    scores = [c for c in every.columns if c.startswith("rel_rms_")]
    assert scores
    pd.testing.assert_frame_equal(none[scores], every[scores], check_exact=True)
    assert "calibrated" in set(best_none.criterion) and np.isfinite(best_none.error_pct).all()
    pd.testing.assert_frame_equal(best_none, best_every, check_exact=True)  # the grid's best, refined, calibrated


def test_one_run_in_memory_computes_every_group_whatever_the_key_says(tmp_path):
    """simulate() is read by the figures' captions (compression phases) and the accuracy study (the energy balance
    and its flag): it computes every group whatever [output] metrics says, as the sweep's own run does."""
    from pounding_sweep.sweep.simulate import simulate

    _, lean = simulate(six_hz(tmp_path, ("none",)), channels=["disp_b1f3"], ks_ratio=1.0, r=0.4)
    _, every = simulate(six_hz(tmp_path, None), channels=["disp_b1f3"], ks_ratio=1.0, r=0.4)
    for name in ("compression_phases_f3", "median_compression_phase_f3_s", "energy_residual_J", "peak_drift_b1s1_m"):
        assert np.isfinite(lean[name]) and lean[name] == every[name], name  # the same kernel, the same run: exact
