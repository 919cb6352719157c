"""Run a chunk of grid points through the kernel on a pool of threads.

Two kernels compute the same metric row of a run: the lane kernel (kernel_lanes.integrate_lanes,
LANES runs side by side in SIMD lanes, in modal coordinates) takes every chunk it is eligible for
(kernel_lanes.lanes_ineligible_reason: metrics only, implicit or event scheme, two shear frames
facing floor by floor with classical damping); the scalar kernel (kernel.integrate_batch) takes the
others (histories, scoring, the paper's scheme) and reruns any run that diverged in a lane. The two
agree to rounding (tests/test_kernel_lanes.py states the tolerances).

The kernels release the GIL, so threads run side by side; work is handed out in small pieces
(a group of LANES runs, or a small batch of runs) from a shared queue, so a thread that draws runs
with many impacts does not hold the others up (static splitting, as numba's prange does, would).
Each run writes only its own row: no shared reductions, results identical whatever the thread
count, lane or group a run lands in.
"""

from __future__ import annotations

import dataclasses
import os
import time
from concurrent.futures import ThreadPoolExecutor


import numpy as np

from pounding_sweep.engine import layout as L
from pounding_sweep.engine.inputs import HistorySpec, KernelOptions, RunArrays, ScoreSpec  # noqa: F401
from pounding_sweep.engine.scalar import integrate_batch
from pounding_sweep.engine.lanes import (LANES, ST_N, coefficient_table, excitation_profiles, integrate_lanes, lane_modes,
                           lanes_ineligible_reason, size_tuples)
from pounding_sweep.model.modal import ModalArrays, modal_arrays
from pounding_sweep.model.coupled import SystemArrays
from pounding_sweep.engine.score import N_SCORES


def resolve_threads(threads: int) -> int:
    return threads if threads > 0 else (len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1)


def kernel_for(sys: SystemArrays, hist: HistorySpec, opts: KernelOptions, score: ScoreSpec | None = None) -> str:
    """'lanes' or 'scalar': the kernel run_chunk uses for such a chunk."""
    return "lanes" if lanes_ineligible_reason(sys, hist, opts, score) is None else "scalar"


#: set to "scalar" to force the scalar kernel everywhere (benchmarks and tests compare the two)
FORCE_KERNEL: str | None = None
#: the lane kernel's work counters (kernel_lanes.ST_*) of the last run_chunk_lanes call (benchmarks)
LAST_LANE_STATS = np.zeros(ST_N, dtype=np.int64)


def run_chunk(sys: SystemArrays, runs: RunArrays, rec, hist: HistorySpec, opts: KernelOptions,
              threads: int = 1, batch_runs: int = 0, score: ScoreSpec | None = None):
    """Integrate every run of the chunk; return (metrics, run_time_s, histories or None, scores or None)."""
    score = score or ScoreSpec.none()
    if FORCE_KERNEL != "scalar" and runs.n > 0:
        ma = lane_modes(sys, hist, opts, score)
        if isinstance(ma, ModalArrays):
            metrics, run_time = run_chunk_lanes(sys, runs, rec, opts, threads, ma)
            return metrics, run_time, None, None
    return run_chunk_scalar(sys, runs, rec, hist, opts, threads, batch_runs, score)


def run_chunk_scalar(sys: SystemArrays, runs: RunArrays, rec, hist: HistorySpec, opts: KernelOptions,
                     threads: int = 1, batch_runs: int = 0, score: ScoreSpec | None = None):
    """run_chunk on the scalar kernel (every option supported)."""
    score = score or ScoreSpec.none()
    n = runs.n
    n_metrics = L.n_metrics(sys.m.size, sys.i1.size)
    metrics = np.zeros((n, n_metrics))
    run_time = np.zeros(n)
    if hist.active:
        n_samples = int(runs.nsteps.max()) // hist.decimate + 1
        hist_arr = np.full((n, hist.kinds.size, n_samples), np.nan)
    else:
        hist_arr = np.zeros((0, 0, 0))
    rec_flat, rec_off, rec_len = rec
    scores = np.full((n, score.dof.size, N_SCORES), np.nan)

    def work(bounds):
        s, e = bounds
        integrate_batch(
            s, e, sys.dt, sys.m, sys.C, sys.K, sys.Kinv, sys.H, sys.S, sys.i1, sys.i2,
            opts.scheme, opts.law, opts.max_iter,
            runs.ks, runs.cdash, runs.gap, runs.exc_kind, runs.exc_amp, runs.exc_omega,
            runs.rec_id, runs.nsteps, runs.status_in,
            rec_flat, rec_off, rec_len,
            hist.kinds, hist.index, hist.decimate, hist_arr,
            score.t, score.x, score.dof, score.max_lag, score.dt_sample,
            metrics, run_time, scores,
        )

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


def run_chunk_lanes(sys: SystemArrays, runs: RunArrays, rec, opts: KernelOptions, threads: int = 1,
                    ma: ModalArrays | None = None):
    """run_chunk on the lane kernel (the caller checked eligibility; `ma`: the system's modal data
    when the caller has them, from kernel_lanes.lane_modes): (metrics, run_time_s).

    Runs are grouped by length, then by excitation profile, then by gap, so a group's lanes end
    together, share their ground motion and tend to be in contact at the same time (a group pays
    for the contact path whenever one of its lanes is in contact). Groups go to the threads one at a
    time, the likely costliest first (longest first; within a length, by excitation, then smallest
    gap), so the last to finish is a cheap
    one. A run's time is its group's time shared among the group's runs. Runs that diverged in a
    lane are rerun by the scalar kernel. (Grouping changes no result: see test_kernel_lanes.)
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
    ms = (ma.phi, ma.psi, ma.om2, ma.dmp, ma.gam)
    cv = coefficient_table(ma)

    stats = np.zeros((n_groups, ST_N), dtype=np.int64)  # one row per group: no thread shares one

    def work(g):
        t0 = time.perf_counter()
        integrate_lanes(order, g, g + 1, sys.dt, opts.scheme, opts.law, opts.max_iter, nt, n1t, ms,
                        ma.W, cv, runs.ks, runs.cdash, runs.gap, runs.status_in, runs.nsteps,
                        runs.exc_kind, runs.exc_amp, runs.exc_omega, coef, pid, prof, metrics, redo, stats[g])
        members = order[g * LANES:(g + 1) * LANES]
        run_time[members] = (time.perf_counter() - t0) / members.size

    threads = max(1, min(threads, n_groups))
    if threads == 1:
        for g in range(n_groups):
            work(g)
    else:
        with ThreadPoolExecutor(max_workers=threads) as pool:
            list(pool.map(work, range(n_groups)))
    again = np.flatnonzero(redo)
    if again.size:
        sub = RunArrays(*(np.ascontiguousarray(getattr(runs, f.name)[again]) for f in dataclasses.fields(RunArrays)))
        m2, t2, _, _ = run_chunk_scalar(sys, sub, rec, HistorySpec.none(), opts, threads)
        metrics[again] = m2
        run_time[again] = t2
    LAST_LANE_STATS[:] = stats.sum(axis=0)
    return metrics, run_time


def compile_kernel(sys: SystemArrays, opts: KernelOptions, hist: HistorySpec | None = None,
                   score: ScoreSpec | None = None) -> float:
    """Compile (or load from cache) the kernel(s) a sweep of this system will use, on one-step runs;
    return the seconds it took. With `hist` and `score` given: the kernel run_chunk picks for them;
    without: the lane kernel where the system and options allow it, and the scalar kernel (which
    chunks with histories or scoring, and diverged runs, use) in any case."""
    t0 = time.perf_counter()
    p = sys.i1.size
    runs = RunArrays(np.ones(1), np.zeros((1, p)), np.zeros(1), np.zeros(1, np.int64), np.zeros(1),
                     np.ones(1), np.zeros(1, np.int64), np.ones(1, np.int64), np.zeros(1, np.int64))
    rec = (np.zeros(1), np.zeros(1, np.int64), np.zeros(1, np.int64))
    none = HistorySpec.none()
    ma = lane_modes(sys, hist or none, opts, score)
    lanes_ok = isinstance(ma, ModalArrays)
    if lanes_ok:
        run_chunk_lanes(sys, runs, rec, opts, 1, ma)
    if hist is None or not lanes_ok:
        run_chunk_scalar(sys, runs, rec, hist or none, opts, score=score)
    return time.perf_counter() - t0
