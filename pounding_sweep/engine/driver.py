"""Run a chunk of grid points through the kernel on a pool of threads.

The kernels (engine/registry.py) compute the same metric row of a run: the lane kernel
(engine/lanes, LANES runs side by side in SIMD lanes, in modal coordinates) takes every chunk it can
run (metrics only, implicit or event scheme, a linear contact law, two shear frames facing floor by
floor with classical damping); the scalar kernels, one run at a time in floor coordinates, take the
others (histories, scoring, the paper's scheme; engine/scalar.py for the linear laws,
engine/nonlinear.py for the Hertz-type ones) and rerun any run that diverged in a lane. The lane and
scalar kernels agree to rounding (tests/engine/test_lanes.py states the tolerances, derived in
tests/tolerances.py). Which kernel runs a chunk is the registry's answer to the chunk and the caller's
choice (registry.CHOICES), never a module global; a chunk's runs of each contact law (RunArrays.law)
go to that law's kernel.

The kernels release the GIL, so threads run side by side; work is handed out in small pieces
(a group of LANES runs, or a small batch of runs) from a shared queue, so a thread that draws runs
with many impacts does not hold the others up (static splitting, as numba's prange does, would).
Each run writes only its own row: no shared reductions, results identical whatever the thread
count, lane or group a run lands in.
"""

from __future__ import annotations

import contextlib
import os
import threading
import time
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from pounding_sweep.codes import LAW_CLASSIC
from pounding_sweep.engine import aside, registry
from pounding_sweep.engine import layout as L
from pounding_sweep.engine.inputs import (
    HistorySpec,
    KernelOptions,
    LaneExcitation,
    LaneOutputs,
    Outputs,
    Records,
    RunArrays,
    ScoreSpec,
    Structure,
)
from pounding_sweep.engine.lanes import (
    LANES,
    ST_N,
    ST_TIMED,
    excitation_profiles,
    group_work,
    integrate_lanes,
    lane_model,
    lane_modes,
)
from pounding_sweep.engine.registry import Chunk
from pounding_sweep.engine.score import N_SCORES
from pounding_sweep.model.coupled import SystemArrays
from pounding_sweep.model.modal import ModalArrays


def resolve_threads(threads: int) -> int:
    return (
        threads
        if threads > 0
        else (len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1)
    )


#: the kernels a chunk may be run on (registry.CHOICES): "auto" (the lane kernel where it computes the
#: chunk, else a scalar one), "scalar" (one run at a time: the benchmarks and tests compare the two), "lanes"
KERNELS = registry.CHOICES


def kernel_for(
    sys: SystemArrays,
    hist: HistorySpec,
    opts: KernelOptions,
    score: ScoreSpec | None = None,
    kernel: str = "auto",
    law: int = LAW_CLASSIC,
) -> str:
    """The name of the kernel (registry.KERNELS) run_chunk uses for a chunk of runs of `law` (codes.LAW_*)
    (ValueError: `kernel` names none of KERNELS, or asks for a kernel that cannot run the chunk)."""
    return registry.choose(Chunk(sys, hist, opts, score or ScoreSpec.none(), law), kernel).name


def run_chunk(
    sys: SystemArrays,
    runs: RunArrays,
    rec,
    hist: HistorySpec,
    opts: KernelOptions,
    threads: int = 1,
    batch_runs: int = 0,
    score: ScoreSpec | None = None,
    kernel: str = "auto",
    done: Callable[[int], None] | None = None,
):
    """Integrate every run of the chunk on `kernel` (KERNELS); return (metrics, run_time_s, histories or
    None, scores or None). The runs of each contact law (runs.law) go to the kernel the registry picks for
    them and the rows come back in the chunk's order. `done(n)`, when given, is called from the worker
    threads as each group or batch of n runs finishes (progress within a chunk; it must be thread-safe and
    quick)."""
    score = score if score is not None else ScoreSpec.none()
    codes_in = np.unique(runs.law)
    if codes_in.size > 1:
        parts = []
        for code in codes_in:
            idx = np.flatnonzero(runs.law == code)
            parts.append(
                (idx, run_chunk(sys, runs.take(idx), rec, hist, opts, threads, batch_runs, score, kernel, done))
            )
        return merge_rows(runs.n, parts)
    law = int(codes_in[0]) if codes_in.size else LAW_CLASSIC
    k = registry.choose(Chunk(sys, hist, opts, score, law), kernel)
    if k.lanes and runs.n > 0:
        metrics, run_time = run_chunk_lanes(sys, runs, rec, opts, threads, done=done)
        return metrics, run_time, None, None
    return run_chunk_scalar(sys, runs, rec, hist, opts, threads, batch_runs, score, done)


def merge_rows(n: int, parts) -> tuple:
    """A chunk's results computed in groups of its runs, put back in the chunk's order. `parts`: [(run indices,
    (metrics, run_time, histories or None, scores or None[, a dict of per-run arrays])), ...] as run_chunk (and
    sweep.prepare's runs, with their derived columns) return them; a slot None in every group stays None,
    histories shorter than the longest group's are NaN-padded, a dict key missing from a group is NaN there."""
    first = parts[0][1]
    out = [np.zeros((n,) + first[0].shape[1:]), np.zeros(n), None, None] + [{} for _ in first[4:]]
    for idx, part in parts:
        out[0][idx], out[1][idx] = part[0], part[1]
        for slot in (2, 3):
            if part[slot] is not None:
                if out[slot] is None:
                    out[slot] = np.full((n,) + part[slot].shape[1:], np.nan)
                out[slot][idx, ..., : part[slot].shape[-1]] = part[slot]
        for merged, columns in zip(out[4:], part[4:]):
            for k, v in columns.items():
                merged.setdefault(k, np.full(n, np.nan))[idx] = v
    return tuple(out)


def run_chunk_scalar(
    sys: SystemArrays,
    runs: RunArrays,
    rec,
    hist: HistorySpec,
    opts: KernelOptions,
    threads: int = 1,
    batch_runs: int = 0,
    score: ScoreSpec | None = None,
    done: Callable[[int], None] | None = None,
):
    """run_chunk on a one-run-at-a-time kernel (every option supported; registry choice "scalar"):
    engine/scalar.py for the linear laws, engine/nonlinear.py for the Hertz-type ones."""
    score = score if score is not None else ScoreSpec.none()
    if np.unique(runs.law).size > 1:
        return run_chunk(sys, runs, rec, hist, opts, threads, batch_runs, score, "scalar", done)
    law = int(runs.law[0]) if runs.n else LAW_CLASSIC
    kernel_fn = registry.choose(Chunk(sys, hist, opts, score, law), "scalar").entry
    n = runs.n
    n_metrics = L.n_metrics(sys.m.size, sys.i1.size)
    metrics = np.zeros((n, n_metrics))
    run_time = np.zeros(n)
    if hist.active:
        n_samples = int(runs.nsteps.max()) // hist.decimate + 1
        hist_arr = np.full((n, hist.kinds.size, n_samples), np.nan)
    else:
        hist_arr = np.zeros((0, 0, 0))
    scores = np.full((n, score.dof.size, N_SCORES), np.nan)

    model = Structure.of(sys)
    records = Records(*rec)
    out = Outputs(metrics, run_time, hist_arr, scores)

    def work(bounds):
        kernel_fn(bounds[0], bounds[1], model, opts, runs, records, hist, score, out)
        if done is not None:
            done(bounds[1] - bounds[0])

    threads = max(1, min(threads, n))
    if batch_runs <= 0:
        batch_runs = max(1, min(32, n // (threads * 8)))
    bounds = [(s, min(n, s + batch_runs)) for s in range(0, n, batch_runs)]
    if threads == 1:
        for b in bounds:
            work(b)
    else:
        with ThreadPoolExecutor(max_workers=threads) as pool:
            list(pool.map(work, bounds))
    L.leave_out(metrics, sys.m.size, sys.i1.size, opts.groups)
    return metrics, run_time, (hist_arr if hist.active else None), (scores if score.active else None)


def run_chunk_lanes(
    sys: SystemArrays,
    runs: RunArrays,
    rec,
    opts: KernelOptions,
    threads: int = 1,
    ma: ModalArrays | None = None,
    stats: np.ndarray | None = None,
    done: Callable[[int], None] | None = None,
):
    """run_chunk on the lane kernel (the caller checked that it can run the chunk: registry.choose; the runs
    share one contact law; `ma`: the system's modal data when the caller has them, from lanes.lane_modes):
    (metrics, run_time_s). `stats` (int64[lanes.ST_N]), when given, is added the kernel's work counters (the
    benchmarks' profile); `done(n)`: as run_chunk's. The metric groups not in opts.groups are left out of
    the vector steps' work and NaN in the rows (layout.leave_out), as run_chunk_scalar leaves them.

    Runs are grouped by length, then by excitation profile, then by gap, so a group's lanes end
    together, share their ground motion and tend to be in contact at the same time (a group pays
    for the contact path whenever one of its lanes is in contact). Groups go to the threads one at a
    time, the likely costliest first (longest first; within a length, by excitation, then smallest
    gap), so the last to finish is a cheap
    one. A run's time is its group's time shared among the group's runs. Runs that diverged in a
    lane are rerun by the scalar kernel. (Grouping changes no result: see tests/engine/test_lanes.py.)
    """
    n = runs.n
    if np.unique(runs.law).size > 1:
        raise ValueError("the lane kernel runs the runs of one contact law at a time (run_chunk splits a chunk)")
    n_metrics = L.n_metrics(sys.m.size, sys.i1.size)
    metrics = np.zeros((n, n_metrics))
    run_time = np.zeros(n)
    redo = np.zeros(n, np.int64)
    coef, pid, prof = excitation_profiles(runs, rec, sys.dt)
    order = np.lexsort((runs.gap, pid, -runs.nsteps)).astype(np.int64)
    n_groups = -(-n // LANES)
    model = lane_model(sys, opts, ma)
    excitation = LaneExcitation(coef, pid, prof)
    stats_g = np.zeros((n_groups, ST_N), dtype=np.int64)  # one row per group: no thread shares one
    if stats is not None:
        stats_g[:, ST_TIMED] = 1  # time the scalar steps (only when asked: the clock reads cost 1 %)

    local = threading.local()  # each thread's work arrays (lanes.group_work), made once

    def work(g):
        t0 = time.perf_counter()
        if not hasattr(local, "gw"):
            local.gw = group_work(model, opts.max_iter)
        out = LaneOutputs(metrics, redo, stats_g[g])
        integrate_lanes(order, g, g + 1, model, opts, runs, excitation, out, local.gw)
        members = order[g * LANES : (g + 1) * LANES]
        run_time[members] = (time.perf_counter() - t0) / members.size
        if done is not None:
            done(members.size)

    threads = max(1, min(threads, n_groups))
    if threads == 1:
        for g in range(n_groups):
            work(g)
    else:
        with ThreadPoolExecutor(max_workers=threads) as pool:
            list(pool.map(work, range(n_groups)))
    again = np.flatnonzero(redo)
    if again.size:
        m2, t2, _, _ = run_chunk_scalar(sys, runs.take(again), rec, HistorySpec.none(), opts, threads)
        metrics[again] = m2
        run_time[again] = t2
    if stats is not None:
        stats_g[:, ST_TIMED] = 0  # a switch, not a counter
        stats += stats_g.sum(axis=0)
    L.leave_out(metrics, sys.m.size, sys.i1.size, opts.groups)
    return metrics, run_time


#: announce(kernel, label, estimate_s, measured_here) -> end(seconds): told when Numba starts compiling a kernel
#: (not when it loads one from the cache), so a caller can say so and show the time passing; estimate_s: the
#: least and most seconds expected (engine/compile_times.py)
Announce = Callable[[str, str, tuple[float, float], bool], Callable[[float], None]]


@contextlib.contextmanager
def _announced(kernel: str, label: str, announce: Announce | None, pieces: Callable[[], tuple] = tuple):
    """Call `announce` when Numba starts compiling inside (a cache miss: Numba's 'numba:compile' event
    fires only then), its return value when done; remember how long the compile took here (apart when the kernel's
    largest piece was cached: compile_times.AGAIN). Then too, start compiling the kernel's self-contained pieces
    (what `pieces()` returns) in a second process (engine/aside.py)."""
    from numba.core import event

    from pounding_sweep.engine import compile_times

    started: list = []
    helpers: list = []
    keys: list = []

    class _Listener(event.Listener):
        def on_start(self, ev):
            if not started:
                started.append(time.perf_counter())
                keys.append(compile_times.key(kernel, aside.first_cached(pieces)))
                est, here = compile_times.compile_estimate(keys[0])
                started.append(announce(kernel, label, est, here) if announce is not None else None)
                helpers.append(aside.start(pieces))

        def on_end(self, ev):
            pass

    listener = _Listener()
    event.register("numba:compile", listener)
    try:
        yield
    finally:
        event.unregister("numba:compile", listener)
        try:
            for proc in helpers:
                aside.stop(proc)
        finally:
            if started:
                took = time.perf_counter() - started[0]
                compile_times.record_compile(keys[0], took)
                if started[1] is not None:
                    started[1](took)


def compile_kernel(
    sys: SystemArrays,
    opts: KernelOptions,
    hist: HistorySpec | None = None,
    score: ScoreSpec | None = None,
    kernel: str = "auto",
    laws=None,
    announce: Announce | None = None,
) -> float:
    """Compile (or load from cache) the kernel(s) a sweep of this system will use, on one-step runs;
    return the seconds it took. `laws`: the codes.LAW_* the sweep uses (default: the classic law). With
    `hist` and `score` given: the kernel run_chunk picks for each law's runs; without: that kernel, and
    where it is the lane kernel, the scalar one too (which chunks with histories or scoring, and diverged
    runs, use). `announce` (Announce) is told when a kernel is really compiled, not loaded from the cache."""
    t0 = time.perf_counter()
    laws = [LAW_CLASSIC] if laws is None else sorted(set(int(x) for x in laws))
    none = HistorySpec.none()
    compiled = set()
    for law in laws:
        chunk = Chunk(sys, hist or none, opts, score or ScoreSpec.none(), law)
        picks = [registry.choose(chunk, kernel)]
        if hist is None and picks[0].lanes:
            picks.append(registry.choose(chunk, "scalar"))
        for k in picks:
            key = k.compile_key(score)
            if key not in compiled:
                compiled.add(key)
                with _announced(*key, announce, lambda k=k, chunk=chunk: k.aside(chunk)):
                    _one_step(k, sys, opts, law, hist or none, score)
    return time.perf_counter() - t0


def _one_step(k: registry.Kernel, sys, opts, law, hist, score):
    """One run of one step of `law` on kernel k: compiles it (or loads it from the cache)."""
    runs = RunArrays.one_at_rest(sys.i1.size, law)
    rec = Records(np.zeros(1), np.zeros(1, np.int64), np.zeros(1, np.int64))
    if k.lanes:
        run_chunk_lanes(sys, runs, rec, opts, 1, lane_modes(sys, hist, opts, score, law))
    else:
        run_chunk_scalar(sys, runs, rec, hist, opts, score=score)
