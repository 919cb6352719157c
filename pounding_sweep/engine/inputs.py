"""The kernels' inputs and outputs as typed records (NamedTuples of arrays and numbers): Numba takes
them as they are, and each field is documented once, here. No Numba in this module, so any layer
above may build them without loading the kernels.

A kernel entry point takes a few of these records instead of dozens of loose arrays:
Structure (the coupled model at one dt), RunArrays (per-run contact and excitation), Records (the
resampled ground-motion records, flattened), KernelOptions, HistorySpec and ScoreSpec (what to keep
and what to score against), and the Outputs it fills.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from pounding_sweep.engine.layout import GROUPS_ALL


class Structure(NamedTuple):
    """The coupled two-building model at one dt (model.coupled.SystemArrays), float64 / int64, C-contiguous.
    DOFs are building 1's floors (n1 of them) then building 2's; pair j faces floor i1[j] of building 1 and
    floor i2[j] of building 2 (P = 0 pairs: no contact)."""

    dt: float  # time step [s]
    m: np.ndarray  # (N,) lumped floor masses [kg]
    C: np.ndarray  # (N, N) Rayleigh damping [N s/m], block-diagonal
    K: np.ndarray  # (N, N) shear-frame stiffness [N/m], block-diagonal
    Kinv: np.ndarray  # (N, N) (K + 2/dt C + 4/dt^2 M)^-1: Newmark's effective stiffness, inverted
    H: np.ndarray  # (N, P) Kinv G, G[:, j] = e(i1[j]) - e(i2[j])
    S: np.ndarray  # (P, P) G^T Kinv G (symmetric)
    i1: np.ndarray  # (P,) DOF of building 1 in pair j
    i2: np.ndarray  # (P,) DOF of building 2 in pair j
    n1: int  # building 1's floor count (DOFs 0 .. n1 - 1)

    @classmethod
    def of(cls, sysarr) -> Structure:
        """The record of a model.coupled.SystemArrays (same fields, and building 1's floor count)."""
        return cls(
            float(sysarr.dt),
            sysarr.m,
            sysarr.C,
            sysarr.K,
            sysarr.Kinv,
            sysarr.H,
            sysarr.S,
            sysarr.i1,
            sysarr.i2,
            building_split(sysarr),
        )


def building_split(sysarr) -> int:
    """Building 1's floor count of a model.coupled.SystemArrays: its `n1` where it has one, else the DOF of
    building 2's first pair (pairs face floor by floor from the ground), else every DOF (no pairs: one building)."""
    n1 = getattr(sysarr, "n1", None)
    if n1 is not None:
        return int(n1)
    return int(sysarr.i2[0]) if sysarr.i2.size else int(sysarr.m.size)


class RunArrays(NamedTuple):
    """Per-run inputs of one chunk (index: the run's row in the chunk)."""

    ks: np.ndarray  # (R,) contact stiffness k_s [N/m]
    cdash: np.ndarray  # (R, P) dashpot c_j [N s/m] (eq. 9)
    gap: np.ndarray  # (R,) seismic gap d [m]
    exc_kind: np.ndarray  # (R,) codes.EXC_HARMONIC or codes.EXC_RECORD
    exc_amp: np.ndarray  # (R,) harmonic: table amplitude [m] (times scale); record: scale
    exc_omega: np.ndarray  # (R,) harmonic: table circular frequency [rad/s]
    rec_id: np.ndarray  # (R,) record: which of Records
    nsteps: np.ndarray  # (R,) steps of the run
    status_in: np.ndarray  # (R,) status bits known before the run (engine.layout.STATUS_*)
    law: np.ndarray  # (R,) the run's contact law, codes.LAW_* (int64)

    @property
    def n(self) -> int:
        return self.ks.size

    def take(self, idx) -> RunArrays:
        """The runs at `idx`, contiguous."""
        return RunArrays(*(np.ascontiguousarray(a[idx]) for a in self))

    @classmethod
    def one_at_rest(cls, pairs: int, law: int) -> RunArrays:
        """One harmonic run of one step with no table motion (what a compile runs the kernels on)."""
        return cls(
            np.ones(1),
            np.zeros((1, pairs)),
            np.zeros(1),
            np.zeros(1, np.int64),
            np.zeros(1),
            np.ones(1),
            np.zeros(1, np.int64),
            np.ones(1, np.int64),
            np.zeros(1, np.int64),
            np.full(1, law, np.int64),
        )


class Records(NamedTuple):
    """Every ground-motion record a chunk may use, resampled to dt [m/s^2] and flattened."""

    flat: np.ndarray  # all records one after another
    off: np.ndarray  # (records,) start of record k in flat
    len: np.ndarray  # (records,) samples of record k (sample s at t = s dt)


class KernelOptions(NamedTuple):
    """How to integrate: codes.SCHEME_*, the implicit scheme's active-set iterations per step, and the
    Hertz-damp law's floor on the approach speed of an impact [m/s] (engine/nonlinear.py), and the metric
    groups to compute (engine/layout.py GROUP_*: a bit mask; the others are left out). The contact law is
    the runs' (RunArrays.law)."""

    scheme: int
    max_iter: int
    min_impact_speed: float = 0.01
    groups: int = GROUPS_ALL


class HistorySpec(NamedTuple):
    """Channels to keep (codes.H_* and their DOF or pair) and the decimation; no kinds: metrics only."""

    kinds: np.ndarray  # (channels,) int64
    index: np.ndarray  # (channels,) int64
    decimate: int  # keep every decimate-th step

    @classmethod
    def none(cls) -> HistorySpec:
        return cls(np.zeros(0, np.int64), np.zeros(0, np.int64), 1)

    @property
    def active(self) -> bool:
        return self.kinds.size > 0


class ScoreSpec(NamedTuple):
    """Experiment samples to score every run against (sweep/scoring.py); no DOFs: no scoring.

    A channel is a floor's displacement relative to the table (codes.H_DISP) or its absolute acceleration
    (codes.H_ABS_ACC). `sos` is the low-pass filter of the acceleration channels: the kernel applies it,
    causally from rest, to each run's samples of those channels before scoring them (engine/score.py
    sos_filter); `x` holds the experiment's samples already filtered the same way."""

    t: np.ndarray  # (samples,) simulation times [s]
    x: np.ndarray  # (channels, samples) experimental displacement [m] or absolute acceleration [m/s^2]
    dof: np.ndarray  # (channels,) the model DOF each channel tracks
    max_lag: int  # samples searched either side for the best correlation
    dt_sample: float  # the experiment's sample interval [s]
    kind: np.ndarray  # (channels,) codes.H_DISP or codes.H_ABS_ACC, int64
    sos: np.ndarray  # (sections, 6) second-order sections [b0, b1, b2, 1, a1, a2]; (0, 6): no filter

    @classmethod
    def none(cls) -> ScoreSpec:
        return cls(
            np.zeros(0), np.zeros((0, 0)), np.zeros(0, np.int64), 0, 1.0, np.zeros(0, np.int64), np.zeros((0, 6))
        )

    @property
    def active(self) -> bool:
        return self.dof.size > 0


class Outputs(NamedTuple):
    """What the scalar kernel fills, per run of the chunk."""

    metrics: np.ndarray  # (R, engine.layout.n_metrics) the metric row
    run_time: np.ndarray  # (R,) wall time in the kernel [s]
    hist: np.ndarray  # (R, channels, samples) histories, or (0, 0, 0) for none
    scores: np.ndarray  # (R, experiment channels, engine.score.N_SCORES), or nothing to fill


class LaneModel(NamedTuple):
    """The lane kernel's model (engine/lanes): modal data of the coupled model at dt (model.modal.ModalArrays)."""

    dt: float  # time step [s]
    n: int  # the floor count N (the vector loops are compiled for it: engine/lanes/loops.py)
    n1: int  # building 1's floor count N1
    gt: tuple  # (0,): every metric group, fixed at compile time; (): the groups in KernelOptions.groups, at run time
    phi: np.ndarray  # (N, N) mode shapes, mass-normalised, block-diagonal (a mode moves one building)
    psi: np.ndarray  # (N, P) Phi^T G: the modes' share of each pair's relative displacement
    om2: np.ndarray  # (N,) w_k^2 [1/s^2]
    dmp: np.ndarray  # (N,) d_k = 2 zeta_k w_k [1/s]
    gam: np.ndarray  # (N,) participation Phi^T M 1 [kg^0.5]
    W: np.ndarray  # (P, P) Psi^T diag(cf) Psi at dt (contact flexibility in modes)
    Cv: np.ndarray  # the vector steps' coefficients (lanes.coefficient_table)


class LaneExcitation(NamedTuple):
    """Ground acceleration of each run as coef[run] * prof[pid[run], step] (lanes.excitation_profiles)."""

    coef: np.ndarray  # (R,)
    pid: np.ndarray  # (R,) profile of the run
    prof: np.ndarray  # (profiles, max steps + 1)


class LaneOutputs(NamedTuple):
    """What the lane kernel fills."""

    metrics: np.ndarray  # (R, engine.layout.n_metrics)
    redo: np.ndarray  # (R,) 1: the run diverged in a lane, rerun it on the scalar kernel
    stats: np.ndarray  # (ST_N,) int64 work counters (lanes.ST_*), added to


class LaneWork(NamedTuple):
    """Work arrays of one lane's scalar step (lanes.Z_*, B_*, I_* rows; allocated once per call)."""

    Z: np.ndarray
    B: np.ndarray
    I: np.ndarray  # noqa: E741
    A: np.ndarray
    orow: np.ndarray
    dur: np.ndarray
    nph: np.ndarray
