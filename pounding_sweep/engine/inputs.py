"""The kernels' inputs as plain data: per-run arrays, the histories and experiment samples to keep,
the options. No Numba here, so any layer above may build them without loading the kernels."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


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
