"""Issue 16: a first run explains itself, and a resumed one reports what it did.

* `--help` lists every subcommand with one line each;
* a kernel that Numba really compiles (not one loaded from the cache) is announced once, with about
  how long it takes, and on a terminal its seconds are counted; with --quiet nothing is said; a run
  whose kernels come from the cache says nothing about compiling;
* the progress meter moves within a part (as groups of runs finish), not only once per part;
* a resumed run reports the rate of the runs it ran (none: it says so), and reuses the refinement
  stored in the best table instead of redoing it.
"""

from __future__ import annotations

import dataclasses
import io
import itertools
import math
import os
import subprocess
import sys
import threading
import types

import numba
import pandas as pd
import pytest
from conftest import REPO, SWEEPS
from gates import SAFETY_S

from pounding_sweep import progress
from pounding_sweep.cli.run import SUBCOMMANDS, _run_text
from pounding_sweep.engine import compile_times, driver, jit
from pounding_sweep.engine.lanes.rows import LANES
from pounding_sweep.progress import Progress
from pounding_sweep.scene import Axis, load_scene
from pounding_sweep.sweep.results import part_files
from pounding_sweep.sweep.run import run_scene


def test_help_lists_every_subcommand():
    p = subprocess.run([sys.executable, "-m", "pounding_sweep", "--help"], capture_output=True, text=True, cwd=REPO)
    assert p.returncode == 0
    listed = [line.split()[0] for line in p.stdout.split("subcommands", 1)[1].splitlines()[1:] if line.startswith("  ")]
    assert sorted(listed) == sorted(SUBCOMMANDS)
    assert "--describe" in p.stdout


# ------------------------------------------------------------------ compiling


def _compile_clock(monkeypatch, step_s: float = 1.25) -> None:
    """driver.py's clock, stepped by step_s at every reading: a compile (two readings) takes step_s, however fast
    the machine compiles (a real compile of a small function takes milliseconds, which the record rounds to 0.01 s,
    and 0 s reads as no record)."""
    clock = itertools.count(100.0, step_s)
    monkeypatch.setattr(driver, "time", types.SimpleNamespace(perf_counter=lambda: next(clock)))


def test_a_real_compile_is_announced_once_and_timed(tmp_path, monkeypatch):
    monkeypatch.setattr(jit, "_root", lambda: tmp_path)  # the compile-time record goes here, not to ~/.cache
    _compile_clock(monkeypatch)
    heard, ended = [], []

    def announce(kernel, label, estimate_s, measured_here):
        heard.append((kernel, label, estimate_s, measured_here))
        return ended.append

    @numba.njit(cache=False)
    def fresh(x):  # compiled at its first call: Numba's 'numba:compile' event fires
        return x + 1.0

    with driver._announced("scalar", "the scalar kernel", announce):
        fresh(1.0)
    assert heard == [("scalar", "the scalar kernel", compile_times.TYPICAL_COMPILE_S["scalar"], False)]
    assert ended == [1.25]  # the stepped clock's two readings
    # the next estimate: the time taken
    assert compile_times.compile_estimate("scalar") == ((1.25, 1.25), True)
    with driver._announced("scalar", "the scalar kernel", announce):
        fresh(2.0)  # compiled already: nothing to announce
    assert len(heard) == 1


def test_a_compile_with_its_largest_piece_cached_is_estimated_and_recorded_apart(tmp_path, monkeypatch):
    """The lane kernel for a new pair of floor counts, its step cached, compiles in a third of a first compile's
    time: it has a range of its own and its own record; the first compile's record is left as it was."""
    monkeypatch.setattr(jit, "_root", lambda: tmp_path)
    _compile_clock(monkeypatch)
    heard = []

    def announce(kernel, label, estimate_s, measured_here):
        heard.append((kernel, estimate_s, measured_here))
        return lambda seconds: None

    @numba.njit(cache=False)
    def piece(x):
        return x * 2.0

    @numba.njit(cache=False)
    def kernel(x):
        return piece(x) + 1.0

    piece(1.0)  # the largest piece, compiled already
    compile_times.record_compile("lanes", 40.0)
    # the kernel's pieces in groups (engine/aside.py): the first, the largest piece, cached
    with driver._announced("lanes", "the lane kernel", announce, lambda: (((piece, (numba.float64,)),),)):
        kernel(1.0)
    assert heard == [("lanes", compile_times.TYPICAL_COMPILE_S["lanes_again"], False)]
    assert compile_times.compile_estimate("lanes") == ((40.0, 40.0), True)
    (least, most), here = compile_times.compile_estimate("lanes_again")
    assert here and least == most == 1.25
    # a key with no range of its own falls back to the first compile's
    assert compile_times.compile_estimate("nonlinear_again") == (compile_times.TYPICAL_COMPILE_S["nonlinear"], False)


def test_the_compile_line_and_the_clock(monkeypatch):
    err = io.StringIO()
    monkeypatch.setattr(sys, "stderr", err)
    quiet = Progress(enabled=False)
    quiet.compiling("lanes", "the lane kernel", (24.0, 47.0), False)(24.0)
    assert err.getvalue() == ""
    log = Progress()  # stderr is no terminal here: one line, no clock
    log.compiling("lanes", "the lane kernel", (24.0, 47.0), False)(24.0)
    assert err.getvalue() == (
        "compiling the lane kernel for this machine (once; about 24-47 s on a 2-core machine; "
        "later runs load it from the cache)\n"
    )
    err.truncate(0), err.seek(0)
    clock = _SteppedClock(seconds=2)
    monkeypatch.setattr(progress, "time", clock)
    monkeypatch.setattr(progress, "threading", clock)
    tty = Progress()
    tty.enabled = True  # as on a terminal
    end = tty.compiling("scalar", "the scalar kernel", (14.2, 14.2), True)
    assert clock.ticked.wait(SAFETY_S), "the compile clock did not tick twice"
    end(2.3)
    out = err.getvalue()
    assert out.startswith("compiling the scalar kernel for this machine (once; about 14 s here last time;")
    assert out.endswith("\r  compiling: 1 s \r  compiling: 2 s \r  compiled in 2.3 s \n")


class _SteppedClock:
    """progress.py's `time` and `threading` for the compile clock, stepped instead of waited for: each of the
    clock thread's one-second waits passes a second at once, `seconds` times; the next wait lasts until the
    clock is stopped, and sets `ticked` (those seconds have all been written). Threads and locks are the real
    ones."""

    Thread = threading.Thread
    Lock = threading.Lock

    def __init__(self, seconds: int):
        self.now, self.seconds = 1000.0, seconds
        self.waits = 0
        self.ticked = threading.Event()

    def perf_counter(self) -> float:
        return self.now

    def Event(self):  # noqa: N802 - stands for threading.Event
        clock, stopped = self, threading.Event()

        class Stepped:
            def wait(self, timeout: float) -> bool:
                clock.waits += 1
                if clock.waits <= clock.seconds:
                    clock.now += timeout
                    return False
                clock.ticked.set()
                return stopped.wait(SAFETY_S)

            def set(self) -> None:
                stopped.set()

        return Stepped()


def test_the_first_run_announces_its_compile_and_a_run_from_the_cache_says_nothing(tmp_path):
    """Through the command line, with a cache of its own (the user's cache folder is shared with other
    checkouts, which may evict it): the scalar kernel (the 6 Hz scene with histories), the cheapest to compile."""
    scene = tmp_path / "h.toml"
    scene.write_text(
        (SWEEPS / "paper_6hz.toml")
        .read_text()
        .replace("duration_s = 5.0", "duration_s = 0.01")
        .replace("[output]", '[output]\nhistories = ["disp_b1f3"]')
    )
    env = {k: v for k, v in os.environ.items() if not k.startswith("PYTEST")}
    env["NUMBA_CACHE_DIR"] = str(tmp_path / "cache")
    runs = [
        subprocess.run(
            [sys.executable, "-m", "pounding_sweep", scene, "--out", tmp_path / f"{k}.parquet"],
            capture_output=True,
            text=True,
            cwd=REPO,
            env=env,
        )
        for k in range(2)
    ]
    assert [r.returncode for r in runs] == [0, 0], runs[0].stderr + runs[1].stderr
    assert runs[0].stderr.startswith("compiling the scalar kernel for this machine (once; about ")
    assert runs[0].stderr.count("\n") == 1  # one line off a terminal (no clock), nothing else
    assert runs[1].stderr == ""
    assert "compile (or cache load)" in runs[1].stdout


# ------------------------------------------------------------------ progress within a part


@pytest.mark.parametrize("scored", [False, True], ids=["lane kernel", "scalar kernel, scored"])
def test_progress_moves_within_a_part(tmp_path, scored):
    s = load_scene(SWEEPS / ("scored_6hz.toml" if scored else "paper_6hz.toml"))
    s = dataclasses.replace(
        s,
        excitation=dataclasses.replace(s.excitation, duration_s=0.3 if not scored else s.excitation.duration_s),
        sweep=(Axis("ks_ratio", (0.5, 1.0, 2.0, 4.0)), Axis("r", tuple(0.1 * k for k in range(1, 11)))),
        experiment=dataclasses.replace(s.experiment, refine=False) if scored else None,
    )
    calls = []
    summary = run_scene(s, out_path=tmp_path / "p.parquet", threads=1, progress=lambda d, t: calls.append((d, t)))
    assert summary.parts == 1 and summary.runs == 40
    done = [d for d, _ in calls]
    assert done == sorted(done) and done[-1] == 40 and {t for _, t in calls} == {40}
    # groups of runs one SIMD value wide (the lane kernel: a report after each of its ceil(40 / LANES) groups, 4 or
    # 8 runs by the CPU) or batches (the scalar kernel) reported as they finish
    least = math.ceil(40 / LANES) - 1 if not scored else 4
    assert len([d for d in done if d < 40]) >= least, (done, LANES)


# ------------------------------------------------------------------ resuming


def test_a_resumed_run_reports_its_own_rate_and_reuses_the_refinement(tmp_path):
    s = load_scene(SWEEPS / "scored_6hz.toml")
    s = dataclasses.replace(s, execution=dataclasses.replace(s.execution, chunk_runs=5))  # 4 parts of 5 runs
    out = tmp_path / "scored.parquet"
    first = run_scene(s, out_path=out, threads=1)
    assert first.new_runs == 20 and first.refinement is not None and not first.refinement_reused
    assert first.refinement.evaluations > 10
    best = pd.read_parquet(out.with_name("scored.best.parquet")).set_index("criterion")
    assert best.loc["refined_combined", "evaluations"] == first.refinement.evaluations

    again = run_scene(s, out_path=out, threads=1)  # everything finished: nothing runs, nothing is refined
    assert again.new_runs == 0 and again.new_steps == 0 and again.compile_s == 0.0 and again.threads == 0
    assert _run_text(again) == "nothing to run: all 20 runs kept from an earlier run"
    assert again.refinement_reused and again.refinement.optimum == first.refinement.optimum
    assert again.refinement.error_pct == first.refinement.error_pct
    assert again.refinement.start == first.refinement.start
    pd.testing.assert_frame_equal(again.best, first.best)

    part_files(out)[2].unlink()  # one part lost: 5 runs to do; the rate is theirs, not the kept runs'
    third = run_scene(s, out_path=out, threads=1)
    assert third.new_runs == 5 and third.resumed_parts == 3 and third.refinement_reused
    df = pd.read_parquet(out)
    lost = df[df.run_id.between(10, 14)]
    assert third.new_steps == int(lost.steps.sum())
    assert third.new_kernel_s == pytest.approx(lost.run_time_s.sum(), rel=1e-9)
    text = _run_text(third)
    assert "for 5 runs; 15 kept from an earlier run" in text and f"{third.new_steps:,} steps" in text
