"""Numba kernel: Newmark average-acceleration integration of two shear frames with Kelvin-Voigt contact.

Knows nothing of TOML, Parquet or threads: it takes arrays, integrates runs [start, stop) of a
batch and writes one metric row (and optionally decimated histories) per run.

Equations (SI): M a + C v + K u + sum_j g_j F_j = -M 1 ag(t), the paper's eqs. (1)-(2) written
with the restoring sign (F_j > 0 in compression pushes building 1 back by -F_j and building 2 by
+F_j; g_j = e(1, j) - e(2, j)). Newmark gamma = 1/2, beta = 1/4 (average acceleration, the paper's
eqs. 11-16; Chopra, Dynamics of Structures, Table 5.4.2), unconditionally stable for the linear
part, second order for smooth motion, first order across an impact that falls inside a step.

Scheme "implicit": the Kelvin-Voigt forces are evaluated at the end of the step, with
the set of pairs in contact chosen so that it agrees with the end-of-step state (active-set
iteration). With Keff0 = K + 2/dt C + 4/dt^2 M and u0 the end-of-step state without contact,
the end state with active set A is u = u0 - H_A F_A, H = Keff0^-1 G, and F_A solves the small
system (S_AA + diag(1/ke_A)) F_A = z0_A - b_A / ke_A with S = G^T H, z0 = G^T u0,
ke = k_s + 2 c / dt, b = k_s d + c (2/dt g.u_n + g.v_n) (from F = k_s(g.u - d) + c g.v_{n+1}).

Scheme "paper" (section 2 of the paper): a trial step with F = 0; where a pair penetrates, F from
eq. (8) on the trial displacement and velocity is applied as a load and the step repeated once.
This is explicit in the contact force and loses stability when k_s dt^2 / m_eff is large.

Scheme "event": the step is first taken with the contact set of its start. Where a pair's state at
the end disagrees with that set (an impact, a separation, or under the no-tension law the force
reaching zero), the crossing is located on the step's cubic Hermite interpolant of the penetration
(exact here: Newmark average acceleration moves quadratically inside a step), the step is split
there, the set switched, the acceleration restored from equilibrium (the Kelvin-Voigt force jumps
by c v_rel at an impact) and the rest of the step integrated with the new set (Newmark with the
sub-step length, a fresh n x n solve). Every piece is smooth, so the scheme stays second order across
impacts (Wriggers, Computational Contact Mechanics, 2006, sec. 9.5 on event-driven integration).
"""

from __future__ import annotations

import numpy as np

from pounding_sweep.codes import EXC_HARMONIC, EXC_RECORD, SCHEME_EVENT, SCHEME_IMPLICIT, SCHEME_PAPER, SCHEMES  # noqa: F401
from pounding_sweep.engine import bookkeeping as bk
from pounding_sweep.engine import layout as L
from pounding_sweep.engine.clock import _clock
from pounding_sweep.engine.events import (
    EVENT_MIN_FRACTION,
    MAX_EVENTS,
    _ag_inside,
    _force_extremes,
    _illinois,  # noqa: F401
    _secant_point,
    _switch_tolerance,
    _want_contact,
    ground_acceleration,
)
from pounding_sweep.engine.jit import njit_kernel

# energy accumulator changed by _switch: the spring energy lost when a no-tension contact lets go while
# compressed (less what it stores again when it re-engages overlapped)
EN_W_RELEASE = 0
EN_N = 1


@njit_kernel
def gauss_solve(A, b, n, pivot):
    """Solve A[:n,:n] x = b[:n] in place by Gaussian elimination; with `pivot`, partial pivoting (the Hertz-type
    laws' Newton Jacobian I + D S is not symmetric); without, none (A symmetric positive definite)."""
    for k in range(n):
        if pivot:
            p = k
            for i in range(k + 1, n):
                if abs(A[i, k]) > abs(A[p, k]):
                    p = i
            if p != k:
                for j in range(n):
                    A[k, j], A[p, j] = A[p, j], A[k, j]
                b[k], b[p] = b[p], b[k]
        piv = A[k, k]
        for i in range(k + 1, n):
            f = A[i, k] / piv
            for j in range(k, n):
                A[i, j] -= f * A[k, j]
            b[i] -= f * b[k]
    for i in range(n - 1, -1, -1):
        s = b[i]
        for j in range(i + 1, n):
            s -= A[i, j] * b[j]
        b[i] = s / A[i, i]


@njit_kernel
def _contact_forces(S, z0, bb, ke, active, n_pairs, idx, Asmall, rhs, F):
    """Forces of the pairs in `active` (others 0) for the implicit step: gauss_solve, symmetric positive definite."""
    na = 0
    for j in range(n_pairs):
        F[j] = 0.0
        if active[j]:
            idx[na] = j
            na += 1
    if na == 0:
        return
    for p in range(na):
        jp = idx[p]
        for q in range(na):
            Asmall[p, q] = S[jp, idx[q]]
        Asmall[p, p] += 1.0 / ke[jp]
        rhs[p] = z0[jp] - bb[jp] / ke[jp]
    gauss_solve(Asmall, rhs, na, False)
    for p in range(na):
        F[idx[p]] = rhs[p]


@njit_kernel
def integrate_batch(start, stop, model, opts, runs, records, histories, experiment, out):
    """Integrate runs start..stop-1 of the chunk: fill out.metrics[run] (engine/layout.py), out.run_time[run],
    the histories out.hist[run] when histories.kinds is not empty, and, when experiment.dof is not empty,
    out.scores[run, channel, :] (engine/score.py).

    Records (engine/inputs.py): model Structure, opts KernelOptions, runs RunArrays, records Records,
    histories HistorySpec, experiment ScoreSpec, out Outputs."""
    dt, m, C, K, Kinv, H, S, i1, i2 = model
    scheme, law, max_iter = opts.scheme, opts.law, opts.max_iter
    ks, cdash, gap, exc_kind, exc_amp, exc_omega, rec_id, nsteps, status_in = runs
    rec_flat, rec_off, rec_len = records
    hist_kind, hist_index, decimate = histories
    exp_t, exp_dof, exp_kind = experiment.t, experiment.dof, experiment.kind
    has_acc = bk.any_acceleration(exp_kind)  # then keep the step's starting acceleration too
    metrics, run_time, hist, scores = out
    n = m.shape[0]
    npair = i1.shape[0]
    keep_hist = hist.shape[0] > 0
    a1 = 4.0 / (dt * dt)
    a2 = 4.0 / dt
    b1 = 2.0 / dt
    # work arrays, allocated once per batch (never inside the time loop)
    u = np.empty(n)
    v = np.empty(n)
    a = np.empty(n)
    un = np.empty(n)
    vn = np.empty(n)
    an = np.empty(n)
    w = np.empty(n)
    rhs0 = np.empty(n)
    u0 = np.empty(n)
    z0 = np.empty(npair)
    wrel = np.empty(npair)
    bb = np.empty(npair)
    ke = np.empty(npair)
    F = np.empty(npair)
    Fprev = np.empty(npair)
    active = np.zeros(npair, dtype=np.bool_)
    trial = np.zeros(npair, dtype=np.bool_)
    prev = np.zeros(npair, dtype=np.bool_)
    was_active = np.zeros(npair, dtype=np.bool_)
    in_comp = np.zeros(npair, dtype=np.bool_)
    comp_acc = np.zeros(npair)  # duration of the compressive phase in progress
    idx = np.empty(npair, dtype=np.int64)
    Asmall = np.empty((npair, npair))
    rsmall = np.empty(npair)
    durations = np.empty((npair, L.MEDIAN_BUFFER))
    nphase = np.zeros(npair, dtype=np.int64)
    seen = np.zeros(max_iter + 1, dtype=np.int64)
    Sprev = np.zeros(npair)  # spring and dashpot parts of F at the step start (energy bookkeeping)
    Dprev = np.zeros(npair)
    pen_prev = np.zeros(npair)
    Cdu = np.empty(n)
    astep = np.empty(n)  # relative acceleration at the step start (acceleration channels)
    ustep = np.empty(n)  # state at the step start (experiment sampling)
    just = np.zeros(npair, dtype=np.bool_)  # pairs switched at the event just handled
    thetas = np.empty(npair)
    Amat = np.empty((n, n))
    rvec = np.empty(n)
    en = np.zeros(EN_N)  # energy accumulators (EN_*)
    xs = np.empty((exp_dof.size, exp_t.size))  # the run sampled at the experiment's time stamps
    pbase = L.PER_DOF * n
    rbase = pbase + L.PER_PAIR * npair

    for run in range(start, stop):
        t_start = _clock()
        out = metrics[run]
        bk.start_row(out, npair, pbase, gap[run])
        for j in range(npair):
            active[j] = False
            was_active[j] = False
            F[j] = 0.0
            Sprev[j] = 0.0
            Dprev[j] = 0.0
            pen_prev[j] = -gap[run]  # at rest the pair is `gap` apart
            in_comp[j] = False
            comp_acc[j] = 0.0
            nphase[j] = 0
            Fprev[j] = 0.0
        status = status_in[run]
        k_s = ks[run]
        d = gap[run]
        kind = exc_kind[run]
        amp = exc_amp[run]
        om = exc_omega[run]
        roff = 0
        rlen = 0
        if kind == EXC_RECORD:
            roff = rec_off[rec_id[run]]
            rlen = rec_len[rec_id[run]]
        for j in range(npair):
            ke[j] = k_s + b1 * cdash[run, j]
        # initial state: at rest relative to the table; eq. (11): a0 = M^-1 (p0 - C v0 - K u0) = -ag(0)
        ag = ground_acceleration(kind, amp, om, rec_flat, roff, rlen, 0, dt)
        for i in range(n):
            u[i] = 0.0
            v[i] = 0.0
            a[i] = -ag
        if keep_hist:
            bk.keep_history(hist, run, 0, hist_kind, hist_index, u, v, a, F, ag)
        nst = nsteps[run]
        ke_next = bk.samples_at_rest(exp_t, xs)  # next experiment sample to fill
        unsettled = 0
        e_in = 0.0
        e_in_abs = 0.0
        d_struct = 0.0
        w_spring = 0.0
        w_dash = 0.0
        en[EN_W_RELEASE] = 0.0  # also changed by _switch
        ag_prev = ag
        max_it_seen = 0
        steps_done = 0
        for step in range(1, nst + 1):
            ag = ground_acceleration(kind, amp, om, rec_flat, roff, rlen, step, dt)
            agstep = ag_prev  # the table's acceleration at the step start
            for i in range(n):
                ustep[i] = u[i]
            if has_acc:
                for i in range(n):
                    astep[i] = a[i]
            # Newmark effective load without contact (Chopra Table 5.4.2; paper eq. 13)
            for i in range(n):
                w[i] = b1 * u[i] + v[i]
            for i in range(n):
                s = -m[i] * ag + m[i] * (a1 * u[i] + a2 * v[i] + a[i])
                for k in range(n):
                    s += C[i, k] * w[k]
                rhs0[i] = s
            for i in range(n):
                s = 0.0
                for k in range(n):
                    s += Kinv[i, k] * rhs0[k]
                u0[i] = s
            for j in range(npair):
                z0[j] = u0[i1[j]] - u0[i2[j]]
                wrel[j] = w[i1[j]] - w[i2[j]]
                bb[j] = k_s * d + cdash[run, j] * wrel[j]
            if scheme == SCHEME_IMPLICIT:
                it = 0
                settled = False
                cycled = False
                while it < max_iter and not cycled:
                    seen[it] = _mask(active, npair)
                    it += 1
                    _contact_forces(S, z0, bb, ke, active, npair, idx, Asmall, rsmall, F)
                    changed = False
                    for j in range(npair):
                        z = z0[j]
                        for l in range(npair):
                            z -= S[j, l] * F[l]
                        pen = z - d
                        want = pen > 0.0
                        if want and law == 1:  # no tension: contact only while it pushes
                            want = (ke[j] * z - bb[j]) > 0.0
                        trial[j] = want
                        if want != active[j]:
                            changed = True
                    if not changed:
                        settled = True
                        break
                    for j in range(npair):
                        prev[j] = active[j]
                        active[j] = trial[j]
                    # a set already tried means the iteration cycles: stop early
                    mk = _mask(active, npair)
                    for q in range(it):
                        if seen[q] == mk and npair <= 62:
                            cycled = True
                if it > max_it_seen:
                    max_it_seen = it
                if not settled:
                    # the active set cycles (an impact inside the step under the classic law): keep
                    # every pair the last two sets disagree on in contact, solve once more, count it
                    unsettled += 1
                    for j in range(npair):
                        active[j] = prev[j] or trial[j]
                    _contact_forces(S, z0, bb, ke, active, npair, idx, Asmall, rsmall, F)
            elif scheme == SCHEME_PAPER:
                # paper's scheme: contact force from the trial (F = 0) state, applied as a load
                for j in range(npair):
                    F[j] = 0.0
                    pen = z0[j] - d
                    active[j] = False
                    if pen > 0.0:
                        vrel = b1 * z0[j] - wrel[j]
                        f = k_s * pen + cdash[run, j] * vrel
                        if law == 1 and f <= 0.0:
                            continue  # no tension: no contact while the element would pull
                        F[j] = f
                        active[j] = True
            else:
                # event scheme: the whole step with the contact set of its start; a pair whose state
                # disagrees with that set at the end is an event inside the step, handled below
                _contact_forces(S, z0, bb, ke, active, npair, idx, Asmall, rsmall, F)
            # end-of-step state u = u0 - H F, then Newmark velocity and acceleration (eqs. 15-16)
            for i in range(n):
                s = u0[i]
                for j in range(npair):
                    s -= H[i, j] * F[j]
                un[i] = s
            for i in range(n):
                du = un[i] - u[i]
                vn[i] = b1 * du - v[i]
                an[i] = a1 * du - a2 * v[i] - a[i]
            h = dt  # what is left of the step
            t_s = (step - 1) * dt
            ag_s = ag_prev
            n_ev = 0
            for j in range(npair):
                just[j] = False
            while True:  # the step, or its pieces between contact events (event scheme)
                finite = True
                for i in range(n):
                    if not (abs(un[i]) < L.DIVERGED_M) or not (abs(an[i]) < 1e300):
                        finite = False
                if not finite:
                    break
                hs = h  # the piece to accept now
                ag_e = ag
                last = True
                if scheme == SCHEME_EVENT:
                    # a pair whose end state contradicts the set means an event inside the piece
                    contradicts = False
                    for j in range(npair):
                        pe = un[i1[j]] - un[i2[j]] - d
                        if law == 1 and pe > 0.0:
                            pe = min(pe, pe + (cdash[run, j] / k_s) * (vn[i1[j]] - vn[i2[j]]))
                        tol = _switch_tolerance(un[i1[j]], un[i2[j]])
                        if (pe < -tol) if active[j] else (pe > tol):
                            contradicts = True
                    if contradicts:
                        theta = _first_event(
                            h, u, v, un, vn, active, just, law, k_s, cdash[run], d, i1, i2, npair, thetas, trial
                        )
                        if theta <= 1.0 and n_ev >= MAX_EVENTS:
                            unsettled += 1  # events chatter: keep the last trial, say so
                        elif theta <= 1.0:
                            n_ev += 1
                            last = False
                            hs = _locate_event(
                                theta,
                                h,
                                EVENT_MIN_FRACTION * dt,
                                ag_s,
                                ag,
                                kind == EXC_HARMONIC,
                                amp,
                                om,
                                t_s,
                                u,
                                v,
                                a,
                                m,
                                C,
                                K,
                                i1,
                                i2,
                                active,
                                just,
                                law,
                                k_s,
                                cdash[run],
                                d,
                                Amat,
                                rvec,
                                un,
                                vn,
                                an,
                                F,
                                thetas,
                                trial,
                            )
                            if hs <= EVENT_MIN_FRACTION * dt:
                                hs = 0.0  # switch at the start of what is left
                            elif h - hs <= EVENT_MIN_FRACTION * dt:
                                hs = h
                            ag_e = _ag_inside(hs, h, ag_s, ag, kind == EXC_HARMONIC, amp, om, t_s)
                            for i in range(n):
                                if not (abs(un[i]) < L.DIVERGED_M) or not (abs(an[i]) < 1e300):
                                    finite = False
                            if not finite:
                                break
                if hs > 0.0:
                    # accept the piece [t_s, t_s + hs]: energy increments, exact for Newmark average
                    # acceleration (trapezoidal work with du = hs (v_n + v_n+1) / 2): input -du.M1 ag,
                    # structural damping du.C du / hs, the work of the contact's spring and dashpot
                    # parts on the pair's relative displacement; then the contact metrics
                    t_e = t_s + hs
                    de, dd = bk.structure_work(u, un, m, C, Cdu, ag_s, ag_e, hs)
                    e_in += de
                    e_in_abs += abs(de)
                    d_struct += dd
                    for j in range(npair):
                        pen = un[i1[j]] - un[i2[j]] - d
                        sp = k_s * pen if active[j] else 0.0
                        dp = F[j] - sp if active[j] else 0.0
                        w_spring += 0.5 * (Sprev[j] + sp) * (pen - pen_prev[j])
                        w_dash += 0.5 * (Dprev[j] + dp) * (pen - pen_prev[j])
                        if was_active[j] and not active[j] and pen > 0.0:
                            # released while still compressed (no-tension law): the spring's energy is
                            # lost to the contact, a physical dissipation, not a numerical residual
                            en[EN_W_RELEASE] += 0.5 * k_s * pen * pen
                        Sprev[j] = sp
                        Dprev[j] = dp
                        pen_prev[j] = pen
                    bk.pair_pieces(
                        out, pbase, pen_prev, F, active, was_active, hs, t_e, in_comp, comp_acc, durations, nphase
                    )
                    for i in range(n):
                        u[i] = un[i]
                        v[i] = vn[i]
                        a[i] = an[i]
                if last:
                    h = 0.0
                    break
                t_s += hs
                h -= hs
                ag_s = ag_e
                _switch(
                    trial,
                    t_s,
                    ag_s,
                    n,
                    npair,
                    m,
                    C,
                    K,
                    i1,
                    i2,
                    k_s,
                    cdash[run],
                    d,
                    u,
                    v,
                    a,
                    F,
                    active,
                    was_active,
                    just,
                    Sprev,
                    Dprev,
                    en,
                    out,
                    pbase,
                )
                if h <= 0.0:
                    break
                _fixed_set_step(h, ag, u, v, a, m, C, K, i1, i2, active, k_s, cdash[run], d, Amat, rvec, un, vn, an, F)
            if n_ev > max_it_seen and scheme == SCHEME_EVENT:
                max_it_seen = n_ev
            if not finite:
                status |= L.STATUS_NONFINITE
                break
            ag_prev = ag
            t = step * dt
            if ke_next < exp_t.size:
                ke_next = bk.sample_experiment(
                    ke_next, exp_t, exp_dof, exp_kind, xs, ustep, u, astep, agstep, a, ag, t, dt
                )
            steps_done = step
            bk.floor_peaks(out, u, a, ag, t, i2)
            if keep_hist and step % decimate == 0:
                bk.keep_history(hist, run, step // decimate, hist_kind, hist_index, u, v, a, F, ag)
        status = bk.close_row(out, pbase, npair, in_comp, comp_acc, durations, nphase, status)
        status = bk.score_run(scores, run, xs, experiment, ke_next, status)
        # energy balance at the end: E_in = KE + SE + D_struct + D_contact + E_spring + residual;
        # the residual is the spring work the discrete contact switching did not store
        e_spring = 0.0
        for j in range(npair):
            if active[j]:
                e_spring += 0.5 * k_s * pen_prev[j] * pen_prev[j]
        residual = w_spring - e_spring - en[EN_W_RELEASE]
        status = bk.energy_row(
            out, rbase, m, K, u, v, e_in, e_in_abs, d_struct, w_dash + en[EN_W_RELEASE], e_spring, residual, status
        )
        bk.run_counts(out, rbase, unsettled, max_it_seen, steps_done, status)
        run_time[run] = _clock() - t_start


@njit_kernel
def _fixed_set_step(h, ag, u, v, a, m, C, K, i1, i2, active, k_s, c, d, A, r, un, vn, an, F):
    """One Newmark average-acceleration step of length h with the pairs in `active` in contact.

    (K + 2/h C + 4/h^2 M + sum_A ke g g^T) u_n+1 = p_hat + sum_A b g, with ke = k_s + 2 c / h and
    b = k_s d + c (2/h g.u_n + g.v_n) from F = k_s (g.u_n+1 - d) + c g.v_n+1 (eq. 8) and eq. 15."""
    n = m.shape[0]
    q1 = 4.0 / (h * h)
    q2 = 4.0 / h
    q3 = 2.0 / h
    for i in range(n):
        s = -m[i] * ag + m[i] * (q1 * u[i] + q2 * v[i] + a[i])
        for k in range(n):
            A[i, k] = K[i, k] + q3 * C[i, k]
            s += C[i, k] * (q3 * u[k] + v[k])
        A[i, i] += q1 * m[i]
        r[i] = s
    for j in range(i1.shape[0]):
        if active[j]:
            p, q = i1[j], i2[j]
            kej = k_s + q3 * c[j]
            bj = k_s * d + c[j] * (q3 * (u[p] - u[q]) + v[p] - v[q])
            A[p, p] += kej
            A[q, q] += kej
            A[p, q] -= kej
            A[q, p] -= kej
            r[p] += bj
            r[q] -= bj
    gauss_solve(A, r, n, False)
    for i in range(n):
        un[i] = r[i]
        vn[i] = q3 * (un[i] - u[i]) - v[i]
    for j in range(i1.shape[0]):
        F[j] = 0.0
        if active[j]:
            p, q = i1[j], i2[j]
            F[j] = k_s * (un[p] - un[q] - d) + c[j] * (vn[p] - vn[q])
    # the end acceleration from equilibrium, equal to Newmark's 4/h^2 du - 4/h v - a in exact
    # arithmetic but free of its 1/h^2 rounding amplification on short sub-steps
    _equilibrium_acceleration(ag, m, C, K, i1, i2, un, vn, F, an)


@njit_kernel
def _first_event(h, u, v, un, vn, active, just, law, k_s, c, d, i1, i2, npair, thetas, switch):
    """Fraction of the step (0..1] at which the first pair leaves its contact state, or 2.0 if none
    does; marks in `switch` the pairs whose switch falls there (bisection on the indicator)."""
    first = 2.0
    for j in range(npair):
        thetas[j] = 2.0
        p, q = i1[j], i2[j]
        p0 = u[p] - u[q] - d
        p1 = un[p] - un[q] - d
        m0 = (v[p] - v[q]) * h
        m1 = (vn[p] - vn[q]) * h
        sign = -1.0 if active[j] else 1.0  # phi > 0: the state contradicts the set
        if sign * _want_contact(p0, p1, m0, m1, 1.0, h, law, k_s, c[j]) <= _switch_tolerance(un[p], un[q]):
            continue
        if not just[j] and sign * _want_contact(p0, p1, m0, m1, 0.0, h, law, k_s, c[j]) >= 0.0:
            thetas[j] = 0.0  # already contradicts at the start
        else:
            lo, hi = 0.0, 1.0
            for _ in range(60):
                mid = 0.5 * (lo + hi)
                if sign * _want_contact(p0, p1, m0, m1, mid, h, law, k_s, c[j]) >= 0.0:
                    hi = mid
                else:
                    lo = mid
            thetas[j] = hi
        if thetas[j] < first:
            first = thetas[j]
    for j in range(npair):
        switch[j] = thetas[j] <= first + 1e-9
    return first


@njit_kernel
def _indicator(j, u, v, active, law, k_s, c, d, i1, i2):
    """The contact indicator of pair j in the state (u, v), signed so that >= 0 contradicts `active`."""
    p, q = i1[j], i2[j]
    pen = u[p] - u[q] - d
    want = pen
    if law == 1:
        want = min(pen, pen + (c[j] / k_s) * (v[p] - v[q]))
    return -want if active[j] else want


@njit_kernel
def _locate_event(
    theta,
    h,
    hmin,
    ag_s,
    ag_e,
    harmonic,
    amp,
    om,
    t_s,
    u,
    v,
    a,
    m,
    C,
    K,
    i1,
    i2,
    active,
    just,
    law,
    k_s,
    c,
    d,
    A,
    r,
    un,
    vn,
    an,
    F,
    thetas,
    switch,
):
    """Length hs (0 <= hs <= h) of the sub-step that ends where the first pair switches.

    The interpolant's estimate (theta) starts a safeguarded false-position search (Illinois) on
    the indicator after a real Newmark sub-step of length hs, so the switch happens where the
    discrete motion crosses (penetration 0, or no-tension force 0) and the contact springs store or
    return no energy there. A pair that crosses earlier inside the accepted sub-step takes over.
    Leaves the sub-step's end state in un, vn, an, F and the pairs to switch in `switch`; 0 (switch at
    the start) when the crossing is closer than hmin."""
    npair = i1.shape[0]
    if theta * h < hmin:
        return 0.0
    target = 0
    for j in range(npair):
        if thetas[j] < thetas[target]:
            target = j
    hi = h
    f_hi = _indicator(target, un, vn, active, law, k_s, c, d, i1, i2)  # the trial over h contradicts
    for _ in range(npair + 1):
        lo = 0.0
        f_lo = min(_indicator(target, u, v, active, law, k_s, c, d, i1, i2), -1e-300)  # agrees at the start
        if theta * hi < hmin:
            return 0.0  # a sub-step this short only amplifies rounding (the solve scales as 1/h^2)
        hs = min(max(theta * hi, hmin), hi)
        side = 0
        scale = 0.0
        pp, qq = i1[target], i2[target]
        for _it in range(100):
            _fixed_set_step(
                hs,
                _ag_inside(hs, h, ag_s, ag_e, harmonic, amp, om, t_s),
                u,
                v,
                a,
                m,
                C,
                K,
                i1,
                i2,
                active,
                k_s,
                c,
                d,
                A,
                r,
                un,
                vn,
                an,
                F,
            )
            h_eval = hs
            phi = _indicator(target, un, vn, active, law, k_s, c, d, i1, i2)
            scale = max(scale, abs(un[pp] - un[qq] - d) + abs(u[pp] - u[qq] - d))
            lo, hi, f_lo, f_hi, side = _illinois(lo, hi, f_lo, f_hi, side, hs, phi)
            if abs(phi) <= 1e-13 * scale or hi - lo <= 1e-13 * h or (hs <= hmin and phi >= 0.0):
                break
            hs = max(_secant_point(lo, hi, f_lo, f_hi), hmin)
        hs = h_eval  # the sub-step whose end state is in un, vn, an, F
        # does another pair switch inside this sub-step, before it ends?
        _first_event(hs, u, v, un, vn, active, just, law, k_s, c, d, i1, i2, npair, thetas, switch)
        earlier = -1
        for j in range(npair):
            if j != target and thetas[j] < 1.0 - 1e-9 and (earlier < 0 or thetas[j] < thetas[earlier]):
                earlier = j
        if earlier < 0:
            break
        target = earlier
        theta = thetas[earlier]
        f_hi = _indicator(target, un, vn, active, law, k_s, c, d, i1, i2)
        hi = hs
    for j in range(npair):
        switch[j] = j == target or thetas[j] <= 1.0  # the target, and pairs crossing with it
    return hs


@njit_kernel
def _switch(
    switch,
    t,
    ag,
    n,
    npair,
    m,
    C,
    K,
    i1,
    i2,
    k_s,
    c,
    d,
    u,
    v,
    a,
    F,
    active,
    was_active,
    just,
    Sprev,
    Dprev,
    en,
    out,
    pbase,
):
    """Switch the contact state of the pairs in `switch` at an event (time t); restore the
    acceleration from equilibrium, M a = -M 1 ag - C v - K u - G F (eqs. 1-2), since the
    Kelvin-Voigt force jumps there (by c v_rel at an impact)."""
    for j in range(npair):
        just[j] = switch[j]
        if not switch[j]:
            continue
        p, q = i1[j], i2[j]
        pen = u[p] - u[q] - d
        base = pbase + L.PER_PAIR * j
        if active[j]:
            active[j] = False
            if pen > 0.0:
                en[EN_W_RELEASE] += 0.5 * k_s * pen * pen
            F[j] = 0.0
            Sprev[j] = 0.0
            Dprev[j] = 0.0
        else:
            active[j] = True
            if pen > 0.0:
                # a no-tension contact re-engaging while still overlapped (its force is zero here):
                # the spring energy booked as lost at its release is stored again
                en[EN_W_RELEASE] -= 0.5 * k_s * pen * pen
            out[base + L.PAIR_IMPACTS] += 1.0
            F[j] = k_s * pen + c[j] * (v[p] - v[q])
            Sprev[j] = k_s * pen
            Dprev[j] = F[j] - Sprev[j]
            _force_extremes(out, base, F[j], t)
        was_active[j] = active[j]
    for j in range(npair):  # every force from the Kelvin-Voigt law at this instant (eq. 8)
        p, q = i1[j], i2[j]
        F[j] = k_s * (u[p] - u[q] - d) + c[j] * (v[p] - v[q]) if active[j] else 0.0
    _equilibrium_acceleration(ag, m, C, K, i1, i2, u, v, F, a)


@njit_kernel
def _equilibrium_acceleration(ag, m, C, K, i1, i2, u, v, F, a):
    """a = M^-1 (-M 1 ag - C v - K u - G F), the equations of motion (eqs. 1-2, restoring sign)."""
    n = m.shape[0]
    for i in range(n):
        s = -m[i] * ag
        for k in range(n):
            s -= C[i, k] * v[k] + K[i, k] * u[k]
        a[i] = s
    for j in range(i1.shape[0]):
        a[i1[j]] -= F[j]
        a[i2[j]] += F[j]
    for i in range(n):
        a[i] /= m[i]


@njit_kernel
def _mask(active, npair):
    """Active set as a bit mask (meaningful for up to 62 pairs; only used to spot cycles)."""
    mk = 0
    for j in range(min(npair, 62)):
        if active[j]:
            mk |= 1 << j
    return mk
