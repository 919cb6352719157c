"""The continuous-time references: the equations of motion (paper eqs. 1-2, 8) integrated by scipy's
solve_ivp to tight tolerances, one smooth piece per contact set, restarted at contact events located by
root finding. It shares no discretisation with the kernels: the difference is their time-stepping error."""

from __future__ import annotations

import dataclasses
import math
import time

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import minimize_scalar

from pounding_sweep.model.excitation import Excitation
from pounding_sweep.reference.newmark import Problem, resolve
from pounding_sweep.sweep.simulate import with_overrides


def contact_set_systems(P: Problem):
    """system(active) -> (Asys, f0): y' = Asys y + f0 (+ the ground motion term) in y = (u, v) for the
    contact set `active` (a tuple of bools): the Kelvin-Voigt springs and dashpots of the pairs in
    contact join K and C, and k_s d g_j the load (eqs. 1-2, 8). Cached per set."""
    n, p = P.n_dof, P.n_pairs
    Minv = np.linalg.inv(P.M)  # diagonal (lumped masses): an exact inverse
    systems: dict[tuple, tuple[np.ndarray, np.ndarray]] = {}

    def system(active: tuple) -> tuple[np.ndarray, np.ndarray]:
        if active not in systems:
            Ka, Ca, fa = P.K.copy(), P.C.copy(), np.zeros(n)
            for j in range(p):
                if active[j]:
                    g = P.G[:, j]
                    Ka += P.ks * np.outer(g, g)
                    Ca += P.c[j] * np.outer(g, g)
                    fa += P.ks * P.gap * g
            Asys = np.block([[np.zeros((n, n)), np.eye(n)], [-Minv @ Ka, -Minv @ Ca]])
            systems[active] = (Asys, np.concatenate([np.zeros(n), Minv @ fa]))
        return systems[active]

    return system


def contact_force(P: Problem, j: int, y: np.ndarray) -> np.ndarray:
    """Eq. (8) formula for pair j (whether or not in contact); y = (u, v) may be (2n,) or (2n, m)."""
    g = P.G[:, j]
    n = P.n_dof
    return P.ks * (g @ y[:n] - P.gap) + P.c[j] * (g @ y[n:])


def ivp_reference(
    scene, t_end=None, rtol=1e-10, atol=1e-13, method="DOP853", max_step=1e-3, dt_out=None, **overrides
) -> dict:
    """The continuous-time problem (eqs. 1-2 and 8) by solve_ivp, one smooth piece per contact set.

    First-order form y = (u, v). With a fixed set A of pairs in contact, eq. (8) is linear in y:

        M v' = -(K + sum_A k_s g g^T) u - (C + sum_A c_j g g^T) v + sum_A k_s d g - M 1 ag(t),

    so every piece is a linear ODE with a smooth (harmonic) right-hand side, which an explicit
    high-order method integrates to tolerance without trouble. The contact set changes only at
    events, each the zero of one continuous function per pair:

        h_j = g_j.u - d                            (classic: contact iff penetration > 0)
        h_j = min(g_j.u - d, F_j / k_s)            (no_tension: iff penetration AND force > 0)

    watched upward for pairs out of contact and downward for pairs in contact. Each event is
    terminal: the piece ends at the root (found by solve_ivp on the dense output), the pair
    flips, and a fresh solve_ivp starts from the event state. Nothing is ever integrated across
    a discontinuity of the right-hand side (the dashpot force jumps at impact under the classic
    law), which is what keeps the high order and the tight tolerance meaningful.

    Method: DOP853 (explicit Runge-Kutta 8(5,3) with a 7th-order dense output). The pieces are
    not stiff: the largest |eigenvalue| of any piece of the 6 Hz scene is 170-460 1/s (k_s/k
    from 0.1 to 10, all pairs in contact; building 2's third mode and the contact spring on the
    reduced floor mass), so at the steps a 1e-10 tolerance asks for (well under a millisecond)
    an explicit method is far inside its stability region; Radau would pay a linear solve per
    stage for stiffness the problem does not have, at a lower order (5). max_step (1 ms, under a
    tenth of the shortest contact period, 14 ms at k_s/k = 10) keeps steps short enough that a
    brief contact cannot hide between two event checks.

    Returns t (uniform grid, spacing dt_out, default the scene's dt_s, up to t_end or the
    scene's duration), u, v, a
    (relative accelerations from the equation of motion), F, active on that grid, the events as
    a list of (time, pair, "contact" | "separation"), impacts per pair and the Problem.
    Harmonic excitation only.
    """
    P = resolve(scene, **overrides)
    if P.exc_kind != "harmonic":
        raise NotImplementedError("ivp_reference: harmonic excitation only")
    n, p, ks, d = P.n_dof, P.n_pairs, P.ks, P.gap
    t_end = P.nsteps * P.dt if t_end is None else float(t_end)
    drive = np.concatenate([np.zeros(n), np.ones(n) * P.amp * P.omega**2])  # -1 ag(t) = 1 A w^2 sin(w t)
    system = contact_set_systems(P)

    def force(j: int, y: np.ndarray) -> np.ndarray:
        return contact_force(P, j, y)

    def event_function(j: int):
        def h(t, y):
            pen = P.G[:, j] @ y[:n] - d
            if P.law == "no_tension":
                return min(pen, force(j, y) / ks)
            return pen

        h.terminal = True
        return h

    dt_out = P.dt if dt_out is None else float(dt_out)
    grid = np.arange(int(math.floor(t_end / dt_out + 1e-9)) + 1) * dt_out
    Y = np.full((grid.size, 2 * n), np.nan)
    ACT = np.zeros((grid.size, p), dtype=bool)
    events: list[tuple[float, int, str]] = []
    y = np.zeros(2 * n)
    t0 = 0.0
    active = tuple(False for _ in range(p))
    stalls = 0
    while True:
        Asys, f0 = system(active)
        evs = []
        for j in range(p):
            h = event_function(j)
            h.direction = -1.0 if active[j] else 1.0
            evs.append(h)
        sol = solve_ivp(
            lambda t, yy: Asys @ yy + f0 + drive * math.sin(P.omega * t),
            (t0, t_end),
            y,
            method=method,
            rtol=rtol,
            atol=atol,
            max_step=max_step,
            events=evs,
            dense_output=True,
        )
        if sol.status < 0:
            raise RuntimeError(f"ivp_reference: solve_ivp failed at t = {sol.t[-1]}: {sol.message}")
        t1 = sol.t[-1]
        sel = (grid >= t0) & (grid <= t1)
        if np.any(sel):
            Y[sel] = sol.sol(grid[sel]).T
            ACT[sel] = active
        if sol.status == 0:
            break
        # which pair's event ended the piece (the earliest; ties are not expected)
        hits = [(te[0], j) for j, te in enumerate(sol.t_events) if te.size]
        te, j = min(hits)
        y = sol.y_events[j][0].copy()
        stalls = stalls + 1 if te - t0 < 1e-12 else 0
        if stalls > 10:
            raise RuntimeError(f"ivp_reference: contact set chatters at t = {te}")
        active = tuple((not a) if i == j else a for i, a in enumerate(active))
        events.append((float(te), j, "contact" if active[j] else "separation"))
        t0 = te

    u, v = Y[:, :n], Y[:, n:]
    F = np.zeros((grid.size, p))
    for j in range(p):
        F[:, j] = np.where(ACT[:, j], force(j, Y.T), 0.0)
    ag = -P.amp * P.omega**2 * np.sin(P.omega * grid)
    # relative acceleration from the equation of motion, M a = -C v - K u - G F - M 1 ag
    a = (-(v @ P.C.T) - (u @ P.K.T) - F @ P.G.T) @ np.linalg.inv(P.M).T - ag[:, None]
    impacts = np.array([sum(1 for e in events if e[1] == j and e[2] == "contact") for j in range(p)])
    return dict(t=grid, u=u, v=v, a=a, F=F, active=ACT, ag=ag, events=events, impacts=impacts, problem=P)


# ----------------------------------------------------------------------------- records too (the accuracy ladder's reference)

SAMPLE_DT = (
    5e-3  # the continuous reference's output grid: the coarsest dt of the accuracy ladder, which every dt divides
)
REF_RTOL, REF_ATOL = 1e-12, 1e-15  # its tolerances (checked against themselves at 10x tighter)
PEAK_SCAN_S = 2e-5  # dense-output scan spacing for its peaks (then refined by Brent)
TOP = 3  # floor of the top-floor channels and of the pounding-force pair


@dataclasses.dataclass
class Reference:
    """The continuous-time solution, reduced to what the errors need."""

    t: np.ndarray  # sample grid (SAMPLE_DT spacing from 0)
    top: np.ndarray  # (t.size, 2): top-floor displacement of building 1 and 2 [m]
    peak_disp: np.ndarray  # (n_dof,): max |u_i| over the run [m] (refined on the dense output)
    peak_force: np.ndarray  # (n_pairs,): max F_j over the run [N] (impact instants included)
    impacts: np.ndarray  # (n_pairs,): contact events per pair
    events: list  # (time, pair, "contact" | "separation")
    rtol: float
    wall_s: float


def ground_acceleration_fn(scene, t_end):
    """(ag(t), knots): the ground acceleration the kernel converges to as dt -> 0, and the times in
    (0, t_end) where it has a kink. Harmonic: -A w^2 sin(w t), no kinks. Record: the similitude-scaled
    record (times `scale`), linear between its samples (the package resamples it that way), 0 past its end."""
    e = scene.excitation
    if e.type == "harmonic":
        amp, om = e.amplitude_m * e.scale, 2.0 * math.pi * e.frequency_Hz
        return (lambda t: -amp * om * om * math.sin(om * t)), np.array([])
    rec = Excitation.from_scene(scene, scene.integration.dt_s).records[0]
    tk, ak = rec.time_s, e.scale * np.asarray(rec.acc_m_s2)
    t_last = tk[-1]

    def ag(t):
        if t > t_last * (1 + 1e-12):
            return 0.0
        return float(np.interp(t, tk, ak))

    return ag, tk[(tk > 0.0) & (tk < t_end)]


def continuous_reference(
    scene, sample_dt=SAMPLE_DT, rtol=REF_RTOL, atol=REF_ATOL, max_step=1e-3, peak_scan_s=PEAK_SCAN_S, **overrides
) -> Reference:
    """solve_ivp (DOP853) with contact events on the scene's point (`overrides`: ks_ratio, r, law, ...).

    Each piece is a linear ODE y' = A_S y + f_S - [0; 1] ag(t) for the contact set S (y = (u, v)),
    smooth up to its end: the next contact event (a pair's penetration, or under no_tension its
    Kelvin-Voigt force, crossing zero: terminal events located on the dense output), or the next
    record sample (where ag has a kink), or the end. `ivp_reference` for records
    too; `check_against_ivp_reference` compares the two on a harmonic scene."""
    t_wall = time.perf_counter()
    s = with_overrides(scene, **overrides)
    P = resolve(scene, **overrides)  # matrices and contact parameters
    n, p, ks, d = P.n_dof, P.n_pairs, P.ks, P.gap
    e = s.excitation
    if e.type == "harmonic":
        t_end = e.duration_s
    else:
        rec_dur = Excitation.from_scene(s, s.integration.dt_s).records[0].duration_s
        t_end = min(e.duration_s, rec_dur) if e.duration_s is not None else rec_dur
    ag, knots = ground_acceleration_fn(s, t_end)
    stops = np.concatenate([knots, [t_end]])
    ones = np.concatenate([np.zeros(n), np.ones(n)])
    system = contact_set_systems(P)  # the same first-order systems as ivp_reference

    def force(j, y):
        return contact_force(P, j, y)

    def event(j, direction):
        def h(t, y):
            pen = P.G[:, j] @ y[:n] - d
            return min(pen, force(j, y) / ks) if P.law == "no_tension" else pen

        h.terminal, h.direction = True, direction
        return h

    grid = np.arange(int(math.floor(t_end / sample_dt + 1e-9)) + 1) * sample_dt
    top_idx = [TOP - 1, n // 2 + TOP - 1]  # building 1's and building 2's top floor (3 stories each)
    top = np.full((grid.size, 2), np.nan)
    best_u = np.zeros((n, 3))  # value, time, piece
    best_F = np.zeros((p, 3))
    pieces = []
    events = []
    y = np.zeros(2 * n)
    t0, k_stop, stalls = 0.0, 0, 0
    active = (False,) * p
    while True:
        A, f0 = system(active)
        evs = [event(j, -1.0 if active[j] else 1.0) for j in range(p)]
        t_stop = stops[k_stop]
        if e.type == "harmonic":
            rhs = lambda t, yy: A @ yy + f0 - ones * ag(t)  # noqa: E731
        else:  # ag linear on [t0, t_stop]: write it as such (no interp call per stage)
            a0, a1 = ag(t0), ag(t_stop)
            slope = (a1 - a0) / (t_stop - t0) if t_stop > t0 else 0.0
            rhs = lambda t, yy, a0=a0, slope=slope, t0=t0: A @ yy + f0 - ones * (a0 + slope * (t - t0))  # noqa: E731
        sol = solve_ivp(
            rhs,
            (t0, t_stop),
            y,
            method="DOP853",
            rtol=rtol,
            atol=atol,
            max_step=max_step,
            events=evs,
            dense_output=True,
        )
        if sol.status < 0:
            raise RuntimeError(f"continuous_reference: solve_ivp failed at t = {sol.t[-1]}: {sol.message}")
        t1 = sol.t[-1]
        k = len(pieces)
        pieces.append((t0, t1, sol.sol, active))
        sel = (grid >= t0 - 1e-12) & (grid <= t1 + 1e-12)
        if sel.any():
            top[sel] = sol.sol(np.clip(grid[sel], t0, t1))[top_idx].T
        m = max(2, int(math.ceil((t1 - t0) / peak_scan_s)) + 1)
        ts = np.linspace(t0, t1, m)
        Y = sol.sol(ts)
        absu = np.abs(Y[:n])
        i_max = absu.argmax(axis=1)
        for i in range(n):
            if absu[i, i_max[i]] > best_u[i, 0]:
                best_u[i] = absu[i, i_max[i]], ts[i_max[i]], k
        for j in range(p):
            if active[j]:
                Fj = force(j, Y)
                q = Fj.argmax()
                if Fj[q] > best_F[j, 0]:
                    best_F[j] = Fj[q], ts[q], k
        if sol.status == 1:  # a contact event ended the piece
            te, j = min((tev[0], jj) for jj, tev in enumerate(sol.t_events) if tev.size)
            y = sol.y_events[j][0].copy()
            stalls = stalls + 1 if te - t0 < 1e-12 else 0
            if stalls > 10:
                raise RuntimeError(f"continuous_reference: contact set chatters at t = {te}")
            active = tuple((not a) if i == j else a for i, a in enumerate(active))
            events.append((float(te), j, "contact" if active[j] else "separation"))
            t0 = te
        else:
            y = sol.y[:, -1].copy()
            t0 = t_stop
            k_stop += 1
            if k_stop == stops.size:
                break

    def refine(fun, best):
        """Brent's maximum of fun(piece, t) near the scanned best, in its piece and the neighbours."""
        val, t_b, k = best
        out = val
        for kk in (int(k) - 1, int(k), int(k) + 1):
            if not 0 <= kk < len(pieces):
                continue
            a, b = max(pieces[kk][0], t_b - peak_scan_s), min(pieces[kk][1], t_b + peak_scan_s)
            if b <= a:
                continue
            r = minimize_scalar(
                lambda t: -fun(kk, t), bounds=(a, b), method="bounded", options={"xatol": 1e-14 + 1e-12 * abs(t_b)}
            )
            out = max(out, -r.fun, fun(kk, a), fun(kk, b))
        return out

    peak_u = np.array([refine(lambda kk, t, i=i: abs(pieces[kk][2](t)[i]), best_u[i]) for i in range(n)])
    peak_F = np.array(
        [
            refine(lambda kk, t, j=j: force(j, pieces[kk][2](t)) if pieces[kk][3][j] else 0.0, best_F[j])
            for j in range(p)
        ]
    )
    impacts = np.array([sum(1 for ev in events if ev[1] == j and ev[2] == "contact") for j in range(p)])
    return Reference(grid, top, peak_u, peak_F, impacts, events, rtol, time.perf_counter() - t_wall)


# ----------------------------------------------------------------------------- the Hertz-type laws


def law_ivp_reference(scene, t_end=None, rtol=1e-10, atol=1e-13, max_step=1e-3, dt_out=None, **overrides) -> dict:
    """The continuous-time problem with a Hertz-type law (reference/nonlinear.py writes the laws out) by
    solve_ivp (DOP853), one smooth piece at a time. Harmonic excitation only.

    Within a piece every pair keeps its branch: out of contact (F = 0), or in contact with the law's
    formula fixed (jankowski: approaching, delta_dot > 0, or restituting; hertzdamp: pushing, or clipped
    at F = 0 where 1 + a delta_dot / v0 <= 0). Each branch change is a terminal event located on the
    dense output: penetration crossing zero (an impact starts: hertzdamp takes v0 from the state there,
    floored at min_impact_speed_m_s; or a contact ends), jankowski's delta_dot crossing zero, hertzdamp's
    1 + a delta_dot / v0 crossing zero. So nothing is integrated across a kink of the right-hand side.
    Jankowski's dashpot c0 delta^0.25 delta_dot is continuous at an impact's start but not Lipschitz there;
    DOP853's error control shortens its steps to meet the tolerance.

    Returns t (grid of spacing dt_out, default the scene's dt), u, v, F on it, the events (time, pair,
    kind), impacts per pair, the peak force per pair (scanned on the dense output), grazing (a v0 was
    floored) and the LawProblem."""
    from pounding_sweep.reference.nonlinear import pounding_force, resolve_law

    Q = resolve_law(scene, **overrides)
    P = Q.base
    if P.exc_kind != "harmonic":
        raise NotImplementedError("law_ivp_reference: harmonic excitation only")
    n, p, d = P.n_dof, P.n_pairs, P.gap
    t_end = P.nsteps * P.dt if t_end is None else float(t_end)
    Minv = np.linalg.inv(P.M)
    drive = np.ones(n) * P.amp * P.omega**2  # -1 ag(t) = 1 A w^2 sin(w t)
    dt_out = P.dt if dt_out is None else float(dt_out)
    grid = np.arange(int(math.floor(t_end / dt_out + 1e-9)) + 1) * dt_out
    Y = np.full((grid.size, 2 * n), np.nan)
    contact = [False] * p
    branch = [True] * p  # jankowski: approaching; hertzdamp: pushing (not clipped)
    v0 = np.full(p, np.inf)
    grazing = False

    def forces(y):
        z = P.G.T @ y[:n] - d
        zd = P.G.T @ y[n:]
        out = np.zeros(p)
        for j in range(p):
            if not contact[j]:
                continue
            if Q.law == "jankowski":
                # the branch's formula, continued past its end so the event can be located
                el = Q.kh * max(z[j], 0.0) ** 1.5
                out[j] = el + (
                    2.0 * Q.xi * math.sqrt(Q.kh * math.sqrt(max(z[j], 0.0)) * Q.meff[j]) * zd[j] if branch[j] else 0.0
                )
            elif Q.law == "hertzdamp":
                out[j] = Q.kh * max(z[j], 0.0) ** 1.5 * (1.0 + Q.a * zd[j] / v0[j]) if branch[j] else 0.0
            else:
                out[j] = pounding_force(Q, j, z[j], zd[j], v0[j])
        return out

    def rhs(t, y):
        acc = Minv @ (-P.C @ y[n:] - P.K @ y[:n] - P.G @ forces(y)) + drive * math.sin(P.omega * t)
        return np.concatenate([y[n:], acc])

    def events_now():
        evs = []
        for j in range(p):
            g = P.G[:, j]

            def pen(t, y, g=g):
                return g @ y[:n] - d

            pen.terminal, pen.direction = True, -1.0 if contact[j] else 1.0
            pen.pair, pen.kind = j, "contact"
            evs.append(pen)
            if contact[j] and Q.law == "jankowski":

                def rate(t, y, g=g):
                    return g @ y[n:]

                rate.terminal, rate.direction = True, -1.0 if branch[j] else 1.0
                rate.pair, rate.kind = j, "branch"
                evs.append(rate)
            if contact[j] and Q.law == "hertzdamp" and Q.a > 0.0:

                def push(t, y, g=g, j=j):
                    return 1.0 + Q.a * (g @ y[n:]) / v0[j]

                push.terminal, push.direction = True, -1.0 if branch[j] else 1.0
                push.pair, push.kind = j, "branch"
                evs.append(push)
        return evs

    events = []
    pieces = []
    y = np.zeros(2 * n)
    t0, stalls = 0.0, 0
    peak = np.zeros(p)
    while True:
        evs = events_now()
        sol = solve_ivp(
            rhs, (t0, t_end), y, method="DOP853", rtol=rtol, atol=atol, max_step=max_step, events=evs, dense_output=True
        )
        if sol.status < 0:
            raise RuntimeError(f"law_ivp_reference: solve_ivp failed at t = {sol.t[-1]}: {sol.message}")
        t1 = sol.t[-1]
        sel = (grid >= t0 - 1e-12) & (grid <= t1 + 1e-12)
        if sel.any():
            Y[sel] = sol.sol(np.clip(grid[sel], t0, t1)).T
        ts = np.linspace(t0, t1, max(2, int(math.ceil((t1 - t0) / 2e-5)) + 1))
        Fs = np.array([forces(yy) for yy in sol.sol(ts).T])
        peak = np.maximum(peak, Fs.max(axis=0))
        pieces.append((t0, t1, list(contact), list(branch), v0.copy()))
        if sol.status == 0:
            break
        hits = [(te[0], k) for k, te in enumerate(sol.t_events) if te.size]
        te, k = min(hits)
        ev = evs[k]
        y = sol.y_events[k][0].copy()
        stalls = stalls + 1 if te - t0 < 1e-12 else 0
        if stalls > 10:
            raise RuntimeError(f"law_ivp_reference: the contact state chatters at t = {te}")
        j = ev.pair
        if ev.kind == "contact":
            contact[j] = not contact[j]
            branch[j] = True
            if contact[j]:
                rate_j = float(P.G[:, j] @ y[n:])
                if Q.law == "jankowski":
                    branch[j] = rate_j > 0.0
                if Q.law == "hertzdamp":
                    v0[j] = max(rate_j, Q.vmin)
                    grazing |= rate_j < Q.vmin
            else:
                v0[j] = np.inf
            events.append((float(te), j, "contact" if contact[j] else "separation"))
        else:
            branch[j] = not branch[j]
            events.append((float(te), j, "branch"))
        t0 = te

    u, v = Y[:, :n], Y[:, n:]
    F = np.zeros((grid.size, p))
    for i, tt in enumerate(grid):  # forces on the grid with the branch of the piece holding tt
        for t_a, t_b, c_k, b_k, v0_k in pieces:
            if t_a - 1e-12 <= tt <= t_b + 1e-12:
                contact[:], branch[:], v0[:] = c_k, b_k, v0_k
                F[i] = forces(Y[i])
                break
    impacts = np.array([sum(1 for e in events if e[1] == j and e[2] == "contact") for j in range(p)])
    return dict(t=grid, u=u, v=v, F=F, events=events, impacts=impacts, peak_force=peak, grazing=grazing, problem=Q)
