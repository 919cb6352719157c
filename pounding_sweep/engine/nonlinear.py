"""Numba kernel for the Hertz-type contact laws: Newmark average acceleration of two shear frames with a
nonlinear pounding force, one run at a time in floor coordinates. The linear Kelvin-Voigt laws stay on
engine/scalar.py and engine/lanes; this kernel fills the same metric row, histories and scores
(engine/bookkeeping.py), so a sweep over laws reads as one table.

Laws (delta = g.u - d > 0 the penetration, delta_dot = g.v its rate, F > 0 in compression, 0 for delta <= 0):

    hertz      F = k_h delta^1.5                                  (Hertz 1882; Davis 1992, EESD 21:253)
    hertzdamp  F = k_h delta^1.5 (1 + a delta_dot / v0), F >= 0   (Muthukumar & DesRoches 2006, EESD 35:811)
    jankowski  F = k_h delta^1.5 + c0 delta^0.25 delta_dot  while delta_dot > 0 (approach),
               F = k_h delta^1.5                            while delta_dot <= 0  (Jankowski 2005, EESD 34:595)

with v0 the approach speed at the start of the impact (hertzdamp; floored at opts.min_impact_speed, the
run flagged STATUS_GRAZING where the floor acts), a the normalised damping ("xiNorm") and
c0 = 2 xi sqrt(k_h m_eff) (model/laws.py turns the restitution into a and xi). Every law is continuous
in the state and vanishes at delta = 0, so an impact starts and ends without a force jump.

The step. With u0 the end-of-step state without contact and z = g.u the pairs' relative displacements
(z = z0 - S F, S = G^T Keff^-1 G as in engine/scalar.py), the end-of-step forces solve the small
nonlinear system F = f(z - d, (2/h) z - g.(2/h u_n + v_n)) (the rate from Newmark's eq. 15). It is solved
in pair space by Newton's method on R(F) = F - f(z0 - S F) with the Jacobian I + D S (D = df/dz >= 0:
every law is nondecreasing in z, so the Jacobian is nonsingular), each step halved until the residual
norm drops (Armijo); converged when every |R_j| is within 1e-12 of |F_j| + |f_j| plus the rounding of
f through z (8 eps |df/dz| (|z0| + d + |S F|)); after NEWTON_MAX iterations the step is kept and counted
unsettled (STATUS_UNSETTLED).

Schemes. "implicit": every pair carries its law at the end of the step (no active set is needed: the
law is 0 out of contact). "event": the step is taken with the pairs in contact at its start carrying the
law, the others force-free; where a pair's end penetration contradicts that (an impact or a separation),
the instant where its penetration crosses zero is located on the real sub-step map (from the step's
Hermite estimate, Newton and secant steps inside a false-position bracket: engine/events.py, the step
written once for every kernel), the step split there and continued;
at an impact the hertzdamp law takes v0 from the located state. The law's own kinks (Jankowski's
approach/restitution switch at delta_dot = 0, Hertz-damp's clip at F = 0) are not located: the force is
continuous there, so a kink inside a step costs O(h^2) in the velocity, the scheme's order.
"paper": the forces from the trial state without contact, applied as loads (the paper's section 2).
Hertz-damp's v0 in the implicit and paper schemes is the rate where the step's contact-free Hermite
interpolant of the penetration crosses zero.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from pounding_sweep.codes import EXC_HARMONIC, LAW_HERTZ, LAW_HERTZDAMP, SCHEME_EVENT, SCHEME_PAPER
from pounding_sweep.engine import bookkeeping as bk
from pounding_sweep.engine import floors
from pounding_sweep.engine import layout as L
from pounding_sweep.engine.clock import _clock
from pounding_sweep.engine.events import (
    EVENT_MIN_FRACTION,
    EventOps,
    Ground,
    Pairs,
    bisect_crossing,
    empty_pairs,
    event_functions,
    ground_acceleration,
    hermite_indicator,
)
from pounding_sweep.engine.jit import inline_kernel, njit_inner, njit_kernel

NEWTON_MAX = 60  # Newton iterations per contact solve before the step is kept and flagged
NEWTON_RTOL = 1e-12  # relative residual of a converged contact solve
EPS = 2.220446049250313e-16
D_MAX = 1e30  # cap on df/d(delta) [N/m]: Jankowski's dashpot has an infinite slope at first touch

# energy accumulators of a run (HertzState.en): input work and its absolute sum, structural damping, the
# work of the law's spring part and of the rest (its dashpot)
EN_IN, EN_ABS, EN_DST, EN_WSP, EN_WDA = range(5)
EN_N = 5


@njit_kernel
def law_force(law, k, coef, alpha, delta, rate):
    """(F, dF/d delta, dF/d delta_dot) of one pair; k = k_h [N/m^1.5], coef: Jankowski's c0
    [N s/m^1.25], alpha = a / v0 [s/m] (Hertz-damp)."""
    if not delta > 0.0:
        return 0.0, 0.0, 0.0
    sq = np.sqrt(delta)
    el = k * delta * sq
    d_el = 1.5 * k * sq
    if law == LAW_HERTZ:
        return el, d_el, 0.0
    if law == LAW_HERTZDAMP:
        fac = 1.0 + alpha * rate
        f = el * fac
        if not f > 0.0:
            return 0.0, 0.0, 0.0  # clipped: the law never pulls
        return f, d_el * fac, el * alpha
    if rate > 0.0:  # Jankowski, approaching: the dashpot c0 delta^(1/4) acts
        q = np.sqrt(sq)
        c = coef * q
        return el + c * rate, min(d_el + 0.25 * coef * rate / (q * q * q), D_MAX), c
    return el, d_el, 0.0


@njit_kernel
def spring_part(k, delta):
    """The elastic part k_h delta^1.5 of every law here (its dashpot part is F minus this)."""
    return k * delta * np.sqrt(delta) if delta > 0.0 else 0.0


@njit_inner
def _residual(S, z0, wrel, q, d, lw, use, F, z, rows):
    """R = F - f(z), z = z0 - S F, D = df/dz, tol the convergence bound per pair (rows = (R, D, tol));
    lw = (law, k_h, coef, alpha) as law_force takes them. Returns ||R||^2."""
    law, k, coef, alpha = lw
    R, D, tol = rows
    P = z0.shape[0]
    rr = 0.0
    for j in range(P):
        s = z0[j]
        sa = abs(z0[j]) + d
        for l in range(P):
            s -= S[j, l] * F[l]
            sa += abs(S[j, l] * F[l])
        z[j] = s
        f, fd, fr = 0.0, 0.0, 0.0
        if use[j]:
            f, fd, fr = law_force(law, k, coef[j], alpha[j], s - d, q * s - wrel[j])
        D[j] = fd + q * fr
        R[j] = F[j] - f
        tol[j] = NEWTON_RTOL * (abs(F[j]) + abs(f)) + 8.0 * EPS * D[j] * sa
        rr += R[j] * R[j]
    return rr


@njit_inner
def solve_pairs(S, z0, wrel, q, d, lw, use, F, z, W):
    """The end-of-step contact forces F (warm start: F as given) with z = z0 - S F: Newton on
    R = F - f(z0 - S F) with Armijo halving; rate = q z - wrel, the pairs in `use` carrying the law
    lw = (law, k_h, coef, alpha). W: (P, P + 6) work rows.
    Returns the iterations taken, negative when NEWTON_MAX passed without convergence."""
    P = z0.shape[0]
    if P == 0:
        return 0
    J = W[:, :P]
    rows = (W[:, P], W[:, P + 1], W[:, P + 2])
    R, D, tol = rows
    dF = W[:, P + 3]
    Ft = W[:, P + 4]
    zt = W[:, P + 5]
    rr = _residual(S, z0, wrel, q, d, lw, use, F, z, rows)
    for it in range(NEWTON_MAX):
        done = True
        for j in range(P):
            if abs(R[j]) > tol[j]:
                done = False
        if done:
            return it
        for j in range(P):
            for l in range(P):
                J[j, l] = D[j] * S[j, l]
            J[j, j] += 1.0
            dF[j] = -R[j]
        floors.gauss_solve(J, dF, P, floors.PIVOT)
        lam = 1.0
        for _ in range(40):
            for j in range(P):
                Ft[j] = F[j] + lam * dF[j]
            rt = _residual(S, z0, wrel, q, d, lw, use, Ft, zt, rows)
            if rt <= (1.0 - 1e-4 * lam) * rr or lam < 1e-9:
                break
            lam *= 0.5
        for j in range(P):
            F[j] = Ft[j]
            z[j] = zt[j]
        rr = rt
    for j in range(P):
        if abs(R[j]) > tol[j]:
            return -NEWTON_MAX
    return NEWTON_MAX


@njit_inner
def _crossing_rate(p0, p1, m0, m1, h):
    """Rate d(delta)/dt where the step's cubic Hermite interpolant of the penetration (p0 <= 0 < p1, end
    slopes m0, m1 = rate * h) first crosses zero: Hertz-damp's approach speed in the implicit and paper
    schemes."""
    herm = (p0, p1, m0, m1)
    lo, hi = 0.0, 1.0
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        if hermite_indicator(herm, mid, h, (np.bool_(False), 1.0, 0.0)) > 0.0:
            hi = mid
        else:
            lo = mid
    t = hi
    t2 = t * t
    dp = (6 * t2 - 6 * t) * p0 + (3 * t2 - 4 * t + 1) * m0 + (-6 * t2 + 6 * t) * p1 + (3 * t2 - 2 * t) * m1
    return dp / h


@njit_inner
def _approach(a_j, rate, vmin):
    """(alpha = a / v0, floored?) for an impact starting at `rate` [m/s]; v0 = max(rate, vmin)."""
    if rate >= vmin:
        return a_j / rate, False
    return a_j / vmin, True


class HertzState(NamedTuple):
    """One run of this kernel inside a step: what the event step's pieces (EventOps) read and write."""

    m: np.ndarray  # (N,) the model (engine/inputs.py Structure)
    C: np.ndarray
    K: np.ndarray
    i1: np.ndarray
    i2: np.ndarray
    gap: float  # the run's gap d [m]
    u: np.ndarray  # (N,) start of the piece: displacement, velocity, acceleration (relative to the table)
    v: np.ndarray
    a: np.ndarray
    un: np.ndarray  # (N,) end of the piece
    vn: np.ndarray
    an: np.ndarray
    F: np.ndarray  # (P,) contact forces at the end of the piece [N], compression > 0
    pairs: Pairs  # in contact (event scheme: the set; else delta > 0 at the step end), switch marks
    law: int  # codes.LAW_HERTZ, LAW_HERTZDAMP or LAW_JANKOWSKI
    k: float  # k_h [N/m^1.5]
    alpha: np.ndarray  # (P,) Hertz-damp: a / v0 of the impact in progress [s/m]
    graze: np.ndarray  # (P,) bool, Hertz-damp: that v0 is the floor, not the approach speed
    vmin: float  # Hertz-damp's floor on v0 [m/s]
    flags: np.ndarray  # (1,) status bits raised inside the step (STATUS_GRAZING)
    scheme: int  # codes.SCHEME_*
    dt: float  # the step [s]
    was: np.ndarray  # (P,) in contact over the last accepted piece
    Sprev: np.ndarray  # (P,) spring and dashpot parts of F at the start of the piece (energy book-keeping)
    Dprev: np.ndarray
    pen_prev: np.ndarray  # (P,) penetration at the start of the piece
    en: np.ndarray  # (EN_N,) energy accumulators
    row: np.ndarray  # the run's metric row (engine/layout.py)
    phases: tuple  # (in_comp, comp_acc, durations, nphase): compressive phases (bookkeeping.pair_pieces)
    Cdu: np.ndarray  # (N,) work: C du
    work: tuple  # (A (N, N), B (N, P + 1), Sh (P, P), z0, wrel, zz (P,), W (P, P + 6)): _substep's


@njit_inner
def _substep(st, h, ag):
    """One Newmark average-acceleration step of length h from (u, v, a) with the pairs in contact carrying
    the law: (K + 2/h C + 4/h^2 M) solved for the contact-free end state and the pairs' flexibility
    (columns of B: the load, then G), the pair forces by solve_pairs, the end state u0 - H F, the
    velocity by eq. 15 and the acceleration from equilibrium. Returns solve_pairs' iteration count."""
    m, C, K, i1, i2, u, v, a, F = st.m, st.C, st.K, st.i1, st.i2, st.u, st.v, st.a, st.F
    A, B, Sh, z0, wrel, z, W = st.work
    n = m.shape[0]
    P = i1.shape[0]
    q1 = 4.0 / (h * h)
    q3 = 2.0 / h
    for i in range(n):
        s = -m[i] * ag + m[i] * (q1 * u[i] + 2.0 * q3 * v[i] + a[i])
        for kk in range(n):
            A[i, kk] = K[i, kk] + q3 * C[i, kk]
            s += C[i, kk] * (q3 * u[kk] + v[kk])
        A[i, i] += q1 * m[i]
        B[i, 0] = s
        for j in range(P):
            B[i, 1 + j] = (1.0 if i == i1[j] else 0.0) - (1.0 if i == i2[j] else 0.0)
    # symmetric positive definite: elimination without pivoting, every right-hand side at once
    for kk in range(n):
        piv = A[kk, kk]
        for i in range(kk + 1, n):
            f = A[i, kk] / piv
            for j in range(kk, n):
                A[i, j] -= f * A[kk, j]
            for c in range(P + 1):
                B[i, c] -= f * B[kk, c]
    for i in range(n - 1, -1, -1):
        for c in range(P + 1):
            s = B[i, c]
            for j in range(i + 1, n):
                s -= A[i, j] * B[j, c]
            B[i, c] = s / A[i, i]
    for j in range(P):
        p, qq = i1[j], i2[j]
        z0[j] = B[p, 0] - B[qq, 0]
        wrel[j] = q3 * (u[p] - u[qq]) + v[p] - v[qq]
        for l in range(P):
            Sh[j, l] = B[p, 1 + l] - B[qq, 1 + l]
    lw = (st.law, st.k, st.pairs.c, st.alpha)
    it = solve_pairs(Sh, z0, wrel, q3, st.gap, lw, st.pairs.active, F, z, W)
    for i in range(n):
        s = B[i, 0]
        for j in range(P):
            s -= B[i, 1 + j] * F[j]
        st.un[i] = s
        st.vn[i] = q3 * (st.un[i] - u[i]) - v[i]
    floors.equilibrium_acceleration(st, ag, st.un, st.vn, F, st.an)
    return it


@njit_inner
def _advance(st, h, ag_s, ag_e, cold):
    """EventOps.advance: _substep over h (its contact solve from zero force when cold, else from the forces
    at hand); negative when Newton did not converge."""
    if cold:
        for j in range(st.F.size):
            st.F[j] = 0.0
    return _substep(st, h, ag_e)


@inline_kernel
def _accept(st, hs, t_e, ag_s, ag_e):
    """EventOps.accept: book the piece [t_e - hs, t_e] (energy increments as engine/scalar.py's, the law's
    spring part k_h delta^1.5) and make its end the start. Outside the event scheme the pairs in contact are
    those penetrating at the end (implicit) or, in the paper's scheme, those whose law acted: its forces come
    from the contact-free trial state (st.work[3]), and a stiff contact at a coarse step can push a pair apart
    by the step's end (as scalar._paper_forces books the linear laws); an impact that starts takes its approach
    speed (Hertz-damp)."""
    u, v, un, vn, i1, i2, d, F, en = st.u, st.v, st.un, st.vn, st.i1, st.i2, st.gap, st.F, st.en
    touching, coef, alpha, graze, dt = st.pairs.active, st.pairs.c, st.alpha, st.graze, st.dt
    de, dd = bk.structure_work(u, un, st.m, st.C, st.Cdu, ag_s, ag_e, hs)
    en[EN_IN] += de
    en[EN_ABS] += abs(de)
    en[EN_DST] += dd
    z_trial = st.work[3]
    for j in range(i1.shape[0]):
        pen = un[i1[j]] - un[i2[j]] - d
        if st.scheme != SCHEME_EVENT:
            touch = z_trial[j] - d > 0.0 if st.scheme == SCHEME_PAPER else pen > 0.0
            if touch and not touching[j] and st.law == LAW_HERTZDAMP:
                # an impact started in this step: keep its v0; where the contact-free trial did not
                # close the gap (other pairs' forces did), take v0 from the step
                if alpha[j] == 0.0 and coef[j] > 0.0:
                    rate = _crossing_rate(
                        u[i1[j]] - u[i2[j]] - d, pen, (v[i1[j]] - v[i2[j]]) * dt, (vn[i1[j]] - vn[i2[j]]) * dt, dt
                    )
                    alpha[j], graze[j] = _approach(coef[j], rate, st.vmin)
                if graze[j]:
                    st.flags[0] |= L.STATUS_GRAZING
            touching[j] = touch
            if not touching[j]:
                alpha[j] = 0.0
        # the law's spring part of the force applied: in the paper's scheme that of its trial state (so a pure
        # Hertz law books no dashpot work, and what the applied spring force did on the motion against what the
        # spring stores at the end shows as the residual: the energy the explicit force made or lost)
        sp = spring_part(st.k, z_trial[j] - d if st.scheme == SCHEME_PAPER else pen) if touching[j] else 0.0
        dp = F[j] - sp if touching[j] else 0.0
        en[EN_WSP] += 0.5 * (st.Sprev[j] + sp) * (pen - st.pen_prev[j])
        en[EN_WDA] += 0.5 * (st.Dprev[j] + dp) * (pen - st.pen_prev[j])
        st.Sprev[j] = sp
        st.Dprev[j] = dp
        st.pen_prev[j] = pen
    bk.pair_pieces(st.row, L.PER_DOF * u.size, st.pen_prev, F, touching, st.was, hs, t_e, st.phases)
    for i in range(u.shape[0]):
        u[i] = un[i]
        v[i] = vn[i]
        st.a[i] = st.an[i]


@njit_inner
def _switch(st, t, ag):
    """EventOps.switch: the located switch: impacts start (Hertz-damp takes v0 here), contacts end. Every
    law here is continuous in the state, so the forces and the acceleration do not jump."""
    pr = st.pairs
    for j in range(pr.active.size):
        pr.just[j] = pr.switch[j]
        if not pr.switch[j]:
            continue
        pr.active[j] = not pr.active[j]
        st.alpha[j] = 0.0
        if pr.active[j] and st.law == LAW_HERTZDAMP:
            st.alpha[j], floored = _approach(pr.c[j], st.v[st.i1[j]] - st.v[st.i2[j]], st.vmin)
            if floored:
                st.flags[0] |= L.STATUS_GRAZING
        if not pr.active[j]:
            st.F[j] = 0.0


#: the event step's pieces in floor coordinates with the Hertz-type laws
OPS = EventOps(_advance, floors.pair, floors.tolerance, floors.finite, _accept, _switch, bisect_crossing)
_event_step, _contradicts = event_functions(OPS)


@inline_kernel
def _impact_speeds(st, z0, wrel, b1):
    """Hertz-damp outside the event scheme: an impact may start in this step; for each pair out of
    contact whose contact-free end state penetrates, v0 where that motion closes the gap."""
    u, v, d, dt = st.u, st.v, st.gap, st.dt
    for j in range(z0.size):
        if not st.pairs.active[j]:
            p, q = st.i1[j], st.i2[j]
            st.alpha[j] = 0.0
            st.graze[j] = False
            if z0[j] - d > 0.0:
                rate = _crossing_rate(u[p] - u[q] - d, z0[j] - d, (v[p] - v[q]) * dt, (b1 * z0[j] - wrel[j]) * dt, dt)
                st.alpha[j], st.graze[j] = _approach(st.pairs.c[j], rate, st.vmin)


class StepWork(NamedTuple):
    """The time loop's arrays besides the run's state."""

    u0: np.ndarray  # (N,) the contact-free end state
    rhs0: np.ndarray  # (N,) Newmark's effective load without contact
    w: np.ndarray  # (N,) 2/dt u + v
    ustep: np.ndarray  # (N,) displacement at the step start (experiment sampling)
    astep: np.ndarray  # (N,) relative acceleration at the step start (acceleration channels)
    use: np.ndarray  # (P,) bool: the pairs carrying the law in the step's contact solve
    xs: np.ndarray  # (channels, samples) the run sampled at the experiment's time stamps


@njit_inner
def _time_loop(run, model, opts, runs, records, histories, experiment, out, st, wk):
    """The run's steps from rest (st: its state, reset), as scalar._time_loop_for's: the end state of each step
    by the scheme (the contact solve, solve_pairs), its pieces (the event scheme's located impacts and
    separations), the per-step metrics, experiment samples and histories. Without Numba's reference counts
    (it allocates nothing). Returns (status bits, unsettled steps, most Newton iterations or located switches
    in a step, steps done, experiment samples filled)."""
    dt, Kinv, H, S, i1, i2, n1 = model.dt, model.Kinv, model.H, model.S, model.i1, model.i2, model.n1
    scheme = opts.scheme
    u0, rhs0, w, ustep, astep, use, xs = wk
    u, v, a, F, pr, row = st.u, st.v, st.a, st.F, st.pairs, st.row
    touching, coef, alpha, law, k, d = pr.active, pr.c, st.alpha, st.law, st.k, st.gap
    z0, wrel, zz, W = st.work[3], st.work[4], st.work[5], st.work[6]
    channels = (experiment.t, experiment.dof, experiment.kind)
    has_acc = bk.any_acceleration(experiment.kind)  # then keep the step's starting acceleration too
    hist = out.hist
    keep_hist = hist.shape[0] > 0
    P = i1.shape[0]
    b1 = 2.0 / dt
    hmin = EVENT_MIN_FRACTION * dt
    kind = runs.exc_kind[run]
    ground = Ground(kind == EXC_HARMONIC, runs.exc_amp[run], runs.exc_omega[run])
    rec_flat = records.flat
    roff, rlen, ag = bk.start_at_rest(run, runs, records, dt, u, v, a)
    if keep_hist:
        bk.keep_history(hist, run, np.int64(0), histories.kinds, histories.index, u, v, a, F, ag)
    ke_next = bk.samples_at_rest(experiment.t, xs)
    status = 0
    unsettled = 0
    ag_prev = ag
    max_it_seen = 0
    steps_done = 0
    for step in range(1, runs.nsteps[run] + 1):
        ag = ground_acceleration(kind, ground.amp, ground.omega, rec_flat, roff, rlen, step, dt)
        agstep = ag_prev  # the table's acceleration at the step start
        floors.step_start(st, ustep, astep, has_acc)
        floors.free_end(st, Kinv, ag, dt, w, rhs0, u0)
        for j in range(P):
            p, q = i1[j], i2[j]
            z0[j] = u0[p] - u0[q]
            wrel[j] = b1 * (u[p] - u[q]) + v[p] - v[q]
            use[j] = touching[j] if scheme == SCHEME_EVENT else True
        if law == LAW_HERTZDAMP and scheme != SCHEME_EVENT:
            _impact_speeds(st, z0, wrel, b1)
        if scheme == SCHEME_PAPER:
            for j in range(P):
                F[j], _, _ = law_force(law, k, coef[j], alpha[j], z0[j] - d, b1 * z0[j] - wrel[j])
        else:
            it = solve_pairs(S, z0, wrel, b1, d, (law, k, coef, alpha), use, F, zz, W)
            if it < 0:
                unsettled += 1
                it = -it
            if it > max_it_seen and scheme != SCHEME_EVENT:
                max_it_seen = it
        floors.end_state(st, u0, H, dt)
        if scheme == SCHEME_EVENT and _contradicts(st):
            finite, n_ev, uns = _event_step(st, ground, (step - 1) * dt, dt, ag_prev, ag, hmin)
            unsettled += uns
            if n_ev > max_it_seen:
                max_it_seen = n_ev
        else:
            finite = floors.finite(st)
            if finite:
                _accept(st, dt, (step - 1) * dt + dt, ag_prev, ag)
        if not finite:
            status |= L.STATUS_NONFINITE
            break
        ag_prev = ag
        t = step * dt
        ke_next = bk.sample_experiment(ke_next, channels, xs, (ustep, astep, agstep), (u, a, ag), t, dt)
        steps_done = step
        bk.floor_peaks(row, u, a, ag, t, n1)
        if keep_hist and step % histories.decimate == 0:
            bk.keep_history(hist, run, step // histories.decimate, histories.kinds, histories.index, u, v, a, F, ag)
    return status, unsettled, max_it_seen, steps_done, ke_next


def _nonlinear_kernel(scored: bool):
    """The Hertz-type kernel compiled with or without the scoring code (as scalar._batch_kernel)."""

    @njit_kernel
    def integrate_nonlinear(start, stop, model, opts, runs, records, histories, experiment, out):
        m, C, K, i1, i2 = model.m, model.C, model.K, model.i1, model.i2
        n = m.shape[0]
        P = i1.shape[0]
        u, v, a = np.empty(n), np.empty(n), np.empty(n)
        un, vn, an = np.empty(n), np.empty(n), np.empty(n)
        work = (
            np.empty((n, n)),
            np.empty((n, P + 1)),
            np.empty((P, P)),
            np.empty(P),
            np.empty(P),
            np.empty(P),
            np.empty((P, P + 6)),
        )
        F = np.zeros(P)
        alpha = np.zeros(P)
        graze = np.zeros(P, dtype=np.bool_)
        touching = np.zeros(P, dtype=np.bool_)
        flags = np.zeros(1, dtype=np.int64)
        phases = (np.zeros(P, dtype=np.bool_), np.zeros(P), np.empty((P, L.MEDIAN_BUFFER)), np.zeros(P, np.int64))
        bufs = (np.zeros(P, dtype=np.bool_), np.zeros(P), np.zeros(P), np.zeros(P))
        was, Sprev, Dprev, pen_prev = bufs
        marks = (np.zeros(P, dtype=np.bool_), np.zeros(P, dtype=np.bool_), np.empty(P))  # just, flip, thetas
        en = np.zeros(EN_N)
        Cdu = np.empty(n)
        xs = np.empty((experiment.dof.size, experiment.t.size))
        wk = StepWork(np.empty(n), np.empty(n), np.empty(n), np.empty(n), np.empty(n), np.ones(P, dtype=np.bool_), xs)
        pbase = L.PER_DOF * n
        rbase = pbase + L.PER_PAIR * P
        for run in range(start, stop):
            t_start = _clock()
            row = out.metrics[run]
            d = runs.gap[run]
            k = runs.ks[run]
            # no_tension typed, not a literal False: the event pieces the scalar kernel compiles serve this one too
            pr = Pairs(touching, marks[0], marks[1], marks[2], runs.cdash[run], 1.0, np.bool_(False))
            st = HertzState(
                m, C, K, i1, i2, d, u, v, a, un, vn, an, F, pr, runs.law[run], k, alpha, graze, opts.min_impact_speed,
                flags, opts.scheme, model.dt, was, Sprev, Dprev, pen_prev, en, row, phases, Cdu, work,
            )  # fmt: skip
            bk.start_row(row, P, pbase, d)
            bk.start_pairs(touching, F, bufs, phases, d)
            for j in range(P):
                alpha[j] = 0.0
            for q in range(EN_N):
                en[q] = 0.0
            flags[0] = 0
            status, unsettled, max_it_seen, steps_done, ke_next = _time_loop(
                run, model, opts, runs, records, histories, experiment, out, st, wk
            )
            status |= runs.status_in[run] | flags[0]
            status = bk.close_row(row, pbase, P, phases, status)
            if scored:  # a closure constant: the other variant has no scoring code
                status = bk.score_run(out.scores, run, xs, experiment, ke_next, status)
            # energy: the spring part's trapezoidal work against the energy k_h delta^2.5 / 2.5 it stores at
            # the end; their difference (the residual) is the quadrature error of the steps across impacts
            e_spring = 0.0
            for j in range(P):
                if touching[j] and pen_prev[j] > 0.0:
                    e_spring += k * pen_prev[j] ** 2.5 / 2.5
            energies = (en[EN_IN], en[EN_ABS], en[EN_DST], en[EN_WDA], e_spring, en[EN_WSP] - e_spring)
            status = bk.energy_row(row, rbase, m, K, u, v, energies, status)
            bk.run_counts(row, rbase, unsettled, max_it_seen, steps_done, status)
            out.run_time[run] = _clock() - t_start

    return integrate_nonlinear


_VARIANTS = (_nonlinear_kernel(False), _nonlinear_kernel(True))


def event_pieces() -> tuple:
    """The pieces of this kernel's step a second process can compile for it (engine/aside.py), with the argument
    types the kernel calls them with, in the order its typing reaches them: solve_pairs (from the time loop; the
    substep calls it with the same types), _advance, bookkeeping.pair_pieces (through _accept; the scalar kernel's
    event step calls it with the same types) and _switch, about 2 s of a first compile. Every scheme's: the time
    loop holds the event step whatever the scheme. The types are those of integrate_nonlinear's run state
    (HertzState, of C-contiguous arrays of the kernel's dtypes): tests/engine/test_aside.py checks that the kernel
    finds the pieces in the cache."""
    from numba import typeof, types

    phases = bk.empty_phases()
    b1, f1, f2, i1 = phases
    pr = empty_pairs()
    work = (f2, f2, f2, f1, f1, f1, f2)
    st = typeof(
        HertzState(
            f1, f2, f2, i1, i1, 0.0, f1, f1, f1, f1, f1, f1, f1, pr, 0, 0.0, f1, b1, 0.0, i1, 0, 0.0, b1, f1, f1, f1,
            f1, f1, phases, f1, work,
        )
    )  # fmt: skip
    f64, i64 = types.float64, types.int64
    tf1, tf2, tb1 = typeof(f1), typeof(f2), typeof(b1)
    law = types.Tuple((i64, f64, tf1, tf1))
    return (
        (solve_pairs, (tf2, tf1, tf1, f64, f64, law, tb1, tf1, tf1, tf2)),
        (_advance, (st, f64, f64, f64, types.boolean)),
        (bk.pair_pieces, bk.pair_pieces_signature()),
        (_switch, (st, f64, f64)),
    )


def integrate_nonlinear(start, stop, model, opts, runs, records, histories, experiment, out):
    """engine.scalar.integrate_batch for a Hertz-type law (runs.law: codes.LAW_HERTZ, LAW_HERTZDAMP,
    LAW_JANKOWSKI): runs start..stop-1 of the chunk into out (metrics, run_time, histories, scores).
    runs.ks holds k_h [N/m^1.5] and runs.cdash[run, j] the law's coefficient (hertzdamp: a; jankowski:
    c0; hertz: unused)."""
    _VARIANTS[experiment.active](start, stop, model, opts, runs, records, histories, experiment, out)
