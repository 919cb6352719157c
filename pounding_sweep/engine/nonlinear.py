"""Numba kernel for the Hertz-type contact laws: Newmark average acceleration of two shear frames with a
nonlinear pounding force, one run at a time in floor coordinates. The linear Kelvin-Voigt laws stay on
engine/scalar.py and engine/lanes.py; this kernel fills the same metric row, histories and scores
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
the instant where its penetration crosses zero is located on the real sub-step map (Illinois false
position from the step's Hermite estimate, as engine/scalar.py), the step split there and continued;
at an impact the hertzdamp law takes v0 from the located state. The law's own kinks (Jankowski's
approach/restitution switch at delta_dot = 0, Hertz-damp's clip at F = 0) are not located: the force is
continuous there, so a kink inside a step costs O(h^2) in the velocity, the scheme's order.
"paper": the forces from the trial state without contact, applied as loads (the paper's section 2).
Hertz-damp's v0 in the implicit and paper schemes is the rate where the step's contact-free Hermite
interpolant of the penetration crosses zero.
"""

from __future__ import annotations

import numpy as np

from pounding_sweep.codes import EXC_HARMONIC, EXC_RECORD, LAW_HERTZ, LAW_HERTZDAMP, SCHEME_EVENT, SCHEME_PAPER
from pounding_sweep.engine import bookkeeping as bk
from pounding_sweep.engine import layout as L
from pounding_sweep.engine.clock import _clock
from pounding_sweep.engine.events import (
    EVENT_MIN_FRACTION,
    MAX_EVENTS,
    _ag_inside,
    _illinois,
    _secant_point,
    _switch_tolerance,
    _want_contact,
    ground_acceleration,
)
from pounding_sweep.engine.jit import njit_kernel
from pounding_sweep.engine.scalar import _equilibrium_acceleration, _first_event, _indicator, gauss_solve

NEWTON_MAX = 60  # Newton iterations per contact solve before the step is kept and flagged
NEWTON_RTOL = 1e-12  # relative residual of a converged contact solve
EPS = 2.220446049250313e-16
D_MAX = 1e30  # cap on df/d(delta) [N/m]: Jankowski's dashpot has an infinite slope at first touch


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


@njit_kernel
def _residual(S, z0, wrel, q, d, law, k, coef, alpha, use, F, z, R, D, tol):
    """R = F - f(z), z = z0 - S F, D = df/dz, tol the convergence bound per pair; returns ||R||^2."""
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


@njit_kernel
def solve_pairs(S, z0, wrel, q, d, law, k, coef, alpha, use, F, z, W):
    """The end-of-step contact forces F (warm start: F as given) with z = z0 - S F: Newton on
    R = F - f(z0 - S F) with Armijo halving. Rate = q z - wrel. W: (P, P + 6) work rows.
    Returns the iterations taken, negative when NEWTON_MAX passed without convergence."""
    P = z0.shape[0]
    if P == 0:
        return 0
    J = W[:, :P]
    R = W[:, P]
    D = W[:, P + 1]
    tol = W[:, P + 2]
    dF = W[:, P + 3]
    Ft = W[:, P + 4]
    zt = W[:, P + 5]
    rr = _residual(S, z0, wrel, q, d, law, k, coef, alpha, use, F, z, R, D, tol)
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
        gauss_solve(J, dF, P, True)
        lam = 1.0
        for _ in range(40):
            for j in range(P):
                Ft[j] = F[j] + lam * dF[j]
            rt = _residual(S, z0, wrel, q, d, law, k, coef, alpha, use, Ft, zt, R, D, tol)
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


@njit_kernel
def _crossing_rate(p0, p1, m0, m1, h):
    """Rate d(delta)/dt where the step's cubic Hermite interpolant of the penetration (p0 <= 0 < p1, end
    slopes m0, m1 = rate * h) first crosses zero: Hertz-damp's approach speed in the implicit and paper
    schemes."""
    lo, hi = 0.0, 1.0
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        if _want_contact(p0, p1, m0, m1, mid, h, 0, 1.0, 0.0) > 0.0:
            hi = mid
        else:
            lo = mid
    t = hi
    t2 = t * t
    dp = (6 * t2 - 6 * t) * p0 + (3 * t2 - 4 * t + 1) * m0 + (-6 * t2 + 6 * t) * p1 + (3 * t2 - 2 * t) * m1
    return dp / h


@njit_kernel
def _approach(a_j, rate, vmin):
    """(alpha = a / v0, floored?) for an impact starting at `rate` [m/s]; v0 = max(rate, vmin)."""
    if rate >= vmin:
        return a_j / rate, False
    return a_j / vmin, True


@njit_kernel
def _substep(h, ag, u, v, a, m, C, K, i1, i2, law, k, coef, alpha, d, use, A, B, Sh, z0, wrel, z, W, un, vn, an, F):
    """One Newmark average-acceleration step of length h from (u, v, a) with the pairs in `use` carrying
    the law: (K + 2/h C + 4/h^2 M) solved for the contact-free end state and the pairs' flexibility
    (columns of B: the load, then G), the pair forces by solve_pairs, the end state u0 - H F, the
    velocity by eq. 15 and the acceleration from equilibrium. Returns solve_pairs' iteration count."""
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
    it = solve_pairs(Sh, z0, wrel, q3, d, law, k, coef, alpha, use, F, z, W)
    for i in range(n):
        s = B[i, 0]
        for j in range(P):
            s -= B[i, 1 + j] * F[j]
        un[i] = s
        vn[i] = q3 * (un[i] - u[i]) - v[i]
    _equilibrium_acceleration(ag, m, C, K, i1, i2, un, vn, F, an)
    return it


@njit_kernel
def integrate_nonlinear(start, stop, model, opts, runs, records, histories, experiment, out):
    """engine.scalar.integrate_batch for a Hertz-type law (opts.law >= codes.LAW_HERTZ): runs start..stop-1
    of the chunk into out (metrics, run_time, histories, scores). runs.ks holds k_h [N/m^1.5] and
    runs.cdash[run, j] the law's coefficient (hertzdamp: a; jankowski: c0; hertz: unused)."""
    dt, m, C, K, Kinv, H, S, i1, i2 = model
    scheme, law, vmin = opts.scheme, opts.law, opts.min_impact_speed
    ks, cdash, gap, exc_kind, exc_amp, exc_omega, rec_id, nsteps, status_in = runs
    rec_flat, rec_off, rec_len = records
    hist_kind, hist_index, decimate = histories
    exp_t, exp_dof, exp_kind = experiment.t, experiment.dof, experiment.kind
    has_acc = bk.any_acceleration(exp_kind)  # then keep the step's starting acceleration too
    metrics, run_time, hist, scores = out
    n = m.shape[0]
    P = i1.shape[0]
    keep_hist = hist.shape[0] > 0
    a1 = 4.0 / (dt * dt)
    a2 = 4.0 / dt
    b1 = 2.0 / dt
    u = np.empty(n)
    v = np.empty(n)
    a = np.empty(n)
    un = np.empty(n)
    vn = np.empty(n)
    an = np.empty(n)
    u0 = np.empty(n)
    rhs0 = np.empty(n)
    astep = np.empty(n)  # relative acceleration at the step start (acceleration channels)
    ustep = np.empty(n)
    Cdu = np.empty(n)
    A = np.empty((n, n))
    B = np.empty((n, P + 1))
    Sh = np.empty((P, P))
    z0 = np.empty(P)
    zz = np.empty(P)
    wrel = np.empty(P)
    F = np.zeros(P)
    W = np.empty((P, P + 6))
    alpha = np.zeros(P)  # Hertz-damp: a / v0 of the impact in progress
    graze = np.zeros(P, dtype=np.bool_)  # Hertz-damp: that v0 is the floor, not the approach speed
    touching = np.zeros(P, dtype=np.bool_)  # in contact (event scheme: the set; else delta > 0 at the step end)
    was = np.zeros(P, dtype=np.bool_)
    use = np.ones(P, dtype=np.bool_)
    just = np.zeros(P, dtype=np.bool_)
    flip = np.zeros(P, dtype=np.bool_)
    thetas = np.empty(P)
    in_comp = np.zeros(P, dtype=np.bool_)
    comp_acc = np.zeros(P)
    durations = np.empty((P, L.MEDIAN_BUFFER))
    nphase = np.zeros(P, dtype=np.int64)
    Sprev = np.zeros(P)
    Dprev = np.zeros(P)
    pen_prev = np.zeros(P)
    xs = np.empty((exp_dof.size, exp_t.size))
    pbase = L.PER_DOF * n
    rbase = pbase + L.PER_PAIR * P
    for run in range(start, stop):
        t_start = _clock()
        row = metrics[run]
        d = gap[run]
        k = ks[run]
        coef = cdash[run]
        bk.start_row(row, P, pbase, d)
        for j in range(P):
            touching[j] = False
            was[j] = False
            F[j] = 0.0
            alpha[j] = 0.0
            Sprev[j] = 0.0
            Dprev[j] = 0.0
            pen_prev[j] = -d
            in_comp[j] = False
            comp_acc[j] = 0.0
            nphase[j] = 0
        status = status_in[run]
        kind = exc_kind[run]
        amp = exc_amp[run]
        om = exc_omega[run]
        roff = 0
        rlen = 0
        if kind == EXC_RECORD:
            roff = rec_off[rec_id[run]]
            rlen = rec_len[rec_id[run]]
        ag = ground_acceleration(kind, amp, om, rec_flat, roff, rlen, 0, dt)
        for i in range(n):
            u[i] = 0.0
            v[i] = 0.0
            a[i] = -ag
        if keep_hist:
            bk.keep_history(hist, run, 0, hist_kind, hist_index, u, v, a, F, ag)
        ke_next = bk.samples_at_rest(exp_t, xs)
        unsettled = 0
        e_in = 0.0
        e_in_abs = 0.0
        d_struct = 0.0
        w_spring = 0.0
        w_dash = 0.0
        ag_prev = ag
        max_it_seen = 0
        steps_done = 0
        finite = True
        for step in range(1, nsteps[run] + 1):
            ag = ground_acceleration(kind, amp, om, rec_flat, roff, rlen, step, dt)
            agstep = ag_prev  # the table's acceleration at the step start
            for i in range(n):
                ustep[i] = u[i]
            if has_acc:
                for i in range(n):
                    astep[i] = a[i]
            # the contact-free end state (as engine/scalar.py: Newmark's effective load, Keff^-1)
            for i in range(n):
                s = -m[i] * ag + m[i] * (a1 * u[i] + a2 * v[i] + a[i])
                for kk in range(n):
                    s += C[i, kk] * (b1 * u[kk] + v[kk])
                rhs0[i] = s
            for i in range(n):
                s = 0.0
                for kk in range(n):
                    s += Kinv[i, kk] * rhs0[kk]
                u0[i] = s
            for j in range(P):
                p, q = i1[j], i2[j]
                z0[j] = u0[p] - u0[q]
                wrel[j] = b1 * (u[p] - u[q]) + v[p] - v[q]
                use[j] = touching[j] if scheme == SCHEME_EVENT else True
                if law == LAW_HERTZDAMP and scheme != SCHEME_EVENT and not touching[j]:
                    # an impact may start in this step: v0 where the contact-free motion closes the gap
                    alpha[j] = 0.0
                    graze[j] = False
                    if z0[j] - d > 0.0:
                        rate = _crossing_rate(
                            u[p] - u[q] - d, z0[j] - d, (v[p] - v[q]) * dt, (b1 * z0[j] - wrel[j]) * dt, dt
                        )
                        alpha[j], graze[j] = _approach(coef[j], rate, vmin)
            if scheme == SCHEME_PAPER:
                for j in range(P):
                    F[j], _, _ = law_force(law, k, coef[j], alpha[j], z0[j] - d, b1 * z0[j] - wrel[j])
            else:
                it = solve_pairs(S, z0, wrel, b1, d, law, k, coef, alpha, use, F, zz, W)
                if it < 0:
                    unsettled += 1
                    it = -it
                if it > max_it_seen and scheme != SCHEME_EVENT:
                    max_it_seen = it
            for i in range(n):
                s = u0[i]
                for j in range(P):
                    s -= H[i, j] * F[j]
                un[i] = s
                du = un[i] - u[i]
                vn[i] = b1 * du - v[i]
                an[i] = a1 * du - a2 * v[i] - a[i]
            h = dt
            t_s = (step - 1) * dt
            ag_s = ag_prev
            n_ev = 0
            for j in range(P):
                just[j] = False
            while True:  # the step, or its pieces between impacts and separations (event scheme)
                for i in range(n):
                    if not (abs(un[i]) < L.DIVERGED_M) or not (abs(an[i]) < 1e300):
                        finite = False
                if not finite:
                    break
                hs = h
                ag_e = ag
                last = True
                if scheme == SCHEME_EVENT:
                    contradicts = False
                    for j in range(P):
                        pe = un[i1[j]] - un[i2[j]] - d
                        tol = _switch_tolerance(un[i1[j]], un[i2[j]])
                        if (pe < -tol) if touching[j] else (pe > tol):
                            contradicts = True
                    if contradicts:
                        theta = _first_event(h, u, v, un, vn, touching, just, 0, 1.0, coef, d, i1, i2, P, thetas, flip)
                        if theta <= 1.0 and n_ev >= MAX_EVENTS:
                            unsettled += 1  # impacts and separations chatter: keep the trial, say so
                        elif theta <= 1.0:
                            n_ev += 1
                            last = False
                            hs = _locate(
                                theta, h, EVENT_MIN_FRACTION * dt, ag_s, ag, kind == EXC_HARMONIC, amp, om, t_s,
                                u, v, a, m, C, K, i1, i2, law, k, coef, alpha, d, touching, just,
                                A, B, Sh, z0, wrel, zz, W, un, vn, an, F, thetas, flip,
                            )  # fmt: skip
                            if hs <= EVENT_MIN_FRACTION * dt:
                                hs = 0.0
                            elif h - hs <= EVENT_MIN_FRACTION * dt:
                                hs = h
                            ag_e = _ag_inside(hs, h, ag_s, ag, kind == EXC_HARMONIC, amp, om, t_s)
                            for i in range(n):
                                if not (abs(un[i]) < L.DIVERGED_M) or not (abs(an[i]) < 1e300):
                                    finite = False
                            if not finite:
                                break
                if hs > 0.0:
                    # accept the piece [t_s, t_s + hs] (energy increments: see engine/scalar.py)
                    t_e = t_s + hs
                    de, dd = bk.structure_work(u, un, m, C, Cdu, ag_s, ag_e, hs)
                    e_in += de
                    e_in_abs += abs(de)
                    d_struct += dd
                    for j in range(P):
                        pen = un[i1[j]] - un[i2[j]] - d
                        if scheme != SCHEME_EVENT:
                            if pen > 0.0 and not touching[j] and law == LAW_HERTZDAMP:
                                # an impact started in this step: keep its v0; where the contact-free
                                # trial did not close the gap (other pairs' forces did), take v0 from the step
                                if alpha[j] == 0.0 and coef[j] > 0.0:
                                    rate = _crossing_rate(
                                        u[i1[j]] - u[i2[j]] - d, pen, (v[i1[j]] - v[i2[j]]) * dt,
                                        (vn[i1[j]] - vn[i2[j]]) * dt, dt,
                                    )  # fmt: skip
                                    alpha[j], graze[j] = _approach(coef[j], rate, vmin)
                                if graze[j]:
                                    status |= L.STATUS_GRAZING
                            touching[j] = pen > 0.0
                            if not touching[j]:
                                alpha[j] = 0.0
                        sp = spring_part(k, pen) if touching[j] else 0.0
                        dp = F[j] - sp if touching[j] else 0.0
                        w_spring += 0.5 * (Sprev[j] + sp) * (pen - pen_prev[j])
                        w_dash += 0.5 * (Dprev[j] + dp) * (pen - pen_prev[j])
                        Sprev[j] = sp
                        Dprev[j] = dp
                        pen_prev[j] = pen
                    bk.pair_pieces(
                        row, pbase, pen_prev, F, touching, was, hs, t_e, in_comp, comp_acc, durations, nphase
                    )
                    for i in range(n):
                        u[i] = un[i]
                        v[i] = vn[i]
                        a[i] = an[i]
                if last:
                    break
                t_s += hs
                h -= hs
                ag_s = ag_e
                # the located switch: impacts start (Hertz-damp takes v0 here), contacts end
                for j in range(P):
                    just[j] = flip[j]
                    if not flip[j]:
                        continue
                    touching[j] = not touching[j]
                    alpha[j] = 0.0
                    if touching[j] and law == LAW_HERTZDAMP:
                        alpha[j], floored = _approach(coef[j], v[i1[j]] - v[i2[j]], vmin)
                        if floored:
                            status |= L.STATUS_GRAZING
                    if not touching[j]:
                        F[j] = 0.0
                    use[j] = touching[j]
                if h <= 0.0:
                    break
                it = _substep(
                    h, ag, u, v, a, m, C, K, i1, i2, law, k, coef, alpha, d, touching,
                    A, B, Sh, z0, wrel, zz, W, un, vn, an, F,
                )  # fmt: skip
                if it < 0:
                    unsettled += 1
            if n_ev > max_it_seen and scheme == SCHEME_EVENT:
                max_it_seen = n_ev
            if not finite:
                status |= L.STATUS_NONFINITE
                break
            ag_prev = ag
            t = step * dt
            ke_next = bk.sample_experiment(ke_next, exp_t, exp_dof, exp_kind, xs, ustep, u, astep, agstep, a, ag, t, dt)
            steps_done = step
            bk.floor_peaks(row, u, a, ag, t, i2)
            if keep_hist and step % decimate == 0:
                bk.keep_history(hist, run, step // decimate, hist_kind, hist_index, u, v, a, F, ag)
        status = bk.close_row(row, pbase, P, in_comp, comp_acc, durations, nphase, status)
        status = bk.score_run(scores, run, xs, experiment, ke_next, status)
        # energy: the spring part's trapezoidal work against the energy k_h delta^2.5 / 2.5 it stores at
        # the end; their difference (the residual) is the quadrature error of the steps across impacts
        e_spring = 0.0
        for j in range(P):
            if touching[j] and pen_prev[j] > 0.0:
                e_spring += k * pen_prev[j] ** 2.5 / 2.5
        status = bk.energy_row(
            row, rbase, m, K, u, v, e_in, e_in_abs, d_struct, w_dash, e_spring, w_spring - e_spring, status
        )
        bk.run_counts(row, rbase, unsettled, max_it_seen, steps_done, status)
        run_time[run] = _clock() - t_start


@njit_kernel
def _locate(
    theta, h, hmin, ag_s, ag_e, harmonic, amp, om, t_s, u, v, a, m, C, K, i1, i2, law, k, coef, alpha, d,
    touching, just, A, B, Sh, z0, wrel, zz, W, un, vn, an, F, thetas, flip,
):  # fmt: skip
    """Length hs of the sub-step that ends where the first pair's penetration crosses zero (an impact of
    a pair out of contact, a separation of one in contact): Illinois false position on the real sub-step
    map from the Hermite estimate theta, as engine/scalar.py's _locate_event for the linear laws. Leaves
    the sub-step's end state in un, vn, an, F and the pairs that switch there in `flip`; 0 when the
    crossing is closer than hmin."""
    P = i1.shape[0]
    if theta * h < hmin:
        return 0.0
    target = 0
    for j in range(P):
        if thetas[j] < thetas[target]:
            target = j
    hi = h
    f_hi = _indicator(target, un, vn, touching, 0, 1.0, coef, d, i1, i2)
    h_eval = h
    for _ in range(P + 1):
        lo = 0.0
        f_lo = min(_indicator(target, u, v, touching, 0, 1.0, coef, d, i1, i2), -1e-300)
        if theta * hi < hmin:
            return 0.0
        hs = min(max(theta * hi, hmin), hi)
        side = 0
        scale = 0.0
        pp, qq = i1[target], i2[target]
        for _it in range(100):
            for j in range(P):
                F[j] = 0.0
            _substep(
                hs, _ag_inside(hs, h, ag_s, ag_e, harmonic, amp, om, t_s), u, v, a, m, C, K, i1, i2, law, k,
                coef, alpha, d, touching, A, B, Sh, z0, wrel, zz, W, un, vn, an, F,
            )  # fmt: skip
            h_eval = hs
            phi = _indicator(target, un, vn, touching, 0, 1.0, coef, d, i1, i2)
            scale = max(scale, abs(un[pp] - un[qq] - d) + abs(u[pp] - u[qq] - d))
            lo, hi, f_lo, f_hi, side = _illinois(lo, hi, f_lo, f_hi, side, hs, phi)
            if abs(phi) <= 1e-13 * scale or hi - lo <= 1e-13 * h or (hs <= hmin and phi >= 0.0):
                break
            hs = max(_secant_point(lo, hi, f_lo, f_hi), hmin)
        hs = h_eval
        _first_event(hs, u, v, un, vn, touching, just, 0, 1.0, coef, d, i1, i2, P, thetas, flip)
        earlier = -1
        for j in range(P):
            if j != target and thetas[j] < 1.0 - 1e-9 and (earlier < 0 or thetas[j] < thetas[earlier]):
                earlier = j
        if earlier < 0:
            break
        target = earlier
        theta = thetas[earlier]
        f_hi = _indicator(target, un, vn, touching, 0, 1.0, coef, d, i1, i2)
        hi = hs
    for j in range(P):
        flip[j] = j == target or thetas[j] <= 1.0
    return hs
