"""One lane's step in scalar code, for the rare steps with a contact event: the event scheme's located
step (engine/events.py, written once for every kernel) with this kernel's modal pieces, or the implicit
scheme's active-set iteration (engine/scalar.py's, in modal form).

The lane's state moves from the group's lane-major rows (W) into small scalar work rows (LaneState:
Z, B, I, A) and back. Modal form (model/modal.py): q the modal displacement, q' its velocity,
Psi^T q - gap each pair's penetration, floors Phi q; a step of length h is dq = cf fsum + cq q +
cr (h/2) q' per mode, the contact forces at its end solve (I + diag(kappa) W)_SS F_S = (k_s delta +
c delta')_S of the free step (W = Psi^T diag(cf) Psi, kappa = k_s + 2 c / h): the same system as
engine/scalar.py's S = G^T Keff^-1 G.

The pieces here are inlined into their callers at Numba's IR level (engine/jit.py `inline`; lane_step,
_mask and end_phase are compiled functions), as are the event step's small functions
(events.event_functions(..., inline=True)): LLVM left these small functions as calls, and the calls, each
passing the lane's state, made the scalar steps 20-30 % slower than when they took their arrays one by one
(benchmarks/compare_checkouts.py). The event step's three large functions (event_step,
locate_event, first_event: once or twice per step or switch) are calls, with these pieces inlined into
them: inlined into lane_step too they cost the compile 9 s more (38.0 s against 28.7 s) and the run
nothing measurable (events.event_functions). bracket_crossing and the scalar helpers of engine/events.py stay calls (LLVM
inlines them).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from pounding_sweep.codes import LAW_NO_TENSION, SCHEME_EVENT
from pounding_sweep.engine import layout as ML
from pounding_sweep.engine.bookkeeping import force_extremes
from pounding_sweep.engine.events import (
    EVENT_MIN_FRACTION,
    EventOps,
    Ground,
    Pairs,
    bracket_crossing,
    event_functions,
    switch_tolerance,
)
from pounding_sweep.engine.jit import inline, njit_step, njit_step_once
from pounding_sweep.engine.lanes.rows import (
    B_ACT,
    B_INC,
    B_JUST,
    B_TRIAL,
    B_WAS,
    E_ABS,
    E_DST,
    E_IN,
    E_WDA,
    E_WREL,
    E_WSP,
    I_IDX,
    I_SEEN,
    LANES,
    S_AGE,
    S_AGS,
    S_BAD,
    S_DST,
    S_EABS,
    S_EIN,
    S_GAP,
    S_KS,
    S_MIT,
    S_UNS,
    S_WDA,
    S_WREL,
    S_WSP,
    Z_B,
    Z_C,
    Z_CAC,
    Z_CF,
    Z_CQ,
    Z_CR,
    Z_DDF,
    Z_DF,
    Z_DMP,
    Z_DP,
    Z_DQF,
    Z_EN,
    Z_F,
    Z_FE,
    Z_FS,
    Z_GAM,
    Z_OM2,
    Z_PHI,
    Z_PP,
    Z_Q,
    Z_QD,
    Z_QDE,
    Z_QE,
    Z_SP,
    Z_TH,
    row_offsets,
)


class LaneState(NamedTuple):
    """One lane inside its scalar step: what the event step's pieces (EventOps) read and write."""

    Z: np.ndarray  # (ZR, max(N, P, 6)) float rows (rows.Z_*): start and end states, forces, energies, work
    B: np.ndarray  # (BR, P) bool rows (rows.B_*): contact set and book-keeping flags
    I: np.ndarray  # (2, max(P, max_iter + 1)) int rows (rows.I_*): pair indices, the sets tried  # noqa: E741
    A: np.ndarray  # (P, 2 P) small solves
    orow: np.ndarray  # the lane's metric slots (per floor and pair)
    dur: np.ndarray  # (LANES, P, MEDIAN_BUFFER) every lane's compressive phases' durations
    nph: np.ndarray  # (LANES, P) and their counts
    l: int  # the lane
    phi: np.ndarray  # (N, N) mode shapes (floor i, mode k)
    psi: np.ndarray  # (N, P) Phi^T G
    pairs: Pairs  # views of B and Z rows: contact set, switch marks, crossings, dashpots; k_s, no tension
    gap: float  # the lane's gap [m]
    sizes: tuple  # (N, N1, P): floors, building 1's floors, pairs


@inline
def _floor_u(Z, row, i, phi, N):
    s = 0.0
    for k in range(N):
        s += phi[i, k] * Z[row, k]
    return s


@inline
def _pair(Z, rq, rqd, j, psi, gap, N):
    """(penetration, its rate) of pair j in the state (Z[rq], Z[rqd])."""
    s = 0.0
    v = 0.0
    for k in range(N):
        s += psi[k, j] * Z[rq, k]
        v += psi[k, j] * Z[rqd, k]
    return s - gap, v


@inline
def _keff_coefs(Z, h, N):
    """Newmark coefficients of each mode for a step of length h (modal.py)."""
    for k in range(N):
        f = 1.0 / (Z[Z_OM2, k] + 2.0 * Z[Z_DMP, k] / h + 4.0 / (h * h))
        Z[Z_CF, k] = f
        Z[Z_CQ, k] = -2.0 * Z[Z_OM2, k] * f
        Z[Z_CR, k] = 8.0 / (h * h) * f


@inline
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


@inline
def _active_pairs(B, I, P):
    """The pairs in B_ACT into I[I_IDX, :na]; returns na."""
    na = 0
    for j in range(P):
        if B[B_ACT, j]:
            I[I_IDX, na] = j
            na += 1
    return na


@inline
def _set_forces(Z, B, I, A, h, k_s, psi, sizes):
    """Contact forces Z_FS at the end of a step of length h with the set B_ACT (others 0): the SPD
    system (W_SS + diag(1/kappa)) F_S = (k_s delta + c delta')_S / kappa of the free end state,
    W = Psi^T diag(cf) Psi, kappa = k_s + 2 c / h (scalar._contact_forces' system in modal form).
    sizes = (N, N1, P)."""
    N, _n1, P = sizes
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


@inline
def _end_state(Z, h, psi, N, P):
    """End state of a step with forces Z_FS: dq = dqf - cf Psi F, q+ = q + dq, q'+ = (2/h) dq - q'."""
    for k in range(N):
        g = 0.0
        for j in range(P):
            g += psi[k, j] * Z[Z_FS, j]
        dq = Z[Z_DQF, k] - Z[Z_CF, k] * g
        Z[Z_QE, k] = Z[Z_Q, k] + dq
        Z[Z_QDE, k] = (2.0 / h) * dq - Z[Z_QD, k]


@inline
def _law_forces(Z, B, rows, k_s, gap, psi, sizes):
    """Row rf := the Kelvin-Voigt forces (eq. 8) of the pairs in B_ACT in the state (rq, rqd), 0 for
    the others; rows = (rq, rqd, rf)."""
    rq, rqd, rf = rows
    N, _n1, P = sizes
    for j in range(P):
        Z[rf, j] = 0.0
        if B[B_ACT, j]:
            pen, vr = _pair(Z, rq, rqd, j, psi, gap, N)
            Z[rf, j] = k_s * pen + Z[Z_C, j] * vr


@inline
def _fixed_set_step(Z, B, I, A, h, ags, k_s, gap, psi, sizes):
    """scalar._advance in modal form: one Newmark step of length h from (Z_Q, Z_QD, Z_F) with the pairs in
    B_ACT in contact at its end (ags = (ag_s, ag_e): the ground acceleration at its ends); end state in Z_QE,
    Z_QDE, its Kelvin-Voigt forces (eq. 8) in Z_FE."""
    N, _n1, P = sizes
    _keff_coefs(Z, h, N)
    _free_step(Z, h, ags[0], ags[1], gap, psi, N, P)
    _set_forces(Z, B, I, A, h, k_s, psi, sizes)
    _end_state(Z, h, psi, N, P)
    _law_forces(Z, B, (Z_QE, Z_QDE, Z_FE), k_s, gap, psi, sizes)


@inline
def _modal_acc(Z, rq, rqd, rf, psi, N, P):
    """Modal absolute accelerations of the state (rq, rqd) with forces in row rf into row Z_B:
    -d q' - w^2 q - Psi F (equilibrium; the ground term cancels in absolute acceleration)."""
    for k in range(N):
        g = 0.0
        for j in range(P):
            g += psi[k, j] * Z[rf, j]
        Z[Z_B, k] = -Z[Z_DMP, k] * Z[rqd, k] - Z[Z_OM2, k] * Z[rq, k] - g


@inline
def _finite_rows(Z, rf, phi, psi, sizes):
    """The scalar kernels' divergence guard on the end state Z_QE, Z_QDE (forces in row rf): floors within
    DIVERGED_M, accelerations below 1e300. A floor's value is at most sum_k max_i |phi_ik| |x_k| of the modal
    values x: where that bound is well inside both limits (half the first, a tenth of the second: room for
    its rounding), every floor is, and the floors are not computed (a NaN or inf fails the bound's test)."""
    N, _n1, P = sizes
    _modal_acc(Z, Z_QE, Z_QDE, rf, psi, N, P)
    bu = 0.0
    ba = 0.0
    for k in range(N):
        bu += Z[Z_PHI, k] * abs(Z[Z_QE, k])
        ba += Z[Z_PHI, k] * abs(Z[Z_B, k])
    if bu < 0.5 * ML.DIVERGED_M and ba < 1e299:
        return True
    for i in range(N):
        u = 0.0
        a = 0.0
        for k in range(N):
            u += phi[i, k] * Z[Z_QE, k]
            a += phi[i, k] * Z[Z_B, k]
        if not (abs(u) < ML.DIVERGED_M) or not (abs(a) < 1e300):
            return False
    return True


@inline
def _switch_rows(Z, B, orow, t, k_s, gap, psi, sizes):
    """scalar._switch in modal form: the pairs in B_TRIAL switched at an event (time t, state Z_Q, Z_QD);
    every force from the Kelvin-Voigt law at this instant (the acceleration follows from equilibrium,
    never stored)."""
    N, _n1, P = sizes
    pbase = ML.PER_DOF * N
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
            force_extremes(orow, base, f, t)
        B[B_WAS, j] = B[B_ACT, j]
    _law_forces(Z, B, (Z_Q, Z_QD, Z_F), k_s, gap, psi, sizes)


@njit_step
def end_phase(dur, nph, l, j, duration):
    """bookkeeping.end_phase for lane l."""
    k = nph[l, j]
    if k < dur.shape[2]:
        dur[l, j, k] = duration
    nph[l, j] = k + 1


@inline
def _accept_rows(Z, B, book, piece, k_s, gap, psi, sizes):
    """Accept the piece [t_e - hs, t_e] (scalar._accept in modal form), end state Z_QE, Z_QDE with forces in
    row rf: energy increments, exact for Newmark average acceleration (input -Gamma.dq ag, structural
    damping sum d_k dq_k^2 / hs, the contact spring and dashpot work on each pair's penetration),
    contact metrics; then the state and forces move to Z_Q, Z_QD, Z_F. book = (orow, dur, nph, l): the
    lane's metric slots and compressive phases; piece = (hs, t_e, ag_s, ag_e, rf)."""
    orow, dur, nph, l = book
    hs, t_e, ag_s, ag_e, rf = piece
    N, _n1, P = sizes
    pbase = ML.PER_DOF * N
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
        base = pbase + ML.PER_PAIR * j
        if -pen < orow[base + ML.PAIR_CLOSEST]:  # closest approach, at every accepted piece's end
            orow[base + ML.PAIR_CLOSEST] = -pen
            orow[base + ML.PAIR_CLOSEST_TIME] = t_e
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
        if act:
            if not was:
                orow[base + ML.PAIR_IMPACTS] += 1.0
            orow[base + ML.PAIR_CONTACT_TIME] += hs
            if pen > orow[base + ML.PAIR_MAX_PENETRATION]:
                orow[base + ML.PAIR_MAX_PENETRATION] = pen
            force_extremes(orow, base, f, t_e)
        comp = act and f > 0.0
        if comp:
            orow[base + ML.PAIR_COMPRESSION_TIME] += hs
            Z[Z_CAC, j] = Z[Z_CAC, j] + hs if B[B_INC, j] else hs
        elif B[B_INC, j]:
            end_phase(dur, nph, l, j, Z[Z_CAC, j])
        B[B_INC, j] = comp
        B[B_WAS, j] = act
    for k in range(N):
        Z[Z_Q, k] = Z[Z_QE, k]
        Z[Z_QD, k] = Z[Z_QDE, k]
    for j in range(P):
        Z[Z_F, j] = Z[rf, j]


# The event step's pieces (EventOps) in modal form: thin wrappers of the functions above, which take the
# few arrays they use.


@inline
def _advance(st, h, ag_s, ag_e, cold):
    """EventOps.advance: _fixed_set_step; returns 0 (a direct solve)."""
    _fixed_set_step(st.Z, st.B, st.I, st.A, h, (ag_s, ag_e), st.pairs.k_s, st.gap, st.psi, st.sizes)
    return 0


@inline
def _pair_at(st, end, j):
    """EventOps.pair: (penetration, its rate) of pair j at the end or start state."""
    rq, rqd = (Z_QE, Z_QDE) if end else (Z_Q, Z_QD)  # one inlined copy of _pair, not one per branch
    return _pair(st.Z, rq, rqd, j, st.psi, st.gap, st.sizes[0])


@inline
def _tolerance(st, j):
    """EventOps.tolerance: events.switch_tolerance of pair j's two floors at the end state."""
    N, N1, _p = st.sizes
    return switch_tolerance(_floor_u(st.Z, Z_QE, j, st.phi, N), _floor_u(st.Z, Z_QE, N1 + j, st.phi, N))


@inline
def _finite(st):
    """EventOps.finite: _finite_rows with the event step's forces."""
    return _finite_rows(st.Z, Z_FE, st.phi, st.psi, st.sizes)


@inline
def _accept(st, hs, t_e, ag_s, ag_e):
    """EventOps.accept: _accept_rows with the event step's forces."""
    book = (st.orow, st.dur, st.nph, st.l)
    _accept_rows(st.Z, st.B, book, (hs, t_e, ag_s, ag_e, Z_FE), st.pairs.k_s, st.gap, st.psi, st.sizes)


@inline
def _switch(st, t, ag):
    """EventOps.switch: _switch_rows."""
    _switch_rows(st.Z, st.B, st.orow, t, st.pairs.k_s, st.gap, st.psi, st.sizes)


#: the event step's pieces in modal coordinates
OPS = EventOps(_advance, _pair_at, _tolerance, _finite, _accept, _switch, bracket_crossing)
_event_step, _contradicts = event_functions(OPS, inline=True)


@njit_step
def _mask(active):
    """Active set as a bit mask (meaningful for up to 62 pairs; only used to spot cycles)."""
    mk = 0
    for j in range(min(active.size, 62)):
        if active[j]:
            mk |= 1 << j
    return mk


@inline
def _implicit_step(st, step, dt, max_iter, ag_prev, ag):
    """Implicit scheme, one lane, one step: scalar._implicit_forces' active-set iteration from the start
    set (cycle detection), then the accepted step. Returns (finite, iterations, settled); not settled (no
    set agrees with its end state: an impact inside the step under the classic law) nothing is accepted and
    the start's set is restored for the event step to take the step."""
    Z, B, I, psi, pr = st.Z, st.B, st.I, st.psi, st.pairs
    N, _n1, P = st.sizes
    _keff_coefs(Z, dt, N)
    _free_step(Z, dt, ag_prev, ag, st.gap, psi, N, P)
    it = 0
    settled = False
    cycled = False
    while it < max_iter and not cycled:
        I[I_SEEN, it] = _mask(pr.active)
        it += 1
        _set_forces(Z, B, I, st.A, dt, pr.k_s, psi, st.sizes)
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
            if want and pr.no_tension:
                want = (pr.k_s * pen + Z[Z_C, j] * (Z[Z_DDF, j] - (2.0 / dt) * wf)) > 0.0
            B[B_TRIAL, j] = want
            if want != pr.active[j]:
                changed = True
        if not changed:
            settled = True
            break
        for j in range(P):
            pr.active[j] = B[B_TRIAL, j]
        mk = _mask(pr.active)
        for z in range(it):
            if I[I_SEEN, z] == mk and P <= 62:
                cycled = True
    if not settled:
        for j in range(P):
            pr.active[j] = B[B_WAS, j]  # the start's set (the last accepted piece's)
        return True, it, False
    _end_state(Z, dt, psi, N, P)
    if not _finite_rows(Z, Z_FS, st.phi, psi, st.sizes):
        return False, it, True
    book = (st.orow, st.dur, st.nph, st.l)
    _accept_rows(Z, B, book, (dt, (step - 1) * dt + dt, ag_prev, ag, Z_FS), pr.k_s, st.gap, psi, st.sizes)
    return True, it, True


@inline
def _lane_factors(W, st, Wm, dt, r_R):
    """The lane's R = (I + diag(kappa) W)_SS^-1 for its set S, in full P x P (zeros outside S), into W."""
    I, A, l, pr = st.I, st.A, st.l, st.pairs
    P = st.sizes[2]
    for z in range(P * P):
        W[(r_R + z) * LANES + l] = 0.0
    na = _active_pairs(st.B, I, P)
    if na == 0:
        return
    # Gauss-Jordan on [I + diag(kappa) W_SS | I] (no pivoting: similar to I + SPD, positive pivots)
    for p in range(na):
        kap = pr.k_s + 2.0 * pr.c[I[I_IDX, p]] / dt
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


@inline
def _load(W, st, l, src, dt):
    """Lane l's start state, forces, set, phases, energies and metric slots from W (buffer src) into st."""
    Z, B, pr, orow = st.Z, st.B, st.pairs, st.orow
    N, _n1, P = st.sizes
    r_q0, r_q1, r_g, r_f, r_pen, r_act, r_inc, r_cac, r_end, r_cd, r_R, r_s, r_met = row_offsets(N, P)
    for k in range(N):
        Z[Z_Q, k] = W[(src + k) * LANES + l]
        Z[Z_QD, k] = (2.0 / dt) * W[(src + N + k) * LANES + l]
    for j in range(P):
        Z[Z_F, j] = W[(r_f + j) * LANES + l]
        act = W[(r_act + j) * LANES + l] > 0.5
        pr.active[j] = act
        B[B_WAS, j] = act
        B[B_INC, j] = W[(r_inc + j) * LANES + l] > 0.5
        Z[Z_CAC, j] = W[(r_cac + j) * LANES + l]
        pen, vr = _pair(Z, Z_Q, Z_QD, j, st.psi, st.gap, N)
        Z[Z_PP, j] = pen
        Z[Z_SP, j] = pr.k_s * pen if act else 0.0
        Z[Z_DP, j] = Z[Z_F, j] - Z[Z_SP, j] if act else 0.0
    Z[Z_EN, E_IN] = W[(r_s + S_EIN) * LANES + l]
    Z[Z_EN, E_ABS] = W[(r_s + S_EABS) * LANES + l]
    Z[Z_EN, E_DST] = W[(r_s + S_DST) * LANES + l]
    Z[Z_EN, E_WSP] = W[(r_s + S_WSP) * LANES + l]
    Z[Z_EN, E_WDA] = W[(r_s + S_WDA) * LANES + l]
    Z[Z_EN, E_WREL] = W[(r_s + S_WREL) * LANES + l]
    for z in range(ML.PER_DOF * N + ML.PER_PAIR * P):
        orow[z] = W[(r_met + z) * LANES + l]


@inline
def _store(W, st, l, dst, step, dt):
    """The step's end back into W (buffer dst): per-floor peaks at the step end, state, forces and their
    modal resultant, set, phases, energies, metric slots."""
    Z, B, pr, orow, phi, psi = st.Z, st.B, st.pairs, st.orow, st.phi, st.psi
    N, N1, P = st.sizes
    r_q0, r_q1, r_g, r_f, r_pen, r_act, r_inc, r_cac, r_end, r_cd, r_R, r_s, r_met = row_offsets(N, P)
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
        W[(r_act + j) * LANES + l] = 1.0 if pr.active[j] else 0.0
        W[(r_inc + j) * LANES + l] = 1.0 if B[B_INC, j] else 0.0
        W[(r_cac + j) * LANES + l] = Z[Z_CAC, j]
        W[(r_pen + j) * LANES + l] = Z[Z_PP, j]
    W[(r_s + S_EIN) * LANES + l] = Z[Z_EN, E_IN]
    W[(r_s + S_EABS) * LANES + l] = Z[Z_EN, E_ABS]
    W[(r_s + S_DST) * LANES + l] = Z[Z_EN, E_DST]
    W[(r_s + S_WSP) * LANES + l] = Z[Z_EN, E_WSP]
    W[(r_s + S_WDA) * LANES + l] = Z[Z_EN, E_WDA]
    W[(r_s + S_WREL) * LANES + l] = Z[Z_EN, E_WREL]
    for z in range(ML.PER_DOF * N + ML.PER_PAIR * P):
        W[(r_met + z) * LANES + l] = orow[z]


@inline
def _vector_trial(W, st, l, dst, dt):
    """The trial (the whole step with the start's contact set) as the vector step left it in buffer dst: its
    end state into Z_QE, Z_QDE, the Kelvin-Voigt forces (eq. 8) of that state into Z_FE. The vector step
    took exactly this step before it marked the lane (_fixed_set_step's, in its own rounding), so the
    scalar step does not take it again."""
    Z, N = st.Z, st.sizes[0]
    for k in range(N):
        Z[Z_QE, k] = W[(dst + k) * LANES + l]
        Z[Z_QDE, k] = (2.0 / dt) * W[(dst + N + k) * LANES + l]
    _law_forces(Z, st.B, (Z_QE, Z_QDE, Z_FE), st.pairs.k_s, st.gap, st.psi, st.sizes)


@njit_step_once
def lane_step(W, l, bufs, run, ctx, modal, cdash, work):
    """Lane l's whole step in scalar code, from its start state to its end, its metric and energy rows
    updated. bufs = (src, dst, step): the state buffers of the step's start and end, and the step; run:
    the lane's run; ctx = (dt, scheme, law, max_iter, harmonic, amp, omega, N, N1, P): the step's
    constants (the run's law and excitation, the model's sizes); modal = (phi, psi, Wm) (engine/inputs.py
    LaneModel); cdash: the runs' dashpots; work: LaneWork. Returns False when the state is no longer finite."""
    src, dst, step = bufs
    dt, scheme, law, max_iter, harmonic, amp, om, N, N1, P = ctx
    phi, psi, Wm = modal
    Z, B, I, A, orow, dur, nph = work
    r_s = row_offsets(N, P)[11]
    k_s = W[(r_s + S_KS) * LANES + l]
    gap = W[(r_s + S_GAP) * LANES + l]
    ag_s = W[(r_s + S_AGS) * LANES + l]
    ag = W[(r_s + S_AGE) * LANES + l]
    for j in range(P):
        Z[Z_C, j] = cdash[run, j]
    pr = Pairs(B[B_ACT, :P], B[B_JUST, :P], B[B_TRIAL, :P], Z[Z_TH, :P], Z[Z_C, :P], k_s, law == LAW_NO_TENSION)
    st = LaneState(Z, B, I, A, orow, dur, nph, l, phi, psi, pr, gap, (N, N1, P))
    _load(W, st, l, src, dt)
    start = _mask(pr.active)
    finite, count, uns = True, 0, 0
    locate = scheme == SCHEME_EVENT
    if not locate:
        finite, count, settled = _implicit_step(st, step, dt, max_iter, ag_s, ag)
        locate = not settled  # no consistent set: the step is taken as the event scheme takes it
    if locate:
        _vector_trial(W, st, l, dst, dt)  # the trial: the whole step with the start's set
        ground = Ground(harmonic, amp, om)
        finite, n_ev, uns = _event_step(st, ground, (step - 1) * dt, dt, ag_s, ag, EVENT_MIN_FRACTION * dt)
        count = max(count, n_ev)
    if count > W[(r_s + S_MIT) * LANES + l]:
        W[(r_s + S_MIT) * LANES + l] = count
    W[(r_s + S_UNS) * LANES + l] += uns
    if not finite:
        W[(r_s + S_BAD) * LANES + l] = 1.0
        return False
    _store(W, st, l, dst, step, dt)
    if _mask(pr.active) != start:
        _lane_factors(W, st, Wm, dt, row_offsets(N, P)[10])
    return True
