"""Issue 16: mistakes that ran through silently now warn (pounding_sweep.warn), through one mechanism:
printed by the command line as `warning: ...` lines on stderr as they happen, listed in the summary,
stored in the result metadata. A scene without such a mistake prints no warning.

* gap_m = [1, 5] (millimetres in a metre field): no run makes contact;
* a time step that under-resolves every run's contact: a dt to use instead;
* a CSV record whose time column is in ms: implausible step and length, before the long run;
* the separated Duzce scene (no contact by design): the same no-contact warning, without the metres hint.
"""

from __future__ import annotations

import contextlib
import dataclasses
import io
import warnings

import numpy as np
import pandas as pd
import pytest
from conftest import SWEEPS

from pounding_sweep.cli.run import main
from pounding_sweep.scene import Axis, load_scene
from pounding_sweep.sweep.results import read_metadata
from pounding_sweep.sweep.run import run_scene
from pounding_sweep.warn import InputWarning, collecting, warn

SIX_HZ = (SWEEPS / "paper_6hz.toml").read_text()


def scene_file(tmp_path, text: str, name: str = "scene.toml"):
    p = tmp_path / name
    p.write_text(text.replace('path = "../results/paper_6hz.parquet"', 'path = "out.parquet"'))
    return p


def short(text: str, sweep: str) -> str:
    """The 6 Hz scene, 0.5 s, with this [sweep]."""
    head, _, tail = text.partition("[sweep]")
    return (
        head.replace("duration_s = 5.0", "duration_s = 0.5")
        + "[sweep]\n"
        + sweep
        + "\n[output]"
        + tail.split("[output]")[1]
    )


def cli(*argv) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main([str(a) for a in argv])
    return code, out.getvalue(), err.getvalue()


def warning_lines(stderr: str) -> list[str]:
    return [line for line in stderr.splitlines() if line.startswith("warning: ")]


def test_gap_in_millimetres_warns_that_no_run_made_contact(tmp_path):
    p = scene_file(tmp_path, short(SIX_HZ, "gap_m = [1, 5]\nks_ratio = [1.0, 10.0]\nr = [0.4]"))
    code, stdout, stderr = cli(p)
    assert code == 0
    (line,) = warning_lines(stderr)
    assert line.startswith("warning: no run made contact (4 run(s), largest pounding force 0 N)")
    assert "against a gap of 1000 mm" in line and "gap_m = 1 is 1 m (for 1 mm write 0.001)" in line
    assert "the swept gap_m, ks_ratio, r change nothing here" not in line  # r is not swept (one value)
    assert "the swept gap_m, ks_ratio change nothing here" in line
    assert "largest pounding force   0.000 N" in stdout and line.removeprefix("warning: ") in stdout
    assert read_metadata(tmp_path / "out.parquet")["warnings"] == [line.removeprefix("warning: ")]
    # the facing floors' real closest approach: the largest u1 - u2 of any run and pair (gap - closest approach), not
    # the sum of the floors' peaks (which need not come at the same instant, nor toward each other)
    df = pd.read_parquet(tmp_path / "out.parquet")
    approach = {j: (df.gap_m - df[f"closest_approach_f{j}_m"]).max() for j in (1, 2, 3)}
    j = max(approach, key=approach.get)
    assert f"came at most {approach[j] * 1e3:.3g} mm nearer than at rest (floor pair {j})" in line
    assert approach[j] < (df.peak_disp_b1f3_m.abs() + df.peak_disp_b2f3_m.abs()).max()
    # a resumed run says it again (from the stored rows), and leaves the stored warnings as they are
    code, stdout, stderr2 = cli(p)
    assert code == 0 and warning_lines(stderr2) == [line] and "nothing to run" in stdout


def test_the_same_scene_in_metres_warns_nothing(tmp_path):
    p = scene_file(tmp_path, short(SIX_HZ, "gap_m = [0.001, 0.005]\nks_ratio = [1.0, 10.0]\nr = [0.4]"))
    code, stdout, stderr = cli(p)
    assert code == 0 and warning_lines(stderr) == [] and "warning" not in stdout
    assert read_metadata(tmp_path / "out.parquet")["warnings"] == []


def test_a_coarse_time_step_warns_and_suggests_one_that_resolves_every_run(tmp_path):
    text = short(SIX_HZ, "ks_ratio = [5.0, 10.0]\nr = [0.4]").replace("dt_s = 1e-4", "dt_s = 2e-3")
    p = scene_file(tmp_path, text)
    code, stdout, stderr = cli(p, "--quiet")  # warnings are printed with --quiet too
    assert code == 0 and stdout == ""
    (line,) = warning_lines(stderr)
    assert line.startswith("warning: [integration] dt_s = 0.002 s under-resolves every run's contact: 10.1 steps")
    assert "use dt_s = 0.001 (the softest contact) or 0.0005 (every run), or dt_s = 'auto'" in line
    assert set(pd.read_parquet(tmp_path / "out.parquet").status) == {"contact_underresolved"}
    # the suggestions do what they say
    for dt, flagged in (("1e-3", {"ok", "contact_underresolved"}), ("5e-4", {"ok"})):
        q = scene_file(tmp_path, text.replace("dt_s = 2e-3", f"dt_s = {dt}"), f"dt{dt}.toml")
        code, _, stderr = cli(q, "--out", tmp_path / f"dt{dt}.parquet", "--quiet")
        assert code == 0 and warning_lines(stderr) == []
        assert set(pd.read_parquet(tmp_path / f"dt{dt}.parquet").status) == flagged


@pytest.mark.parametrize("sweep", ["r = [0.4]", "kh_N_per_m1_5 = [2e5, 4e5]\nr = [0.4]"], ids=["kh fixed", "kh swept"])
def test_a_hertz_scene_with_kh_alone_runs_and_its_time_step_is_checked(tmp_path, sweep):
    """k_h given as kh_N_per_m1_5 without ks_ratio (the documented way to set a Hertz stiffness) used to end in a
    TypeError in the time-step check; it runs, and a coarse dt warns by the law's tangent stiffness 1.5 k_h
    sqrt(reference_penetration_m) (sweep/prepare.py contact_arrays)."""
    text = short(SIX_HZ, sweep).replace("ks_ratio = 1.0\n", "").replace('law = "classic"', 'law = "hertzdamp"')
    if "kh_N_per_m1_5 = [" not in text:
        text = text.replace('law = "hertzdamp"', 'law = "hertzdamp"\nkh_N_per_m1_5 = 2e5')
    code, _, stderr = cli(scene_file(tmp_path, text), "--quiet")
    assert code == 0 and warning_lines(stderr) == [], stderr
    coarse = scene_file(tmp_path, text.replace("dt_s = 1e-4", "dt_s = 2e-3"), "coarse.toml")
    code, _, stderr = cli(coarse, "--out", tmp_path / "coarse.parquet", "--quiet")
    assert code == 0
    (line,) = warning_lines(stderr)
    assert line.startswith("warning: [integration] dt_s = 0.002 s under-resolves every run's contact: ")
    assert ": 19.1 steps per contact period 2 pi sqrt(m_eff / k) at the softest k_h = 2e+05 N/m^1.5" in line
    df = pd.read_parquet(tmp_path / "coarse.parquet")
    assert df.status.str.contains("contact_underresolved").all() and df.kh_N_per_m1_5.notna().all()


def test_a_record_in_milliseconds_warns_before_it_runs(tmp_path):
    t_ms = np.arange(100) * 5.0  # 200 samples/s written in ms: read as a 5 s step, 495 s long
    acc = 0.5 * np.sin(2 * np.pi * 2.0 * t_ms / 1e3)
    (tmp_path / "rec.csv").write_text("t,acc\n" + "".join(f"{t:.1f},{a:.6f}\n" for t, a in zip(t_ms, acc)))
    head, _, tail = short(SIX_HZ, "ks_ratio = [0.1]").partition("[excitation]")
    text = (
        head + '[excitation]\ntype = "record"\nrecord = "rec.csv"\n\n[integration]' + tail.partition("[integration]")[2]
    )
    text = text.replace("dt_s = 1e-4", "dt_s = 1e-3")
    p = scene_file(tmp_path, text)
    code, stdout, stderr = cli(p)
    assert code == 0
    (line,) = warning_lines(stderr)
    assert line == (
        f"warning: {tmp_path / 'rec.csv'}: a sample step of 5 s is implausible for a ground-motion record "
        "(steps above 0.05 s): is its time in ms rather than s? A run takes 495,000 steps of 0.001 s."
    )
    assert "495,000 steps" in stdout


def test_a_scene_separated_on_purpose_does_not_warn(tmp_path):
    """paper_duzce_separated: a 50 mm gap, which the floors approach by at most 21 mm. Every gap of the grid is at
    least twice the closest approach of any run (checks.SEPARATED_ON_PURPOSE): the separation is the study, and no
    run making contact is what it is for."""
    s = load_scene(SWEEPS / "paper_duzce_separated.toml")
    with collecting() as outer:
        summary = run_scene(s, out_path=tmp_path / "sep.parquet")
    assert summary.warnings == [] and outer.messages() == []
    df = pd.read_parquet(tmp_path / "sep.parquet")
    approach = max((df.gap_m - df[f"closest_approach_f{j}_m"]).max() for j in (1, 2, 3))
    assert 0 < 2 * approach <= df.gap_m.min()  # the criterion, as it held here
    assert df.impacts_f3.sum() == 0
    # the same scene at a gap the floors come within half of: no contact still, and now it is said
    near = dataclasses.replace(s, contact=dataclasses.replace(s.contact, gap_m=1.5 * approach))
    with collecting() as outer:
        summary = run_scene(near, out_path=tmp_path / "near.parquet")
    (msg,) = summary.warnings
    assert msg.startswith("no run made contact (20 run(s)") and f"came at most {approach * 1e3:.3g} mm nearer" in msg
    assert "in metres" not in msg and "the swept ks_ratio, r change nothing here" in msg


def test_buildings_that_never_approach_are_said_so(tmp_path):
    """Two identical buildings at gap 0 move in phase: they never come nearer than at rest. The message says so,
    instead of the sum of their peaks (which it used to give as an approach they never made)."""
    s = load_scene(SWEEPS / "paper_6hz.toml")
    s = dataclasses.replace(
        s,
        building2=s.building1,
        excitation=dataclasses.replace(s.excitation, duration_s=0.5),
        sweep=(Axis("ks_ratio", (1.0, 10.0)),),
    )
    summary = run_scene(s, out_path=tmp_path / "twins.parquet")
    (msg,) = summary.warnings
    assert "the facing floors never moved toward each other (the buildings move in phase), against a gap of 0 mm" in msg
    df = pd.read_parquet(tmp_path / "twins.parquet")
    approach = (df.gap_m - df.closest_approach_f3_m).max()  # rounding of two equal motions: checks.ROUNDING_APPROACH
    assert approach < 1e-9 * df.peak_disp_b1f3_m.max() and (df.peak_disp_b1f3_m > 1e-3).all()


def test_outside_a_collector_a_warning_is_a_python_warning():
    with pytest.warns(InputWarning, match="something odd"):
        warn("test", "something odd")
    with collecting() as c, warnings.catch_warnings():
        warnings.simplefilter("error")
        warn("test", "once")
        warn("test", "once")  # the same message is kept once
    assert c.messages() == ["once"]
