"""A continuous-time reference with a model error the engine cannot represent: story springs whose stiffness
falls with the drift (amplitude-dependent stiffness), integrated by solve_ivp with contact events.

Why: a calibration must say when its model is wrong and widen its intervals accordingly (sweep/uncertainty.py).
Testing that needs data made by a structure the fitted model is not: a shear frame whose secant stiffness
depends on the motion's amplitude, as real frames' (joint slip, friction) does, so the stiffness a linear
model fits to the strong part of a record differs from the one it fits to the quiet part.

The story spring (per story i of a building, drift delta_i = u_i - u_(i-1), u_0 = 0 the table):

    f_i(delta) = k_i s tanh(delta / s)

k_i the scene's story stiffness, s the drift scale [m]. For |delta| << s it is the linear spring k_i delta;
in harmonic motion of drift amplitude X its equivalent (first-harmonic) stiffness is, to leading order,
k_i (1 - X^2 / (4 s^2)): tanh x = x - x^3/3 + ..., and a cubic term eps delta^3 adds (3/4) eps X^2 to the
equivalent stiffness (harmonic balance: Nayfeh & Mook 1979, Nonlinear Oscillations, sec. 4.1).
drift_scale_m = None (or inf) gives the linear frame.

The rest is the paper's model (eqs. 1-2, 8): lumped masses, Rayleigh damping of the linear frame, the
Kelvin-Voigt contact (laws classic and no_tension) between facing floors, harmonic or record ground motion:

    M v' = -C v - f(u) - G F(u, v) - M 1 ag(t).

Integration: DOP853 to rtol 1e-10 (atol 1e-13 m), one smooth piece per contact set, each piece ended at a
contact event (terminal events on the dense output, as reference/ivp.py's) or at a record sample (where ag
has a kink), so nothing is integrated across a discontinuity of the right-hand side. With drift_scale_m =
None it solves the same equations as reference/ivp.py's continuous_reference, by a nonlinear right-hand side
instead of the linear systems (tests/sweep/test_synthetic_ivp.py compares the two)."""

from __future__ import annotations

import math

import numpy as np
from scipy.integrate import solve_ivp

from pounding_sweep.reference.ivp import contact_force, ground_acceleration_fn
from pounding_sweep.reference.newmark import resolve
from pounding_sweep.sweep.simulate import with_overrides


def story_chains(K: np.ndarray, floors: tuple[int, ...]) -> list[tuple[np.ndarray, np.ndarray]]:
    """Per building: (its DOFs, floor 1 first; its story stiffnesses k_1..k_n) read off the assembled shear-frame
    stiffness K (K[i, i] = k_i + k_(i+1), K[i, i+1] = -k_(i+1)); the chain rebuilt from them must give K back."""
    out, start = [], 0
    for n in floors:
        dof = np.arange(start, start + n)
        k = np.empty(n)
        for i in range(n - 1, -1, -1):
            above = k[i + 1] if i + 1 < n else 0.0
            k[i] = K[dof[i], dof[i]] - above
            if i > 0:
                k[i] = -K[dof[i - 1], dof[i]]
        out.append((dof, k))
        start += n
    rebuilt = np.zeros_like(K)
    for dof, k in out:
        for i, d in enumerate(dof):
            rebuilt[d, d] += k[i]
            if i > 0:
                rebuilt[dof[i - 1], dof[i - 1]] += k[i]
                rebuilt[d, dof[i - 1]] = rebuilt[dof[i - 1], d] = -k[i]
    if not np.allclose(rebuilt, K, rtol=1e-12, atol=1e-12 * np.abs(K).max()):
        raise ValueError("story_chains: K is not two shear-frame chains")
    return out


def story_forces(u: np.ndarray, chains, s: float | None) -> np.ndarray:
    """The story springs' force on each DOF (module docstring); s None: linear (K u)."""
    out = np.zeros_like(u)
    for dof, k in chains:
        x = u[dof]
        drift = np.diff(x, prepend=0.0)
        f = k * drift if s is None else k * s * np.tanh(drift / s)
        out[dof] = f - np.append(f[1:], 0.0)
    return out


def _chord(f, t0: float, t1: float):
    """The straight line through (t0, f(t0)) and (t1, f(t1)) (f(t0) where t1 = t0)."""
    f0, f1 = f(t0), f(t1)
    rate = (f1 - f0) / (t1 - t0) if t1 > t0 else 0.0
    return lambda t: f0 + rate * (t - t0)


def softening_reference(
    scene, drift_scale_m: float | None, t_end=None, dt_out=1e-3, rtol=1e-10, atol=1e-13, max_step=1e-3, **overrides
) -> dict:
    """The scene's point (`overrides`: ks_ratio, r, ...) with softening story springs of drift scale
    `drift_scale_m` (module docstring). Returns t (grid of spacing dt_out from 0 to t_end, default the scene's
    duration), u, v (relative to the table), a_abs (absolute acceleration), F (contact force per pair), ag on
    that grid, the events (time, pair, "contact" | "separation") and impacts per pair."""
    s = with_overrides(scene, **overrides)
    if s.contact.law not in ("classic", "no_tension"):
        raise ValueError(f"softening_reference: law {s.contact.law!r}; classic or no_tension only")
    if drift_scale_m is not None and not (math.isinf(drift_scale_m) or drift_scale_m > 0.0):
        raise ValueError(f"softening_reference: drift_scale_m = {drift_scale_m}, must be > 0")
    scale = None if drift_scale_m is None or math.isinf(drift_scale_m) else float(drift_scale_m)
    P = resolve(scene, **overrides)
    n, p, ks, d = P.n_dof, P.n_pairs, P.ks, P.gap
    floors = (len(s.building1.masses_kg), len(s.building2.masses_kg))
    chains = story_chains(P.K, floors)
    minv = 1.0 / np.diag(P.M)  # lumped masses
    if t_end is None:
        t_end = P.nsteps * P.dt
    ag, knots = ground_acceleration_fn(s, t_end)
    stops = np.concatenate([knots, [t_end]])
    grid = np.arange(int(math.floor(t_end / dt_out + 1e-9)) + 1) * dt_out
    Y = np.full((grid.size, 2 * n), np.nan)
    ACT = np.zeros((grid.size, p), dtype=bool)

    def rhs_for(active, ground):
        sel = [j for j in range(p) if active[j]]

        def rhs(t, y):
            u, v = y[:n], y[n:]
            f = P.C @ v + story_forces(u, chains, scale)
            for j in sel:
                f = f + P.G[:, j] * contact_force(P, j, y)
            return np.concatenate([v, -minv * f - ground(t)])

        return rhs

    def event(j, direction):
        def h(t, y):
            pen = P.G[:, j] @ y[:n] - d
            return min(pen, contact_force(P, j, y) / ks) if P.law == "no_tension" else pen

        h.terminal, h.direction = True, direction
        return h

    events = []
    y = np.zeros(2 * n)
    t0, k_stop, stalls = 0.0, 0, 0
    active = (False,) * p
    harmonic = s.excitation.type == "harmonic"
    options = dict(method="DOP853", rtol=rtol, atol=atol, max_step=max_step, dense_output=True)
    while True:
        t_stop = stops[k_stop]
        # ag: smooth (harmonic), evaluated at every stage; or linear between record samples, the pieces ending there
        ground = ag if harmonic else _chord(ag, t0, t_stop)
        evs = [event(j, -1.0 if active[j] else 1.0) for j in range(p)]
        sol = solve_ivp(rhs_for(active, ground), (t0, t_stop), y, events=evs, **options)
        if sol.status < 0:
            raise RuntimeError(f"softening_reference: solve_ivp failed at t = {sol.t[-1]}: {sol.message}")
        t1 = sol.t[-1]
        on = np.flatnonzero((grid >= t0 - 1e-12) & (grid <= t1 + 1e-12))  # the output instants in this piece
        if on.size:
            Y[on], ACT[on] = sol.sol(np.clip(grid[on], t0, t1)).T, active
        if sol.status == 1:  # a contact event ended the piece: the earliest pair flips
            j = int(np.argmin([tev[0] if tev.size else np.inf for tev in sol.t_events]))
            te, y = float(sol.t_events[j][0]), sol.y_events[j][0].copy()
            stalls = (stalls + 1) * (te - t0 < 1e-12)
            if stalls > 10:
                raise RuntimeError(f"softening_reference: contact set chatters at t = {te}")
            active = active[:j] + (not active[j],) + active[j + 1 :]
            events.append((te, j, "contact" if active[j] else "separation"))
            t0 = te
            continue
        y, t0, k_stop = sol.y[:, -1].copy(), t_stop, k_stop + 1
        if k_stop == stops.size:
            break
    u, v = Y[:, :n], Y[:, n:]
    F = np.zeros((grid.size, p))
    for j in range(p):
        F[:, j] = np.where(ACT[:, j], contact_force(P, j, Y.T), 0.0)
    restoring = np.array([story_forces(uu, chains, scale) for uu in u])
    a_abs = -(v @ P.C.T + restoring + F @ P.G.T) * minv  # M (a + ag) = -C v - f(u) - G F
    impacts = np.array([sum(1 for e in events if e[1] == j and e[2] == "contact") for j in range(p)])
    agv = np.array([ag(t) for t in grid])
    return dict(t=grid, u=u, v=v, a_abs=a_abs, F=F, ag=agv, events=events, impacts=impacts, problem=P)
