"""Run a chunk of grid points through the kernel on a pool of threads.

The kernel releases the GIL, so threads run side by side; runs are handed out in small
batches from a shared queue, so a thread that draws runs with many impacts does not hold the
others up (static splitting, as numba's prange does, would). Each run writes only its own
rows: no shared reductions, results identical whatever the thread count.
"""

from __future__ import annotations

import os
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np

from . import metrics_layout as L
from .kernel import integrate_batch
from .model import SystemArrays
from .score_kernel import N_SCORES


@dataclass
class RunArrays:
    """Per-run kernel inputs for one chunk (see kernel.integrate_batch)."""

    ks: np.ndarray
    cdash: np.ndarray  # (runs, pairs)
    gap: np.ndarray
    exc_kind: np.ndarray
    exc_amp: np.ndarray
    exc_omega: np.ndarray
    rec_id: np.ndarray
    nsteps: np.ndarray
    status_in: np.ndarray

    @property
    def n(self) -> int:
        return self.ks.size


@dataclass(frozen=True)
class HistorySpec:
    """Channels to keep (kernel codes) and the decimation; empty kinds: metrics only."""

    kinds: np.ndarray
    index: np.ndarray
    decimate: int

    @classmethod
    def none(cls) -> "HistorySpec":
        return cls(np.zeros(0, np.int64), np.zeros(0, np.int64), 1)

    @property
    def active(self) -> bool:
        return self.kinds.size > 0


@dataclass(frozen=True)
class ScoreSpec:
    """Experiment samples to score against: simulation times, displacements [m] per channel, DOFs."""

    t: np.ndarray
    x: np.ndarray  # (channels, samples)
    dof: np.ndarray
    max_lag: int
    dt_sample: float

    @classmethod
    def none(cls) -> "ScoreSpec":
        return cls(np.zeros(0), np.zeros((0, 0)), np.zeros(0, np.int64), 0, 1.0)

    @property
    def active(self) -> bool:
        return self.dof.size > 0


@dataclass(frozen=True)
class KernelOptions:
    scheme: int
    law: int
    max_iter: int


def resolve_threads(threads: int) -> int:
    return threads if threads > 0 else (len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1)


def run_chunk(sys: SystemArrays, runs: RunArrays, rec, hist: HistorySpec, opts: KernelOptions,
              threads: int = 1, batch_runs: int = 0, score: ScoreSpec | None = None):
    """Integrate every run of the chunk; return (metrics, run_time_s, histories or None, scores or None)."""
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


def compile_kernel(sys: SystemArrays, opts: KernelOptions) -> float:
    """Compile (or load from cache) the kernel on a one-step run; return the seconds it took."""
    t0 = time.perf_counter()
    p = sys.i1.size
    runs = RunArrays(np.ones(1), np.zeros((1, p)), np.zeros(1), np.zeros(1, np.int64), np.zeros(1),
                     np.ones(1), np.zeros(1, np.int64), np.ones(1, np.int64), np.zeros(1, np.int64))
    rec = (np.zeros(1), np.zeros(1, np.int64), np.zeros(1, np.int64))
    run_chunk(sys, runs, rec, HistorySpec.none(), opts)
    return time.perf_counter() - t0
