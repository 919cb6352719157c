"""Executors, Parquet parts and resume (issue 6): the same rows whoever runs them, exactly once.

* local threads and a Dask LocalCluster (2 worker processes) give bit-identical tables;
* a Dask worker killed mid-sweep: the scheduler reruns its tasks, each part is written once;
* the CLI killed with SIGKILL after its fourth part (tests/gates.py), then rerun: finished parts are kept (not recomputed),
  the rest is run, no row is missing or duplicated, and the result equals an uninterrupted run;
* a rerun with a changed scene into the same folder is refused with a clear message.
"""

from __future__ import annotations

import dataclasses
import os
import signal

import numpy as np
import pandas as pd
import pytest
from conftest import SWEEPS
from gates import GatedSweep, run

from pounding_sweep.errors import OutputError
from pounding_sweep.scene import Axis, load_scene
from pounding_sweep.sweep.results import MANIFEST, part_files, read_manifest
from pounding_sweep.sweep.run import run_scene


def small_scene(runs_per_part: int = 4, duration_s: float = 0.5):
    """The 6 Hz scene over 24 grid points (k_s/k x r x gap), short runs, small parts."""
    s = load_scene(SWEEPS / "paper_6hz.toml")
    return dataclasses.replace(
        s,
        excitation=dataclasses.replace(s.excitation, duration_s=duration_s),
        sweep=(Axis("ks_ratio", (0.1, 1.0, 10.0, 100.0)), Axis("r", (0.0, 0.5, 1.0)), Axis("gap_m", (0.0, 0.001))),
        execution=dataclasses.replace(s.execution, chunk_runs=runs_per_part),
    )


def table(path) -> pd.DataFrame:
    """A result dataset without the timing column (the only one that differs between runs)."""
    return pd.read_parquet(path).drop(columns=["run_time_s"]).sort_values("run_id").reset_index(drop=True)


@pytest.fixture(scope="module")
def dask_executor():
    """A two-worker local cluster; without the 'dask' extra only the tests that take it skip (not the file's others)."""
    pytest.importorskip("dask.distributed", reason="dask.distributed is not installed (the 'dask' extra)")
    from pounding_sweep.sweep.executors import DaskExecutor

    ex = DaskExecutor(workers=2)
    yield ex
    ex.close()


def test_local_and_dask_give_identical_tables(tmp_path, dask_executor):
    s = small_scene()
    local = run_scene(s, out_path=tmp_path / "local.parquet", threads=2)
    dask = run_scene(s, out_path=tmp_path / "dask.parquet", executor=dask_executor)
    assert local.parts == dask.parts == 6 and dask.executor == "dask"
    a, b = table(local.path), table(dask.path)
    assert len(a) == 24 and a.run_id.tolist() == list(range(24))
    pd.testing.assert_frame_equal(a, b, check_exact=True)  # bit-identical, not merely close
    assert len(part_files(dask.path)) == 6


def test_a_worker_killed_mid_sweep_loses_and_duplicates_nothing(tmp_path, dask_executor):
    s = small_scene(runs_per_part=2, duration_s=2.0)
    pids = list(dask_executor.client.run(os.getpid).values())
    killed = []

    def kill_one_worker(done, total):
        if not killed and done < total:
            os.kill(pids[0], signal.SIGKILL)
            killed.append(done)

    res = run_scene(s, out_path=tmp_path / "killed.parquet", executor=dask_executor, progress=kill_one_worker)
    assert killed, "the worker was killed while parts were still running"
    got = table(res.path)
    assert got.run_id.tolist() == list(range(24))  # exactly one row per grid point
    ref = run_scene(s, out_path=tmp_path / "ref.parquet", threads=1)
    pd.testing.assert_frame_equal(got, table(ref.path), check_exact=True)


def _cli(scene_file, out, *extra):
    return [scene_file, "--out", out, "--threads", "1", *extra]


def _write_scene(tmp_path, r_values="[0.2, 0.6, 1.0]", duration="0.5", name="killable.toml"):
    """A scene of 30 runs, one run per part (k_s/k x r, 0.5 s at dt = 2e-5 s)."""
    text = (SWEEPS / "paper_6hz.toml").read_text()
    text = text.replace("duration_s = 5.0", f"duration_s = {duration}").replace("dt_s = 1e-4", "dt_s = 2e-5")
    text = text.replace(
        "ks_ratio = [0.1, 1.0, 5.0, 10.0]", "ks_ratio = [0.1, 0.5, 1.0, 2.0, 5.0, 10.0, 20.0, 50.0, 100.0, 200.0]"
    )
    text = text.replace("r = [0.2, 0.4, 0.6, 0.8, 1.0]", f"r = {r_values}")
    text += "\n[execution]\nchunk_runs = 1\n"
    f = tmp_path / name
    f.write_text(text)
    return f


def test_cli_killed_with_sigkill_resumes_without_recomputing(tmp_path):
    """SIGKILL (no handler runs) once the fourth part is written (the sweep stopped there: tests/gates.py)."""
    scene_file = _write_scene(tmp_path)
    out = tmp_path / "out.parquet"
    proc = GatedSweep(tmp_path / "gate", ["part-4"], *_cli(scene_file, out, "--quiet"))
    try:
        proc.wait_at("part-4")
        proc.signal(signal.SIGKILL)
    finally:
        proc.kill()
    kept = {p.name: p.stat().st_mtime_ns for p in part_files(out)}
    assert len(kept) == 4
    assert read_manifest(out)["parts"] == 30
    for p in part_files(out):  # every visible part is whole (a part killed mid-write stays hidden)
        assert len(pd.read_parquet(p)) == 1

    rerun = run(*_cli(scene_file, out))
    assert rerun.returncode == 0, rerun.stderr
    assert f"{len(kept)} kept from an earlier run" in rerun.stdout
    assert {p.name: p.stat().st_mtime_ns for p in part_files(out) if p.name in kept} == kept  # not recomputed
    got = table(out)
    assert got.run_id.tolist() == list(range(30))  # none missing, none twice
    assert not [p for p in out.iterdir() if p.name.startswith(".")]  # no temporaries left
    fresh = run_scene(load_scene(scene_file), out_path=tmp_path / "fresh.parquet", threads=2)
    pd.testing.assert_frame_equal(got, table(fresh.path), check_exact=True)


def test_resume_with_a_changed_scene_is_refused(tmp_path):
    first = _write_scene(tmp_path, duration="0.2")
    out = tmp_path / "out.parquet"
    assert run(*_cli(first, out, "--quiet")).returncode == 0
    before = sorted((p.name, p.stat().st_mtime_ns) for p in out.iterdir())
    changed = _write_scene(tmp_path, r_values="[0.2, 0.6, 0.9]", duration="0.2", name="changed.toml")
    p = run(*_cli(changed, out))
    assert p.returncode == 2 and "Traceback" not in p.stderr
    assert "holds results of a different sweep" in p.stderr and "--overwrite" in p.stderr
    assert "[sweep] r = [0.2, 0.6, 1.0] there, [0.2, 0.6, 0.9] now" in p.stderr  # the key that differs, by name
    assert sorted((q.name, q.stat().st_mtime_ns) for q in out.iterdir()) == before  # untouched
    # asked for, it replaces them
    p = run(*_cli(changed, out, "--overwrite", "--quiet"))
    assert p.returncode == 0, p.stderr
    assert sorted(pd.read_parquet(out).r.unique()) == [0.2, 0.6, 0.9]
    assert read_manifest(out)["config_hash"] == load_scene(changed).config_hash()


def test_rerun_of_a_finished_sweep_recomputes_nothing(tmp_path):
    s = small_scene()
    a = run_scene(s, out_path=tmp_path / "o.parquet")
    mtimes = {p.name: p.stat().st_mtime_ns for p in part_files(a.path)}
    b = run_scene(s, out_path=tmp_path / "o.parquet")
    assert b.resumed_parts == b.parts == 6 and b.runs == 24
    assert {p.name: p.stat().st_mtime_ns for p in part_files(b.path)} == mtimes
    assert b.statuses == a.statuses and b.steps == a.steps
    assert (tmp_path / "o.parquet" / MANIFEST).exists()


def test_output_path_that_is_a_file_is_refused(tmp_path):
    f = tmp_path / "old.parquet"
    f.write_bytes(b"not ours")
    with pytest.raises(OutputError, match="is a file"):
        run_scene(small_scene(), out_path=f)
    assert f.read_bytes() == b"not ours"


def test_dataset_reads_in_pyarrow_and_duckdb_style_globs(tmp_path):
    """The folder is one table for pandas/pyarrow; its parts match part-*.parquet (DuckDB, polars)."""
    import pyarrow.dataset as ds

    res = run_scene(small_scene(), out_path=tmp_path / "o.parquet")
    t = ds.dataset(res.path, format="parquet").to_table()
    assert t.num_rows == 24 and np.array_equal(np.sort(t.column("run_id").to_numpy()), np.arange(24))
    assert len(list(res.path.glob("part-*.parquet"))) == res.parts
