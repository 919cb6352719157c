"""The discrete references: the kernels' Newmark schemes on the full coupled system, plain NumPy.

Nothing here is fast on purpose: every step assembles and solves the full coupled system with
NumPy, so the arithmetic can be read line by line against the equations it implements.

Physics (SI; Sekerci & Damci, eqs. 1-2 written with the restoring sign, as in kernel.py):

    M a + C v + K u + G F = -M 1 ag(t)                                          (eqs. 1-2)

u: floor displacements relative to the table, building 1's floors then building 2's; G column j
is g_j = e(building 1, floor j) - e(building 2, floor j), so g_j.u - d is the penetration of
facing floor pair j for a seismic gap d. The Kelvin-Voigt force (positive in compression) is

    F_j = k_s (g_j.u - d) + c_j g_j.v   while g_j.u - d > 0, else 0              (eq. 8)
    c_j = 2 xi_s sqrt(k_s m1j m2j / (m1j + m2j))                                 (eq. 9)
    xi_s = -ln r / sqrt(pi^2 + (ln r)^2)                                         (eq. 10)

Law "classic" is eq. 8 as printed (F may be negative just before separation, the dashpot
pulling); law "no_tension" is contact only while the penetration AND the formula are > 0.

Harmonic excitation: table displacement A sin(w t), so ag(t) = -A w^2 sin(w t) and the
structure starts at rest relative to the table (u = v = 0, a0 = -ag(0); eq. 11).

Three references:

* `newmark_reference(scheme="implicit")`: Newmark average acceleration (gamma = 1/2,
  beta = 1/4; the paper's eqs. 11-16, Chopra's Table 5.4.2) on the full coupled system, the
  contact force taken at the end of the step with an active set consistent with the end state.
  The same discrete scheme as the kernel, but through a different linear-algebra route (one
  full np.linalg.solve per candidate set instead of the kernel's Schur complement on the
  pairs), so kernel and reference must agree to rounding.
* `newmark_reference(scheme="paper")`: the paper's section-2 scheme (trial step with F = 0,
  eq. 8 on the trial state applied as a load, step repeated once).
* `newmark_reference(scheme="event")`: Newmark with each step split where a pair switches: the
  switch instants found by scipy's brentq on the sub-step map (the kernel uses an interpolant
  estimate, then Newton and secant steps inside a false-position bracket), every sub-step a full
  np.linalg.solve.
(The continuous-time reference is reference/ivp.py; closed forms without contact reference/closed_form.py.)
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from pounding_sweep.model.coupled import CoupledModel
from pounding_sweep.model.excitation import Excitation
from pounding_sweep.sweep.simulate import with_overrides

LAWS = ("classic", "no_tension")
SCHEMES = ("implicit", "paper", "event")


# ----------------------------------------------------------------------------- the problem


def restitution_damping_ratio(r: float) -> float:
    """xi_s = -ln r / sqrt(pi^2 + (ln r)^2), eq. (10), with its limits xi_s(0) = 1 and xi_s(1) = 0.

    Written out again here (not imported) so the test can check the package's version against it.
    """
    if not 0.0 <= r <= 1.0:
        raise ValueError(f"r must lie in [0, 1], got {r!r}")
    if r == 0.0:
        return 1.0  # limit of -ln r / sqrt(pi^2 + ln^2 r) as r -> 0+
    if r == 1.0:
        return 0.0
    lnr = math.log(r)
    return -lnr / math.sqrt(math.pi**2 + lnr**2)


@dataclasses.dataclass(frozen=True)
class Problem:
    """Everything one run needs, resolved from a scene: matrices, contact parameters, loading."""

    M: np.ndarray  # (n, n) lumped mass, eq. (3)
    C: np.ndarray  # (n, n) Rayleigh damping, eq. (4)
    K: np.ndarray  # (n, n) shear-frame stiffness, eq. (3)
    G: np.ndarray  # (n, p) contact directions g_j = e(1, j) - e(2, j)
    ks: float  # contact spring k_s [N/m]
    c: np.ndarray  # (p,) dashpot c_j [N s/m], eq. (9)
    gap: float  # seismic gap d [m]
    law: str  # "classic" or "no_tension"
    scheme: str  # "implicit" or "paper"
    max_iter: int  # active-set solves per step before falling back (kernel: max_contact_iterations)
    dt: float  # time step [s] (for the ivp: the output grid spacing)
    nsteps: int
    exc_kind: str  # "harmonic" or "record"
    amp: float  # harmonic: table displacement amplitude A [m] (times the scene's scale)
    omega: float  # harmonic: table circular frequency w [rad/s]
    record: np.ndarray | None  # record: ground acceleration at t = n dt [m/s^2] (times scale)
    noise: float = 0.0  # Monte Carlo arithmetic: relative size of the random rounding (newmark_reference)
    rng: object = None

    def rounded(self, x):
        """x with a random relative rounding of size `noise` (none by default)."""
        if self.noise <= 0.0:
            return x
        return x * (1.0 + self.noise * self.rng.uniform(-1.0, 1.0, np.shape(x)))

    @property
    def n_dof(self) -> int:
        return self.M.shape[0]

    @property
    def n_pairs(self) -> int:
        return self.G.shape[1]

    def ground_acceleration(self, step: int) -> float:
        """ag at t = step * dt: -A w^2 sin(w t) for the harmonic table motion, else the record (0 past its end)."""
        if self.exc_kind == "harmonic":
            return -self.amp * self.omega**2 * math.sin(self.omega * step * self.dt)
        return float(self.record[step]) if step < self.record.size else 0.0


def resolve(scene, **overrides) -> Problem:
    """The single-point problem of `scene` with `overrides` (ks_ratio, r, gap_m, dt_s, scheme, law, ...).

    Structural matrices come from the package's CoupledModel (tested on their own in
    test_structure.py); the contact parameters are recomputed here from eqs. (9)-(10).
    """
    s = with_overrides(scene, **overrides)
    model = CoupledModel.from_scene(s)
    M, C, K = model.matrices()
    G = model.contact_matrix()
    m1, m2 = model.pair_masses()
    con = s.contact
    ks = con.ks_N_per_m if con.ks_N_per_m is not None else con.ks_ratio * con.k_ref_N_per_m
    xi = restitution_damping_ratio(con.r)
    c = np.array([2.0 * xi * math.sqrt(ks * a * b / (a + b)) for a, b in zip(m1, m2)])  # eq. (9)
    dt = s.integration.dt_s
    e = s.excitation
    if e.type == "harmonic":
        nsteps = int(round(e.duration_s / dt))
        amp, omega, record = e.amplitude_m * e.scale, 2.0 * math.pi * e.frequency_Hz, None
    else:
        # the record resampled to t = n dt by the package (linear interpolation, zero-padded),
        # the same samples the kernel reads; the reference only integrates them differently
        exc = Excitation.from_scene(s, dt)
        record = e.scale * exc.rec_flat[: exc.rec_len[0]].copy()
        nsteps, amp, omega = record.size - 1, 0.0, 0.0
    return Problem(
        M,
        C,
        K,
        G,
        float(ks),
        c,
        float(con.gap_m),
        con.law,
        s.integration.scheme,
        s.integration.max_contact_iterations,
        float(dt),
        int(nsteps),
        e.type,
        float(amp),
        float(omega),
        record,
    )


# ----------------------------------------------------------------------------- Newmark


def _solve_with_contact(P: Problem, Keff, p_hat, u_n, v_n, active):
    """End-of-step displacement and forces with the pairs in `active` in contact (implicit scheme).

    With gamma = 1/2, beta = 1/4 the end velocity is v = 2/dt (u - u_n) - v_n (Chopra Table 5.4.2;
    paper eq. 15), so eq. (8) at the end of the step is linear in u:

        F_j = k_s (g_j.u - d) + c_j g_j.v = ke_j g_j.u - b_j,
        ke_j = k_s + 2 c_j / dt,   b_j = k_s d + c_j g_j.(2/dt u_n + v_n).

    Putting F into the equation of motion at t_{n+1} (Keff u + G F = p_hat) moves ke_j g_j g_j^T
    to the left-hand side and b_j g_j to the right, for every j in the active set.
    """
    ke = P.ks + 2.0 * P.c / P.dt
    b = P.ks * P.gap + P.c * (P.G.T @ (2.0 / P.dt * u_n + v_n))
    A = Keff.copy()
    rhs = p_hat.copy()
    for j in np.flatnonzero(active):
        g = P.G[:, j]
        A += ke[j] * np.outer(g, g)
        rhs += b[j] * g
    u = P.rounded(np.linalg.solve(A, rhs))
    F = np.where(active, ke * (P.G.T @ u) - b, 0.0)
    return u, F, ke, b


def _wanted_set(P: Problem, u, ke, b) -> np.ndarray:
    """Pairs that are in contact according to the end-of-step state u (eq. 8 and the law)."""
    z = P.G.T @ u
    want = z - P.gap > 0.0
    if P.law == "no_tension":
        want &= ke * z - b > 0.0  # the force formula must push
    return want


def newmark_reference(scene, noise: float = 0.0, seed: int = 0, **overrides) -> dict:
    """Newmark average acceleration on the full coupled system, plain NumPy, one solve at a time.

    Returns t (steps+1,), u, v, a (steps+1, n_dof), F (steps+1, n_pairs), active (bool, like F),
    ag (steps+1,), impacts (per pair: steps where a pair enters the active set), unsettled (steps
    whose contact switches chattered), located (implicit scheme: steps whose active set cycled, taken by
    the event step) and the resolved Problem. Overrides are those of
    `pounding_sweep.simulate.with_overrides` (ks_ratio, r, gap_m, dt_s, scheme, law, ...).

    Each step (Chopra Table 5.4.2 in total rather than incremental form; paper eqs. 11-16):
      Keff   = K + 2/dt C + 4/dt^2 M                                  (gamma = 1/2, beta = 1/4)
      p_hat  = p_{n+1} + M (4/dt^2 u_n + 4/dt v_n + a_n) + C (2/dt u_n + v_n),  p = -M 1 ag
      solve  Keff u_{n+1} + G F_{n+1} = p_hat
      v_{n+1} = 2/dt (u_{n+1} - u_n) - v_n
      a_{n+1} = 4/dt^2 (u_{n+1} - u_n) - 4/dt v_n - a_n

    scheme "implicit": F_{n+1} from eq. (8) at the end of the step (see _solve_with_contact), for
    an active set that agrees with the end state. Starting from the previous step's set, solve,
    read off the set the solution asks for, and repeat until it stops changing. If a set comes
    back (the iteration cycles, e.g. an impact inside the step under the classic law: with the
    pair in, the dashpot throws it out; with it out, it penetrates) or max_iter solves pass, no
    set agrees with the step's end: the step is taken as the event scheme takes it (_event_step,
    from the start's set, its switches located).

    scheme "paper" (section 2): a trial step with F = 0; F from eq. (8) on the trial displacement
    and velocity (no_tension: clipped at 0) is applied as a load and the step repeated once.

    noise > 0: Monte Carlo arithmetic (Parker, Pierce & Eggert, "Monte Carlo arithmetic: how to gamble
    with floating point and win", Comput. Sci. Eng. 2(4), 2000): every displacement a solve returns,
    and every velocity and acceleration formed from it, is multiplied by (1 + noise xi), xi uniform
    in [-1, 1] (seeded): a random rounding of relative size `noise` where a program rounds, before
    the 2/dt and 4/dt^2 of eqs. 15-16 amplify it. Two runs with different seeds differ as two programs
    that round differently do: their spread measures how this trajectory amplifies rounding
    (tests/tolerances.py turns it into the tolerance of kernel-vs-reference comparisons).
    """
    P = resolve(scene, **overrides)
    if noise > 0.0:
        P = dataclasses.replace(P, noise=noise, rng=np.random.default_rng(seed))
    if P.scheme not in SCHEMES or P.law not in LAWS:
        raise ValueError(f"unknown scheme {P.scheme!r} or law {P.law!r}")
    n, p, dt, N = P.n_dof, P.n_pairs, P.dt, P.nsteps
    ones = np.ones(n)
    Keff = P.K + (2.0 / dt) * P.C + (4.0 / dt**2) * P.M

    t = np.arange(N + 1) * dt
    U, V, A = np.zeros((N + 1, n)), np.zeros((N + 1, n)), np.zeros((N + 1, n))
    F_hist, act_hist = np.zeros((N + 1, p)), np.zeros((N + 1, p), dtype=bool)
    ag = np.array([P.ground_acceleration(k) for k in range(N + 1)])
    A[0] = -ag[0] * ones  # eq. (11): a0 = M^-1 (p0 - C v0 - K u0) with u0 = v0 = 0, p0 = -M 1 ag(0)
    active = np.zeros(p, dtype=bool)
    unsettled = 0
    located = 0  # implicit scheme: steps whose active set cycled, taken by the event step
    # event scheme: entries, contact time and force extremes over every sub-step and switch
    stats = dict(impacts=np.zeros(p, dtype=int), contact_time=np.zeros(p), peak_force=np.zeros(p))

    for k in range(N):
        u_n, v_n, a_n = U[k], V[k], A[k]
        p_next = -(P.M @ ones) * ag[k + 1]
        p_hat = p_next + P.M @ (4.0 / dt**2 * u_n + 4.0 / dt * v_n + a_n) + P.C @ (2.0 / dt * u_n + v_n)

        locate = P.scheme == "event"
        if P.scheme == "implicit":
            start = active.copy()
            tried = []
            settled = False
            for _ in range(P.max_iter):
                solved = active.copy()
                tried.append(solved)
                u, F, ke, b = _solve_with_contact(P, Keff, p_hat, u_n, v_n, solved)
                want = _wanted_set(P, u, ke, b)
                if np.array_equal(want, solved):
                    settled = True
                    break
                if any(np.array_equal(want, s) for s in tried):
                    break  # cycles
                active = want
            if settled:
                stats["impacts"] += active & ~start
                stats["contact_time"] += np.where(active, dt, 0.0)
                stats["peak_force"] = np.maximum(stats["peak_force"], np.where(active, F, 0.0))
            else:  # no set agrees with its end state: the step as the event scheme takes it, from the start's set
                located += 1
                locate, active = True, start
        if locate:
            u, v, a, F, active, n_unsettled = _event_step(P, k, u_n, v_n, a_n, active, ag, stats)
            unsettled += n_unsettled
            U[k + 1], V[k + 1], A[k + 1] = u, v, a
            F_hist[k + 1] = F
            act_hist[k + 1] = active
            continue
        if P.scheme == "paper":
            u0 = P.rounded(np.linalg.solve(Keff, p_hat))  # trial step, F = 0
            z0 = P.G.T @ u0
            v0 = 2.0 / dt * (u0 - u_n) - v_n  # trial velocity (eq. 15)
            pen = z0 - P.gap
            F = np.where(pen > 0.0, P.ks * pen + P.c * (P.G.T @ v0), 0.0)  # eq. (8) on the trial state
            if P.law == "no_tension":
                F = np.maximum(F, 0.0)
                active = (pen > 0.0) & (F > 0.0)
            else:
                active = pen > 0.0
            u = P.rounded(np.linalg.solve(Keff, p_hat - P.G @ F))  # the step repeated with F as a load

        du = u - u_n
        U[k + 1] = u
        V[k + 1] = 2.0 / dt * du - v_n
        A[k + 1] = 4.0 / dt**2 * du - 4.0 / dt * v_n - a_n
        V[k + 1], A[k + 1] = P.rounded(V[k + 1]), P.rounded(A[k + 1])
        F_hist[k + 1] = F
        act_hist[k + 1] = active

    entered = act_hist[1:] & ~act_hist[:-1]
    if P.scheme in ("event", "implicit"):
        impacts, contact_time, peak = stats["impacts"], stats["contact_time"], stats["peak_force"]
    else:
        impacts, contact_time = entered.sum(axis=0), dt * act_hist[1:].sum(axis=0)
        peak = np.maximum(F_hist.max(axis=0), 0.0)
    return dict(
        t=t,
        u=U,
        v=V,
        a=A,
        F=F_hist,
        active=act_hist,
        ag=ag,
        impacts=impacts,
        contact_time=contact_time,
        peak_force=peak,
        unsettled=unsettled,
        located=located,
        problem=P,
    )


def _substep(P: Problem, h: float, ag_end: float, u, v, a, active):
    """Newmark average acceleration over h with the pairs in `active` in contact; the end state
    (u, v, a, F). As _solve_with_contact with h for dt; a from the equations of motion."""
    ones = np.ones(P.n_dof)
    Keff = P.K + (2.0 / h) * P.C + (4.0 / h**2) * P.M
    p_hat = -(P.M @ ones) * ag_end + P.M @ (4.0 / h**2 * u + 4.0 / h * v + a) + P.C @ (2.0 / h * u + v)
    ke = P.ks + 2.0 * P.c / h
    b = P.ks * P.gap + P.c * (P.G.T @ (2.0 / h * u + v))
    A = Keff.copy()
    rhs = p_hat.copy()
    for j in np.flatnonzero(active):
        A += ke[j] * np.outer(P.G[:, j], P.G[:, j])
        rhs += b[j] * P.G[:, j]
    u1 = P.rounded(np.linalg.solve(A, rhs))
    v1 = P.rounded(2.0 / h * (u1 - u) - v)
    F = np.where(active, P.ks * (P.G.T @ u1 - P.gap) + P.c * (P.G.T @ v1), 0.0)
    return u1, v1, P.rounded(_acceleration(P, ag_end, u1, v1, F)), F


def _acceleration(P: Problem, ag, u, v, F):
    """a from the equations of motion, M a = -M 1 ag - C v - K u - G F (eqs. 1-2)."""
    return np.linalg.solve(P.M, -(P.M @ np.ones(P.n_dof)) * ag - P.C @ v - P.K @ u - P.G @ F)


def _contradiction(P: Problem, u, v, active) -> np.ndarray:
    """Per pair, > 0 where the state (u, v) contradicts the contact set: penetration (and, no-tension,
    the Kelvin-Voigt force over k_s) positive for a pair out of contact, not positive for one in."""
    pen = P.G.T @ u - P.gap
    want = pen if P.law == "classic" else np.minimum(pen, pen + P.c / P.ks * (P.G.T @ v))
    return np.where(active, -want, want)


def _tolerance(P: Problem, u) -> np.ndarray:
    """Contact switches smaller than this are rounding (the kernel's _switch_tolerance)."""
    return 1e-15 + 1e-12 * (np.abs(P.G).T @ np.abs(u))


def first_root(phi, h: float, dt: float, scan: int) -> float:
    """The first s in (0, h] where phi(s) turns >= 0 (phi < 0 at 0): `scan` even points bracket it, brentq
    refines it to 1e-15 dt. Both references' event schemes locate a contact switch with it."""
    from scipy.optimize import brentq

    lo = 0.0
    for i in range(1, scan + 1):
        hi = h * i / scan
        if i == scan or phi(hi) >= 0.0:
            break
        lo = hi
    return brentq(phi, lo, hi, xtol=1e-15 * dt, rtol=4 * np.finfo(float).eps, maxiter=200)


def _event_step(P: Problem, k: int, u, v, a, active, ag, stats, max_events: int = 16, scan: int = 32):
    """One step of the event scheme from t_k: integrate with the current set; where the end
    contradicts it, find the first switch instant on the sub-step map, take the sub-step, switch
    (force from eq. 8 at that instant, a from equilibrium), and go on with what is left.

    The switch instant of a pair is the first s in (0, h] at which the state after a real Newmark
    sub-step of length s contradicts the set: the sub-step map is scanned at `scan` equal fractions
    of what is left of the step, and brentq polishes the first bracket. At s = 0 the contradiction
    is that of the start state itself (the map's limit), never a sub-step: a sub-step of length s
    carries the rounding of u amplified by 2/s in its velocity (1e-8 m in the no-tension indicator
    at s = 1e-13 s, as large as the indicator itself near a release). A pair switched at this very
    instant is on the agreeing side by construction (its indicator is zero to rounding), so its start
    is not tested; the kernel does the same (kernel._first_event's `just`)."""

    dt = P.dt
    t0 = k * dt

    def ag_at(s):  # ground acceleration s into the step: exact (harmonic) or linear between samples
        if P.exc_kind == "harmonic":
            return -P.amp * P.omega**2 * math.sin(P.omega * (t0 + s))
        return ag[k] + (ag[k + 1] - ag[k]) * s / dt

    active = active.copy()
    just = np.zeros(P.n_pairs, dtype=bool)
    s0, unsettled, events = 0.0, 0, 0
    while True:
        h = dt - s0
        end = _substep(P, h, ag_at(dt), u, v, a, active)
        bad = _contradiction(P, end[0], end[1], active) > _tolerance(P, end[0])
        if not bad.any() or events >= max_events:
            unsettled += int(bad.any())
            break
        events += 1
        times = np.full(P.n_pairs, np.inf)
        start = _contradiction(P, u, v, active)
        for j in np.flatnonzero(bad):

            def phi(s, j=j):
                if s == 0.0:
                    return -1e-300 if just[j] else min(start[j], -1e-300)
                e = _substep(P, s, ag_at(s0 + s), u, v, a, active)
                return _contradiction(P, e[0], e[1], active)[j]

            if h <= 1e-9 * dt or (not just[j] and start[j] >= 0.0):
                times[j] = 0.0  # contradicts already at the start
                continue
            times[j] = first_root(phi, h, dt, scan)
        s = times.min()
        if s > 1e-9 * dt:
            if dt - (s0 + s) <= 1e-9 * dt:
                s = h
            u, v, a, F = _substep(P, s, ag_at(s0 + s), u, v, a, active)
            stats["contact_time"] += np.where(active, s, 0.0)
            stats["peak_force"] = np.maximum(stats["peak_force"], np.where(active, F, 0.0))
            s0 += s
        switch = times <= s * (1 + 1e-9) + 1e-12 * dt
        just = switch
        stats["impacts"] += switch & ~active
        active = active ^ switch
        F = np.where(active, P.ks * (P.G.T @ u - P.gap) + P.c * (P.G.T @ v), 0.0)
        stats["peak_force"] = np.maximum(stats["peak_force"], np.where(active, F, 0.0))
        a = _acceleration(P, ag_at(s0), u, v, F)
        if dt - s0 <= 1e-9 * dt:
            return u, v, a, F, active, unsettled
    u, v, a, F = end
    stats["contact_time"] += np.where(active, h, 0.0)
    stats["peak_force"] = np.maximum(stats["peak_force"], np.where(active, F, 0.0))
    return u, v, a, F, active, unsettled


def paper_scheme_reference(scene, **overrides) -> dict:
    """newmark_reference with the paper's section-2 scheme (trial step, eq. 8 as a load, step repeated)."""
    return newmark_reference(scene, **dict(overrides, scheme="paper"))
