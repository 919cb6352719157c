"""Issue 17: nothing lost, nothing mixed, one clear line for every failure. The faults a corpus case
(tests/bad_inputs) cannot express: a user's file under --overwrite, a moved project folder, leftover
temporaries, two sweeps on one folder, deleted history parts, a full disk, an unusable output found
before computing, a lost Dask node and a lost scheduler, Ctrl-C under a LocalCluster, SIGTERM.

Each ends in one of two ways: the sweep completes with every row exactly once (equal to an
uninterrupted run), or it exits 2 (130/143 for a signal) with one stderr line, having written
nothing where it failed, and the same command then resumes to that complete result.
"""

from __future__ import annotations

import dataclasses
import errno
import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd
import pytest
from conftest import SWEEPS
from gates import SAFETY_S, GatedSweep, run

from pounding_sweep.errors import ClusterError, OutputError
from pounding_sweep.scene import Axis, load_scene
from pounding_sweep.sweep.results import MANIFEST, part_files, read_manifest
from pounding_sweep.sweep.run import run_scene


def table(path) -> pd.DataFrame:
    """A result dataset without the timing column (the only one that differs between runs)."""
    return pd.read_parquet(path).drop(columns=["run_time_s"]).sort_values("run_id").reset_index(drop=True)


def small_scene(runs_per_part: int = 4, duration_s: float = 0.5, histories=()):
    """The 6 Hz scene over 24 grid points, short runs, small parts."""
    s = load_scene(SWEEPS / "paper_6hz.toml")
    return dataclasses.replace(
        s,
        excitation=dataclasses.replace(s.excitation, duration_s=duration_s),
        sweep=(Axis("ks_ratio", (0.1, 1.0, 10.0, 100.0)), Axis("r", (0.0, 0.5, 1.0)), Axis("gap_m", (0.0, 0.001))),
        execution=dataclasses.replace(s.execution, chunk_runs=runs_per_part),
        output=dataclasses.replace(s.output, histories=tuple(histories), history_decimate=10),
    )


def gated_scene_file(folder: Path, name: str = "gated.toml") -> Path:
    """30 runs of 0.5 s with a history, one run per part: a sweep of many parts, each written on its own, that a
    test stops at a part (tests/gates.py) whatever the machine's speed."""
    text = (SWEEPS / "paper_6hz.toml").read_text()
    text = text.replace("duration_s = 5.0", "duration_s = 0.5")
    text = text.replace("[output]", '[output]\nhistories = ["disp_b1f3"]\nhistory_decimate = 100')
    text = text.replace(
        "ks_ratio = [0.1, 1.0, 5.0, 10.0]", "ks_ratio = [0.1, 0.5, 1.0, 2.0, 5.0, 10.0, 20.0, 50.0, 100.0, 200.0]"
    )
    text = text.replace("r = [0.2, 0.4, 0.6, 0.8, 1.0]", "r = [0.2, 0.6, 1.0]") + "\n[execution]\nchunk_runs = 1\n"
    f = folder / name
    f.write_text(text)
    return f


def gated(tmp_path, scene_file, out, point, *extra, **kw) -> GatedSweep:
    """The sweep of `scene_file` into `out`, waiting at `point` until released."""
    return GatedSweep(tmp_path / "gate", [point], scene_file, "--out", out, "--quiet", *extra, **kw)


def finish_and_compare(scene_file: Path, out: Path, tmp_path: Path) -> None:
    """The same command completes what is left, and the result equals an uninterrupted run's."""
    p = run(scene_file, "--out", out, "--threads", "2")
    assert p.returncode == 0, p.stderr
    got = table(out)
    fresh = run_scene(load_scene(scene_file), out_path=tmp_path / "fresh.parquet", threads=2)
    assert got.run_id.tolist() == list(range(fresh.runs))  # none missing, none twice
    pd.testing.assert_frame_equal(got, table(fresh.path), check_exact=True)
    assert not [q.name for q in out.iterdir() if q.name.startswith(".")]  # no temporaries, no lock


# ------------------------------------------------------------------ item 1: a user's file is never deleted


@pytest.mark.parametrize("how", ["--out", "[output] path"])
def test_overwrite_never_deletes_a_users_file(tmp_path, how):
    from pounding_sweep.cli.run import main

    notes = tmp_path / "notes.txt"
    notes.write_text("three weeks of notes\n")
    text = (SWEEPS / "paper_6hz.toml").read_text().replace("duration_s = 5.0", "duration_s = 0.2")
    if how == "--out":
        (tmp_path / "s.toml").write_text(text)
        argv = [str(tmp_path / "s.toml"), "--out", str(notes), "--overwrite", "--quiet"]
    else:
        (tmp_path / "s.toml").write_text(text.replace('path = "../results/paper_6hz.parquet"', 'path = "notes.txt"'))
        argv = [str(tmp_path / "s.toml"), "--overwrite", "--quiet"]
    assert 'path = "../results/paper_6hz.parquet"' in text
    with pytest.raises(OutputError) as e:
        run_scene(load_scene(tmp_path / "s.toml"), out_path=notes, overwrite=True)
    assert main(argv) == 2
    assert notes.read_text() == "three weeks of notes\n"
    assert "--overwrite" not in str(e.value)  # the refusal does not suggest the flag that would delete it
    assert sorted(p.name for p in tmp_path.iterdir()) == ["notes.txt", "s.toml"]


def test_overwrite_replaces_only_a_sweeps_own_files(tmp_path):
    """In a folder with a manifest, --overwrite deletes the sweep's parts and manifest, nothing else; a
    Parquet file named like a part but not written by a sweep stops it (kept)."""
    out = tmp_path / "o.parquet"
    first = small_scene()
    run_scene(first, out_path=out)
    (out / "README.txt").write_text("what this folder is\n")
    second = dataclasses.replace(first, sweep=first.sweep[:2])  # 12 runs, 3 parts instead of 6
    with pytest.raises(OutputError, match="different sweep"):
        run_scene(second, out_path=out)
    res = run_scene(second, out_path=out, overwrite=True)
    assert res.parts == 3 and len(part_files(out)) == 3
    assert sum(len(pd.read_parquet(p)) for p in part_files(out)) == 12
    assert (out / "README.txt").read_text() == "what this folder is\n"
    import pyarrow as pa
    import pyarrow.parquet as pq

    pq.write_table(pa.table({"x": [1]}), out / "part-00007.parquet")
    with pytest.raises(OutputError, match="part-00007.parquet: not a part this package wrote"):
        run_scene(first, out_path=out, overwrite=True)
    assert (out / "part-00007.parquet").exists() and len(part_files(out)) == 4  # nothing deleted


# ------------------------------------------------------------------ items 2, 3: foreign parts, moved folders


def test_a_foreign_part_is_refused_and_recomputed_once_removed(tmp_path):
    a = small_scene()
    b = dataclasses.replace(a, integration=dataclasses.replace(a.integration, dt_s=2e-4))
    run_scene(a, out_path=tmp_path / "a.parquet")
    run_scene(b, out_path=tmp_path / "b.parquet")
    shutil.copy(tmp_path / "b.parquet" / "part-00003.parquet", tmp_path / "a.parquet" / "part-00003.parquet")
    with pytest.raises(OutputError) as e:
        run_scene(a, out_path=tmp_path / "a.parquet")
    assert "part-00003.parquet: a part of a different sweep ([integration] dt_s = 0.0002 there, 0.0001 now)" in str(
        e.value
    )
    (tmp_path / "a.parquet" / "part-00003.parquet").unlink()
    res = run_scene(a, out_path=tmp_path / "a.parquet")
    assert res.resumed_parts == 5
    ref = run_scene(a, out_path=tmp_path / "ref.parquet")
    pd.testing.assert_frame_equal(table(res.path), table(ref.path), check_exact=True)


def test_a_moved_project_folder_resumes_and_hashes_the_same(tmp_path):
    """Scene, record and experiment in one project folder; results inside it. Half the parts are
    written, the folder is moved (another checkout path, another machine): the same command resumes."""
    project = tmp_path / "here" / "project"
    (project / "records").mkdir(parents=True)
    (project / "experiments").mkdir()
    shutil.copy(SWEEPS / "records" / "RSN1605_DUZCE_DZC180.AT2", project / "records")
    shutil.copy(SWEEPS / "experiments" / "synthetic_duzce.parquet", project / "experiments")
    text = (SWEEPS / "scored_duzce.toml").read_text() + "\n[execution]\nchunk_runs = 4\n"
    text = text.replace("refine = true", "refine = false")
    (project / "scene.toml").write_text(text)
    scene = load_scene(project / "scene.toml")
    here_hash = scene.config_hash()
    res = run_scene(scene, out_path=project / "results" / "r.parquet")
    for p in part_files(res.path)[2:]:  # an interrupted sweep: 2 of 5 parts written
        p.unlink()
    kept = {p.name: p.stat().st_mtime_ns for p in part_files(res.path)}
    moved = tmp_path / "elsewhere" / "renamed_project"
    moved.parent.mkdir()
    shutil.move(project, moved)
    again = load_scene(moved / "scene.toml")
    assert again.config_hash() == here_hash == read_manifest(moved / "results" / "r.parquet")["config_hash"]
    assert str(tmp_path) not in str(again.canonical())  # no absolute path in what is hashed
    res2 = run_scene(again, out_path=moved / "results" / "r.parquet")
    assert res2.resumed_parts == 2 and res2.parts == 5
    assert {p.name: p.stat().st_mtime_ns for p in part_files(res2.path) if p.name in kept} == kept
    fresh = run_scene(again, out_path=tmp_path / "fresh.parquet")
    pd.testing.assert_frame_equal(table(res2.path), table(fresh.path), check_exact=True)
    # a changed record (same name, other content) is a different sweep, named as such
    rec = moved / "records" / "RSN1605_DUZCE_DZC180.AT2"
    lines = rec.read_text().splitlines(keepends=True)
    rec.write_text("".join([lines[0], lines[1].rstrip("\n") + " (copy)\n", *lines[2:]]))
    with pytest.raises(OutputError, match=r"\[excitation\] record = RSN1605_DUZCE_DZC180.AT2 \(sha256 "):
        run_scene(load_scene(moved / "scene.toml"), out_path=moved / "results" / "r.parquet")


# ------------------------------------------------------------------ items 5, 9: temporaries, two sweeps


def test_leftover_temporaries_do_not_block_and_are_cleaned(tmp_path):
    out = tmp_path / "o.parquet"
    out.mkdir()
    (out / "._sweep.json.tmp").write_text('{"config_ha')  # a kill during the first manifest write
    res = run_scene(small_scene(), out_path=out)
    assert res.parts == 6 and not [p.name for p in out.iterdir() if p.name.startswith(".")]
    (out / "part-00004.parquet").unlink()  # then a kill while part 4 was being written
    (out / ".part-00004.parquet.12345.tmp").write_bytes(b"PAR1 half")
    (out / "._sweep.json.999.tmp").write_text("{")
    res = run_scene(small_scene(), out_path=out)
    assert res.resumed_parts == 5 and not [p.name for p in out.iterdir() if p.name.startswith(".")]


def test_a_second_sweep_on_a_folder_in_use_is_refused_at_once(tmp_path):
    """The first sweep holds the folder (stopped after its first part); a second one on it is refused by the
    lock, not made to wait (were it to wait, it would wait for ever: only the safety net would end it)."""
    scene_file = gated_scene_file(tmp_path)
    out = tmp_path / "out.parquet"
    first = gated(tmp_path, scene_file, out, "part-1", "--threads", "1")
    try:
        first.wait_at("part-1")
        second = run(scene_file, "--out", out, "--threads", "1")
        assert second.returncode == 2 and second.stderr.count("\n") == 1, second.stderr
        assert f"another sweep is writing to this folder (process {first.pid})" in second.stderr
        overwrite = run(scene_file, "--out", out, "--overwrite")
        assert overwrite.returncode == 2 and "another sweep is writing" in overwrite.stderr
        first.signal(signal.SIGINT)  # Ctrl-C while it waits: the interrupt of a running sweep
        code, _, err = first.finish()
    finally:
        first.kill()
    assert code == 130 and err.count("\n") == 1, err
    assert len(part_files(out)) == 1
    finish_and_compare(scene_file, out, tmp_path)


# ------------------------------------------------------------------ item 10: deleted history parts


def test_deleted_history_parts_are_written_again(tmp_path):
    s = small_scene(runs_per_part=4, histories=("disp_b1f3", "force_f3"))
    a = run_scene(s, out_path=tmp_path / "h.parquet")
    hparts = part_files(a.histories_path)
    assert len(hparts) == 6
    before = {p.name: p.stat().st_mtime_ns for p in part_files(a.path)}
    hist_before = pd.read_parquet(a.histories_path)
    for p in hparts[1::2]:
        p.unlink()
    b = run_scene(s, out_path=tmp_path / "h.parquet")
    assert b.resumed_parts == 3 and len(part_files(a.histories_path)) == 6
    after = {p.name: p.stat().st_mtime_ns for p in part_files(a.path)}
    assert [n for n in before if before[n] == after[n]] == [
        "part-00000.parquet",
        "part-00002.parquet",
        "part-00004.parquet",
    ]
    pd.testing.assert_frame_equal(pd.read_parquet(a.histories_path), hist_before, check_exact=True)
    pd.testing.assert_frame_equal(table(b.path), table(a.path), check_exact=True)


# ------------------------------------------------------------------ items 8, 12: unusable or full output


def test_an_unusable_output_is_found_before_anything_is_computed(tmp_path, monkeypatch):
    import pounding_sweep.sweep.run as run_module

    def no_computing(*a, **k):
        raise AssertionError("prepare() ran before the output was checked")

    monkeypatch.setattr(run_module, "prepare", no_computing)
    for out in ("/proc/pounding_out.parquet", str(tmp_path / ("x" * 300 + ".parquet"))):
        with pytest.raises(OutputError, match="cannot create the results folder here"):
            run_scene(small_scene(), out_path=out)
    if os.geteuid() != 0:  # root writes into a read-only folder regardless of its mode
        ro = tmp_path / "ro"
        ro.mkdir()
        ro.chmod(0o555)
        try:
            with pytest.raises(OutputError, match="Permission denied"):
                run_scene(small_scene(), out_path=ro / "out.parquet")
        finally:
            ro.chmod(0o755)
    assert sorted(p.name for p in tmp_path.iterdir()) in ([], ["ro"])


def test_a_failed_sweep_leaves_no_empty_folders(tmp_path):
    """Bad input found after the output was claimed (a record that is not there): the folders the sweep
    made for its output, parents included, are gone again."""
    text = (SWEEPS / "paper_duzce.toml").read_text().replace("records/RSN1605_DUZCE_DZC180.AT2", "nowhere.AT2")
    (tmp_path / "s.toml").write_text(text)
    from pounding_sweep.errors import RecordError

    with pytest.raises(RecordError, match="nowhere.AT2"):
        run_scene(load_scene(tmp_path / "s.toml"), out_path=tmp_path / "a" / "b" / "out.parquet")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.toml"]


def test_a_full_disk_is_one_line_naming_the_part(tmp_path, monkeypatch):
    """The third part cannot be written (ENOSPC): one OutputError naming that part; the two before it are
    kept whole, no temporary stays, and the same sweep then resumes from them."""
    import pyarrow.parquet as pq

    real = pq.write_table
    calls = []

    def full_disk(table, where, **kw):
        calls.append(1)
        if len(calls) == 3:
            raise OSError(errno.ENOSPC, "No space left on device")
        return real(table, where, **kw)

    monkeypatch.setattr(pq, "write_table", full_disk)
    out = tmp_path / "o.parquet"
    with pytest.raises(OutputError) as e:
        run_scene(small_scene(), out_path=out, threads=1)
    assert str(e.value) == (
        f"{out / 'part-00002.parquet'}: cannot write (No space left on device) (free some space, then run the same "
        "command again to resume)"
    )
    assert [p.name for p in part_files(out)] == ["part-00000.parquet", "part-00001.parquet"]
    assert not [p.name for p in out.iterdir() if p.name.startswith(".")]
    monkeypatch.setattr(pq, "write_table", real)
    res = run_scene(small_scene(), out_path=out)
    assert res.resumed_parts == 2 and len(table(out)) == 24


# ------------------------------------------------------------------ item 4: Dask, signals

try:  # the 'dask' extra (in the test extra): without it only these tests skip, not the module's others above
    import dask.distributed as dask_distributed
except ImportError:
    dask_distributed = None
needs_dask = pytest.mark.skipif(dask_distributed is None, reason="dask.distributed is not installed (the 'dask' extra)")


@needs_dask
def test_a_lost_dask_node_completes_the_sweep_exactly_once(tmp_path):
    """Both workers of a LocalCluster are killed after the first part (a node lost: every copy of the
    prepared scene with them). The scene is scattered again to the restarted workers, the unfinished
    chunks resubmitted: one row per grid point, bit-identical to a local run."""
    from pounding_sweep.sweep.executors import DaskExecutor

    s = small_scene(runs_per_part=2, duration_s=2.0)
    ex = DaskExecutor(workers=2, timeout_s=SAFETY_S)  # restarted workers are waited for (a safety net only)
    recovered = []
    original = ex._recover
    ex._recover = lambda *a: (recovered.append(a[-1]), original(*a))
    killed = []

    def kill_every_worker(done, total):
        if not killed and done < total:
            for pid in ex.client.run(os.getpid).values():
                os.kill(pid, signal.SIGKILL)
            killed.append(done)

    try:
        res = run_scene(s, out_path=tmp_path / "lost.parquet", executor=ex, progress=kill_every_worker)
    finally:
        ex.close()
    assert killed and recovered, "the workers were killed mid-sweep and the scene was scattered again"
    ref = run_scene(s, out_path=tmp_path / "ref.parquet", threads=1)
    got = table(res.path)
    assert got.run_id.tolist() == list(range(24))
    pd.testing.assert_frame_equal(got, table(ref.path), check_exact=True)


def _scheduler_address(scheduler: subprocess.Popen, file: Path) -> str:
    """The address a scheduler started on a port of its own choosing (--port 0: no other process can take it
    first) writes to its scheduler file; a safety net only bounds the wait."""
    deadline = time.monotonic() + SAFETY_S
    while True:
        try:
            return json.loads(file.read_text())["address"]
        except (OSError, ValueError, KeyError):  # not written yet, or half written
            assert scheduler.poll() is None, "the Dask scheduler ended before it wrote its address"
            assert time.monotonic() < deadline, f"safety net: no scheduler address within {SAFETY_S:g} s"
            time.sleep(0.05)


@needs_dask
def test_a_lost_scheduler_is_one_line_and_the_sweep_resumes(tmp_path):
    bindir = Path(sys.executable).parent
    if not (bindir / "dask").exists():
        pytest.skip("the dask command is not installed beside this Python")
    quiet = dict(stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    file = tmp_path / "scheduler.json"
    scheduler = subprocess.Popen(
        [
            bindir / "dask",
            "scheduler",
            "--host",
            "127.0.0.1",
            "--port",
            "0",
            "--no-dashboard",
            "--scheduler-file",
            file,
        ],
        **quiet,
    )
    workers = None
    scene_file = gated_scene_file(tmp_path)
    out = tmp_path / "out.parquet"
    sweep = None
    try:
        address = _scheduler_address(scheduler, file)
        workers = subprocess.Popen(
            [bindir / "dask", "worker", address, "--nworkers", "2", "--nthreads", "1", "--no-dashboard"], **quiet
        )
        with dask_distributed.Client(address, timeout=f"{SAFETY_S}s") as c:  # up and staffed before the sweep
            c.wait_for_workers(2, timeout=SAFETY_S)
        sweep = gated(tmp_path, scene_file, out, "part-2", "--dask-address", address)
        sweep.wait_at("part-2")  # 28 of 30 parts still to run: the rest cannot finish without the scheduler
        os.killpg(scheduler.pid, signal.SIGKILL)
        scheduler.wait()
        sweep.release("part-2")
        code, _, err = sweep.finish()
        assert code == 2, err
        assert err.count("\n") == 1 and err.startswith(f"error: Dask: lost the scheduler at {address}"), err
        assert "run the same command again to resume" in err
    finally:
        if sweep is not None:
            sweep.kill()
        for p in (scheduler, workers):
            if p is None:
                continue
            try:
                os.killpg(p.pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
            p.wait()
    finish_and_compare(scene_file, out, tmp_path)  # resumed here, on the local executor


@needs_dask
def test_an_unreachable_scheduler_is_reported_at_once(tmp_path):
    """Nothing listens: the connection is refused, said by the probe before Dask's own connect (which would retry
    for its whole timeout, then report a timeout)."""
    held = socket.socket()  # bound, never listening: the port is refused, and no other process can take it
    held.bind(("127.0.0.1", 0))
    port = held.getsockname()[1]
    with held, pytest.raises(ClusterError, match=rf"cannot reach a Dask scheduler at tcp://127.0.0.1:{port}"):
        s = small_scene()
        run_scene(
            dataclasses.replace(
                s, execution=dataclasses.replace(s.execution, executor="dask", dask_address=f"tcp://127.0.0.1:{port}")
            ),
            out_path=tmp_path / "o.parquet",
        )
    assert list(tmp_path.iterdir()) == []


@needs_dask
def test_a_server_that_is_not_a_dask_scheduler_is_one_line(tmp_path):
    """Something listens at the address, accepts, and says nothing (a web server waiting for its request): Dask's
    client would wait for its handshake for ever. The probe waits timeout_s for the server's first bytes, then
    says so; nothing is written. (A real scheduler writes its handshake at once: the lost-scheduler test.)"""
    import threading

    from pounding_sweep.sweep.executors import DaskExecutor

    server = socket.socket()
    server.bind(("127.0.0.1", 0))
    server.listen()
    accepted = []
    threading.Thread(target=lambda: accepted.append(server.accept()), daemon=True).start()
    address = f"tcp://127.0.0.1:{server.getsockname()[1]}"
    try:
        with pytest.raises(ClusterError) as e:
            DaskExecutor(address, timeout_s=1.0)
        assert str(e.value).startswith(
            f"no Dask scheduler at {address}: something listens there, but no Dask handshake"
        )
        s = small_scene()  # the scene's dask_timeout_s is the probe's wait
        ex = dataclasses.replace(s.execution, executor="dask", dask_address=address, dask_timeout_s=1.5)
        with pytest.raises(ClusterError, match=r"no Dask scheduler at .* no Dask handshake within 1\.5 s"):
            run_scene(dataclasses.replace(s, execution=ex), out_path=tmp_path / "o.parquet")
        assert list(tmp_path.iterdir()) == []
    finally:
        server.close()
        for conn, _ in accepted:
            conn.close()


@needs_dask
@pytest.mark.parametrize(
    "sig, code, line", [(signal.SIGINT, 130, "interrupted:"), (signal.SIGTERM, 143, "terminated (SIGTERM):")]
)
def test_ctrl_c_and_sigterm_under_a_local_cluster_are_one_line(tmp_path, sig, code, line):
    """The terminal's Ctrl-C (and a batch scheduler's SIGTERM) reach the whole process group, workers
    included: one line, the finished parts kept, and the same command resumes."""
    scene_file = gated_scene_file(tmp_path)
    out = tmp_path / "out.parquet"
    sweep = gated(tmp_path, scene_file, out, "part-2", "--executor", "dask", "--workers", "2", start_new_session=True)
    got, _, err = sweep.stop_at("part-2", sig, group=True)
    assert got == code and err.count("\n") == 1 and err.startswith(line), err
    assert "the finished parts are kept; run the same command again to resume" in err
    assert (out / MANIFEST).exists() and len(part_files(out)) == 2
    finish_and_compare(scene_file, out, tmp_path)


def test_sigterm_on_the_local_executor_is_one_line(tmp_path):
    scene_file = gated_scene_file(tmp_path)
    out = tmp_path / "out.parquet"
    code, _, err = gated(tmp_path, scene_file, out, "part-2", "--threads", "1").stop_at("part-2", signal.SIGTERM)
    assert code == 143 and err == (
        "terminated (SIGTERM): the finished parts are kept; run the same command again to resume\n"
    )
    assert len(part_files(out)) == 2
    finish_and_compare(scene_file, out, tmp_path)
