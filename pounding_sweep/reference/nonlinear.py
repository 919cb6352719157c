"""The discrete reference for the Hertz-type laws: engine/nonlinear.py's Newmark schemes on the full coupled
system, plain NumPy and SciPy root finders, one step at a time.

The laws, written out again from their papers (not imported, so the tests check the kernel against them);
delta = g.u - d the penetration, delta_dot = g.v its rate, F > 0 in compression, 0 for delta <= 0:

    hertz      F = k_h delta^1.5                                               (Hertz 1882; Davis 1992)
    hertzdamp  F = max(0, k_h delta^1.5 (1 + a delta_dot / v0))                 (Muthukumar & DesRoches 2006)
    jankowski  F = k_h delta^1.5 + 2 xi sqrt(k_h sqrt(delta) m_eff) delta_dot  if delta_dot > 0, else k_h delta^1.5
                                                                               (Jankowski 2005)

v0 = max(approach speed at the impact's start, min_impact_speed_m_s). The damping parameters come from
the package's relations (model/laws.py, checked on their own by the single-impact tests); the stiffness
k_h = kh_N_per_m1_5, or k_s / sqrt(reference_penetration_m), is formed here.

Each step (the kernel's schemes, a different route through the algebra):
* implicit: the full n-DOF equation Keff u + G F(G^T u - d, G^T v(u)) = p_hat with v(u) = 2/dt (u - u_n) - v_n
  (eq. 15) solved by MINPACK's hybrid Powell method (scipy.optimize.root, finite-difference Jacobian;
  the kernel works in pair space with its analytic Jacobian), where the contact-free step penetrates;
* event: the step with the pairs in contact at its start carrying the law, split where a pair's
  penetration crosses zero, the crossing found by brentq on the sub-step map (hertzdamp: v0 from that
  state);
* paper: the forces from the contact-free trial state applied as loads, the step repeated once.
Hertz-damp's v0 in the implicit and paper schemes: the rate where the cubic Hermite interpolant of the
contact-free step's penetration first crosses zero.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from scipy.optimize import brentq, root

from pounding_sweep.model.laws import damping_parameter
from pounding_sweep.reference.newmark import Problem, first_root, resolve
from pounding_sweep.sweep.simulate import with_overrides

LAWS = ("hertz", "hertzdamp", "jankowski")


@dataclasses.dataclass(frozen=True)
class LawProblem:
    """A Problem (matrices, loading, dt) with a Hertz-type law's parameters."""

    base: Problem
    law: str
    kh: float  # k_h [N/m^1.5]
    a: float  # hertzdamp: normalised damping a
    xi: float  # jankowski: damping ratio
    meff: np.ndarray  # (p,) reduced masses of the facing floors [kg]
    vmin: float  # hertzdamp: floor on v0 [m/s]


def resolve_law(scene, **overrides) -> LawProblem:
    """The single point of `scene` with `overrides` (law, ks_ratio, r, gap_m, scheme, dt_s, ...)."""
    s = with_overrides(scene, **overrides)
    c = s.contact
    if c.law not in LAWS:
        raise ValueError(f"resolve_law: {c.law!r} is not a Hertz-type law")
    base = resolve(scene, **overrides)
    if c.kh_N_per_m1_5 is not None:
        kh = c.kh_N_per_m1_5
    else:
        ks = c.ks_N_per_m if c.ks_N_per_m is not None else c.ks_ratio * c.k_ref_N_per_m
        kh = ks / math.sqrt(c.reference_penetration_m)
    p = damping_parameter(c.law, c.r, c.restitution_relation)
    m = np.diag(base.M)
    g = base.G
    m1 = np.array([m[np.flatnonzero(g[:, j] > 0)[0]] for j in range(g.shape[1])])
    m2 = np.array([m[np.flatnonzero(g[:, j] < 0)[0]] for j in range(g.shape[1])])
    return LawProblem(
        base,
        c.law,
        float(kh),
        p if c.law == "hertzdamp" else 0.0,
        p if c.law == "jankowski" else 0.0,
        m1 * m2 / (m1 + m2),
        c.min_impact_speed_m_s,
    )


def pounding_force(Q: LawProblem, j: int, delta: float, rate: float, v0: float) -> float:
    """The law's force on pair j (module docstring)."""
    if delta <= 0.0:
        return 0.0
    el = Q.kh * delta**1.5
    if Q.law == "hertz":
        return el
    if Q.law == "hertzdamp":
        return max(0.0, el * (1.0 + Q.a * rate / v0)) if Q.a > 0.0 else el
    if rate > 0.0:
        return el + 2.0 * Q.xi * math.sqrt(Q.kh * math.sqrt(delta) * Q.meff[j]) * rate
    return el


def _hermite_crossing_rate(p0, p1, m0, m1, h):
    """Rate where the cubic Hermite interpolant (values p0 <= 0 < p1, end slopes m0, m1 over [0, h]) first
    crosses zero."""

    def p(t):
        return (
            (2 * t**3 - 3 * t**2 + 1) * p0
            + (t**3 - 2 * t**2 + t) * m0 * h
            + (-2 * t**3 + 3 * t**2) * p1
            + (t**3 - t**2) * m1 * h
        )

    ts = np.linspace(0.0, 1.0, 257)
    vals = np.array([p(t) for t in ts])
    k = int(np.argmax(vals > 0.0))
    t = brentq(p, ts[k - 1], ts[k], xtol=1e-16) if k > 0 and vals[k - 1] <= 0.0 else 0.0
    dp = (
        (6 * t**2 - 6 * t) * p0
        + (3 * t**2 - 4 * t + 1) * m0 * h
        + (-6 * t**2 + 6 * t) * p1
        + (3 * t**2 - 2 * t) * m1 * h
    )
    return dp / h


def law_newmark_reference(scene, noise: float = 0.0, seed: int = 0, **overrides) -> dict:
    """Newmark average acceleration with a Hertz-type law (module docstring). Returns t, u, v, a, F, active,
    ag, impacts, peak_force, contact_time, unsettled, grazing (a v0 was floored) and the LawProblem.
    noise > 0: Monte Carlo arithmetic twins as newmark_reference's."""
    Q = resolve_law(scene, **overrides)
    P = Q.base
    if noise > 0.0:
        P = dataclasses.replace(P, noise=noise, rng=np.random.default_rng(seed))
        Q = dataclasses.replace(Q, base=P)
    n, p, dt, N = P.n_dof, P.n_pairs, P.dt, P.nsteps
    ones = np.ones(n)
    t = np.arange(N + 1) * dt
    U, V, A = np.zeros((N + 1, n)), np.zeros((N + 1, n)), np.zeros((N + 1, n))
    F_hist, act_hist = np.zeros((N + 1, p)), np.zeros((N + 1, p), dtype=bool)
    ag = np.array([P.ground_acceleration(k) for k in range(N + 1)])
    A[0] = -ag[0] * ones
    st = dict(
        active=np.zeros(p, dtype=bool),
        v0=np.full(p, np.inf),
        impacts=np.zeros(p, dtype=int),
        contact_time=np.zeros(p),
        peak_force=np.zeros(p),
        unsettled=0,
        grazing=False,
    )
    for k in range(N):
        if P.scheme == "event":
            u, v, a, F = _event_step(Q, k, U[k], V[k], A[k], ag, st)
        else:
            u, v, a, F = _plain_step(Q, k, U[k], V[k], A[k], ag, st)
        U[k + 1], V[k + 1], A[k + 1] = u, v, a
        F_hist[k + 1] = F
        act_hist[k + 1] = st["active"]
    return dict(
        t=t,
        u=U,
        v=V,
        a=A,
        F=F_hist,
        active=act_hist,
        ag=ag,
        impacts=st["impacts"],
        contact_time=st["contact_time"],
        peak_force=st["peak_force"],
        unsettled=st["unsettled"],
        grazing=st["grazing"],
        problem=Q,
    )


def _v0(Q: LawProblem, rate: float, st) -> float:
    """v0 of an impact starting at `rate`, floored (and the run flagged) below min_impact_speed."""
    if rate < Q.vmin:
        st["grazing"] = True
        return Q.vmin
    return rate


def _forces(Q: LawProblem, u, v, carry, v0) -> np.ndarray:
    z, zd = Q.base.G.T @ u - Q.base.gap, Q.base.G.T @ v
    return np.array([pounding_force(Q, j, z[j], zd[j], v0[j]) if carry[j] else 0.0 for j in range(z.size)])


def _solve(Q: LawProblem, h, ag_end, u, v, a, carry, v0):
    """Newmark over h from (u, v, a) with the pairs in `carry` carrying the law: the end state (u, v, a, F)."""
    P = Q.base
    Keff = P.K + (2.0 / h) * P.C + (4.0 / h**2) * P.M
    p_hat = -(P.M @ np.ones(P.n_dof)) * ag_end + P.M @ (4.0 / h**2 * u + 4.0 / h * v + a) + P.C @ (2.0 / h * u + v)
    u_free = np.linalg.solve(Keff, p_hat)
    u1 = u_free
    if carry.any() and (P.G.T @ u_free - P.gap > 0.0)[carry].any():

        def residual(x):
            return Keff @ x + P.G @ _forces(Q, x, 2.0 / h * (x - u) - v, carry, v0) - p_hat

        sol = root(residual, u_free, method="hybr", options={"xtol": 1e-15, "maxfev": 20000})
        u1 = sol.x
        if not sol.success and np.max(np.abs(residual(u1))) > 1e-9 * np.max(np.abs(p_hat)):
            raise RuntimeError(f"law_newmark_reference: the contact solve failed ({sol.message})")
    u1 = P.rounded(u1)
    v1 = P.rounded(2.0 / h * (u1 - u) - v)
    F = _forces(Q, u1, v1, carry, v0)
    a1 = P.rounded(np.linalg.solve(P.M, -(P.M @ np.ones(P.n_dof)) * ag_end - P.C @ v1 - P.K @ u1 - P.G @ F))
    return u1, v1, a1, F


def _plain_step(Q: LawProblem, k, u, v, a, ag, st):
    """The implicit or paper scheme's step (module docstring)."""
    P = Q.base
    dt = P.dt
    active = st["active"]
    v0 = st["v0"].copy()
    Keff = P.K + (2.0 / dt) * P.C + (4.0 / dt**2) * P.M
    p_hat = (
        -(P.M @ np.ones(P.n_dof)) * ag[k + 1] + P.M @ (4.0 / dt**2 * u + 4.0 / dt * v + a) + P.C @ (2.0 / dt * u + v)
    )
    u_free = np.linalg.solve(Keff, p_hat)
    v_free = 2.0 / dt * (u_free - u) - v
    z0, z1 = P.G.T @ u - P.gap, P.G.T @ u_free - P.gap
    graze = np.zeros(P.n_pairs, dtype=bool)
    for j in range(P.n_pairs):
        if not active[j] and z1[j] > 0.0 and Q.law == "hertzdamp":
            rate = _hermite_crossing_rate(z0[j], z1[j], P.G[:, j] @ v, P.G[:, j] @ v_free, dt)
            graze[j] = rate < Q.vmin
            v0[j] = max(rate, Q.vmin)
    carry = np.ones(P.n_pairs, dtype=bool)
    if P.scheme == "paper":
        F = _forces(Q, u_free, v_free, carry, v0)
        u1 = P.rounded(np.linalg.solve(Keff, p_hat - P.G @ F))
    else:
        u1, _, _, F = _solve(Q, dt, ag[k + 1], u, v, a, carry, v0)
    du = u1 - u
    v1 = P.rounded(2.0 / dt * du - v)
    a1 = P.rounded(4.0 / dt**2 * du - 4.0 / dt * v - a)
    pen = P.G.T @ u1 - P.gap
    # in contact: penetrating at the end (implicit), or, in the paper's scheme, where the law acted (its forces
    # come from the contact-free trial, which a stiff contact at a coarse step can push apart by the step's end)
    touch = z1 > 0.0 if P.scheme == "paper" else pen > 0.0
    for j in range(P.n_pairs):
        if touch[j] and not active[j]:
            st["impacts"][j] += 1
            if Q.law == "hertzdamp":
                if not np.isfinite(v0[j]):  # the contact-free trial did not close the gap: v0 from this step
                    rate = _hermite_crossing_rate(z0[j], pen[j], P.G[:, j] @ v, P.G[:, j] @ v1, dt)
                    graze[j] = rate < Q.vmin
                    v0[j] = max(rate, Q.vmin)
                st["grazing"] |= bool(graze[j])
        if not touch[j]:
            v0[j] = np.inf
    st["active"] = touch
    st["v0"] = v0
    st["contact_time"] += np.where(st["active"], dt, 0.0)
    st["peak_force"] = np.maximum(st["peak_force"], np.where(st["active"], F, 0.0))
    return u1, v1, a1, F


def _event_step(Q: LawProblem, k, u, v, a, ag, st, max_events: int = 16, scan: int = 32):
    """The event scheme's step: the pairs in contact carry the law; where the end state's penetration
    contradicts the set, the first crossing is found by a scan of the sub-step map and brentq, the
    sub-step taken, the pair switched (an impact: v0 from the state there), and the rest continued."""
    P = Q.base
    dt = P.dt
    t0 = k * dt

    def ag_at(s):
        if P.exc_kind == "harmonic":
            return -P.amp * P.omega**2 * math.sin(P.omega * (t0 + s))
        return ag[k] + (ag[k + 1] - ag[k]) * s / dt

    def contradiction(uu, active):
        pen = P.G.T @ uu - P.gap
        return np.where(active, -pen, pen)

    def tolerance(uu):
        return 1e-15 + 1e-12 * (np.abs(P.G).T @ np.abs(uu))  # the kernel's _switch_tolerance

    active = st["active"].copy()
    v0 = st["v0"]
    just = np.zeros(P.n_pairs, dtype=bool)
    s0, events = 0.0, 0
    while True:
        h = dt - s0
        end = _solve(Q, h, ag_at(dt), u, v, a, active, v0)
        bad = contradiction(end[0], active) > tolerance(end[0])
        if not bad.any() or events >= max_events:
            st["unsettled"] += int(bad.any())
            break
        events += 1
        times = np.full(P.n_pairs, np.inf)
        start = contradiction(u, active)
        for j in np.flatnonzero(bad):

            def phi(s, j=j):
                if s == 0.0:
                    return -1e-300 if just[j] else min(start[j], -1e-300)
                e = _solve(Q, s, ag_at(s0 + s), u, v, a, active, v0)
                return contradiction(e[0], active)[j]

            if h <= 1e-9 * dt or (not just[j] and start[j] >= 0.0):
                times[j] = 0.0
                continue
            times[j] = first_root(phi, h, dt, scan)
        s = times.min()
        if s > 1e-9 * dt:
            if dt - (s0 + s) <= 1e-9 * dt:
                s = h
            u, v, a, F = _solve(Q, s, ag_at(s0 + s), u, v, a, active, v0)
            st["contact_time"] += np.where(active, s, 0.0)
            st["peak_force"] = np.maximum(st["peak_force"], np.where(active, F, 0.0))
            s0 += s
        switch = times <= s * (1 + 1e-9) + 1e-12 * dt
        just = switch
        for j in np.flatnonzero(switch):
            if not active[j]:
                st["impacts"][j] += 1
                if Q.law == "hertzdamp":
                    v0[j] = _v0(Q, float(P.G[:, j] @ v), st)
            else:
                v0[j] = np.inf
        active = active ^ switch
        F = _forces(Q, u, v, active, v0)
        a = np.linalg.solve(P.M, -(P.M @ np.ones(P.n_dof)) * ag_at(s0) - P.C @ v - P.K @ u - P.G @ F)
        if dt - s0 <= 1e-9 * dt:
            st["active"] = active
            return u, v, a, F
    u, v, a, F = end
    st["contact_time"] += np.where(active, h, 0.0)
    st["peak_force"] = np.maximum(st["peak_force"], np.where(active, F, 0.0))
    st["active"] = active
    return u, v, a, F
