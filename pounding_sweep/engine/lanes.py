"""Lane kernel: LANES runs of a grid advanced side by side in SIMD lanes, in modal coordinates.

Same model, schemes and metric row as the scalar kernel (kernel.integrate_batch, schemes "event"
and "implicit"), computed with other algebra: each building's modes (modal.py) turn Newmark's
2N x 2N solve into N scalar recurrences (mode k: dq = cq q + cr r + cf fsum, two fused
multiply-adds and two additions), the floors are Phi q, and contact at the step end is solved
through the lane's precomputed (I + diag(kappa) W)_SS^-1 of its contact set S. Results agree with
the scalar kernel to rounding (tests/engine/test_lanes.py states the tolerance), not bit for bit.

Per step, for a group of LANES runs (chunks of VW lanes):
- quiet (no lane in contact at the step start): modes, floors, energy increments, per-floor peaks.
  A floor peak is written only in the rare steps where it grows in some lane (no store otherwise);
- contact (some lane in contact): the free step, the contact forces of each lane's set, the end
  state, the per-pair contact metrics and energies;
- events: a lane whose end state contradicts its contact set (an impact starts or ends: by the
  event scheme's test, kernel._switch_tolerance; under the implicit scheme, the active set the end
  state asks for differs) keeps its start state (q, r are double-buffered; other rows are written
  only for the other lanes) and takes the step in scalar code (_lane_step): the event scheme's
  located switches between sub-steps (the pieces of kernel.integrate_batch's event step, in modal form), or the implicit scheme's
  active-set iteration (kernel.integrate_batch). A quiet chunk first tests only "some pair
  penetrates" and recomputes with the exact test when one does.
A run that diverges is handed back to the driver, which reruns it with the scalar kernel.

State per lane: modal displacement q and scaled velocity r = (dt / 2) q' (so that r+ = dq - r
is an addition), contact forces F at the step start and their modal resultant g = Psi F, the
contact set, the penetrations at the step start; the acceleration is never stored (equilibrium).
Floor counts are compile-time constants (the lengths of the tuples nt, n1t), so row offsets are too.
"""

from __future__ import annotations

import numpy as np
from llvmlite import ir
from numba import types
from numba.extending import intrinsic

from pounding_sweep.codes import EXC_HARMONIC, EXC_RECORD, LAW_NO_TENSION, SCHEME_EVENT, SCHEME_IMPLICIT  # noqa: F401
from pounding_sweep.engine import layout as ML
from pounding_sweep.engine.clock import _monotonic_ns
from pounding_sweep.engine.events import (
    EVENT_MIN_FRACTION,
    MAX_EVENTS,
    _ag_inside,
    _force_extremes,
    _illinois,
    _secant_point,
    _switch_tolerance,
    _want_contact,
)
from pounding_sweep.engine.inputs import LaneWork
from pounding_sweep.engine.jit import LANES_JIT, inline, njit_lanes, njit_step  # noqa: F401
from pounding_sweep.engine.simd import (
    SCRATCH,
    VW,
    elem_ptr,
    f64v,
    fence,
    many,
    mconst,
    mcount,
    mfloat,
    scratch,
    select_bits,
    sget,
    splat,
    sset,
    vfma,
    vsel,
    vsplat,
)
from pounding_sweep.model.modal import ModalArrays, modal_arrays

#: runs per group, fixed at compile time (a multiple of simd.VW)
LANES = 8

_inline = inline

# energy accumulators of a lane (the scalar step's `en`)
E_IN, E_ABS, E_DST, E_WSP, E_WDA, E_WREL = range(6)

# counters integrate_lanes adds to (the benchmark's profile): scalar steps taken and their time,
# calls of the vector loops and the steps they advanced
ST_FIXUPS, ST_FIX_NS, ST_CALLS, ST_VSTEPS = range(4)
ST_N = 4

# per-lane scalar rows, after r_s
(S_KS, S_GAP, S_COEF, S_AGS, S_AGE, S_EIN, S_EABS, S_DST, S_WSP, S_WDA, S_WREL, S_UNS, S_MIT, S_EVT, S_BAD) = range(15)
N_SCALARS = 15


@_inline
def _layout(N, P):
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


# ------------------------------------------------------------------------------------------ scalar parts
# One lane's step in scalar code, for the rare steps with a contact event: the scalar kernel's
# algorithms (kernel.integrate_batch's event step: _first_event, _locate_event, _switch, _fixed_set_step; and the
# implicit scheme's active-set iteration), written for modal state. The pieces that do not depend on
# the coordinates (the Hermite indicator, the switch tolerance, the ground motion inside a step, the
# force extremes, the Illinois bracket update) are engine/events.py's, shared with the scalar kernel
# (the Numba cache is keyed by a hash of the engine's sources: engine/jit.py).


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
) = range(24)
ZR = 24
(B_ACT, B_WAS, B_JUST, B_TRIAL, B_PREV, B_INC) = range(6)
BR = 6
I_IDX, I_SEEN = 0, 1


@njit_step
def _floor_u(Z, row, i, phi, N):
    s = 0.0
    for k in range(N):
        s += phi[i, k] * Z[row, k]
    return s


@njit_step
def _pair(Z, rq, rqd, j, psi, gap, N):
    """(penetration, its rate) of pair j in the state (Z[rq], Z[rqd])."""
    s = 0.0
    v = 0.0
    for k in range(N):
        s += psi[k, j] * Z[rq, k]
        v += psi[k, j] * Z[rqd, k]
    return s - gap, v


@njit_step
def _indicator(Z, B, rq, rqd, j, law, k_s, gap, psi, N):
    """kernel._indicator: >= 0 where pair j's state contradicts its contact state."""
    pen, vr = _pair(Z, rq, rqd, j, psi, gap, N)
    want = pen
    if law == LAW_NO_TENSION:
        want = min(pen, pen + (Z[Z_C, j] / k_s) * vr)
    return -want if B[B_ACT, j] else want


@njit_step
def _keff_coefs(Z, h, N):
    """Newmark coefficients of each mode for a step of length h (modal.py)."""
    for k in range(N):
        f = 1.0 / (Z[Z_OM2, k] + 2.0 * Z[Z_DMP, k] / h + 4.0 / (h * h))
        Z[Z_CF, k] = f
        Z[Z_CQ, k] = -2.0 * Z[Z_OM2, k] * f
        Z[Z_CR, k] = 8.0 / (h * h) * f


@njit_step
def _free_step(Z, h, ag_s, ag_e, gap, psi, N, P):
    """The step of length h with no contact force at its end (the start forces Z_F in the load): its
    increment Z_DQF, and the pairs' free end penetration Z_DF and rate Z_DDF."""
    for k in range(N):
        g = 0.0
        for j in range(P):
            g += psi[k, j] * Z[Z_F, j]
        fsum = -Z[Z_GAM, k] * (ag_s + ag_e) - g
        Z[Z_DQF, k] = Z[Z_CF, k] * fsum + Z[Z_CQ, k] * Z[Z_Q, k] + Z[Z_CR, k] * (0.5 * h * Z[Z_QD, k])
    for j in range(P):
        s = 0.0
        v = 0.0
        for k in range(N):
            s += psi[k, j] * (Z[Z_Q, k] + Z[Z_DQF, k])
            v += psi[k, j] * ((2.0 / h) * Z[Z_DQF, k] - Z[Z_QD, k])
        Z[Z_DF, j] = s - gap
        Z[Z_DDF, j] = v


@njit_step
def _active_pairs(B, I, P):
    """The pairs in B_ACT into I[I_IDX, :na]; returns na."""
    na = 0
    for j in range(P):
        if B[B_ACT, j]:
            I[I_IDX, na] = j
            na += 1
    return na


@njit_step
def _set_forces(Z, B, I, A, h, k_s, psi, N, P):
    """Contact forces Z_FS at the end of a step of length h with the set B_ACT (others 0): the SPD
    system (W_SS + diag(1/kappa)) F_S = (k_s delta + c delta')_S / kappa of the free end state,
    W = Psi^T diag(cf) Psi, kappa = k_s + 2 c / h (kernel._contact_forces' system in modal form)."""
    for j in range(P):
        Z[Z_FS, j] = 0.0
    na = _active_pairs(B, I, P)
    if na == 0:
        return
    for p in range(na):
        j = I[I_IDX, p]
        kap = k_s + 2.0 * Z[Z_C, j] / h
        for p2 in range(na):
            j2 = I[I_IDX, p2]
            s = 0.0
            for k in range(N):
                s += psi[k, j] * Z[Z_CF, k] * psi[k, j2]
            A[p, p2] = s
        A[p, p] += 1.0 / kap
        Z[Z_B, p] = (k_s * Z[Z_DF, j] + Z[Z_C, j] * Z[Z_DDF, j]) / kap
    for k in range(na):  # Gaussian elimination (SPD: no pivoting)
        piv = A[k, k]
        for i in range(k + 1, na):
            f = A[i, k] / piv
            for j in range(k, na):
                A[i, j] -= f * A[k, j]
            Z[Z_B, i] -= f * Z[Z_B, k]
    for i in range(na - 1, -1, -1):
        s = Z[Z_B, i]
        for j in range(i + 1, na):
            s -= A[i, j] * Z[Z_B, j]
        Z[Z_B, i] = s / A[i, i]
    for p in range(na):
        Z[Z_FS, I[I_IDX, p]] = Z[Z_B, p]


@njit_step
def _end_state(Z, h, psi, N, P):
    """End state of a step with forces Z_FS: dq = dqf - cf Psi F, q+ = q + dq, q'+ = (2/h) dq - q'."""
    for k in range(N):
        g = 0.0
        for j in range(P):
            g += psi[k, j] * Z[Z_FS, j]
        dq = Z[Z_DQF, k] - Z[Z_CF, k] * g
        Z[Z_QE, k] = Z[Z_Q, k] + dq
        Z[Z_QDE, k] = (2.0 / h) * dq - Z[Z_QD, k]


@njit_step
def _law_forces(Z, B, rq, rqd, rf, k_s, gap, psi, N, P):
    """Row rf := the Kelvin-Voigt forces (eq. 8) of the pairs in B_ACT in the state (rq, rqd), 0 for
    the others."""
    for j in range(P):
        Z[rf, j] = 0.0
        if B[B_ACT, j]:
            pen, vr = _pair(Z, rq, rqd, j, psi, gap, N)
            Z[rf, j] = k_s * pen + Z[Z_C, j] * vr


@njit_step
def _fixed_set_step(Z, B, I, A, h, ag_s, ag_e, k_s, gap, psi, N, P):
    """kernel._fixed_set_step in modal form: one Newmark step of length h from (Z_Q, Z_QD, Z_F) with
    the pairs in B_ACT in contact at its end; end state in Z_QE, Z_QDE, its Kelvin-Voigt forces (eq. 8)
    in Z_FE."""
    _keff_coefs(Z, h, N)
    _free_step(Z, h, ag_s, ag_e, gap, psi, N, P)
    _set_forces(Z, B, I, A, h, k_s, psi, N, P)
    _end_state(Z, h, psi, N, P)
    _law_forces(Z, B, Z_QE, Z_QDE, Z_FE, k_s, gap, psi, N, P)


@njit_step
def _modal_acc(Z, rq, rqd, rf, psi, N, P):
    """Modal absolute accelerations of the state (rq, rqd) with forces in row rf into row Z_B:
    -d q' - w^2 q - Psi F (equilibrium; the ground term cancels in absolute acceleration)."""
    for k in range(N):
        g = 0.0
        for j in range(P):
            g += psi[k, j] * Z[rf, j]
        Z[Z_B, k] = -Z[Z_DMP, k] * Z[rqd, k] - Z[Z_OM2, k] * Z[rq, k] - g


@njit_step
def _finite(Z, rq, rqd, rf, phi, psi, N, P):
    """kernel's divergence guard on a state: floors within DIVERGED_M, accelerations below 1e300."""
    _modal_acc(Z, rq, rqd, rf, psi, N, P)
    for i in range(N):
        u = 0.0
        a = 0.0
        for k in range(N):
            u += phi[i, k] * Z[rq, k]
            a += phi[i, k] * Z[Z_B, k]
        if not (abs(u) < ML.DIVERGED_M) or not (abs(a) < 1e300):
            return False
    return True


@njit_step
def _hermite_root(p0, p1, m0, m1, h, law, k_s, c, sign, f_lo, f_hi):
    """The crossing in (0, 1] of sign * indicator on the interpolant, bracketed by f_lo < 0 <= f_hi.
    kernel._first_event bisects 60 times; here 20 halvings narrow the bracket to 1e-6 exactly as it
    does (so where the interpolant crosses more than once, the same crossing is taken), then Illinois
    false position finishes inside it to 1e-15 in a few evaluations. Returns the upper bracket end."""
    lo, hi = 0.0, 1.0
    for _ in range(20):
        mid = 0.5 * (lo + hi)
        f = sign * _want_contact(p0, p1, m0, m1, mid, h, law, k_s, c)
        if f >= 0.0:
            hi, f_hi = mid, f
        else:
            lo, f_lo = mid, f
    side = 0
    for _it in range(60):
        if hi - lo <= 1e-15 or f_hi == 0.0:
            break
        t = _secant_point(lo, hi, f_lo, f_hi) if _it % 4 != 3 else 0.5 * (lo + hi)
        f = sign * _want_contact(p0, p1, m0, m1, t, h, law, k_s, c)
        lo, hi, f_lo, f_hi, side = _illinois(lo, hi, f_lo, f_hi, side, t, f)
    return hi


@njit_step
def _first_event(Z, B, h, law, k_s, gap, phi, psi, N, N1, P):
    """kernel._first_event: fraction of the step at which the first pair leaves its contact state
    (2.0: none), from each pair's cubic Hermite interpolant between (Z_Q, Z_QD) and (Z_QE, Z_QDE);
    marks the pairs switching there in B_TRIAL."""
    first = 2.0
    for j in range(P):
        Z[Z_TH, j] = 2.0
        p0, v0 = _pair(Z, Z_Q, Z_QD, j, psi, gap, N)
        p1, v1 = _pair(Z, Z_QE, Z_QDE, j, psi, gap, N)
        m0 = v0 * h
        m1 = v1 * h
        c = Z[Z_C, j]
        sign = -1.0 if B[B_ACT, j] else 1.0
        tol = _switch_tolerance(_floor_u(Z, Z_QE, j, phi, N), _floor_u(Z, Z_QE, N1 + j, phi, N))
        f1 = sign * _want_contact(p0, p1, m0, m1, 1.0, h, law, k_s, c)
        if f1 <= tol:
            continue
        f0 = sign * _want_contact(p0, p1, m0, m1, 0.0, h, law, k_s, c)
        if not B[B_JUST, j] and f0 >= 0.0:
            Z[Z_TH, j] = 0.0
        else:
            Z[Z_TH, j] = _hermite_root(p0, p1, m0, m1, h, law, k_s, c, sign, min(f0, -1e-300), f1)
        if Z[Z_TH, j] < first:
            first = Z[Z_TH, j]
    for j in range(P):
        B[B_TRIAL, j] = Z[Z_TH, j] <= first + 1e-9
    return first


@njit_step
def _locate_event(Z, B, I, A, theta, h, hmin, ag_s, ag_e, harmonic, amp, om, t_s, law, k_s, gap, phi, psi, N, N1, P):
    """kernel._locate_event in modal form: length hs (0 <= hs <= h) of the sub-step that ends where the
    first pair switches (Illinois false position on real sub-steps, started at the interpolant's
    estimate); leaves that sub-step's end state in Z_QE, Z_QDE, Z_FE and the pairs to switch in B_TRIAL."""
    if theta * h < hmin:
        return 0.0
    target = 0
    for j in range(P):
        if Z[Z_TH, j] < Z[Z_TH, target]:
            target = j
    hi = h
    f_hi = _indicator(Z, B, Z_QE, Z_QDE, target, law, k_s, gap, psi, N)
    hs = h
    for _ in range(P + 1):
        lo = 0.0
        f_lo = min(_indicator(Z, B, Z_Q, Z_QD, target, law, k_s, gap, psi, N), -1e-300)
        if theta * hi < hmin:
            return 0.0
        hs = min(max(theta * hi, hmin), hi)
        side = 0
        scale = 0.0
        h_eval = hs
        p_start, _v = _pair(Z, Z_Q, Z_QD, target, psi, gap, N)
        for _it in range(100):
            _fixed_set_step(
                Z, B, I, A, hs, ag_s, _ag_inside(hs, h, ag_s, ag_e, harmonic, amp, om, t_s), k_s, gap, psi, N, P
            )
            h_eval = hs
            ph = _indicator(Z, B, Z_QE, Z_QDE, target, law, k_s, gap, psi, N)
            p_end, _v = _pair(Z, Z_QE, Z_QDE, target, psi, gap, N)
            scale = max(scale, abs(p_end) + abs(p_start))
            lo, hi, f_lo, f_hi, side = _illinois(lo, hi, f_lo, f_hi, side, hs, ph)
            if abs(ph) <= 1e-13 * scale or hi - lo <= 1e-13 * h or (hs <= hmin and ph >= 0.0):
                break
            hs = max(_secant_point(lo, hi, f_lo, f_hi), hmin)
        hs = h_eval
        _first_event(Z, B, hs, law, k_s, gap, phi, psi, N, N1, P)
        earlier = -1
        for j in range(P):
            if j != target and Z[Z_TH, j] < 1.0 - 1e-9 and (earlier < 0 or Z[Z_TH, j] < Z[Z_TH, earlier]):
                earlier = j
        if earlier < 0:
            break
        target = earlier
        theta = Z[Z_TH, earlier]
        f_hi = _indicator(Z, B, Z_QE, Z_QDE, target, law, k_s, gap, psi, N)
        hi = hs
    for j in range(P):
        B[B_TRIAL, j] = j == target or Z[Z_TH, j] <= 1.0
    return hs


@njit_step
def _switch(Z, B, orow, t, k_s, gap, psi, N, P, pbase):
    """kernel._switch: switch the pairs in B_TRIAL at an event (time t, state Z_Q, Z_QD); every force
    from the Kelvin-Voigt law at this instant (the acceleration follows from equilibrium)."""
    for j in range(P):
        B[B_JUST, j] = B[B_TRIAL, j]
        if not B[B_TRIAL, j]:
            continue
        pen, vr = _pair(Z, Z_Q, Z_QD, j, psi, gap, N)
        base = pbase + ML.PER_PAIR * j
        if B[B_ACT, j]:
            B[B_ACT, j] = False
            if pen > 0.0:
                Z[Z_EN, E_WREL] += 0.5 * k_s * pen * pen
            Z[Z_F, j] = 0.0
            Z[Z_SP, j] = 0.0
            Z[Z_DP, j] = 0.0
        else:
            B[B_ACT, j] = True
            if pen > 0.0:
                Z[Z_EN, E_WREL] -= 0.5 * k_s * pen * pen
            orow[base + ML.PAIR_IMPACTS] += 1.0
            f = k_s * pen + Z[Z_C, j] * vr
            Z[Z_F, j] = f
            Z[Z_SP, j] = k_s * pen
            Z[Z_DP, j] = f - k_s * pen
            _force_extremes(orow, base, f, t)
        B[B_WAS, j] = B[B_ACT, j]
    _law_forces(Z, B, Z_Q, Z_QD, Z_F, k_s, gap, psi, N, P)


@njit_step
def _end_phase(dur, nph, l, j, duration):
    """kernel._end_phase for lane l."""
    k = nph[l, j]
    if k < dur.shape[2]:
        dur[l, j, k] = duration
    nph[l, j] = k + 1


@njit_step
def _accept(Z, B, orow, dur, nph, l, hs, t_e, ag_s, ag_e, k_s, gap, psi, N, P, pbase, rf):
    """Accept the piece [t_e - hs, t_e] (kernel.integrate_batch's accepted piece), end state Z_QE, Z_QDE with forces in row
    rf: energy increments, exact for Newmark average acceleration (input -Gamma.dq ag, structural
    damping sum d_k dq_k^2 / hs, the contact spring and dashpot work on each pair's penetration),
    contact metrics; then the state and forces move to Z_Q, Z_QD, Z_F."""
    s_in = 0.0
    s_d = 0.0
    for k in range(N):
        dq = Z[Z_QE, k] - Z[Z_Q, k]
        s_in += Z[Z_GAM, k] * dq
        s_d += Z[Z_DMP, k] * dq * dq
    de = -0.5 * (ag_s + ag_e) * s_in
    Z[Z_EN, E_IN] += de
    Z[Z_EN, E_ABS] += abs(de)
    Z[Z_EN, E_DST] += s_d / hs
    for j in range(P):
        act = B[B_ACT, j]
        was = B[B_WAS, j]
        pen, _v = _pair(Z, Z_QE, Z_QDE, j, psi, gap, N)
        if -pen < orow[pbase + ML.PER_PAIR * j + ML.PAIR_CLOSEST]:  # closest approach, at every accepted piece's end
            orow[pbase + ML.PER_PAIR * j + ML.PAIR_CLOSEST] = -pen
            orow[pbase + ML.PER_PAIR * j + ML.PAIR_CLOSEST_TIME] = t_e
        f = Z[rf, j]
        sp = k_s * pen if act else 0.0
        dp = f - sp if act else 0.0
        Z[Z_EN, E_WSP] += 0.5 * (Z[Z_SP, j] + sp) * (pen - Z[Z_PP, j])
        Z[Z_EN, E_WDA] += 0.5 * (Z[Z_DP, j] + dp) * (pen - Z[Z_PP, j])
        if was and not act and pen > 0.0:
            Z[Z_EN, E_WREL] += 0.5 * k_s * pen * pen
        Z[Z_SP, j] = sp
        Z[Z_DP, j] = dp
        Z[Z_PP, j] = pen
        base = pbase + ML.PER_PAIR * j
        if act:
            if not was:
                orow[base + ML.PAIR_IMPACTS] += 1.0
            orow[base + ML.PAIR_CONTACT_TIME] += hs
            if pen > orow[base + ML.PAIR_MAX_PENETRATION]:
                orow[base + ML.PAIR_MAX_PENETRATION] = pen
            _force_extremes(orow, base, f, t_e)
        comp = act and f > 0.0
        if comp:
            orow[base + ML.PAIR_COMPRESSION_TIME] += hs
            Z[Z_CAC, j] = Z[Z_CAC, j] + hs if B[B_INC, j] else hs
        elif B[B_INC, j]:
            _end_phase(dur, nph, l, j, Z[Z_CAC, j])
        B[B_INC, j] = comp
        B[B_WAS, j] = act
    for k in range(N):
        Z[Z_Q, k] = Z[Z_QE, k]
        Z[Z_QD, k] = Z[Z_QDE, k]
    for j in range(P):
        Z[Z_F, j] = Z[rf, j]


@njit_step
def _event_step(
    Z, B, I, A, orow, dur, nph, l, step, dt, law, ag_prev, ag, harmonic, amp, om, k_s, gap, phi, psi, N, N1, P, pbase
):
    """Event scheme, one lane, one step (kernel.integrate_batch's trial with the start set, then
    its pieces between located events). Returns (finite, events located, 1 if the events chattered else 0)."""
    hmin = EVENT_MIN_FRACTION * dt
    _fixed_set_step(Z, B, I, A, dt, ag_prev, ag, k_s, gap, psi, N, P)
    h = dt
    t_s = (step - 1) * dt
    ag_s = ag_prev
    n_ev = 0
    uns = 0
    for j in range(P):
        B[B_JUST, j] = False
    finite = True
    while True:
        finite = _finite(Z, Z_QE, Z_QDE, Z_FE, phi, psi, N, P)
        if not finite:
            break
        hs = h
        ag_e = ag
        last = True
        contradicts = False
        for j in range(P):
            pe, vr = _pair(Z, Z_QE, Z_QDE, j, psi, gap, N)
            if law == LAW_NO_TENSION and pe > 0.0:
                pe = min(pe, pe + (Z[Z_C, j] / k_s) * vr)
            tol = _switch_tolerance(_floor_u(Z, Z_QE, j, phi, N), _floor_u(Z, Z_QE, N1 + j, phi, N))
            if (pe < -tol) if B[B_ACT, j] else (pe > tol):
                contradicts = True
        if contradicts:
            theta = _first_event(Z, B, h, law, k_s, gap, phi, psi, N, N1, P)
            if theta <= 1.0 and n_ev >= MAX_EVENTS:
                uns = 1
            elif theta <= 1.0:
                n_ev += 1
                last = False
                hs = _locate_event(
                    Z, B, I, A, theta, h, hmin, ag_s, ag, harmonic, amp, om, t_s, law, k_s, gap, phi, psi, N, N1, P
                )
                if hs <= hmin:
                    hs = 0.0
                elif h - hs <= hmin:
                    hs = h
                ag_e = _ag_inside(hs, h, ag_s, ag, harmonic, amp, om, t_s)
                finite = _finite(Z, Z_QE, Z_QDE, Z_FE, phi, psi, N, P)
                if not finite:
                    break
        if hs > 0.0:
            _accept(Z, B, orow, dur, nph, l, hs, t_s + hs, ag_s, ag_e, k_s, gap, psi, N, P, pbase, Z_FE)
        if last:
            break
        t_s += hs
        h -= hs
        ag_s = ag_e
        _switch(Z, B, orow, t_s, k_s, gap, psi, N, P, pbase)
        if h <= 0.0:
            break
        _fixed_set_step(Z, B, I, A, h, ag_s, ag, k_s, gap, psi, N, P)
    return finite, n_ev, uns


@njit_step
def _mask(B, row, P):
    mk = 0
    for j in range(min(P, 62)):
        if B[row, j]:
            mk |= 1 << j
    return mk


@njit_step
def _implicit_step(
    Z, B, I, A, orow, dur, nph, l, step, dt, law, max_iter, ag_prev, ag, k_s, gap, phi, psi, N, P, pbase
):
    """Implicit scheme, one lane, one step: kernel.integrate_batch's active-set iteration from the
    start set (cycle detection, the union fallback), then the accepted step. Returns (finite,
    iterations, 1 if the set cycled else 0)."""
    _keff_coefs(Z, dt, N)
    _free_step(Z, dt, ag_prev, ag, gap, psi, N, P)
    it = 0
    settled = False
    cycled = False
    while it < max_iter and not cycled:
        I[I_SEEN, it] = _mask(B, B_ACT, P)
        it += 1
        _set_forces(Z, B, I, A, dt, k_s, psi, N, P)
        changed = False
        for j in range(P):
            wf = 0.0
            for m in range(P):
                s = 0.0
                for k in range(N):
                    s += psi[k, j] * Z[Z_CF, k] * psi[k, m]
                wf += s * Z[Z_FS, m]
            pen = Z[Z_DF, j] - wf
            want = pen > 0.0
            if want and law == LAW_NO_TENSION:
                want = (k_s * pen + Z[Z_C, j] * (Z[Z_DDF, j] - (2.0 / dt) * wf)) > 0.0
            B[B_TRIAL, j] = want
            if want != B[B_ACT, j]:
                changed = True
        if not changed:
            settled = True
            break
        for j in range(P):
            B[B_PREV, j] = B[B_ACT, j]
            B[B_ACT, j] = B[B_TRIAL, j]
        mk = _mask(B, B_ACT, P)
        for z in range(it):
            if I[I_SEEN, z] == mk and P <= 62:
                cycled = True
    uns = 0
    if not settled:
        uns = 1
        for j in range(P):
            B[B_ACT, j] = B[B_PREV, j] or B[B_TRIAL, j]
        _set_forces(Z, B, I, A, dt, k_s, psi, N, P)
    _end_state(Z, dt, psi, N, P)
    if not _finite(Z, Z_QE, Z_QDE, Z_FS, phi, psi, N, P):
        return False, it, uns
    _accept(Z, B, orow, dur, nph, l, dt, (step - 1) * dt + dt, ag_prev, ag, k_s, gap, psi, N, P, pbase, Z_FS)
    return True, it, uns


@njit_step
def _lane_factors(W, l, P, k_s, cdash, run, dt, Wm, B, I, A, r_R):
    """Lane l's R = (I + diag(kappa) W)_SS^-1 for its set S (B_ACT), in full P x P (zeros outside S)."""
    for z in range(P * P):
        W[(r_R + z) * LANES + l] = 0.0
    na = _active_pairs(B, I, P)
    if na == 0:
        return
    # Gauss-Jordan on [I + diag(kappa) W_SS | I] (no pivoting: similar to I + SPD, positive pivots)
    for p in range(na):
        kap = k_s + 2.0 * cdash[run, I[I_IDX, p]] / dt
        for p2 in range(na):
            A[p, p2] = kap * Wm[I[I_IDX, p], I[I_IDX, p2]] + (1.0 if p == p2 else 0.0)
            A[p, na + p2] = 1.0 if p == p2 else 0.0
    for k in range(na):
        piv = A[k, k]
        for z in range(2 * na):
            A[k, z] /= piv
        for i in range(na):
            if i != k:
                f = A[i, k]
                for z in range(2 * na):
                    A[i, z] -= f * A[k, z]
    for p in range(na):
        for p2 in range(na):
            W[(r_R + I[I_IDX, p] * P + I[I_IDX, p2]) * LANES + l] = A[p, na + p2]


@njit_step
def _lane_step(W, l, src, dst, step, run, const, phi, psi, Wm, cdash, work):
    """One lane's whole step in scalar code, from its start state (buffer src) to buffer dst, with
    its metric and energy rows updated. run: the lane's run; const: the step's constants (dt, scheme,
    law, max_iter, harmonic, amp, omega, N, N1, P: the run's excitation and the model's sizes); phi, psi,
    Wm: the modal data (LaneModel); cdash: the runs' dashpots; work: LaneWork. Returns False when the
    state is no longer finite."""
    dt, scheme, law, max_iter, harmonic, amp, om, N, N1, P = const
    Z, B, I, A, orow, dur, nph = work
    r_q0, r_q1, r_g, r_f, r_pen, r_act, r_inc, r_cac, r_end, r_cd, r_R, r_s, r_met = _layout(N, P)
    k_s = W[(r_s + S_KS) * LANES + l]
    gap = W[(r_s + S_GAP) * LANES + l]
    ag_s = W[(r_s + S_AGS) * LANES + l]
    ag = W[(r_s + S_AGE) * LANES + l]
    for k in range(N):
        Z[Z_Q, k] = W[(src + k) * LANES + l]
        Z[Z_QD, k] = (2.0 / dt) * W[(src + N + k) * LANES + l]
    for j in range(P):
        Z[Z_C, j] = cdash[run, j]
        Z[Z_F, j] = W[(r_f + j) * LANES + l]
        act = W[(r_act + j) * LANES + l] > 0.5
        B[B_ACT, j] = act
        B[B_WAS, j] = act
        B[B_INC, j] = W[(r_inc + j) * LANES + l] > 0.5
        Z[Z_CAC, j] = W[(r_cac + j) * LANES + l]
        pen, vr = _pair(Z, Z_Q, Z_QD, j, psi, gap, N)
        Z[Z_PP, j] = pen
        Z[Z_SP, j] = k_s * pen if act else 0.0
        Z[Z_DP, j] = Z[Z_F, j] - Z[Z_SP, j] if act else 0.0
    start = _mask(B, B_ACT, P)
    Z[Z_EN, E_IN] = W[(r_s + S_EIN) * LANES + l]
    Z[Z_EN, E_ABS] = W[(r_s + S_EABS) * LANES + l]
    Z[Z_EN, E_DST] = W[(r_s + S_DST) * LANES + l]
    Z[Z_EN, E_WSP] = W[(r_s + S_WSP) * LANES + l]
    Z[Z_EN, E_WDA] = W[(r_s + S_WDA) * LANES + l]
    Z[Z_EN, E_WREL] = W[(r_s + S_WREL) * LANES + l]
    nmet = ML.PER_DOF * N + ML.PER_PAIR * P
    for z in range(nmet):
        orow[z] = W[(r_met + z) * LANES + l]
    pbase = ML.PER_DOF * N
    if scheme == SCHEME_EVENT:
        finite, count, uns = _event_step(
            Z,
            B,
            I,
            A,
            orow,
            dur,
            nph,
            l,
            step,
            dt,
            law,
            ag_s,
            ag,
            harmonic,
            amp,
            om,
            k_s,
            gap,
            phi,
            psi,
            N,
            N1,
            P,
            pbase,
        )
    else:
        finite, count, uns = _implicit_step(
            Z, B, I, A, orow, dur, nph, l, step, dt, law, max_iter, ag_s, ag, k_s, gap, phi, psi, N, P, pbase
        )
    if count > W[(r_s + S_MIT) * LANES + l]:
        W[(r_s + S_MIT) * LANES + l] = count
    W[(r_s + S_UNS) * LANES + l] += uns
    if not finite:
        W[(r_s + S_BAD) * LANES + l] = 1.0
        return False
    t = step * dt
    _modal_acc(Z, Z_Q, Z_QD, Z_F, psi, N, P)
    below = 0.0  # the floor below's displacement (0: the table, under a building's first floor)
    for i in range(N):  # per-floor peaks at the step end
        u = 0.0
        a = 0.0
        for k in range(N):
            u += phi[i, k] * Z[Z_Q, k]
            a += phi[i, k] * Z[Z_B, k]
        base = ML.PER_DOF * i
        if abs(u) > orow[base + ML.DOF_PEAK_DISP]:
            orow[base + ML.DOF_PEAK_DISP] = abs(u)
            orow[base + ML.DOF_PEAK_DISP_TIME] = t
        if abs(a) > orow[base + ML.DOF_PEAK_ABS_ACC]:
            orow[base + ML.DOF_PEAK_ABS_ACC] = abs(a)
        if i == 0 or i == N1:
            below = 0.0
        dr = abs(u - below)
        if dr > orow[base + ML.DOF_PEAK_DRIFT]:
            orow[base + ML.DOF_PEAK_DRIFT] = dr
        below = u
    for k in range(N):
        W[(dst + k) * LANES + l] = Z[Z_Q, k]
        W[(dst + N + k) * LANES + l] = (0.5 * dt) * Z[Z_QD, k]
        g = 0.0
        for j in range(P):
            g += psi[k, j] * Z[Z_F, j]
        W[(r_g + k) * LANES + l] = g
    for j in range(P):
        W[(r_f + j) * LANES + l] = Z[Z_F, j]
        W[(r_act + j) * LANES + l] = 1.0 if B[B_ACT, j] else 0.0
        W[(r_inc + j) * LANES + l] = 1.0 if B[B_INC, j] else 0.0
        W[(r_cac + j) * LANES + l] = Z[Z_CAC, j]
        W[(r_pen + j) * LANES + l] = Z[Z_PP, j]
    W[(r_s + S_EIN) * LANES + l] = Z[Z_EN, E_IN]
    W[(r_s + S_EABS) * LANES + l] = Z[Z_EN, E_ABS]
    W[(r_s + S_DST) * LANES + l] = Z[Z_EN, E_DST]
    W[(r_s + S_WSP) * LANES + l] = Z[Z_EN, E_WSP]
    W[(r_s + S_WDA) * LANES + l] = Z[Z_EN, E_WDA]
    W[(r_s + S_WREL) * LANES + l] = Z[Z_EN, E_WREL]
    for z in range(nmet):
        W[(r_met + z) * LANES + l] = orow[z]
    if _mask(B, B_ACT, P) != start:
        _lane_factors(W, l, P, k_s, cdash, run, dt, Wm, B, I, A, r_R)
    return True


# ------------------------------------------------------------------------------------------ vector parts


def _vec_ptr(context, builder, sig, args):
    """Pointer to W[r * LANES + c] (args W, r, c) as a vector pointer."""
    idx = builder.mul(context.cast(builder, args[1], sig.args[1], types.int64), ir.Constant(ir.IntType(64), LANES))
    idx = builder.add(idx, context.cast(builder, args[2], sig.args[2], types.int64))
    return elem_ptr(context, builder, sig.args[0], args[0], idx)


@intrinsic
def _row(typingctx, W, r, c):
    """W[r * LANES + c : ... + VW] as a vector (row r, lanes c..c+VW-1)."""

    def codegen(context, builder, sig, args):
        return builder.load(_vec_ptr(context, builder, sig, args), align=8)

    return f64v(W, r, c), codegen


@intrinsic
def _put(typingctx, W, r, c, v):
    """Row r, lanes c..c+VW-1 := v."""

    def codegen(context, builder, sig, args):
        builder.store(args[3], _vec_ptr(context, builder, sig, args), align=8)
        return context.get_dummy_value()

    return types.none(W, r, c, v), codegen


@intrinsic
def _cv(typingctx, Cv, r):
    """Coefficient r of the table in every lane (one broadcast load: on AMD Zen 1 a full-width
    coefficient row would cost as many load slots as the data it multiplies)."""

    def codegen(context, builder, sig, args):
        a = context.make_array(sig.args[0])(context, builder, args[0])
        idx = context.cast(builder, args[1], sig.args[1], types.intp)
        return splat(builder, builder.load(builder.gep(a.data, [idx], inbounds=True)))

    return f64v(Cv, r), codegen


@intrinsic
def _keep(typingctx, W, r, c, cond, new):
    """Row r := new where cond, else unchanged (the old value through an arithmetic fence, so that
    LLVM does not turn the select and store into a masked store: microcoded and slow on AMD Zen)."""

    def codegen(context, builder, sig, args):
        ptr = _vec_ptr(context, builder, sig, args)
        old = fence(builder, builder.load(ptr, align=8))
        builder.store(select_bits(builder, args[3], args[4], old), ptr, align=8)
        return context.get_dummy_value()

    return types.none(W, r, c, cond, new), codegen


# coefficient table Cv (coefficient_table): per mode k / floor i / pair j
C_CQ, C_CR, C_EK, C_NCF, C_NDA, C_NW2, C_DH, C_GAM = range(8)  # row C_X * N + k


@_inline
def _tab(N, P):
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


@_inline
def _ctab(N, P):
    """Row offsets of Phi (i * N + k) and Psi, (2/dt) Psi (k * P + j) in the coefficient table."""
    c_phi = 8 * N
    c_psi = c_phi + N * N
    c_psv = c_psi + N * P
    return c_phi, c_psi, c_psv


def coefficient_table(ma: ModalArrays) -> np.ndarray:
    """The vector code's coefficients (modal.ModalArrays at its dt), in _ctab's order."""
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


@_inline
def _floors(T, N, N1, t_u, t_q, Cv, c_phi):
    """Floor values Phi x of the modal values x = T[t_q:t_q + N] into T[t_u:t_u + N]."""
    for i in range(N):
        lo = 0 if i < N1 else N1
        hi = N1 if i < N1 else N
        u = _cv(Cv, c_phi + i * N + lo) * sget(T, t_q + lo)
        for k in range(lo + 1, hi):
            u = vfma(_cv(Cv, c_phi + i * N + k), sget(T, t_q + k), u)
        sset(T, t_u + i, u)


@_inline
def _floor_acc(T, i, N, N1, t_qa, Cv, c_phi):
    """Absolute acceleration of floor i: Phi applied to the modal accelerations T[t_qa:]."""
    lo = 0 if i < N1 else N1
    hi = N1 if i < N1 else N
    a = _cv(Cv, c_phi + i * N + lo) * sget(T, t_qa + lo)
    for k in range(lo + 1, hi):
        a = vfma(_cv(Cv, c_phi + i * N + k), sget(T, t_qa + k), a)
    return a


@_inline
def _floor_peaks(W, c, T, N, N1, P, t_u, t_qa, r_met, Cv, c_phi, vt, gap, ok_mask):
    """Per-floor peaks of |u| (and its time), of |absolute acceleration| and of |interstory drift| (the story
    below the floor), and each pair's closest approach gap - (u1 - u2) (and its time). One test for all
    floors and pairs; rows are written only in the rare steps where some extreme grows in some lane of
    `ok_mask`. Returns the lanes that diverged (|u| >= DIVERGED_M or |a| >= 1e300; a NaN never grows a
    peak and is caught by the energy rows instead)."""
    pbase = r_met + ML.PER_DOF * N
    grow = mconst(False)
    for i in range(N):
        base = r_met + ML.PER_DOF * i
        u = sget(T, t_u + i)
        drift = u if i == 0 or i == N1 else u - sget(T, t_u + i - 1)
        grow = grow | (abs(u) > _row(W, base + ML.DOF_PEAK_DISP, c))
        grow = grow | (abs(drift) > _row(W, base + ML.DOF_PEAK_DRIFT, c))
        grow = grow | (abs(_floor_acc(T, i, N, N1, t_qa, Cv, c_phi)) > _row(W, base + ML.DOF_PEAK_ABS_ACC, c))
    for j in range(P):
        near = gap - (sget(T, t_u + j) - sget(T, t_u + N1 + j))
        grow = grow | (near < _row(W, pbase + ML.PER_PAIR * j + ML.PAIR_CLOSEST, c))
    bad = mconst(False)
    if many(grow & ok_mask):
        for i in range(N):
            base = r_met + ML.PER_DOF * i
            u = sget(T, t_u + i)
            ad = abs(u)
            up = (ad > _row(W, base + ML.DOF_PEAK_DISP, c)) & ok_mask
            _keep(W, base + ML.DOF_PEAK_DISP, c, up, ad)
            _keep(W, base + ML.DOF_PEAK_DISP_TIME, c, up, vt)
            bad = bad | (up & (ad >= ML.DIVERGED_M))
            dr = abs(u if i == 0 or i == N1 else u - sget(T, t_u + i - 1))
            up = (dr > _row(W, base + ML.DOF_PEAK_DRIFT, c)) & ok_mask
            _keep(W, base + ML.DOF_PEAK_DRIFT, c, up, dr)
            aa = abs(_floor_acc(T, i, N, N1, t_qa, Cv, c_phi))
            up = (aa > _row(W, base + ML.DOF_PEAK_ABS_ACC, c)) & ok_mask
            _keep(W, base + ML.DOF_PEAK_ABS_ACC, c, up, aa)
            bad = bad | (up & (aa >= 1e300))
        for j in range(P):
            base = pbase + ML.PER_PAIR * j
            near = gap - (sget(T, t_u + j) - sget(T, t_u + N1 + j))
            up = (near < _row(W, base + ML.PAIR_CLOSEST, c)) & ok_mask
            _keep(W, base + ML.PAIR_CLOSEST, c, up, near)
            _keep(W, base + ML.PAIR_CLOSEST_TIME, c, up, vt)
    return bad


@_inline
def _exact_events(W, c, T, N, N1, P, t_u, r_act, r_cd, dst, Cv, c_psv, law, scheme, ks, gap):
    """The lanes whose end state contradicts their contact set, by the scheme's own test (event:
    kernel._switch_tolerance, the no-tension indicator min(pen, pen + c/k_s v_rel); implicit: the set
    the end state asks for)."""
    evt = mconst(False)
    zero = vsplat(0.0)
    for j in range(P):
        up = sget(T, t_u + j)
        uq = sget(T, t_u + N1 + j)
        pe = (up - uq) - gap
        act = _row(W, r_act + j, c) > 0.5
        alt = pe
        if law == LAW_NO_TENSION:
            vr = zero
            for k in range(N):
                vr = vfma(_cv(Cv, c_psv + k * P + j), _row(W, dst + N + k, c), vr)
            alt = pe + (_row(W, r_cd + j, c) / ks) * vr
        if scheme == SCHEME_EVENT:
            if law == LAW_NO_TENSION:
                pe = vsel(pe > 0.0, vsel(alt < pe, alt, pe), pe)
            tol = 1e-15 + 1e-12 * (abs(up) + abs(uq))
            evt = evt | (act & (zero - tol > pe)) | (~act & (pe > tol))
        else:
            want = pe > 0.0
            if law == LAW_NO_TENSION:
                want = want & (alt > 0.0)  # k_s pen + c v_rel > 0, divided by k_s > 0
            evt = evt | (want != act)
    return evt


@_inline
def _energy(W, c, r_s, s, pin, dsum, keep):
    """Input work (trapezoid), its absolute sum and structural damping; returns the lanes whose
    accumulators are no longer finite (a NaN or inf anywhere in the state reaches dsum)."""
    de = -0.5 * s * pin
    ein = _row(W, r_s + S_EIN, c) + de
    eab = _row(W, r_s + S_EABS, c) + abs(de)
    dst_ = _row(W, r_s + S_DST, c) + dsum
    _keep(W, r_s + S_EIN, c, keep, ein)
    _keep(W, r_s + S_EABS, c, keep, eab)
    _keep(W, r_s + S_DST, c, keep, dst_)
    return keep & (~(abs(dst_) < 1e300) | ~(abs(eab) < 1e300))


@_inline
def _events_energy_peaks(W, c, T, dst, quiet, s, pin, dsum, vt, law, scheme, N, N1, P, Cv, lay):
    """The end of a vector step, the floors of the new state in T: the lanes with an event (EVT row),
    then energy increments and per-floor peaks of the others. The exact event test runs only where a
    pair out of contact penetrates or one in contact does not: every event of either scheme under the
    classic law is one of these (under the no-tension law a pair in contact can also switch off while
    penetrating: with contact the exact test always runs). Returns (lanes without an event, events,
    divergences)."""
    r_q0, r_q1, r_g, r_f, r_pen, r_act, r_inc, r_cac, r_end, r_cd, r_R, r_s, r_met = lay
    c_phi, c_psi, c_psv = _ctab(N, P)
    t_qa, t_u, t_dq, t_f, t_g, t_qf, t_rf = _tab(N, P)
    gap = _row(W, r_s + S_GAP, c)
    maybe = mconst(law == LAW_NO_TENSION and not quiet)
    for j in range(P):
        pe = (sget(T, t_u + j) - sget(T, t_u + N1 + j)) - gap
        if quiet:
            maybe = maybe | (pe > 0.0)
        else:
            act = _row(W, r_act + j, c) > 0.5
            maybe = maybe | (act != (pe > 0.0))
    evt = mconst(False)
    nevt = 0
    if many(maybe):
        evt = _exact_events(
            W, c, T, N, N1, P, t_u, r_act, r_cd, dst, Cv, c_psv, law, scheme, _row(W, r_s + S_KS, c), gap
        )
        if many(evt):
            _put(W, r_s + S_EVT, c, mfloat(evt))
            nevt = mcount(evt)
    ok = ~evt
    bad = _energy(W, c, r_s, s, pin, dsum, ok)
    bad = bad | _floor_peaks(W, c, T, N, N1, P, t_u, t_qa, r_met, Cv, c_phi, vt, gap, ok)
    nbad = 0
    if many(bad):
        _keep(W, r_s + S_BAD, c, bad, vsplat(1.0))
        nbad = mcount(bad)
    return ok, nevt, nbad


@_inline
def _fill_ag(W, r_s, prof, pid_lane, step, uniform, pid0):
    """Ground acceleration rows: AGS at the step start, AGE at its end (coef * prof[pid, step])."""
    if uniform:
        p0 = prof[pid0, step - 1]
        p1 = prof[pid0, step]
        for c in range(0, LANES, VW):
            cf = _row(W, r_s + S_COEF, c)
            _put(W, r_s + S_AGS, c, cf * p0)
            _put(W, r_s + S_AGE, c, cf * p1)
    else:
        for l in range(LANES):
            cf = W[(r_s + S_COEF) * LANES + l]
            W[(r_s + S_AGS) * LANES + l] = cf * prof[pid_lane[l], step - 1]
            W[(r_s + S_AGE) * LANES + l] = cf * prof[pid_lane[l], step]


@njit_step
def _quiet(W, step0, step1, dt, scheme, law, nt, n1t, Cv, prof, pid_lane, uniform, pid0):
    """Steps step0..step1 with no lane in contact at their start: the free step of every lane. Returns
    at the first step with an event or a divergence: (that step, lanes with an event, lanes diverged);
    event lanes are left for _lane_step (only their dst rows were written)."""
    N = len(nt)
    N1 = len(n1t)
    P = min(N1, N - N1)
    lay = _layout(N, P)
    T = scratch()
    for step in range(step0, step1 + 1):
        src = lay[0] if (step - 1) % 2 == 0 else lay[1]
        dst = lay[1] if (step - 1) % 2 == 0 else lay[0]
        _fill_ag(W, lay[11], prof, pid_lane, step, uniform, pid0)
        nevt, nbad = _quiet_step(W, T, src, dst, step, dt, scheme, law, N, N1, P, Cv, lay)
        if nevt > 0 or nbad > 0:
            return step, nevt, nbad
    return step1, 0, 0


@_inline
def _quiet_step(W, T, src, dst, step, dt, scheme, law, N, N1, P, Cv, lay):
    """One quiet step of every chunk of lanes: modes (Newmark, modal.py), floors, the cheap test
    "some pair penetrates" (then the exact event test), energy increments, peaks."""
    r_q0, r_q1, r_g, r_f, r_pen, r_act, r_inc, r_cac, r_end, r_cd, r_R, r_s, r_met = lay
    c_phi, c_psi, c_psv = _ctab(N, P)
    t_qa, t_u, t_dq, t_f, t_g, t_qf, t_rf = _tab(N, P)
    vt = vsplat(step * dt)
    nevt = 0
    nbad = 0
    for c in range(0, LANES, VW):
        s = _row(W, r_s + S_AGS, c) + _row(W, r_s + S_AGE, c)
        pin = vsplat(0.0)
        dsum = vsplat(0.0)
        for k in range(N):
            q = _row(W, src + k, c)
            r = _row(W, src + N + k, c)
            dq = vfma(_cv(Cv, C_CQ * N + k), q, vfma(_cv(Cv, C_CR * N + k), r, _cv(Cv, C_EK * N + k) * s))
            qn = q + dq
            rn = dq - r
            _put(W, dst + k, c, qn)
            _put(W, dst + N + k, c, rn)
            sset(T, t_dq + k, qn)
            pin = vfma(_cv(Cv, C_GAM * N + k), dq, pin)
            dsum = vfma(_cv(Cv, C_DH * N + k) * dq, dq, dsum)
            sset(T, t_qa + k, vfma(_cv(Cv, C_NDA * N + k), rn, _cv(Cv, C_NW2 * N + k) * qn))
        _floors(T, N, N1, t_u, t_dq, Cv, c_phi)
        ok, ne, nb = _events_energy_peaks(W, c, T, dst, True, s, pin, dsum, vt, law, scheme, N, N1, P, Cv, lay)
        nevt += ne
        nbad += nb
    return nevt, nbad


@njit_step
def _contact(W, step0, step1, dt, scheme, law, nt, n1t, Cv, pon, prof, pid_lane, uniform, pid0):
    """Steps step0..step1 with some lane in contact: the step with each lane's contact set (forces from
    its R), contact metrics and energies. Pairs in contact in no lane (bit j of pon clear) have zero
    force in every lane. Returns at the first step with an event, a divergence or the end of a
    compressive phase: (that step, lanes with an event, lanes diverged, lanes whose phase ended).
    Its loop is _quiet's: one function for both cost the quiet step 6-14 %."""
    N = len(nt)
    N1 = len(n1t)
    P = min(N1, N - N1)
    lay = _layout(N, P)
    T = scratch()
    for step in range(step0, step1 + 1):
        src = lay[0] if (step - 1) % 2 == 0 else lay[1]
        dst = lay[1] if (step - 1) % 2 == 0 else lay[0]
        _fill_ag(W, lay[11], prof, pid_lane, step, uniform, pid0)
        nevt, nbad, nend = _contact_step(W, T, src, dst, step, dt, scheme, law, N, N1, P, Cv, pon, lay)
        if nevt > 0 or nbad > 0 or nend > 0:
            return step, nevt, nbad, nend
    return step1, 0, 0, 0


@_inline
def _contact_step(W, T, src, dst, step, dt, scheme, law, N, N1, P, Cv, pon, lay):
    """One step of every chunk of lanes, some lane in contact."""
    r_q0, r_q1, r_g, r_f, r_pen, r_act, r_inc, r_cac, r_end, r_cd, r_R, r_s, r_met = lay
    c_phi, c_psi, c_psv = _ctab(N, P)
    t_qa, t_u, t_dq, t_f, t_g, t_qf, t_rf = _tab(N, P)
    vt = vsplat(step * dt)
    te = vsplat((step - 1) * dt + dt)
    vdt = vsplat(dt)
    zero = vsplat(0.0)
    half = vsplat(0.5)
    pbase = r_met + ML.PER_DOF * N
    nevt = 0
    nbad = 0
    nend = 0
    for c in range(0, LANES, VW):
        s = _row(W, r_s + S_AGS, c) + _row(W, r_s + S_AGE, c)
        ks = _row(W, r_s + S_KS, c)
        gap = _row(W, r_s + S_GAP, c)
        # the free step (start forces in the load): its end q, r and its increment, in the scratch
        for k in range(N):
            q = _row(W, src + k, c)
            r = _row(W, src + N + k, c)
            dq = vfma(
                _cv(Cv, C_CQ * N + k),
                q,
                vfma(
                    _cv(Cv, C_CR * N + k),
                    r,
                    vfma(_cv(Cv, C_EK * N + k), s, _cv(Cv, C_NCF * N + k) * _row(W, r_g + k, c)),
                ),
            )
            sset(T, t_qf + k, q + dq)
            sset(T, t_rf + k, dq - r)
            sset(T, t_dq + k, dq)
        # each lane's forces: F = R (k_s delta_free + c delta'_free), R zero outside its contact set
        for i in range(P):
            sset(T, t_f + i, zero)
        for j in range(P):
            if (pon >> j) & 1 == 0:
                continue
            d = zero
            v = zero
            for k in range(N):
                d = vfma(_cv(Cv, c_psi + k * P + j), sget(T, t_qf + k), d)
                v = vfma(_cv(Cv, c_psv + k * P + j), sget(T, t_rf + k), v)
            y = vfma(ks, d - gap, _row(W, r_cd + j, c) * v)
            for i in range(P):
                if (pon >> i) & 1:
                    sset(T, t_f + i, vfma(_row(W, r_R + i * P + j, c), y, sget(T, t_f + i)))
        # the end state: dq = dq_free - cf Psi F
        pin = zero
        dsum = zero
        for k in range(N):
            g = zero
            for j in range(P):
                if (pon >> j) & 1:
                    g = vfma(_cv(Cv, c_psi + k * P + j), sget(T, t_f + j), g)
            sset(T, t_g + k, g)
            corr = _cv(Cv, C_NCF * N + k) * g
            dq = sget(T, t_dq + k) + corr
            qn = sget(T, t_qf + k) + corr
            rn = sget(T, t_rf + k) + corr
            _put(W, dst + k, c, qn)
            _put(W, dst + N + k, c, rn)
            sset(T, t_dq + k, qn)
            pin = vfma(_cv(Cv, C_GAM * N + k), dq, pin)
            dsum = vfma(_cv(Cv, C_DH * N + k) * dq, dq, dsum)
            sset(T, t_qa + k, vfma(_cv(Cv, C_NDA * N + k), rn, _cv(Cv, C_NW2 * N + k) * qn) - g)
        _floors(T, N, N1, t_u, t_dq, Cv, c_phi)
        ok, ne, nb = _events_energy_peaks(W, c, T, dst, False, s, pin, dsum, vt, law, scheme, N, N1, P, Cv, lay)
        nevt += ne
        nbad += nb
        # contact spring and dashpot work on each pair's penetration, contact metrics (kernel.py's order)
        wsp = _row(W, r_s + S_WSP, c)
        wda = _row(W, r_s + S_WDA, c)
        ended = mconst(False)
        for j in range(P):
            if (pon >> j) & 1 == 0:
                continue
            f = sget(T, t_f + j)
            pen = (sget(T, t_u + j) - sget(T, t_u + N1 + j)) - gap
            act = _row(W, r_act + j, c) > 0.5
            pen0 = _row(W, r_pen + j, c)
            sp0 = vsel(act, ks * pen0, zero)
            dp0 = vsel(act, _row(W, r_f + j, c) - sp0, zero)
            sp = vsel(act, ks * pen, zero)
            dp = vsel(act, f - sp, zero)
            dpen = pen - pen0
            wsp = vsel(ok, wsp + half * (sp0 + sp) * dpen, wsp)
            wda = vsel(ok, wda + half * (dp0 + dp) * dpen, wda)
            _keep(W, r_pen + j, c, ok, pen)
            _keep(W, r_f + j, c, ok, f)
            base = pbase + ML.PER_PAIR * j
            ak = act & ok
            x = _row(W, base + ML.PAIR_CONTACT_TIME, c)
            _keep(W, base + ML.PAIR_CONTACT_TIME, c, ak, x + vdt)
            # extremes: written only in the steps where some lane improves them
            up = ak & (pen > _row(W, base + ML.PAIR_MAX_PENETRATION, c))
            if many(up):
                _keep(W, base + ML.PAIR_MAX_PENETRATION, c, up, pen)
            up = ak & (f > _row(W, base + ML.PAIR_PEAK_FORCE, c))
            if many(up):
                _keep(W, base + ML.PAIR_PEAK_FORCE, c, up, f)
                _keep(W, base + ML.PAIR_PEAK_FORCE_TIME, c, up, te)
            up = ak & (f < _row(W, base + ML.PAIR_MIN_FORCE, c))
            if many(up):
                _keep(W, base + ML.PAIR_MIN_FORCE, c, up, f)
            comp = ak & (f > 0.0)
            x = _row(W, base + ML.PAIR_COMPRESSION_TIME, c)
            _keep(W, base + ML.PAIR_COMPRESSION_TIME, c, comp, x + vdt)
            inc = _row(W, r_inc + j, c) > 0.5
            x = _row(W, r_cac + j, c)
            _keep(W, r_cac + j, c, comp, vsel(inc, x + vdt, vdt))
            end = inc & ~comp & ok
            if many(end):
                _put(W, r_end + j, c, mfloat(end))
                ended = ended | end
            _keep(W, r_inc + j, c, ok, mfloat(comp))
        _put(W, r_s + S_WSP, c, wsp)
        _put(W, r_s + S_WDA, c, wda)
        nend += mcount(ended)
        for k in range(N):
            _keep(W, r_g + k, c, ok, sget(T, t_g + k))
    return nevt, nbad, nend


# ------------------------------------------------------------------------------------------ group driver


@njit_step
def _park(W, l, nrows, r_s):
    """Lane l at rest, out of contact, with no excitation, far from its neighbour: it computes zeros
    until the group ends and never has an event."""
    for z in range(nrows):
        W[z * LANES + l] = 0.0
    W[(r_s + S_GAP) * LANES + l] = 1.0
    W[(r_s + S_KS) * LANES + l] = 1.0


@njit_step
def _median_inplace(dur, l, j, k):
    """Median of dur[l, j, :k] (the mean of the two middle values for even k, as np.median), sorting
    the buffer in place (heapsort: no allocation, no compiled np.median); 0.0 when k = 0."""
    if k == 0:
        return 0.0
    for start in range(k // 2 - 1, -1, -1):  # heapify, then pop the largest to the end
        _sift_down(dur, l, j, start, k)
    for end in range(k - 1, 0, -1):
        x = dur[l, j, 0]
        dur[l, j, 0] = dur[l, j, end]
        dur[l, j, end] = x
        _sift_down(dur, l, j, 0, end)
    if k % 2 == 1:
        return dur[l, j, k // 2]
    return (dur[l, j, k // 2 - 1] + dur[l, j, k // 2]) / 2.0


@njit_step
def _sift_down(dur, l, j, i, n):
    while True:
        c = 2 * i + 1
        if c >= n:
            return
        if c + 1 < n and dur[l, j, c + 1] > dur[l, j, c]:
            c += 1
        if dur[l, j, c] <= dur[l, j, i]:
            return
        x = dur[l, j, c]
        dur[l, j, c] = dur[l, j, i]
        dur[l, j, i] = x
        i = c


@njit_step
def _finalize_lane(W, l, metrics, run, status, steps_done, dt, om2, psi, N, P, dur, nph):
    """Write lane l's metric row (kernel.integrate_batch's end-of-run code) after its last step."""
    r_q0, r_q1, r_g, r_f, r_pen, r_act, r_inc, r_cac, r_end, r_cd, r_R, r_s, r_met = _layout(N, P)
    buf = r_q1 if steps_done % 2 == 1 else r_q0  # step s writes buffer q1 when s is odd
    nm = metrics.shape[1]
    pbase = ML.PER_DOF * N
    rbase = pbase + ML.PER_PAIR * P
    for z in range(rbase):
        metrics[run, z] = W[(r_met + z) * LANES + l]
    for z in range(rbase, nm):
        metrics[run, z] = 0.0
    for j in range(P):
        if W[(r_inc + j) * LANES + l] > 0.5:
            _end_phase(dur, nph, l, j, W[(r_cac + j) * LANES + l])
        base = pbase + ML.PER_PAIR * j
        k = nph[l, j]
        metrics[run, base + ML.PAIR_COMPRESSION_PHASES] = k
        if k > ML.MEDIAN_BUFFER:
            status |= ML.STATUS_MEDIAN_TRUNCATED
            k = ML.MEDIAN_BUFFER
        metrics[run, base + ML.PAIR_MEDIAN_COMPRESSION] = _median_inplace(dur, l, j, k)
    unsettled = W[(r_s + S_UNS) * LANES + l]
    if unsettled > 0:
        status |= ML.STATUS_UNSETTLED
    # kinetic and strain energy at the end: modes are mass-normalised (1/2 q'^2, 1/2 w^2 q^2)
    ke_end = 0.0
    se_end = 0.0
    for k in range(N):
        qk = W[(buf + k) * LANES + l]
        vk = (2.0 / dt) * W[(buf + N + k) * LANES + l]
        ke_end += 0.5 * vk * vk
        se_end += 0.5 * om2[k] * qk * qk
    ks = W[(r_s + S_KS) * LANES + l]
    gap = W[(r_s + S_GAP) * LANES + l]
    e_spring = 0.0
    for j in range(P):
        if W[(r_act + j) * LANES + l] > 0.5:
            pp = -gap
            for k in range(N):
                pp += psi[k, j] * W[(buf + k) * LANES + l]
            e_spring += 0.5 * ks * pp * pp
    w_release = W[(r_s + S_WREL) * LANES + l]
    residual = W[(r_s + S_WSP) * LANES + l] - e_spring - w_release
    e_in_abs = W[(r_s + S_EABS) * LANES + l]
    metrics[run, rbase + ML.RUN_E_IN] = W[(r_s + S_EIN) * LANES + l]
    metrics[run, rbase + ML.RUN_E_IN_ABS] = e_in_abs
    metrics[run, rbase + ML.RUN_KE] = ke_end
    metrics[run, rbase + ML.RUN_SE] = se_end
    metrics[run, rbase + ML.RUN_D_STRUCT] = W[(r_s + S_DST) * LANES + l]
    metrics[run, rbase + ML.RUN_D_CONTACT] = W[(r_s + S_WDA) * LANES + l] + w_release
    metrics[run, rbase + ML.RUN_E_SPRING] = e_spring
    metrics[run, rbase + ML.RUN_E_RESIDUAL] = residual
    if not (abs(residual) <= ML.ENERGY_TOL * e_in_abs):
        status |= ML.STATUS_ENERGY
    metrics[run, rbase + ML.RUN_UNSETTLED] = unsettled
    metrics[run, rbase + ML.RUN_MAX_ITER] = W[(r_s + S_MIT) * LANES + l]
    metrics[run, rbase + ML.RUN_STEPS] = steps_done
    metrics[run, rbase + ML.RUN_STATUS] = status


@njit_step
def _count_act(W, l, P, r_act, act_pair, sign):
    """Add (sign 1) or remove (-1) lane l's contact set from the per-pair counts; returns the change
    of the total."""
    n = 0
    for j in range(P):
        if W[(r_act + j) * LANES + l] > 0.5:
            act_pair[j] += sign
            n += sign
    return n


def integrate_lanes(order, g_start, g_stop, model, opts, runs, excitation, out):
    """Integrate groups g_start..g_stop-1 of `order` (run indices, LANES at a time: group g is
    order[g * LANES:(g + 1) * LANES]); fill out.metrics[run] (engine/layout.py), or set out.redo[run] = 1
    for a run that diverged (the driver reruns it with the scalar kernel, which decides where it stops
    and what its row holds); add the work counters (ST_*) to out.stats.

    Records (engine/inputs.py): model LaneModel (its nt, n1t are tuples of length N and N1: the floor
    counts, fixed at compile time), opts KernelOptions, runs RunArrays, excitation LaneExcitation
    (ground acceleration coef[run] * prof[pid[run], step]), out LaneOutputs.

    A plain function: the compiled loop takes the records' arrays one by one. Unpacked inside the
    compiled loop's own function they cost the scalar event steps 28 % (2.8 against 2.2 us per step),
    and a compiled wrapper would make Numba optimise the whole kernel once more (about 4 s of compile)."""
    dt, nt, n1t, phi, psi, om2, dmp, gam, Wm, Cv = model
    scheme, law, max_iter = opts.scheme, opts.law, opts.max_iter
    ks, cdash, gap, exc_kind, exc_amp, exc_omega, rec_id, nsteps, status_in = runs
    coef, pid, prof = excitation
    metrics, redo, stats = out
    _integrate_groups(
        order,
        g_start,
        g_stop,
        dt,
        scheme,
        law,
        max_iter,
        nt,
        n1t,
        phi,
        psi,
        om2,
        dmp,
        gam,
        Wm,
        Cv,
        ks,
        cdash,
        gap,
        status_in,
        nsteps,
        exc_kind,
        exc_amp,
        exc_omega,
        coef,
        pid,
        prof,
        metrics,
        redo,
        stats,
    )


@njit_lanes
def _integrate_groups(
    order,
    g_start,
    g_stop,
    dt,
    scheme,
    law,
    max_iter,
    nt,
    n1t,
    phi,
    psi,
    om2,
    dmp,
    gam,
    Wm,
    Cv,
    ks,
    cdash,
    gap,
    status_in,
    nsteps,
    exc_kind,
    exc_amp,
    exc_omega,
    coef,
    pid,
    prof,
    metrics,
    redo,
    stats,
):
    """integrate_lanes' loop over groups and steps (its arguments are the records' fields, same names)."""
    N = len(nt)
    N1 = len(n1t)
    P = min(N1, N - N1)
    lay = _layout(N, P)
    r_q0, r_q1, r_g, r_f, r_pen, r_act, r_inc, r_cac, r_end, r_cd, r_R, r_s, r_met = lay
    nrows = r_met + ML.PER_DOF * N + ML.PER_PAIR * P
    W = np.zeros(nrows * LANES)
    dur = np.empty((LANES, P, ML.MEDIAN_BUFFER))
    nph = np.zeros((LANES, P), dtype=np.int64)
    lane_run = np.zeros(LANES, dtype=np.int64)
    lane_nst = np.zeros(LANES, dtype=np.int64)
    lane_status = np.zeros(LANES, dtype=np.int64)
    live = np.zeros(LANES, dtype=np.bool_)
    pid_lane = np.zeros(LANES, dtype=np.int64)
    act_pair = np.zeros(P, dtype=np.int64)
    stale = np.zeros(LANES, dtype=np.bool_)  # lanes with a compressive phase open on a pair out of contact
    stale_at = np.zeros(LANES, dtype=np.int64)  # ... since the end of this step
    # the scalar step's work arrays (see Z_*, B_*, I_*)
    Z = np.zeros((ZR, max(N, P, 6)))
    for k in range(N):
        Z[Z_OM2, k] = om2[k]
        Z[Z_DMP, k] = dmp[k]
        Z[Z_GAM, k] = gam[k]
    B = np.zeros((BR, P), dtype=np.bool_)
    I = np.zeros((2, max(P, max_iter + 1)), dtype=np.int64)
    A = np.zeros((P, 2 * P))
    orow = np.zeros(ML.PER_DOF * N + ML.PER_PAIR * P)
    work = LaneWork(Z, B, I, A, orow, dur, nph)
    n_runs = order.size
    for g in range(g_start, g_stop):
        base = g * LANES
        nl = min(LANES, n_runs - base)
        max_nst = 0
        uniform = nl > 0  # computed, not the literal True: a literal argument compiles its callee twice
        pid0 = pid[order[base]] if nl > 0 else 0
        for l in range(LANES):
            _park(W, l, nrows, r_s)
            live[l] = False
            nph[l, :] = 0
            if l >= nl:
                continue
            run = order[base + l]
            lane_run[l] = run
            lane_nst[l] = nsteps[run]
            lane_status[l] = status_in[run]
            live[l] = True
            pid_lane[l] = pid[run]
            if pid[run] != pid0:
                uniform = False
            max_nst = max(max_nst, nsteps[run])
            W[(r_s + S_KS) * LANES + l] = ks[run]
            W[(r_s + S_GAP) * LANES + l] = gap[run]
            W[(r_s + S_COEF) * LANES + l] = coef[run]
            for j in range(P):
                W[(r_cd + j) * LANES + l] = cdash[run, j]
                W[(r_pen + j) * LANES + l] = -gap[run]
                W[(r_met + ML.PER_DOF * N + ML.PER_PAIR * j + ML.PAIR_CLOSEST) * LANES + l] = gap[run]
            W[(r_s + S_MIT) * LANES + l] = 1.0 if (nsteps[run] >= 1 and scheme != SCHEME_EVENT) else 0.0
        for l in range(nl):
            if lane_nst[l] == 0:
                _finalize_lane(W, l, metrics, lane_run[l], lane_status[l], lane_nst[l], dt, om2, psi, N, P, dur, nph)
                _park(W, l, nrows, r_s)
                live[l] = False
        next_end = max_nst + 1
        for l in range(nl):
            if live[l] and lane_nst[l] < next_end:
                next_end = lane_nst[l]
        n_act = 0
        act_pair[:] = 0
        stale[:] = False
        any_stale = False
        step = 0
        while step < max_nst:
            # the vector code runs until a step that needs the scalar side (or a lane's last step)
            step_before = step
            if n_act == 0:
                step, nevt, nbad = _quiet(
                    W,
                    step + 1,
                    next_end if next_end <= max_nst else max_nst,
                    dt,
                    scheme,
                    law,
                    nt,
                    n1t,
                    Cv,
                    prof,
                    pid_lane,
                    uniform,
                    pid0,
                )
                nend = 0
            else:
                pon = act_pair[0] * 0  # int64, not a literal (see uniform)
                for j in range(P):
                    if act_pair[j] > 0:
                        pon |= 1 << j
                step, nevt, nbad, nend = _contact(
                    W,
                    step + 1,
                    next_end if next_end <= max_nst else max_nst,
                    dt,
                    scheme,
                    law,
                    nt,
                    n1t,
                    Cv,
                    pon,
                    prof,
                    pid_lane,
                    uniform,
                    pid0,
                )
            stats[ST_CALLS] += 1
            stats[ST_VSTEPS] += step - step_before
            src = r_q0 if (step - 1) % 2 == 0 else r_q1
            dst = r_q1 if (step - 1) % 2 == 0 else r_q0
            if any_stale:
                # a compressive phase left open by a switch-off at a step's very end (see below) closes
                # in the lane's next step, as in kernel.integrate_batch: here, if that step was a vector
                # step; if it is this step's scalar step, _lane_step closes it as the scalar kernel does
                any_stale = False
                for l in range(LANES):
                    if stale[l]:
                        stale[l] = False
                        if step > stale_at[l] + 1 or W[(r_s + S_EVT) * LANES + l] < 0.5:
                            for j in range(P):
                                if W[(r_inc + j) * LANES + l] > 0.5 and W[(r_act + j) * LANES + l] < 0.5:
                                    if live[l]:
                                        _end_phase(dur, nph, l, j, W[(r_cac + j) * LANES + l])
                                    W[(r_inc + j) * LANES + l] = 0.0
            if nevt > 0:
                for l in range(LANES):
                    if W[(r_s + S_EVT) * LANES + l] > 0.5:
                        W[(r_s + S_EVT) * LANES + l] = 0.0
                        if not live[l]:
                            continue
                        run = lane_run[l]
                        n_act += _count_act(W, l, P, r_act, act_pair, -1)
                        t0_ = _monotonic_ns()
                        const = (
                            dt,
                            scheme,
                            law,
                            max_iter,
                            exc_kind[run] == EXC_HARMONIC,
                            exc_amp[run],
                            exc_omega[run],
                            N,
                            N1,
                            P,
                        )
                        ok = _lane_step(W, l, src, dst, step, run, const, phi, psi, Wm, cdash, work)
                        stats[ST_FIX_NS] += _monotonic_ns() - t0_
                        stats[ST_FIXUPS] += 1
                        n_act += _count_act(W, l, P, r_act, act_pair, 1)
                        if not ok:
                            nbad += 1
                        for j in range(P):  # a phase still open on a pair that switched off at the step end
                            if W[(r_inc + j) * LANES + l] > 0.5 and W[(r_act + j) * LANES + l] < 0.5:
                                stale[l] = True
                                stale_at[l] = step
                                any_stale = True
            if nend > 0:
                for l in range(LANES):
                    for j in range(P):
                        if W[(r_end + j) * LANES + l] > 0.5:
                            W[(r_end + j) * LANES + l] = 0.0
                            if live[l]:
                                _end_phase(dur, nph, l, j, W[(r_cac + j) * LANES + l])
            if nbad > 0:
                for l in range(LANES):
                    if W[(r_s + S_BAD) * LANES + l] > 0.5:
                        if live[l]:
                            redo[lane_run[l]] = 1
                            n_act += _count_act(W, l, P, r_act, act_pair, -1)
                            live[l] = False
                        _park(W, l, nrows, r_s)
            if step == next_end:
                next_end = max_nst + 1
                for l in range(LANES):
                    if live[l] and lane_nst[l] == step:
                        _finalize_lane(W, l, metrics, lane_run[l], lane_status[l], step, dt, om2, psi, N, P, dur, nph)
                        n_act += _count_act(W, l, P, r_act, act_pair, -1)
                        _park(W, l, nrows, r_s)
                        live[l] = False
                    elif live[l] and lane_nst[l] < next_end:
                        next_end = lane_nst[l]


# ------------------------------------------------------------------------------------------ excitation


@njit_lanes
def _sin_profile(omega, nsteps, dt, out):
    """out[step] = sin(omega * step * dt), the expression kernel.ground_acceleration evaluates."""
    for step in range(nsteps + 1):
        out[step] = np.sin(omega * step * dt)


def excitation_profiles(runs, rec, dt):
    """Ground acceleration as coef[run] * prof[pid[run], step], equal to kernel.ground_acceleration.

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


def size_tuples(sys):
    """(nt, n1t): tuples whose lengths are the floor counts N and N1, fixed at compile time."""
    n1 = int(sys.i2[0])
    return (0,) * sys.m.size, (0,) * n1


# ------------------------------------------------------------------------------------------ eligibility


def lanes_ineligible_reason(sys, hist, opts, score) -> str | None:
    """Why this chunk must run on the scalar kernel, or None when the lane kernel computes its rows."""
    why = lane_modes(sys, hist, opts, score)
    return why if isinstance(why, str) else None


def lane_modes(sys, hist, opts, score) -> ModalArrays | str:
    """The modal data the lane kernel runs this chunk with, or why it must run on the scalar kernel.

    The lane kernel computes metric rows only (no histories, no scoring against an experiment), for
    the event and implicit schemes, for two shear frames facing floor by floor (pair j: floor j of
    building 1 and floor j of building 2, min(N1, N2) pairs) with classical damping in each.
    """
    if hist is not None and hist.active:
        return "histories requested"
    if score is not None and score.active:
        return "scoring against an experiment"
    if opts.scheme not in (SCHEME_IMPLICIT, SCHEME_EVENT):
        return "scheme is neither 'implicit' nor 'event'"
    if opts.law not in (0, LAW_NO_TENSION):
        return "a Hertz-type contact law (engine/nonlinear.py)"
    if opts.scheme == SCHEME_IMPLICIT and opts.max_iter < 1:
        return "max_contact_iterations < 1"
    n = sys.m.size
    p = sys.i1.size
    if p < 1 or n < 2:
        return "no contact pair"
    n1 = int(sys.i2[0])
    if not (np.array_equal(sys.i1, np.arange(p)) and np.array_equal(sys.i2, n1 + np.arange(p))):
        return "contact pairs are not floor j of building 1 facing floor j of building 2"
    if not (1 <= n1 < n and p == min(n1, n - n1)):
        return "pair count is not min(floors)"
    if 6 * n + p > SCRATCH or p > 62:
        return (
            f"{n} floors and {p} pairs: more than the lane kernel's register scratch ({SCRATCH} vectors for "
            "6 N + P, see _tab) or contact-set masks (62 pairs) hold"
        )
    for name in ("m", "C", "K"):
        if not np.all(np.isfinite(getattr(sys, name))):
            return f"non-finite {name}"
    if np.any(sys.C[:n1, n1:] != 0.0) or np.any(sys.K[:n1, n1:] != 0.0):
        return "the buildings are coupled outside the contact pairs"
    try:
        return modal_arrays(sys, n1)
    except ValueError as e:
        return str(e)
