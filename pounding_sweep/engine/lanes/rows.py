"""Where the lane kernel keeps things: the rows of its lane-major work array W (a group's state, one
float64 per lane and row), the rows of one lane's scalar work arrays (Z, B, I), the per-lane scalars,
the work counters, and the coefficient table of the vector steps. Offsets are functions of the floor
count N and the pair count P, compile-time constants in the vector code (engine/lanes/vector.py).
"""

from __future__ import annotations

import numpy as np

from pounding_sweep.engine.jit import inline
from pounding_sweep.engine.simd import VW
from pounding_sweep.model.modal import ModalArrays

#: runs per group, fixed at compile time: one SIMD value of the target's width (simd.VW: 8 with AVX-512, else 4). A
#: group leaves its vector loop whenever one of its runs has an event, and pays for the contact step while one is
#: in contact, so a group no wider than a value does the least such work: on a Zen 3 (AVX2) groups of 4 took 0.96x
#: (event) and 0.94x (implicit) the time of groups of 8 (benchmarks/compare_checkouts.py --paired 20), the rows
#: identical (grouping changes no result: tests/engine/test_lanes.py)
LANES = VW

# energy accumulators of a lane (the scalar step's Z_EN row)
E_IN, E_ABS, E_DST, E_WSP, E_WDA, E_WREL = range(6)

# counters integrate_lanes adds to (the benchmark's profile): scalar steps taken and their time,
# calls of the vector loops and the steps they advanced; ST_TIMED > 0 (the driver sets it only when its caller
# asks for the counters) times the scalar steps: two clock reads per scalar step cost 1 % of a pounding grid
ST_FIXUPS, ST_FIX_NS, ST_CALLS, ST_VSTEPS, ST_TIMED = range(5)
ST_N = 5

# per-lane scalar rows, after r_s
(S_KS, S_GAP, S_COEF, S_AGS, S_AGE, S_EIN, S_EABS, S_DST, S_WSP, S_WDA, S_WREL, S_UNS, S_MIT, S_EVT, S_BAD) = range(15)
N_SCALARS = 15


@inline
def row_offsets(N, P):
    """Row offsets (compile-time constants once N and P are)."""
    r_q0 = 0  # q (N rows) then r (N rows): buffer 0
    r_q1 = 2 * N  # buffer 1
    r_g = 4 * N  # Psi F at the step start
    r_f = 5 * N  # F at the step start (P rows)
    r_pen = r_f + P  # penetration at the step start
    r_act = r_pen + P  # contact set (1.0 / 0.0)
    r_inc = r_act + P  # in a compressive phase
    r_cac = r_inc + P  # duration of the compressive phase in progress
    r_end = r_cac + P  # a compressive phase ended in this step
    r_cd = r_end + P  # dashpot c_j
    r_R = r_cd + P  # (I + diag(kappa) W)_SS^-1 of the lane's set, R[i, j] at i * P + j
    r_s = r_R + P * P  # per-lane scalars (S_*)
    r_met = r_s + N_SCALARS  # metric slots before the per-run ones (metrics_layout order)
    return r_q0, r_q1, r_g, r_f, r_pen, r_act, r_inc, r_cac, r_end, r_cd, r_R, r_s, r_met


# Work arrays of one lane's scalar step, flat so that calls pass a few arrays (each array argument
# or tuple member that Numba unpacks costs an atomic reference count, which dominated this code):
# Z (float64, ZR rows of max(N, P, 6) columns), B (bool, BR rows of P), I (int64: pair indices and
# the active-set iteration's history), A (P x 2P: small solves).
(
    Z_Q,
    Z_QD,
    Z_QE,
    Z_QDE,
    Z_F,
    Z_FE,
    Z_FS,
    Z_CF,
    Z_CQ,
    Z_CR,
    Z_DQF,
    Z_DF,
    Z_DDF,
    Z_B,
    Z_TH,
    Z_CAC,
    Z_SP,
    Z_DP,
    Z_PP,
    Z_EN,
    Z_C,
    Z_OM2,
    Z_DMP,
    Z_GAM,
    Z_PHI,
) = range(25)
ZR = 25  # Z_OM2, Z_DMP, Z_GAM, Z_PHI (max_i |phi_ik| per mode k) are the model's, set once per call of the kernel
(B_ACT, B_WAS, B_JUST, B_TRIAL, B_INC) = range(5)
BR = 5
I_IDX, I_SEEN = 0, 1


# coefficient table Cv (coefficient_table): per mode k / floor i / pair j
C_CQ, C_CR, C_EK, C_NCF, C_NDA, C_NW2, C_DH, C_GAM = range(8)  # row C_X * N + k


@inline
def scratch_entries(N, P):
    """Entries of the stack scratch T: modal accelerations, floors, increments (then the new q),
    forces, Psi F, the free step's q and r."""
    t_qa = 0
    t_u = N
    t_dq = 2 * N
    t_f = 3 * N
    t_g = 3 * N + P
    t_qf = 4 * N + P
    t_rf = 5 * N + P
    return t_qa, t_u, t_dq, t_f, t_g, t_qf, t_rf


@inline
def table_offsets(N, P):
    """Row offsets of Phi (i * N + k) and Psi, (2/dt) Psi (k * P + j) in the coefficient table."""
    c_phi = 8 * N
    c_psi = c_phi + N * N
    c_psv = c_psi + N * P
    return c_phi, c_psi, c_psv


def coefficient_table(ma: ModalArrays) -> np.ndarray:
    """The vector code's coefficients (modal.ModalArrays at its dt), in table_offsets' order."""
    n = ma.om2.size
    dt = ma.dt
    rows = [
        ma.cq,
        ma.cr,
        -ma.cf * ma.gam,
        -ma.cf,
        (-2.0 / dt) * ma.dmp,
        -ma.om2,
        ma.dmp / dt,
        ma.gam,
        ma.phi.ravel(),
        ma.psi.ravel(),
        (2.0 / dt) * ma.psi.ravel(),
    ]
    flat = np.concatenate([np.asarray(r, dtype=np.float64).ravel() for r in rows])
    assert flat.size == 8 * n + n * n + 2 * n * ma.psi.shape[1]
    return np.ascontiguousarray(flat)
