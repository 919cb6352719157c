"""`python -m pounding_sweep plot`: PNG figures of a result file."""

from __future__ import annotations

import subprocess
import sys

import pytest

from conftest import REPO, SWEEPS

pytest.importorskip("matplotlib", reason="plots need the 'plot' extra (matplotlib)")


def test_plot_command_writes_pngs(tmp_path):
    out = tmp_path / "scored.parquet"
    run = subprocess.run([sys.executable, "-m", "pounding_sweep", str(SWEEPS / "scored_6hz.toml"), "--out", str(out), "--quiet"],
                         capture_output=True, text=True, cwd=REPO)
    assert run.returncode == 0, run.stderr
    p = subprocess.run([sys.executable, "-m", "pounding_sweep", "plot", str(out), "--out", str(tmp_path / "png")],
                       capture_output=True, text=True, cwd=REPO)
    assert p.returncode == 0, p.stderr
    names = {line.rsplit("/", 1)[-1] for line in p.stdout.split()}
    assert names == {"heatmaps.png", "displacement_history.png", "pounding_force.png", "ssp.png"}
    for n in names:
        data = (tmp_path / "png" / n).read_bytes()
        assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 10_000


def test_plot_of_a_missing_file_is_a_clear_error(tmp_path):
    p = subprocess.run([sys.executable, "-m", "pounding_sweep", "plot", str(tmp_path / "nope.parquet")],
                       capture_output=True, text=True, cwd=REPO)
    assert p.returncode == 2 and "nope.parquet" in p.stderr and "Traceback" not in p.stderr
