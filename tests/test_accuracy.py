"""The accuracy benchmark and the stability map on small cases: their references and invariants
(issue 5). Correctness only: run times are measured by the scripts, never asserted here."""

from __future__ import annotations

import dataclasses
import re
import subprocess
import sys

import numpy as np
import pandas as pd
import pytest
from conftest import REPO, SWEEPS

from pounding_sweep import accuracy as ba
from pounding_sweep.reference.ivp import continuous_reference
from pounding_sweep.scene import load_scene


def base_scene(name: str, duration_s: float):
    """The shipped scene's base point, no sweep, the given duration."""
    s = load_scene(SWEEPS / f"{name}.toml")
    return dataclasses.replace(
        s, sweep=(), experiment=None, excitation=dataclasses.replace(s.excitation, duration_s=float(duration_s))
    )


def _quiet(*_):
    pass


def test_continuous_reference_is_ivp_reference_on_harmonic_motion():
    """The benchmark's reference (records too) is tests/reference.py's ivp_reference on a harmonic scene,
    and is converged: 10x tighter tolerances move it by far less than the errors it measures."""
    scene = base_scene("paper_6hz", 0.3)
    ref = continuous_reference(scene, ks_ratio=10.0, r=0.4)
    same = ba.check_against_ivp_reference(scene, ref, ks_ratio=10.0, r=0.4)
    check = ba.reference_self_check(scene, ref, ks_ratio=10.0, r=0.4)
    assert ref.impacts.sum() > 3 and np.all(np.isfinite(ref.top))
    # two solve_ivp integrations (DOP853, rtol 1e-10, atol 1e-13) of the same pieces: they differ by the
    # integrators' error control, which keeps each step's error under rtol (1e-8 % is 1e-10): not rounding
    assert same["same_impacts"] and same["rel_rms_pct"] < 1e-8
    assert check["same_events"] and check["rel_rms_pct"] < 1e-8 and check["peak_force_pct"] < 1e-7
    # the peak force includes the instants of impact and is refined on the dense output: not below any sample
    assert ref.peak_force[2] > 0 and ref.peak_disp[2] >= np.abs(ref.top[:, 0]).max()


def test_accuracy_quick_ladder_6hz(tmp_path):
    """benchmarks/bench_accuracy.py --quick on the 6 Hz scene (k_s/k = 10, 0.5 s, dt 1e-3 .. 1e-4 s), run as a
    user runs it: finite errors, the event scheme second order and below the other two at every resolved dt,
    a CSV the plots module reads and its PNG."""
    from pounding_sweep.plots import read_accuracy_table

    r = subprocess.run(
        [
            sys.executable,
            str(REPO / "benchmarks" / "bench_accuracy.py"),
            "--quick",
            "--scene",
            "paper_6hz",
            "--repeats",
            "1",
            "--out-dir",
            str(tmp_path),
        ],
        capture_output=True,
        text=True,
        cwd=tmp_path,
    )
    assert r.returncode == 0, r.stderr[-2000:]
    df = read_accuracy_table(tmp_path / "bench_accuracy_paper_6hz_quick.csv")
    assert set(df.scheme) == {"event", "implicit", "paper"} and len(df) == 12
    assert np.isfinite(df.rel_rms_pct).all() and (df.rel_rms_pct > 0).all()
    order, lo, hi, n = ba.observed_order(df, "event")
    assert order > 1.8 and n >= 2
    ev = df[df.scheme == "event"].set_index("dt_s")
    for other in ("implicit", "paper"):
        o = df[df.scheme == other].set_index("dt_s")
        assert (ev.rel_rms_pct[ev.index <= 2.5e-4] < o.rel_rms_pct[o.index <= 2.5e-4]).all()
    assert (ev.impacts_f3[ev.index <= 5e-4] == ev.ref_impacts_f3[ev.index <= 5e-4]).all()
    # the Richardson extrapolation lies far closer to the reference than the finest run (it is converged)
    m = re.search(r"Richardson check .*: event ([0-9.e+-]+) %, extrapolated ([0-9.e+-]+) % off", r.stdout)
    assert m, r.stdout[-2000:]
    assert float(m.group(2)) < 0.2 * float(m.group(1))
    assert (tmp_path / "bench_accuracy_paper_6hz_quick.png").is_file()


def test_event_scheme_second_order_on_the_record():
    """The Duzce record (first 1 s, k_s/k = 10): the event scheme converges at second order to the
    record reference (solve_ivp restarted at every record sample)."""
    scene = base_scene("paper_duzce", 1.0)
    ov = {"ks_ratio": 10.0, "r": 0.2}
    ref = continuous_reference(scene, **ov)
    assert ref.impacts.sum() > 3
    df = ba.ladder(scene, ref, dts=(5e-4, 2.5e-4, 1e-4), schemes=("event",), repeats=1, log=_quiet, **ov)
    assert np.isfinite(df.rel_rms_pct).all()
    order = ba.observed_order(df, "event")[0]
    assert order > 1.8, df[["dt_s", "rel_rms_pct"]]


def test_equal_time_ratio_interpolates_in_log_log():
    """The equal-run-time comparison: the slow scheme's curve interpolated at the fast run's time, none
    outside its range, diverged points left out."""
    df = pd.DataFrame(
        {
            "scheme": ["event"] * 2 + ["paper"] * 3,
            "dt_s": [1e-3, 1e-4, 1e-2, 1e-3, 1e-4],
            "run_time_s": [2.0, 20.0, 0.5, 1.0, 10.0],
            "rel_rms_pct": [1e-2, 1e-4, np.nan, 1.0, 0.1],
        }
    )
    r = ba.equal_time_ratios(df).set_index("dt_s")
    assert r.loc[1e-3, "paper_at_same_time_pct"] == pytest.approx(10 ** (-np.log10(2.0)))  # 1 % at 1 s, 0.1 % at 10 s
    assert r.loc[1e-3, "ratio"] == pytest.approx(50.0)
    assert np.isnan(r.loc[1e-4, "ratio"])  # 20 s lies beyond the paper scheme's 10 s


def test_stability_quick_map_invariants(tmp_path):
    """stability_map's quick mode (6 Hz, 0.2 s, k_s/k 1e-2/1/1e4, r 0/1, 10 mm, dt 1e-4 and 5e-3 s, both laws,
    every scheme): the default (event) scheme never diverges, never turns non-finite and makes no energy;
    the under-resolved flag is set exactly where dt exceeds 1/20 of the contact period; the paper scheme's
    blow-up at k_s/k = 1e4, dt = 5e-3 s is caught and flagged; the map's files are written."""
    r = subprocess.run(
        [sys.executable, str(REPO / "benchmarks" / "stability_map.py"), "--quick", "--out-dir", str(tmp_path)],
        capture_output=True,
        text=True,
        cwd=tmp_path,
    )
    assert r.returncode == 0, r.stderr[-2000:]
    df = ba.classify(pd.read_parquet(tmp_path / "stability_map_quick.parquet"))
    assert len(df) == 72
    ev = df[df.scheme == "event"]
    assert not ev.diverged.any() and not ev.nonfinite.any()
    assert not ev.energy_made.any() and not ev.energy_flag.any()
    assert ev.balance_gap.abs().max() < 1e-8
    assert (ev.underresolved == (ev.steps_per_contact_period < 20)).all()
    assert (df.underresolved == (df.steps_per_contact_period < 20)).all()
    stiff = df[(df.scheme == "paper") & (df.ks_ratio == 1e4) & (df.dt_s == 5e-3)]
    assert stiff.diverged.all() and (stiff.category == "diverged").all()
    assert not df[(df.scheme == "paper") & (df.dt_s == 1e-4)].diverged.any()
    b = ba.paper_boundary(df).set_index("ks_ratio")
    assert b.loc[1e4, "smallest_dt_diverged_s"] == 5e-3 and np.isnan(b.loc[1.0, "smallest_dt_diverged_s"])
    assert (tmp_path / "stability_map_quick.png").is_file() and (tmp_path / "stability_map_quick_summary.csv").is_file()


def test_the_figure_ladder_of_a_record_holds_its_strong_motion():
    """The accuracy figure's window (accuracy.ladder_duration): 2 s of a harmonic test; for a record, from rest to
    past its strongest sample (the shipped real Northridge table's first 8 s are the table at rest, so 2 s would
    measure sensor noise), at most 1 s past it, and never beyond the record or the scene's duration_s."""
    from pounding_sweep.model.records import read_record
    from pounding_sweep.scene import load_scene

    assert ba.ladder_duration(load_scene(SWEEPS / "scored_6hz.toml")) == ba.LADDER_S
    s = load_scene(SWEEPS / "real_northridge.toml")
    rec = read_record(s.excitation.record, format=s.excitation.format, units=s.excitation.units)
    t_peak = float(np.argmax(np.abs(rec.acc_m_s2))) * rec.dt_s
    assert t_peak > 8.0  # the strong motion starts after the quiet lead-in
    d = ba.ladder_duration(s)
    assert t_peak < d <= t_peak + ba.LADDER_S / 2 + 1e-12
    short = dataclasses.replace(s, excitation=dataclasses.replace(s.excitation, duration_s=5.0))
    assert ba.ladder_duration(short) == 5.0
