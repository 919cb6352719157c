"""The lane kernel's ground motion: each run's ground acceleration as coef[run] * prof[pid[run], step],
the profiles shared by the runs of a chunk (one per harmonic frequency or record)."""

from __future__ import annotations

import numpy as np

from pounding_sweep.codes import EXC_HARMONIC, EXC_RECORD
from pounding_sweep.engine.jit import njit_lanes


@njit_lanes
def _sin_profile(omega, nsteps, dt, out):
    """out[step] = sin(omega * step * dt), the expression events.ground_acceleration evaluates."""
    for step in range(nsteps + 1):
        out[step] = np.sin(omega * step * dt)


def excitation_profiles(runs, rec, dt):
    """Ground acceleration as coef[run] * prof[pid[run], step], equal to events.ground_acceleration.

    Harmonic: prof = sin(omega step dt) per distinct omega, by compiled code as the scalar kernel
    evaluates it (the C library's sin: NumPy's vectorised sin may differ by an ulp on some CPUs),
    coef = -amp * omega * omega. Record: prof = the resampled record (zero past its end), coef = the
    run's scale.
    Returns (coef, pid, prof).
    """
    rec_flat, rec_off, rec_len = rec
    n = runs.n
    nmax = int(runs.nsteps.max()) if n else 0
    harmonic = runs.exc_kind == EXC_HARMONIC
    coef = np.where(harmonic, -runs.exc_amp * runs.exc_omega * runs.exc_omega, runs.exc_amp)
    keys = [
        (EXC_HARMONIC, float(w)) if h else (EXC_RECORD, int(r))
        for h, w, r in zip(harmonic.tolist(), runs.exc_omega.tolist(), runs.rec_id.tolist())
    ]
    index: dict = {}
    pid = np.array([index.setdefault(k, len(index)) for k in keys], dtype=np.int64)
    prof = np.zeros((max(1, len(index)), nmax + 1))
    for (kind, val), k in index.items():
        if kind == EXC_HARMONIC:
            _sin_profile(val, nmax, dt, prof[k])
        else:
            off, ln = int(rec_off[val]), int(rec_len[val])
            m = min(ln, nmax + 1)
            prof[k, :m] = rec_flat[off : off + m]
    return coef, pid, prof
