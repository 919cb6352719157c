"""Issue 25: `plot` redraws a sweep's best run from the files the sweep read, so it checks them first.

* A record or table replaced since the sweep (same name, other content: the SHA-256 in the result's metadata
  differs) is one error line naming it: the figures would show another run. Nothing is written.
* A project folder moved (or copied) with its results is plotted from its own files, found beside the results
  (the result keeps the scene's folder relative to its own), as a rerun there resumes.
* A folder with a user's PNG of a figure's name is refused, and so is an --out inside the result folder and a
  damaged best table (the corpus: tests/bad_inputs, category 'commands').
"""

from __future__ import annotations

import dataclasses
import shutil

import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from conftest import SWEEPS

from pounding_sweep import plots
from pounding_sweep.cli.run import main
from pounding_sweep.errors import ResultError
from pounding_sweep.scene import load_scene
from pounding_sweep.sweep.run import run_scene


@pytest.fixture
def project(tmp_path):
    """A project folder: scene, experiment table and results (2 runs of 1 s of the scored 6 Hz test)."""
    root = tmp_path / "here" / "project"
    (root / "experiments").mkdir(parents=True)
    shutil.copy(SWEEPS / "experiments" / "synthetic_6hz.parquet", root / "experiments")
    text = (SWEEPS / "scored_6hz.toml").read_text().replace("duration_s = 5.0", "duration_s = 1.0")
    text = text.replace("r = [0.2, 0.4, 0.6, 0.8, 1.0]", "r = [0.4]").replace(
        "ks_ratio = [0.1, 1.0, 5.0, 10.0]", "ks_ratio = [1.0, 5.0]"
    )
    (root / "scene.toml").write_text(text.replace("refine = true", "refine = false"))
    run_scene(load_scene(root / "scene.toml"), out_path=root / "results" / "r.parquet", threads=1)
    return root


def test_a_table_changed_since_the_sweep_is_refused(project, capsys):
    table = project / "experiments" / "synthetic_6hz.parquet"
    t = pq.read_table(table)
    df = t.to_pandas()
    df.iloc[3, 1] += 0.01  # one sample moved by 10 um: another experiment
    pq.write_table(pa.Table.from_pandas(df, preserve_index=False).replace_schema_metadata(t.schema.metadata), table)
    results = project / "results" / "r.parquet"
    assert main(["plot", str(results)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith(f"error: {results}: a file the sweep read is not there as it was")
    assert "[experiment] table = synthetic_6hz.parquet (sha256 " in err and "put the sweep's file back" in err
    assert sorted(p.name for p in results.parent.iterdir()) == ["r.best.parquet", "r.parquet"]  # no figures
    with pytest.raises(ResultError, match="synthetic_6hz.parquet"):
        plots.scene_of(results)


def test_a_moved_project_is_plotted_from_its_own_files(project, tmp_path):
    moved = tmp_path / "elsewhere" / "renamed"
    moved.parent.mkdir()
    shutil.move(project, moved)
    results = moved / "results" / "r.parquet"
    scene = plots.scene_of(results)
    assert scene.experiment.table == str(moved / "experiments" / "synthetic_6hz.parquet")
    assert scene.config_hash() == load_scene(moved / "scene.toml").config_hash()
    best = plots.read_best(results)
    assert "rel_rms_combined_pct" in set(best.criterion)
    # the results alone moved away from their project: the files are found nowhere, and both places are named
    alone = tmp_path / "alone" / "results"
    alone.parent.mkdir()
    shutil.move(moved / "results", alone)
    with pytest.raises(ResultError) as e:
        plots.scene_of(alone / "r.parquet")
    assert str(moved) not in str(e.value) and str(tmp_path / "here" / "project") in str(e.value)
    assert "unreadable" in str(e.value) and str(tmp_path / "alone") in str(e.value)


def test_a_users_png_in_the_plot_folder_is_refused_before_anything_is_drawn(project, capsys):
    results = project / "results" / "r.parquet"
    mine = project / "figures"
    mine.mkdir()
    (mine / "heatmaps.png").write_bytes(b"\x89PNG\r\n\x1a\nmy own figure")
    assert main(["plot", str(results), "--out", str(mine)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "heatmaps.png: exists and is not a figure plot wrote" in err
    assert [p.name for p in mine.iterdir()] == ["heatmaps.png"]
    assert (mine / "heatmaps.png").read_bytes() == b"\x89PNG\r\n\x1a\nmy own figure"


def test_a_best_table_of_another_sweep_is_refused(project, tmp_path):
    """The best table beside the results was written for another scene (say, copied in): the figures would mark
    another run as the best."""
    results = project / "results" / "r.parquet"
    other = load_scene(project / "scene.toml")
    other = dataclasses.replace(other, excitation=dataclasses.replace(other.excitation, duration_s=0.8))
    run_scene(other, out_path=tmp_path / "o.parquet", threads=1)
    shutil.copy(tmp_path / "o.best.parquet", results.with_name("r.best.parquet"))
    with pytest.raises(ResultError, match="the best runs of another sweep"):
        plots.read_best(results)
    assert isinstance(pd.read_parquet(results), pd.DataFrame)
