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
When no set agrees with its end state (the iteration cycles: an impact inside the step under the
classic law), the step is taken as the event scheme below takes it, from the start's set.

Scheme "paper" (section 2 of the paper): a trial step with F = 0; where a pair penetrates, F from
eq. (8) on the trial displacement and velocity is applied as a load and the step repeated once.
This is explicit in the contact force and loses stability when k_s dt^2 / m_eff is large.

Scheme "event" (engine/events.py, the step written once for every kernel): the step is first taken
with the contact set of its start. Where a pair's state at the end disagrees with that set (an
impact, a separation, or under the no-tension law the force reaching zero), the crossing is located
(on the step's cubic Hermite interpolant of the penetration, exact here: Newmark average acceleration
moves quadratically inside a step, then on real sub-steps), the step is split there, the set
switched, the acceleration restored from equilibrium (the Kelvin-Voigt force jumps by c v_rel at an
impact) and the rest of the step integrated with the new set (Newmark with the sub-step length, a
fresh n x n solve: _advance). Every piece is smooth, so the scheme stays second order across impacts
(Wriggers, Computational Contact Mechanics, 2006, sec. 9.5 on event-driven integration).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from pounding_sweep.codes import EXC_HARMONIC, LAW_NO_TENSION, SCHEME_EVENT, SCHEME_IMPLICIT, SCHEME_PAPER, SCHEMES
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
)
from pounding_sweep.engine.jit import inline_kernel, njit_inner, njit_kernel

# energy accumulators of a run (LinearState.en): input work and its absolute sum, structural damping, the
# contact spring's and dashpot's work, and the spring energy lost when a no-tension contact lets go while
# compressed (less what it stores again when it re-engages overlapped)
EN_IN, EN_ABS, EN_DST, EN_WSP, EN_WDA, EN_WREL = range(6)
EN_N = 6


class LinearState(NamedTuple):
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
    pairs: Pairs  # contact set, switch marks, the no-tension indicator's k_s and c
    was_active: np.ndarray  # (P,) in contact over the last accepted piece
    Sprev: np.ndarray  # (P,) spring and dashpot parts of F at the start of the piece (energy book-keeping)
    Dprev: np.ndarray
    pen_prev: np.ndarray  # (P,) penetration at the start of the piece
    en: np.ndarray  # (EN_N,) energy accumulators
    row: np.ndarray  # the run's metric row (engine/layout.py)
    phases: tuple  # (in_comp, comp_acc, durations, nphase): compressive phases (bookkeeping.pair_pieces)
    Cdu: np.ndarray  # (N,) work: C du
    A: np.ndarray  # (N, N) work: the sub-step's matrix
    r: np.ndarray  # (N,) work: its right-hand side


@njit_inner
def _contact_forces(S, z0, bb, ke, active, idx, Asmall, rhs, F):
    """Forces of the pairs in `active` (others 0) for the implicit step: (S_AA + diag(1/ke_A)) F_A =
    z0_A - b_A / ke_A by floors.gauss_solve, symmetric positive definite."""
    na = np.int64(0)  # typed, not a literal 0: gauss_solve compiles once (events.AT_END says why)
    for j in range(active.size):
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
    floors.gauss_solve(Asmall, rhs, na, floors.NO_PIVOT)
    for p in range(na):
        F[idx[p]] = rhs[p]


@njit_inner
def _advance(st, h, ag_s, ag_e, cold):
    """EventOps.advance: one Newmark average-acceleration step of length h from (u, v, a) with the pairs
    in contact carrying the Kelvin-Voigt law, end state in (un, vn, an, F); returns 0 (a direct solve).

    (K + 2/h C + 4/h^2 M + sum_A ke g g^T) u_n+1 = p_hat + sum_A b g, with ke = k_s + 2 c / h and
    b = k_s d + c (2/h g.u_n + g.v_n) from F = k_s (g.u_n+1 - d) + c g.v_n+1 (eq. 8) and eq. 15.
    ag_s enters through a (the start's equilibrium); cold is for solves that iterate (engine/nonlinear.py)."""
    m, C, K, i1, i2, d = st.m, st.C, st.K, st.i1, st.i2, st.gap
    u, v, a, un, vn, an, F, A, r = st.u, st.v, st.a, st.un, st.vn, st.an, st.F, st.A, st.r
    active, k_s, c = st.pairs.active, st.pairs.k_s, st.pairs.c
    n = m.shape[0]
    q1 = 4.0 / (h * h)
    q2 = 4.0 / h
    q3 = 2.0 / h
    for i in range(n):
        s = -m[i] * ag_e + m[i] * (q1 * u[i] + q2 * v[i] + a[i])
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
    floors.gauss_solve(A, r, n, floors.NO_PIVOT)
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
    floors.equilibrium_acceleration(st, ag_e, un, vn, F, an)
    return 0


@inline_kernel
def _accept(st, hs, t_e, ag_s, ag_e):
    """EventOps.accept: book the piece [t_e - hs, t_e] and make its end the start. Energy increments, exact
    for Newmark average acceleration (trapezoidal work with du = hs (v_n + v_n+1) / 2): input -du.M1 ag,
    structural damping du.C du / hs, the work of the contact's spring and dashpot parts on the pair's
    relative displacement; then the contact metrics (bookkeeping.pair_pieces)."""
    u, un, i1, i2, d, F, en = st.u, st.un, st.i1, st.i2, st.gap, st.F, st.en
    active, k_s = st.pairs.active, st.pairs.k_s
    de, dd = bk.structure_work(u, un, st.m, st.C, st.Cdu, ag_s, ag_e, hs)
    en[EN_IN] += de
    en[EN_ABS] += abs(de)
    en[EN_DST] += dd
    for j in range(i1.shape[0]):
        pen = un[i1[j]] - un[i2[j]] - d
        sp = k_s * pen if active[j] else 0.0
        dp = F[j] - sp if active[j] else 0.0
        en[EN_WSP] += 0.5 * (st.Sprev[j] + sp) * (pen - st.pen_prev[j])
        en[EN_WDA] += 0.5 * (st.Dprev[j] + dp) * (pen - st.pen_prev[j])
        if st.was_active[j] and not active[j] and pen > 0.0:
            # released while still compressed (no-tension law): the spring's energy is lost to the
            # contact, a physical dissipation, not a numerical residual
            en[EN_WREL] += 0.5 * k_s * pen * pen
        st.Sprev[j] = sp
        st.Dprev[j] = dp
        st.pen_prev[j] = pen
    bk.pair_pieces(st.row, L.PER_DOF * u.size, st.pen_prev, F, active, st.was_active, hs, t_e, st.phases)
    for i in range(u.shape[0]):
        u[i] = un[i]
        st.v[i] = st.vn[i]
        st.a[i] = st.an[i]


@njit_inner
def _switch(st, t, ag):
    """EventOps.switch: switch the contact state of the pairs marked at an event (time t); restore the
    acceleration from equilibrium, M a = -M 1 ag - C v - K u - G F (eqs. 1-2), since the Kelvin-Voigt
    force jumps there (by c v_rel at an impact)."""
    pr = st.pairs
    u, v, F, i1, i2, d, k_s, c = st.u, st.v, st.F, st.i1, st.i2, st.gap, pr.k_s, pr.c
    pbase = L.PER_DOF * u.size
    for j in range(i1.shape[0]):
        pr.just[j] = pr.switch[j]
        if not pr.switch[j]:
            continue
        p, q = i1[j], i2[j]
        pen = u[p] - u[q] - d
        base = pbase + L.PER_PAIR * j
        if pr.active[j]:
            pr.active[j] = False
            if pen > 0.0:
                st.en[EN_WREL] += 0.5 * k_s * pen * pen
            F[j] = 0.0
            st.Sprev[j] = 0.0
            st.Dprev[j] = 0.0
        else:
            pr.active[j] = True
            if pen > 0.0:
                # a no-tension contact re-engaging while still overlapped (its force is zero here):
                # the spring energy booked as lost at its release is stored again
                st.en[EN_WREL] -= 0.5 * k_s * pen * pen
            st.row[base + L.PAIR_IMPACTS] += 1.0
            F[j] = k_s * pen + c[j] * (v[p] - v[q])
            st.Sprev[j] = k_s * pen
            st.Dprev[j] = F[j] - st.Sprev[j]
            bk.force_extremes(st.row, base, F[j], t)
        st.was_active[j] = pr.active[j]
    for j in range(i1.shape[0]):  # every force from the Kelvin-Voigt law at this instant (eq. 8)
        p, q = i1[j], i2[j]
        F[j] = k_s * (u[p] - u[q] - d) + c[j] * (v[p] - v[q]) if pr.active[j] else 0.0
    floors.equilibrium_acceleration(st, ag, u, v, F, st.a)


#: the event step's pieces in floor coordinates with the linear laws
OPS = EventOps(_advance, floors.pair, floors.tolerance, floors.finite, _accept, _switch, bisect_crossing)
_event_step, _contradicts = event_functions(OPS)


@njit_inner
def _mask(active):
    """Active set as a bit mask (meaningful for up to 62 pairs; only used to spot cycles)."""
    mk = 0
    for j in range(min(active.size, 62)):
        if active[j]:
            mk |= 1 << j
    return mk


class ImplicitWork(NamedTuple):
    """The implicit and paper schemes' per-step arrays (pair space)."""

    S: np.ndarray  # (P, P) G^T Keff^-1 G (engine/inputs.py Structure)
    z0: np.ndarray  # (P,) g.u0: relative displacement at the contact-free end
    wrel: np.ndarray  # (P,) g.(2/dt u + v)
    bb: np.ndarray  # (P,) k_s d + c wrel
    ke: np.ndarray  # (P,) k_s + 2 c / dt
    want: np.ndarray  # (P,) bool: the set the end state asks for
    seen: np.ndarray  # (max_iter + 1,) masks of the sets tried
    small: tuple  # (idx, Asmall, rsmall): _contact_forces' work


@inline_kernel
def _implicit_forces(iw, pr, F, max_iter, d, start):
    """The implicit scheme's end-of-step forces: the active-set iteration from the start set (a set
    already tried means it cycles: stop early); returns (iterations, True if a set agrees with its end
    state). When none does (the iteration cycles: an impact inside the step under the classic law, the
    pair penetrating without contact and thrown clear by the dashpot with it), the start's set `start` is
    restored with its forces, the trial the event step (engine/events.py) continues from."""
    S, z0, bb, ke, want = iw.S, iw.z0, iw.bb, iw.ke, iw.want
    active = pr.active
    npair = active.size
    idx, Asmall, rsmall = iw.small
    it = 0
    cycled = False
    while it < max_iter and not cycled:
        iw.seen[it] = _mask(active)
        it += 1
        _contact_forces(S, z0, bb, ke, active, idx, Asmall, rsmall, F)
        changed = False
        for j in range(npair):
            z = z0[j]
            for l in range(npair):
                z -= S[j, l] * F[l]
            pen = z - d
            w = pen > 0.0
            if w and pr.no_tension:  # no tension: contact only while it pushes
                w = (ke[j] * z - bb[j]) > 0.0
            want[j] = w
            if w != active[j]:
                changed = True
        if not changed:
            return it, True
        for j in range(npair):
            active[j] = want[j]
        mk = _mask(active)
        for q in range(it):
            if iw.seen[q] == mk and npair <= 62:
                cycled = True
    for j in range(npair):
        active[j] = start[j]
    _contact_forces(S, z0, bb, ke, active, idx, Asmall, rsmall, F)
    return it, False


@inline_kernel
def _paper_forces(iw, pr, F, b1, d):
    """The paper's scheme: the contact force from the trial (F = 0) state, applied as a load."""
    k_s, c = pr.k_s, pr.c
    for j in range(pr.active.size):
        F[j] = 0.0
        pen = iw.z0[j] - d
        pr.active[j] = False
        if pen > 0.0:
            vrel = b1 * iw.z0[j] - iw.wrel[j]
            f = k_s * pen + c[j] * vrel
            if pr.no_tension and f <= 0.0:
                continue  # no tension: no contact while the element would pull
            F[j] = f
            pr.active[j] = True


class StepWork(NamedTuple):
    """The time loop's arrays besides the run's state."""

    w: np.ndarray  # (N,) 2/dt u + v
    rhs0: np.ndarray  # (N,) Newmark's effective load without contact
    u0: np.ndarray  # (N,) the contact-free end state
    ustep: np.ndarray  # (N,) displacement at the step start (experiment sampling)
    astep: np.ndarray  # (N,) relative acceleration at the step start (acceleration channels)
    xs: np.ndarray  # (channels, samples) the run sampled at the experiment's time stamps
    iw: ImplicitWork


def _time_loop_for(scheme: int):
    """The time loop compiled for one scheme (codes.SCHEME_*): `scheme` is a closure constant, so Numba prunes
    the other schemes' branches, and a scene compiles only its own scheme's code (the paper's scheme compiles no
    event step: a third less compile, docs/explanation/performance.md). A closure over an int is cached as a plain
    function is (Numba keys it by the int)."""

    @njit_inner
    def _time_loop(run, model, opts, runs, records, histories, experiment, out, st, wk):
        """The run's steps from rest (st: its state, reset): the end state of each step by the scheme, its
        pieces (the event scheme's located switches), the per-step metrics, experiment samples and histories.
        Compiled without Numba's reference counts (it allocates nothing): on the records' arrays they cost
        this loop a third of its time. Returns (status bits, unsettled steps, most iterations or located
        switches in a step, steps done, experiment samples filled)."""
        dt, Kinv, H, i1, i2, n1 = model.dt, model.Kinv, model.H, model.i1, model.i2, model.n1
        max_iter = opts.max_iter
        w, rhs0, u0, ustep, astep, xs, iw = wk
        u, v, a, F, pr, row = st.u, st.v, st.a, st.F, st.pairs, st.row
        z0, wrel, bb, ke = iw.z0, iw.wrel, iw.bb, iw.ke
        channels = (experiment.t, experiment.dof, experiment.kind)
        has_acc = bk.any_acceleration(experiment.kind)  # then keep the step's starting acceleration too
        hist = out.hist
        keep_hist = hist.shape[0] > 0
        npair = i1.shape[0]
        b1 = 2.0 / dt
        hmin = EVENT_MIN_FRACTION * dt
        d, k_s, c = st.gap, pr.k_s, pr.c
        kind = runs.exc_kind[run]
        ground = Ground(kind == EXC_HARMONIC, runs.exc_amp[run], runs.exc_omega[run])
        rec_flat = records.flat
        roff, rlen, ag = bk.start_at_rest(run, runs, records, dt, u, v, a)
        if keep_hist:
            bk.keep_history(hist, run, np.int64(0), histories.kinds, histories.index, u, v, a, F, ag)
        for j in range(npair):
            ke[j] = k_s + b1 * c[j]
        ke_next = bk.samples_at_rest(experiment.t, xs)  # next experiment sample to fill
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
            for j in range(npair):
                z0[j] = u0[i1[j]] - u0[i2[j]]
                wrel[j] = w[i1[j]] - w[i2[j]]
                bb[j] = k_s * d + c[j] * wrel[j]
            locate = False  # the implicit scheme found no consistent set: the event step takes the step
            if scheme == SCHEME_IMPLICIT:
                it, settled = _implicit_forces(iw, pr, F, max_iter, d, st.was_active)
                locate = not settled
                if it > max_it_seen:
                    max_it_seen = it
            elif scheme == SCHEME_PAPER:
                _paper_forces(iw, pr, F, b1, d)
            else:
                # event scheme: the whole step with the contact set of its start (the event step splits it
                # where a pair's state at the end disagrees with that set)
                idx, Asmall, rsmall = iw.small
                _contact_forces(iw.S, z0, bb, ke, pr.active, idx, Asmall, rsmall, F)
            floors.end_state(st, u0, H, dt)
            # (the paper's scheme never locates: its branch is pruned with the event step's code)
            if scheme != SCHEME_PAPER and (locate or (scheme == SCHEME_EVENT and _contradicts(st))):
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
            if ke_next < experiment.t.size:
                ke_next = bk.sample_experiment(ke_next, channels, xs, (ustep, astep, agstep), (u, a, ag), t, dt)
            steps_done = step
            bk.floor_peaks(row, u, a, ag, t, n1)
            if keep_hist and step % histories.decimate == 0:
                bk.keep_history(hist, run, step // histories.decimate, histories.kinds, histories.index, u, v, a, F, ag)
        return status, unsettled, max_it_seen, steps_done, ke_next

    return _time_loop


#: the time loop of each scheme, compiled when a scene first uses it (module names: a compiled caller holding a
#: loop in a closure cell could not be cached, jit.njit_generic)
_time_loop_event = _time_loop_for(SCHEME_EVENT)
_time_loop_implicit = _time_loop_for(SCHEME_IMPLICIT)
_time_loop_paper = _time_loop_for(SCHEME_PAPER)


def _batch_kernel(scored: bool, scheme: int):
    """The scalar kernel compiled with or without the scoring code (eq. 20 against the experiment, its lag
    search) and for one scheme: `scored` and `scheme` are closure constants, so Numba prunes the branches,
    and a scene that scores nothing never compiles the scoring (4.6 s of the 20 s compile:
    benchmarks/profile_compile.py --case 3), nor another scheme's time loop."""

    @njit_kernel
    def integrate_batch(start, stop, model, opts, runs, records, histories, experiment, out):
        m, C, K, S, i1, i2 = model.m, model.C, model.K, model.S, model.i1, model.i2
        n = m.shape[0]
        npair = i1.shape[0]
        # work arrays, allocated once per batch (never inside the time loop) and uninitialised: each is set before it
        # is read (bk.start_pairs and the loop below reset the run's state; the event and implicit steps write their
        # marks before reading them). np.zeros compiled a fill for each dtype: about 0.4 s of a first run
        u, v, a = np.empty(n), np.empty(n), np.empty(n)
        un, vn, an = np.empty(n), np.empty(n), np.empty(n)
        F = np.empty(npair)
        active = np.empty(npair, dtype=np.bool_)
        iw = ImplicitWork(
            S,
            np.empty(npair),
            np.empty(npair),
            np.empty(npair),
            np.empty(npair),
            np.empty(npair, dtype=np.bool_),
            np.empty(opts.max_iter + 1, dtype=np.int64),
            (np.empty(npair, dtype=np.int64), np.empty((npair, npair)), np.empty(npair)),
        )
        xs = np.empty((experiment.dof.size, experiment.t.size))
        wk = StepWork(np.empty(n), np.empty(n), np.empty(n), np.empty(n), np.empty(n), xs, iw)
        phases = (
            np.empty(npair, dtype=np.bool_),
            np.empty(npair),
            np.empty((npair, L.MEDIAN_BUFFER)),
            np.empty(npair, dtype=np.int64),
        )
        bufs = (np.empty(npair, dtype=np.bool_), np.empty(npair), np.empty(npair), np.empty(npair))
        was_active, Sprev, Dprev, pen_prev = bufs
        marks = (np.empty(npair, dtype=np.bool_), np.empty(npair, dtype=np.bool_), np.empty(npair))
        en = np.empty(EN_N)
        solve = (np.empty(n), np.empty((n, n)), np.empty(n))  # Cdu, A, r
        pbase = L.PER_DOF * n
        rbase = pbase + L.PER_PAIR * npair
        for run in range(start, stop):
            t_start = _clock()
            row = out.metrics[run]
            d = runs.gap[run]
            k_s = runs.ks[run]
            pr = Pairs(active, marks[0], marks[1], marks[2], runs.cdash[run], k_s, runs.law[run] == LAW_NO_TENSION)
            st = LinearState(
                m, C, K, i1, i2, d, u, v, a, un, vn, an, F, pr, was_active, Sprev, Dprev, pen_prev, en, row, phases,
                solve[0], solve[1], solve[2],
            )  # fmt: skip
            bk.start_row(row, npair, pbase, d)
            bk.start_pairs(active, F, bufs, phases, d)
            for q in range(EN_N):
                en[q] = 0.0
            # one branch stays (closure constants): the scene's scheme's loop
            if scheme == SCHEME_IMPLICIT:
                done = _time_loop_implicit(run, model, opts, runs, records, histories, experiment, out, st, wk)
            elif scheme == SCHEME_PAPER:
                done = _time_loop_paper(run, model, opts, runs, records, histories, experiment, out, st, wk)
            else:
                done = _time_loop_event(run, model, opts, runs, records, histories, experiment, out, st, wk)
            status, unsettled, max_it_seen, steps_done, ke_next = done
            status |= runs.status_in[run]
            status = bk.close_row(row, pbase, npair, phases, status)
            if scored:  # a closure constant: the other variant has no scoring code
                status = bk.score_run(out.scores, run, xs, experiment, ke_next, status)
            # energy balance at the end: E_in = KE + SE + D_struct + D_contact + E_spring + residual;
            # the residual is the spring work the discrete contact switching did not store
            e_spring = 0.0
            for j in range(npair):
                if active[j]:
                    e_spring += 0.5 * k_s * pen_prev[j] * pen_prev[j]
            residual = en[EN_WSP] - e_spring - en[EN_WREL]
            energies = (en[EN_IN], en[EN_ABS], en[EN_DST], en[EN_WDA] + en[EN_WREL], e_spring, residual)
            status = bk.energy_row(row, rbase, m, K, u, v, energies, status)
            bk.run_counts(row, rbase, unsettled, max_it_seen, steps_done, status)
            out.run_time[run] = _clock() - t_start

    return integrate_batch


#: scheme code -> (unscored, scored) compiled entries; each compiles on its first call
_VARIANTS = {scheme: (_batch_kernel(False, scheme), _batch_kernel(True, scheme)) for scheme in SCHEMES.values()}


def integrate_batch(start, stop, model, opts, runs, records, histories, experiment, out):
    """Integrate runs start..stop-1 of the chunk: fill out.metrics[run] (engine/layout.py), out.run_time[run],
    the histories out.hist[run] when histories.kinds is not empty, and, when experiment.dof is not empty,
    out.scores[run, channel, :] (engine/score.py). The linear laws (runs.law: codes.LAW_CLASSIC,
    codes.LAW_NO_TENSION).

    Records (engine/inputs.py): model Structure, opts KernelOptions, runs RunArrays, records Records,
    histories HistorySpec, experiment ScoreSpec, out Outputs."""
    _VARIANTS[opts.scheme][experiment.active](start, stop, model, opts, runs, records, histories, experiment, out)


def event_pieces(scheme: int) -> tuple:
    """The event step's pieces a second process can compile for this kernel (engine/aside.py), with the argument
    types the step calls them with, in the order the kernel's typing reaches them: _advance, bookkeeping.pair_pieces
    (through _accept) and _switch, about 1 s of the README scene's compile. None for the paper's scheme, whose time
    loop has no event step. The types are those of integrate_batch's run state (LinearState, of C-contiguous arrays
    of the kernel's dtypes): tests/engine/test_aside.py checks that the kernel finds the pieces in the cache."""
    if scheme == SCHEME_PAPER:
        return ()
    from numba import typeof, types

    phases = bk.empty_phases()
    b1, f1, f2, i1 = phases
    pr = empty_pairs()
    st = typeof(
        LinearState(f1, f2, f2, i1, i1, 0.0, f1, f1, f1, f1, f1, f1, f1, pr, b1, f1, f1, f1, f1, f1, phases, f1, f2, f1)
    )
    f64 = types.float64
    return (
        (_advance, (st, f64, f64, f64, types.boolean)),
        (bk.pair_pieces, bk.pair_pieces_signature()),
        (_switch, (st, f64, f64)),
    )
