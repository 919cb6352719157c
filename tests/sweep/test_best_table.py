"""Issue 25: the best table beside a scored sweep, and the calibration it stores.

* A rerun of a finished calibration reuses the stored one (the config hash, [calibrate] and the package version
  match: run.calibration_key) instead of calibrating again for a minute in silence; a new calibration says what
  it does on stderr.
* A rerun whose [calibrate] changed (the grid's parts resume: [calibrate] is not in the config hash) first
  writes the grid's best table without the old calibration, so an interrupted calibration never leaves an older
  one in a table that claims this scene; a Ctrl-C there (tests/gates.py) is one line.
* A kill just before the best table's rename leaves its temporary, which the next sweep removes.
* `--out r/x` and `--out r/x.parquet` both name r/x.best.parquet: the second is refused, after the first and
  while it runs.
"""

from __future__ import annotations

import dataclasses
import re
import signal

import pandas as pd
import pytest
from conftest import SWEEPS
from gates import GatedSweep, run

import pounding_sweep.sweep.calibrate as calibrate_module
from pounding_sweep.cli.run import main
from pounding_sweep.errors import OutputError
from pounding_sweep.scene import Axis, load_scene
from pounding_sweep.scene.schema import CalibrateConfig
from pounding_sweep.sweep.best import calibration_key
from pounding_sweep.sweep.results import part_files, read_metadata
from pounding_sweep.sweep.run import run_scene


def scored_scene(tmp_path, calibrate: bool = True, name: str = "s.toml"):
    """The shipped calibration scene, 1 s of the 6 Hz test over 2 grid points; a small calibration of k_s/k and r
    (4 Sobol points, 1 start, 3-point profiles: a few seconds)."""
    text = (SWEEPS / "calibrate_6hz.toml").read_text().replace('"experiments/', f'"{SWEEPS}/experiments/')
    text = text.replace("duration_s = 5.0", "duration_s = 1.0").replace("r = [0.2, 0.4, 0.6, 0.8, 1.0]", "r = [0.4]")
    text = text.replace("ks_ratio = [0.1, 1.0, 5.0, 10.0]", "ks_ratio = [1.0, 5.0]")
    text = re.sub(r"\[calibrate\].*", "", text, flags=re.S)
    if calibrate:
        text += (
            "[calibrate]\nparameters = { ks_ratio = [0.1, 20.0], r = [0.05, 1.0] }\n"
            "global_points = 4\nstarts = 1\nprofile_points = 3\n"
        )
    (tmp_path / name).write_text(text)
    return tmp_path / name


def best_rows(path) -> pd.DataFrame:
    return pd.read_parquet(path).set_index("criterion")


def test_a_rerun_reuses_the_stored_calibration_and_a_new_one_says_what_it_does(tmp_path, capsys, monkeypatch):
    scene_file = scored_scene(tmp_path)
    out = tmp_path / "r.parquet"
    assert main([str(scene_file), "--out", str(out), "--threads", "1"]) == 0
    first = capsys.readouterr()
    assert "calibrating 2 parameter(s) against the experiment for law classic: 4 global points" in first.err
    assert re.search(r"\n  calibrated in \d+ s\n", first.err)
    best = out.with_name("r.best.parquet")
    stored = best_rows(best)
    md = read_metadata(best)
    assert md["calibration_key"] == calibration_key(load_scene(scene_file)) and md["results"] == "r.parquet"

    def no_calibrating(*a, **k):
        raise AssertionError("calibrated again")

    monkeypatch.setattr(calibrate_module, "calibrate", no_calibrating)
    assert main([str(scene_file), "--out", str(out), "--threads", "1"]) == 0
    again = capsys.readouterr()
    assert "calibrating" not in again.err
    assert "kept from an earlier run of this calibration" in again.out
    fitted = [line for line in first.out.splitlines() if line.startswith(("    ks_ratio", "    r "))]
    assert len(fitted) == 2 and fitted == [line for line in again.out.splitlines() if line in fitted]
    pd.testing.assert_frame_equal(best_rows(best), stored)
    s = load_scene(scene_file)
    summary = run_scene(s, out_path=out, threads=1)
    assert summary.calibration_reused and summary.calibration is None
    assert summary.calibration_summary["fits"] == md["calibration"]["fits"]


def test_a_changed_calibrate_is_never_left_stale_and_is_run_again(tmp_path, monkeypatch):
    s = load_scene(scored_scene(tmp_path))
    out = tmp_path / "r.parquet"
    run_scene(s, out_path=out, threads=1)
    best = out.with_name("r.best.parquet")
    changed = dataclasses.replace(s, calibrate=dataclasses.replace(s.calibrate, profile_points=4))
    assert changed.config_hash() == s.config_hash()  # [calibrate] is not in it: the grid's parts resume
    assert calibration_key(changed) != calibration_key(s)
    real = calibrate_module.calibrate

    def interrupted(*a, **k):
        raise KeyboardInterrupt  # Ctrl-C while the new calibration runs

    monkeypatch.setattr(calibrate_module, "calibrate", interrupted)
    with pytest.raises(KeyboardInterrupt):
        run_scene(changed, out_path=out, threads=1)
    md = read_metadata(best)
    assert md["config_hash"] == s.config_hash() and "calibration" not in md and "calibration_key" not in md
    assert "calibrated" not in set(best_rows(best).index)  # the old calibration is gone, the grid's answer stays
    assert {"rel_rms_b1f3_pct", "rel_rms_combined_pct"} <= set(best_rows(best).index)
    monkeypatch.setattr(calibrate_module, "calibrate", real)
    summary = run_scene(changed, out_path=out, threads=1)
    assert not summary.calibration_reused and summary.resumed_parts == summary.parts
    assert read_metadata(best)["calibration_key"] == calibration_key(changed)


def test_ctrl_c_before_the_calibration_is_one_line_and_leaves_the_grids_best_table(tmp_path):
    scene_file = scored_scene(tmp_path)
    out = tmp_path / "r.parquet"
    sweep = GatedSweep(tmp_path / "gate", ["calibrate"], scene_file, "--out", out, "--threads", "1", "--quiet")
    code, _, err = sweep.stop_at("calibrate", signal.SIGINT)
    assert code == 130 and err == "interrupted: the finished parts are kept; run the same command again to resume\n"
    best = out.with_name("r.best.parquet")
    assert "calibration" not in read_metadata(best) and "calibrated" not in set(best_rows(best).index)
    again = run(scene_file, "--out", out, "--threads", "1")
    assert again.returncode == 0, again.stderr
    assert "calibrated" in set(best_rows(best).index)


def test_a_kill_before_the_best_tables_rename_leaves_a_temporary_the_next_sweep_removes(tmp_path):
    scene_file = scored_scene(tmp_path, calibrate=False)
    out = tmp_path / "r.parquet"
    sweep = GatedSweep(tmp_path / "gate", ["best"], scene_file, "--out", out, "--threads", "1", "--quiet")
    try:
        sweep.wait_at("best")
        left = [p.name for p in tmp_path.iterdir() if p.name.startswith(".r.best.parquet.")]
        sweep.signal(signal.SIGKILL)
    finally:
        sweep.kill()
    assert sorted(left) == [f".r.best.parquet.{sweep.pid}.tmp", ".r.best.parquet.lock"]
    assert not out.with_name("r.best.parquet").exists()
    again = run(scene_file, "--out", out, "--threads", "1", "--quiet")
    assert again.returncode == 0, again.stderr
    assert sorted(p.name for p in tmp_path.iterdir() if p.name.startswith(".r.")) == []  # temporary and lock gone
    assert "rel_rms_combined_pct" in set(best_rows(out.with_name("r.best.parquet")).index)


def test_two_result_folders_never_share_their_best_table(tmp_path):
    s = load_scene(scored_scene(tmp_path, calibrate=False))
    run_scene(s, out_path=tmp_path / "x.parquet", threads=1)
    best = tmp_path / "x.best.parquet"
    kept = best.read_bytes()
    with pytest.raises(OutputError, match=r"x.best.parquet: holds the best runs of the results in .*x.parquet, not of"):
        run_scene(s, out_path=tmp_path / "x", threads=1)
    assert best.read_bytes() == kept and not (tmp_path / "x").exists()
    # while a sweep into y.parquet runs (stopped after its first part), one into y waits for nothing: refused
    scene_file = scored_scene(tmp_path, calibrate=False, name="t.toml")
    text = scene_file.read_text() + "\n[execution]\nchunk_runs = 1\n"
    scene_file.write_text(text)
    first = GatedSweep(tmp_path / "gate", ["part-1"], scene_file, "--out", tmp_path / "y.parquet", "--quiet")
    try:
        first.wait_at("part-1")
        with pytest.raises(
            OutputError, match=rf"y.best.parquet: another sweep is writing to this file \(process {first.pid}\)"
        ):
            run_scene(load_scene(scene_file), out_path=tmp_path / "y", threads=1)
        assert not (tmp_path / "y").exists()
        first.release("part-1")
        code, _, err = first.finish()
    finally:
        first.kill()
    assert code == 0, err
    assert len(part_files(tmp_path / "y.parquet")) == 2
    assert read_metadata(tmp_path / "y.best.parquet")["results"] == "y.parquet"


def test_a_calibration_key_covers_the_calibrate_section():
    s = load_scene(SWEEPS / "calibrate_6hz.toml")
    other = dataclasses.replace(s, calibrate=CalibrateConfig(parameters={"r": (0.05, 1.0)}))
    grid = dataclasses.replace(s, sweep=(Axis("ks_ratio", (1.0, 2.0)),))
    assert len({calibration_key(s), calibration_key(other), calibration_key(grid)}) == 3
