"""Run a chunk of grid points through the kernel on a pool of threads.

Two kernels compute the same metric row of a run: the lane kernel (engine.lanes.integrate_lanes,
LANES runs side by side in SIMD lanes, in modal coordinates) takes every chunk it is eligible for
(lanes.lanes_ineligible_reason: metrics only, implicit or event scheme, two shear frames
facing floor by floor with classical damping); the scalar kernel (engine.scalar.integrate_batch) takes the
others (histories, scoring, the paper's scheme) and reruns any run that diverged in a lane. The two
agree to rounding (tests/engine/test_lanes.py states the tolerances, derived in tests/tolerances.py).
Which kernel runs a chunk is an argument (KERNELS), never a module global.

The kernels release the GIL, so threads run side by side; work is handed out in small pieces
(a group of LANES runs, or a small batch of runs) from a shared queue, so a thread that draws runs
with many impacts does not hold the others up (static splitting, as numba's prange does, would).
Each run writes only its own row: no shared reductions, results identical whatever the thread
count, lane or group a run lands in.
"""

from __future__ import annotations

import contextlib
import os
import time
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from pounding_sweep.codes import is_nonlinear
from pounding_sweep.engine import layout as L
from pounding_sweep.engine.inputs import (
    HistorySpec,
    KernelOptions,
    LaneExcitation,
    LaneModel,
    LaneOutputs,  # noqa: F401
    Outputs,
    Records,
    RunArrays,
    ScoreSpec,
    Structure,
)
from pounding_sweep.engine.lanes import (
    LANES,
    ST_N,
    coefficient_table,
    excitation_profiles,
    integrate_lanes,
    lane_modes,
    lanes_ineligible_reason,
    size_tuples,
)
from pounding_sweep.engine.nonlinear import integrate_nonlinear
from pounding_sweep.engine.scalar import integrate_batch
from pounding_sweep.engine.score import N_SCORES
from pounding_sweep.model.coupled import SystemArrays
from pounding_sweep.model.modal import ModalArrays, modal_arrays


def resolve_threads(threads: int) -> int:
    return (
        threads
        if threads > 0
        else (len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1)
    )


#: the kernels a chunk may be run on: "auto" (the lane kernel where it computes the chunk, else the scalar
#: one), "scalar" (every chunk on the scalar kernel: the benchmarks and tests compare the two), "lanes"
KERNELS = ("auto", "scalar", "lanes")


def kernel_for(
    sys: SystemArrays, hist: HistorySpec, opts: KernelOptions, score: ScoreSpec | None = None, kernel: str = "auto"
) -> str:
    """'lanes' or 'scalar': the kernel run_chunk uses for such a chunk (ValueError: `kernel` names none,
    or asks for the lane kernel where it cannot compute the chunk)."""
    if kernel not in KERNELS:
        raise ValueError(f"kernel = {kernel!r}: expected one of {KERNELS}")
    if kernel == "scalar":
        return "scalar"
    why = lanes_ineligible_reason(sys, hist, opts, score)
    if kernel == "lanes" and why is not None:
        raise ValueError(f"kernel = 'lanes': the lane kernel cannot run this chunk ({why})")
    return "lanes" if why is None else "scalar"


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
    laws: np.ndarray | None = None,
    done: Callable[[int], None] | None = None,
):
    """Integrate every run of the chunk on `kernel` (KERNELS); return (metrics, run_time_s, histories or
    None, scores or None). `laws` (codes.LAW_* per run), when given, overrides opts.law run by run: the
    runs of each law go to that law's kernel (a Hertz-type law to engine/nonlinear.py) and the rows come
    back in the chunk's order. `done(n)`, when given, is called from the worker threads as each group or
    batch of n runs finishes (progress within a chunk; it must be thread-safe and quick)."""
    score = score if score is not None else ScoreSpec.none()
    if laws is not None:
        codes_in = np.unique(laws)
        if codes_in.size > 1:
            return _run_by_law(sys, runs, rec, hist, opts, threads, batch_runs, score, kernel, laws, codes_in, done)
        if codes_in.size == 1:
            opts = opts._replace(law=int(codes_in[0]))
    if is_nonlinear(opts.law):
        if kernel == "lanes":
            raise ValueError("kernel = 'lanes': the lane kernel cannot run this chunk (a Hertz-type contact law)")
        return run_chunk_scalar(sys, runs, rec, hist, opts, threads, batch_runs, score, done)
    if kernel_for(sys, hist, opts, score, kernel) == "lanes" and runs.n > 0:
        ma = lane_modes(sys, hist, opts, score)
        metrics, run_time = run_chunk_lanes(sys, runs, rec, opts, threads, ma, done=done)
        return metrics, run_time, None, None
    return run_chunk_scalar(sys, runs, rec, hist, opts, threads, batch_runs, score, done)


def _run_by_law(sys, runs, rec, hist, opts, threads, batch_runs, score, kernel, laws, codes_in, done):
    """run_chunk for a chunk mixing laws: each law's runs on their kernel, rows put back in order."""
    parts = []
    for code in codes_in:
        idx = np.flatnonzero(laws == code)
        law_opts = opts._replace(law=int(code))
        parts.append(
            (idx, run_chunk(sys, runs.take(idx), rec, hist, law_opts, threads, batch_runs, score, kernel, done=done))
        )
    return merge_rows(runs.n, parts)


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
    """run_chunk on the scalar kernel (every option supported): engine/scalar.py for the linear laws,
    engine/nonlinear.py for the Hertz-type ones."""
    score = score if score is not None else ScoreSpec.none()
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
    kernel_fn = integrate_nonlinear if is_nonlinear(opts.law) else integrate_batch

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
    """run_chunk on the lane kernel (the caller checked eligibility; `ma`: the system's modal data
    when the caller has them, from lanes.lane_modes): (metrics, run_time_s). `stats` (int64[lanes.ST_N]),
    when given, is added the kernel's work counters (the benchmarks' profile); `done(n)`: as run_chunk's.

    Runs are grouped by length, then by excitation profile, then by gap, so a group's lanes end
    together, share their ground motion and tend to be in contact at the same time (a group pays
    for the contact path whenever one of its lanes is in contact). Groups go to the threads one at a
    time, the likely costliest first (longest first; within a length, by excitation, then smallest
    gap), so the last to finish is a cheap
    one. A run's time is its group's time shared among the group's runs. Runs that diverged in a
    lane are rerun by the scalar kernel. (Grouping changes no result: see tests/engine/test_lanes.py.)
    """
    n = runs.n
    n_metrics = L.n_metrics(sys.m.size, sys.i1.size)
    metrics = np.zeros((n, n_metrics))
    run_time = np.zeros(n)
    redo = np.zeros(n, np.int64)
    coef, pid, prof = excitation_profiles(runs, rec, sys.dt)
    order = np.lexsort((runs.gap, pid, -runs.nsteps)).astype(np.int64)
    nt, n1t = size_tuples(sys)
    n_groups = -(-n // LANES)
    ma = ma if ma is not None else modal_arrays(sys, len(n1t))
    model = LaneModel(float(sys.dt), nt, n1t, ma.phi, ma.psi, ma.om2, ma.dmp, ma.gam, ma.W, coefficient_table(ma))
    excitation = LaneExcitation(coef, pid, prof)
    stats_g = np.zeros((n_groups, ST_N), dtype=np.int64)  # one row per group: no thread shares one

    def work(g):
        t0 = time.perf_counter()
        integrate_lanes(order, g, g + 1, model, opts, runs, excitation, LaneOutputs(metrics, redo, stats_g[g]))
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
        stats += stats_g.sum(axis=0)
    return metrics, run_time


#: announce(kernel, label, estimate_s, measured_here) -> end(seconds): told when Numba starts compiling a kernel
#: (not when it loads one from the cache), so a caller can say so and show the time passing
Announce = Callable[[str, str, float, bool], Callable[[float], None]]


@contextlib.contextmanager
def _announced(kernel: str, label: str, announce: Announce | None):
    """Call `announce` when Numba starts compiling inside (a cache miss: Numba's 'numba:compile' event
    fires only then), its return value when done; remember how long the compile took here."""
    from numba.core import event

    from pounding_sweep.engine.jit import compile_estimate, record_compile

    started: list = []

    class _Listener(event.Listener):
        def on_start(self, ev):
            if not started:
                started.append(time.perf_counter())
                est, here = compile_estimate(kernel)
                started.append(announce(kernel, label, est, here) if announce is not None else None)

        def on_end(self, ev):
            pass

    listener = _Listener()
    event.register("numba:compile", listener)
    try:
        yield
    finally:
        event.unregister("numba:compile", listener)
        if started:
            took = time.perf_counter() - started[0]
            record_compile(kernel, took)
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
    return the seconds it took. With `hist` and `score` given: the kernel run_chunk picks for them;
    without: the lane kernel where the system and options allow it, and the scalar kernel (which
    chunks with histories or scoring, and diverged runs, use) in any case. `laws`: the codes.LAW_* the
    sweep uses (default opts.law); a Hertz-type one compiles engine/nonlinear.py as well. `announce`
    (Announce) is told when a kernel is really compiled, not loaded from the cache."""
    t0 = time.perf_counter()
    laws = [opts.law] if laws is None else sorted(set(int(x) for x in laws))
    nonlinear = [x for x in laws if is_nonlinear(x)]
    if nonlinear:
        _compile_one(sys, opts._replace(law=nonlinear[0]), hist, score, kernel, announce)
    linear = [x for x in laws if not is_nonlinear(x)]
    if linear:
        _compile_one(sys, opts._replace(law=linear[0]), hist, score, kernel, announce)
    return time.perf_counter() - t0


def _compile_one(sys, opts, hist, score, kernel, announce):
    """compile_kernel for one law's kernel(s)."""
    p = sys.i1.size
    runs = RunArrays(
        np.ones(1),
        np.zeros((1, p)),
        np.zeros(1),
        np.zeros(1, np.int64),
        np.zeros(1),
        np.ones(1),
        np.zeros(1, np.int64),
        np.ones(1, np.int64),
        np.zeros(1, np.int64),
    )
    rec = Records(np.zeros(1), np.zeros(1, np.int64), np.zeros(1, np.int64))
    none = HistorySpec.none()
    ma = lane_modes(sys, hist or none, opts, score)
    lanes_ok = isinstance(ma, ModalArrays) and kernel != "scalar"
    if lanes_ok:
        with _announced("lanes", "the lane kernel", announce):
            run_chunk_lanes(sys, runs, rec, opts, 1, ma)
    if hist is None or not lanes_ok:
        name, label = (
            ("nonlinear", "the Hertz-type contact kernel")
            if is_nonlinear(opts.law)
            else ("scalar", "the scalar kernel")
        )
        if score is not None and score.active:
            name, label = f"{name}_scored", f"{label} with scoring"
        with _announced(name, label, announce):
            run_chunk_scalar(sys, runs, rec, hist or none, opts, score=score)
