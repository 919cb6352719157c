"""Error against run time per integration scheme, against a converged continuous-time reference.

Usage (from the repository root, after `pip install ".[test]"`):

    python benchmarks/bench_accuracy.py [--quick] [--scene paper_6hz|paper_duzce ...] [--ks-ratio 10] [--r R]

For each shipped scene (`sweeps/paper_6hz.toml`, harmonic; `sweeps/paper_duzce.toml`, the Duzce
record at similitude 1/15), at one contact point (default k_s/k = 10, the stiffest of the paper's
grid, and the scene's own r), each scheme (event, implicit, paper) runs a ladder of time steps
from 5e-3 s down to 1e-6 s (1-2.5-5 steps, every one a whole fraction of 5e-3 s, so all runs are
compared on the same 5 ms grid). Every run has the scene's full duration (6 Hz: 5 s; Duzce: 6.68 s,
the record's 6.682 s cut to a whole number of 5 ms samples), the same for every scheme, every dt
and the reference: the event kernel runs 1e-6 s steps fast enough that no shorter window is needed.

Reference: the continuous-time problem (eqs. 1-2, 8) by solve_ivp DOP853 with contact events
(`continuous_reference` below: tests/reference.py's `ivp_reference` algorithm, one smooth piece per
contact set, restarted at every contact event, extended to records by also restarting at every
record sample, where the linearly interpolated ground acceleration has a kink). It shares no
discretisation with the kernel. Its convergence is checked against itself at a 10x tighter rtol,
against `ivp_reference` itself on the harmonic scene, and against a Richardson extrapolation of
the event scheme at 5e-6 and 1e-5 s; all three are printed. (Below about 2.5e-6 s the kernel's own
rounding floor takes over: Newmark in total form recovers v = 2/dt (u_n+1 - u_n) - v_n from a
difference of nearly equal displacements, an error that grows about as dt^-2; the finest rungs
show it, and the order fit stops at each scheme's smallest error.)

Errors (columns; percentages relative to the reference):
  rel_rms_b1f3_pct, rel_rms_b2f3_pct: top-floor displacement histories, eq. 20, on the 5 ms grid;
  rel_rms_pct: the larger of the two (the column `pounding_sweep.plots` plots);
  peak_disp_err_pct: the larger |relative error| of the two top floors' peak |displacement|;
  peak_force_err_pct: |relative error| of the peak floor-3 pounding force;
  impacts_f3 / ref_impacts_f3: impact counts of the floor-3 pair.
Run time: the kernel's `run_time_s` (compile excluded: the kernel is compiled before any timing),
the least of `--repeats` runs.

Writes results/bench_accuracy_<scene>.csv (readable by `pounding_sweep.plots.read_accuracy_table`)
and results/bench_accuracy_<scene>.png (`error_vs_runtime_figure`: error against dt and against
run time, log-log, one line per scheme). Prints the table, the observed order per scheme (least
squares slope of log error against log dt over the asymptotic range, stated with the fit), and
the equal-run-time ratio of the paper scheme's error to the event scheme's (the paper scheme's
log error against log run time interpolated at each event run's time).
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd
from scipy.integrate import solve_ivp
from scipy.optimize import minimize_scalar

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "tests"))

from pounding_sweep.scene import load_scene  # noqa: E402
from pounding_sweep.model.excitation import Excitation  # noqa: E402
from pounding_sweep.engine.score import relative_rms_error_pct  # noqa: E402
from pounding_sweep.sweep.simulate import simulate, with_overrides  # noqa: E402
from reference import contact_force, contact_set_systems, resolve  # noqa: E402

SCENES = {"paper_6hz": REPO / "sweeps" / "paper_6hz.toml", "paper_duzce": REPO / "sweeps" / "paper_duzce.toml"}
SCHEMES = ("event", "implicit", "paper")
SAMPLE_DT = 5e-3  # histories compared every 5 ms: the coarsest dt, which every dt of the ladder divides
DTS = (5e-3, 2.5e-3, 1e-3, 5e-4, 2.5e-4, 1e-4, 5e-5, 2.5e-5, 1e-5, 5e-6, 2.5e-6, 1e-6)
DURATION_S = {"paper_6hz": 5.0, "paper_duzce": 6.68}
QUICK_DTS = (1e-3, 5e-4, 2.5e-4, 1e-4)
QUICK_DURATION_S = {"paper_6hz": 0.5, "paper_duzce": 1.0}
REF_RTOL, REF_ATOL = 1e-12, 1e-15  # the reference; its check runs at 10x tighter
PEAK_SCAN_S = 2e-5  # dense-output scan spacing for the reference's peaks (then refined by Brent)
RICHARDSON_DT_MIN = 5e-6  # finer, the kernel's rounding floor (Newmark in total form) spoils the extrapolation
TOP = 3  # floor of the top-floor channels and of the pounding-force pair


# ----------------------------------------------------------------------------- the reference


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


def continuous_reference(scene, sample_dt=SAMPLE_DT, rtol=REF_RTOL, atol=REF_ATOL, max_step=1e-3,
                         peak_scan_s=PEAK_SCAN_S, **overrides) -> Reference:
    """solve_ivp (DOP853) with contact events on the scene's point (`overrides`: ks_ratio, r, law, ...).

    Each piece is a linear ODE y' = A_S y + f_S - [0; 1] ag(t) for the contact set S (y = (u, v)),
    smooth up to its end: the next contact event (a pair's penetration, or under no_tension its
    Kelvin-Voigt force, crossing zero: terminal events located on the dense output), or the next
    record sample (where ag has a kink), or the end. tests/reference.py's `ivp_reference` for records
    too; `check_against_ivp_reference` compares the two on a harmonic scene."""
    t_wall = time.perf_counter()
    s = with_overrides(scene, **overrides)
    P = resolve(scene, **overrides)  # matrices and contact parameters, from tests/reference.py
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
    system = contact_set_systems(P)  # the same first-order systems as tests/reference.py's ivp_reference

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
        sol = solve_ivp(rhs, (t0, t_stop), y, method="DOP853", rtol=rtol, atol=atol, max_step=max_step, events=evs,
                        dense_output=True)
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
            r = minimize_scalar(lambda t: -fun(kk, t), bounds=(a, b), method="bounded",
                                options={"xatol": 1e-14 + 1e-12 * abs(t_b)})
            out = max(out, -r.fun, fun(kk, a), fun(kk, b))
        return out

    peak_u = np.array([refine(lambda kk, t, i=i: abs(pieces[kk][2](t)[i]), best_u[i]) for i in range(n)])
    peak_F = np.array([refine(lambda kk, t, j=j: force(j, pieces[kk][2](t)) if pieces[kk][3][j] else 0.0, best_F[j])
                       for j in range(p)])
    impacts = np.array([sum(1 for ev in events if ev[1] == j and ev[2] == "contact") for j in range(p)])
    return Reference(grid, top, peak_u, peak_F, impacts, events, rtol, time.perf_counter() - t_wall)


def reference_self_check(scene, ref: Reference, **overrides) -> dict:
    """The reference against itself at 10x tighter rtol and atol: how much of it is tolerance."""
    tight = continuous_reference(scene, rtol=ref.rtol / 10, atol=REF_ATOL / 10, **overrides)
    same_events = [ev[1:] for ev in ref.events] == [ev[1:] for ev in tight.events]
    dt_ev = max((abs(a[0] - b[0]) for a, b in zip(ref.events, tight.events)), default=0.0)
    return {
        "rtol": ref.rtol, "rtol_check": tight.rtol,
        "rel_rms_pct": max(float(relative_rms_error_pct(ref.top[:, c], tight.top[:, c])) for c in (0, 1)),
        "peak_disp_pct": float(np.max(np.abs(ref.peak_disp / tight.peak_disp - 1))) * 100,
        "peak_force_pct": float(np.max(np.abs(ref.peak_force / tight.peak_force - 1))) * 100,
        "same_events": same_events, "event_time_s": dt_ev, "events": len(ref.events),
        "wall_s": ref.wall_s, "wall_check_s": tight.wall_s,
    }


def check_against_ivp_reference(scene, ref: Reference, **overrides) -> dict:
    """tests/reference.py's ivp_reference (harmonic only) at the same tolerance, on the same grid."""
    from reference import ivp_reference

    other = ivp_reference(scene, rtol=ref.rtol, atol=REF_ATOL, dt_out=SAMPLE_DT, **overrides)
    n = other["u"].shape[1]
    top = other["u"][:, [TOP - 1, n // 2 + TOP - 1]]
    m = min(top.shape[0], ref.top.shape[0])
    return {"rel_rms_pct": max(float(relative_rms_error_pct(ref.top[:m, c], top[:m, c])) for c in (0, 1)),
            "same_impacts": other["impacts"].tolist() == ref.impacts.tolist()}


# ----------------------------------------------------------------------------- the kernel's runs


def base_scene(name: str, duration_s: float):
    """The shipped scene's base point, no sweep, the given duration."""
    s = load_scene(SCENES[name])
    return dataclasses.replace(s, sweep=(), experiment=None,
                               excitation=dataclasses.replace(s.excitation, duration_s=float(duration_s)))


def kernel_run(scene, dt: float, scheme: str, repeats: int = 3, **overrides) -> dict:
    """One (scheme, dt) point: top-floor histories on the SAMPLE_DT grid, metrics, least run time."""
    n = SAMPLE_DT / dt
    if abs(n - round(n)) > 1e-9 * n:
        raise ValueError(f"dt = {dt:g} s does not divide the {SAMPLE_DT:g} s sampling step")
    chans = [f"disp_b1f{TOP}", f"disp_b2f{TOP}"]
    times = []
    for _ in range(max(1, repeats)):
        hist, m = simulate(scene, channels=chans, decimate=int(round(n)), dt_s=dt, scheme=scheme, **overrides)
        times.append(m["run_time_s"])
    m["run_time_s"] = min(times)
    return {"top": hist[[f"{c}_m" for c in chans]].to_numpy(), "metrics": m}


def error_row(run: dict, ref: Reference, scheme: str, dt: float) -> dict:
    """The errors of one kernel run against the reference (NaN where the run diverged)."""
    m = run["metrics"]
    x = run["top"]
    k = min(x.shape[0], ref.top.shape[0])
    rr = [float(relative_rms_error_pct(x[:k, c], ref.top[:k, c])) if np.all(np.isfinite(x[:k, c])) else np.nan
          for c in (0, 1)]
    diverged = "diverged" in m["status"]
    if diverged:
        rr = [np.nan, np.nan]
    n_dof = ref.peak_disp.size
    pk = np.array([m[f"peak_disp_b1f{TOP}_m"], m[f"peak_disp_b2f{TOP}_m"]])
    pk_ref = ref.peak_disp[[TOP - 1, n_dof // 2 + TOP - 1]]
    pf, pf_ref = m[f"peak_force_f{TOP}_N"], ref.peak_force[TOP - 1]
    nan = np.nan
    return {
        "scheme": scheme, "dt_s": dt, "steps": int(m["steps"]), "run_time_s": m["run_time_s"],
        "rel_rms_pct": max(rr) if not diverged else nan,
        "rel_rms_b1f3_pct": rr[0], "rel_rms_b2f3_pct": rr[1],
        "peak_disp_err_pct": nan if diverged else float(np.max(np.abs(pk / pk_ref - 1))) * 100,
        "peak_force_err_pct": nan if diverged else abs(pf / pf_ref - 1) * 100,
        "impacts_f3": int(m[f"impacts_f{TOP}"]), "ref_impacts_f3": int(ref.impacts[TOP - 1]),
        "steps_per_contact_period": nan, "status": m["status"],
    }


def ladder(scene, ref: Reference, dts=DTS, schemes=SCHEMES, repeats: int = 3, log=print, **overrides) -> pd.DataFrame:
    """Every (scheme, dt) point against the reference, one row each (see the module docstring)."""
    kernel_run(scene, dts[0], schemes[0], repeats=1, **overrides)  # compile / cache load before any timing
    rows = []
    for scheme in schemes:
        for dt in dts:
            row = error_row(kernel_run(scene, dt, scheme, repeats, **overrides), ref, scheme, dt)
            rows.append(row)
            log(f"  {scheme:8s} dt {dt:8.1e} s  {row['run_time_s'] * 1e3:9.2f} ms  rel RMS {row['rel_rms_pct']:.3e} %"
                f"  {row['status']}")
    return pd.DataFrame(rows)


# ----------------------------------------------------------------------------- what the table says


def local_orders(g: pd.DataFrame, col: str = "rel_rms_pct") -> np.ndarray:
    """Order between neighbouring dts of one scheme (NaN for the first / where an error is missing)."""
    g = g.sort_values("dt_s", ascending=False)
    e, h = g[col].to_numpy(float), g.dt_s.to_numpy(float)
    out = np.full(e.size, np.nan)
    with np.errstate(divide="ignore", invalid="ignore"):
        out[1:] = np.log(e[:-1] / e[1:]) / np.log(h[:-1] / h[1:])
    return out


def observed_order(df: pd.DataFrame, scheme: str, col: str = "rel_rms_pct",
                   dt_max: float = 2.5e-4) -> tuple[float, float, float, int]:
    """(order, dt_lo, dt_hi, points): least-squares slope of log error against log dt over the
    asymptotic range: from dt_max (the contact resolved by 50+ steps at k_s/k = 10) down to the dt
    of the scheme's smallest error. Past that minimum the error rises again: the kernel's rounding
    floor (Newmark in total form: v = 2/dt (u_n+1 - u_n) - v_n loses digits as dt shrinks), not
    discretisation error."""
    g = df[(df.scheme == scheme) & (df.dt_s <= dt_max * (1 + 1e-9)) & np.isfinite(df[col]) & (df[col] > 0)]
    if len(g) < 2:
        return np.nan, np.nan, np.nan, len(g)
    g = g[g.dt_s >= g.loc[g[col].idxmin(), "dt_s"]]
    if len(g) < 2:
        return np.nan, np.nan, np.nan, len(g)
    slope = np.polyfit(np.log(g.dt_s), np.log(g[col]), 1)[0]
    return float(slope), float(g.dt_s.min()), float(g.dt_s.max()), len(g)


def equal_time_ratios(df: pd.DataFrame, fast: str = "event", slow: str = "paper", col: str = "rel_rms_pct") -> pd.DataFrame:
    """For each `fast` run: the `slow` scheme's error interpolated (log-log, in run time) at its run
    time, and the ratio slow / fast. Only where the run time lies inside the slow scheme's range of
    finite-error runs (no extrapolation); diverged slow runs are left out of the curve."""
    a = df[df.scheme == fast].sort_values("dt_s", ascending=False)
    b = df[(df.scheme == slow) & np.isfinite(df[col])].sort_values("run_time_s")
    rows = []
    for _, r in a.iterrows():
        t = r.run_time_s
        if len(b) < 2 or not (b.run_time_s.min() <= t <= b.run_time_s.max()) or not np.isfinite(r[col]):
            e_slow = np.nan
        else:
            e_slow = float(np.exp(np.interp(np.log(t), np.log(b.run_time_s), np.log(b[col]))))
        rows.append({"dt_s": r.dt_s, "run_time_s": t, f"{fast}_pct": r[col], f"{slow}_at_same_time_pct": e_slow,
                     "ratio": e_slow / r[col] if np.isfinite(e_slow) else np.nan})
    return pd.DataFrame(rows)


def cost_per_step(df: pd.DataFrame, scheme: str, dt_max: float = 2.5e-4) -> float:
    """Median kernel time per step [s] of a scheme over the resolved rungs (dt <= dt_max): one number
    from many runs, steadier on a shared machine than any single run time."""
    g = df[(df.scheme == scheme) & (df.dt_s <= dt_max * (1 + 1e-9)) & (df.steps > 0)]
    return float(np.median(g.run_time_s / g.steps))


def equal_cost_ratios(df: pd.DataFrame, fast: str = "event", slow: str = "paper", col: str = "rel_rms_pct") -> pd.DataFrame:
    """The equal-run-time comparison with run time modelled as (cost per step) x steps: the slow scheme at
    equal time runs dt_slow = dt_fast * c_slow / c_fast; its error there is interpolated (log-log) on its
    error-against-dt curve, which carries no timing noise. Only the cost ratio is measured."""
    c_fast, c_slow = cost_per_step(df, fast), cost_per_step(df, slow)
    b = df[(df.scheme == slow) & np.isfinite(df[col])].sort_values("dt_s")
    rows = []
    for _, r in df[df.scheme == fast].sort_values("dt_s", ascending=False).iterrows():
        dt_s = r.dt_s * c_slow / c_fast
        inside = len(b) >= 2 and b.dt_s.min() <= dt_s <= b.dt_s.max()
        e = float(np.exp(np.interp(np.log(dt_s), np.log(b.dt_s), np.log(b[col])))) if inside else np.nan
        rows.append({"dt_s": r.dt_s, f"{slow}_dt_s": dt_s, f"{fast}_pct": r[col], f"{slow}_at_same_cost_pct": e,
                     "ratio": e / r[col] if np.isfinite(e) else np.nan, "cost_ratio": c_slow / c_fast})
    return pd.DataFrame(rows)


def format_table(df: pd.DataFrame) -> str:
    """The ladder as a fixed-width table (orders between neighbouring dts per scheme)."""
    lines = [f"{'scheme':8s} {'dt [s]':>8s} {'steps':>8s} {'time [ms]':>10s} {'relRMS b1f3%':>13s} {'relRMS b2f3%':>13s} "
             f"{'order':>6s} {'peak u err%':>11s} {'peak F3 err%':>12s} {'imp f3':>6s} {'ref':>4s}  status"]
    for scheme, g in df.groupby("scheme", sort=False):
        g = g.sort_values("dt_s", ascending=False)
        orders = local_orders(g)
        for (_, r), o in zip(g.iterrows(), orders):
            lines.append(f"{scheme:8s} {r.dt_s:8.1e} {r.steps:8d} {r.run_time_s * 1e3:10.3f} {r.rel_rms_b1f3_pct:13.3e} "
                         f"{r.rel_rms_b2f3_pct:13.3e} {o:6.2f} {r.peak_disp_err_pct:11.3e} {r.peak_force_err_pct:12.3e} "
                         f"{r.impacts_f3:6d} {r.ref_impacts_f3:4d}  {r.status}")
    return "\n".join(lines)


def richardson_check(scene, ref: Reference, dt: float, **overrides) -> dict:
    """Event scheme at dt and 2 dt, extrapolated as second order (u_h + (u_h - u_2h) / 3): if the
    reference is converged the extrapolation lies far closer to it than the dt run does."""
    fine = kernel_run(scene, dt, "event", 1, **overrides)["top"]
    coarse = kernel_run(scene, 2 * dt, "event", 1, **overrides)["top"]
    k = min(fine.shape[0], ref.top.shape[0])
    rich = fine[:k] + (fine[:k] - coarse[:k]) / 3.0
    e = lambda x: max(float(relative_rms_error_pct(x[:, c], ref.top[:k, c])) for c in (0, 1))  # noqa: E731
    return {"dt_s": dt, "event_err_pct": e(fine[:k]), "richardson_err_pct": e(rich)}


# ----------------------------------------------------------------------------- main


def run_scene_ladder(name: str, quick: bool, ks_ratio: float, r: float | None, repeats: int, out_dir: Path,
                     log=print) -> dict:
    dur = (QUICK_DURATION_S if quick else DURATION_S)[name]
    dts = QUICK_DTS if quick else DTS
    scene = base_scene(name, dur)
    ov = {"ks_ratio": ks_ratio, "r": scene.contact.r if r is None else r}
    log(f"\n[load average before: {_loadavg()}]")
    log(f"=== {name}: k_s/k = {ov['ks_ratio']:g}, r = {ov['r']:g}, law {scene.contact.law}, {dur:g} s, "
        f"dt {dts[0]:g} .. {dts[-1]:g} s ===")
    ref = continuous_reference(scene, **ov)
    log(f"reference: DOP853 rtol {ref.rtol:g} atol {REF_ATOL:g}, {len(ref.events)} contact events "
        f"(impacts per pair {ref.impacts.tolist()}), peak F3 {ref.peak_force[TOP - 1]:.6f} N, {ref.wall_s:.1f} s wall")
    check = reference_self_check(scene, ref, **ov)
    log(f"reference vs itself at rtol {check['rtol_check']:g}: rel RMS {check['rel_rms_pct']:.1e} %, peak u "
        f"{check['peak_disp_pct']:.1e} %, peak F {check['peak_force_pct']:.1e} %, event times {check['event_time_s']:.1e} s, "
        f"same event sequence: {check['same_events']}")
    if scene.excitation.type == "harmonic":
        iv = check_against_ivp_reference(scene, ref, **ov)
        log(f"reference vs tests/reference.py ivp_reference (same tolerance): rel RMS {iv['rel_rms_pct']:.1e} %, "
            f"same impacts: {iv['same_impacts']}")
    df = ladder(scene, ref, dts, SCHEMES, repeats, log=log, **ov)
    df["scene"], df["ks_ratio"], df["r"], df["law"], df["duration_s"] = name, ov["ks_ratio"], ov["r"], scene.contact.law, dur
    df["ref_scheme"] = f"solve_ivp DOP853 rtol {ref.rtol:g} (continuous time)"
    df["steps_per_contact_period"] = contact_period_s(scene, ov) / df.dt_s
    df["ref_selfcheck_rel_rms_pct"] = check["rel_rms_pct"]
    log(f"[load average after the ladder: {_loadavg()}]")
    rich_dt = min(d for d in dts if d >= RICHARDSON_DT_MIN)
    rich = richardson_check(scene, ref, rich_dt, **ov)
    log(f"Richardson check (event, dt {rich_dt:g} and {2 * rich_dt:g} s): event {rich['event_err_pct']:.2e} %, "
        f"extrapolated {rich['richardson_err_pct']:.2e} % off the reference")
    out_dir.mkdir(parents=True, exist_ok=True)
    csv = out_dir / f"bench_accuracy_{name}{'_quick' if quick else ''}.csv"
    df.to_csv(csv, index=False)
    rep = report(df, csv, log)
    return {**rep, "check": check, "richardson": rich}


def report(df: pd.DataFrame, csv: Path, log=print) -> dict:
    """Print the table, the observed orders and the equal-time ratios of a ladder; write its PNG
    beside the CSV."""
    orders = {s: observed_order(df, s) for s in SCHEMES}
    ratios = equal_time_ratios(df)
    log("\n" + format_table(df))
    for s, (o, lo, hi, npts) in orders.items():
        log(f"observed order {s:8s}: {o:5.2f}  (rel RMS, least squares over dt {lo:g} .. {hi:g} s, {npts} points)")
    same_dt = df[df.scheme == "paper"].set_index("dt_s").rel_rms_pct
    log("paper scheme's error / event scheme's, at equal run time (the paper curve interpolated at the event run's "
        "time) and at equal dt:")
    for _, rr in ratios.iterrows():
        e_dt = same_dt.get(rr.dt_s, np.nan)
        log(f"  event dt {rr.dt_s:8.1e} s, {rr.run_time_s * 1e3:8.3f} ms: event {rr.event_pct:.3e} %, paper at that time "
            f"{rr.paper_at_same_time_pct:.3e} % (ratio {rr.ratio:6.3g}); paper at that dt {e_dt:.3e} % "
            f"(ratio {e_dt / rr.event_pct:6.3g})")
    cost = equal_cost_ratios(df)
    log(f"the same with run time modelled as cost per step x steps (median kernel time per step over dt <= 2.5e-4 s: "
        f"event {cost_per_step(df, 'event') * 1e9:.0f} ns, paper {cost_per_step(df, 'paper') * 1e9:.0f} ns, implicit "
        f"{cost_per_step(df, 'implicit') * 1e9:.0f} ns):")
    for _, rr in cost.iterrows():
        log(f"  event dt {rr.dt_s:8.1e} s: paper at equal cost runs dt {rr.paper_dt_s:8.2e} s, error "
            f"{rr.paper_at_same_cost_pct:.3e} % (ratio {rr.ratio:6.3g})")
    png = csv.with_suffix(".png")
    r0 = df.iloc[0]
    try:
        from pounding_sweep.plots import error_vs_runtime_figure

        title = (f"{r0.scene}: k_s/k = {r0.ks_ratio:g}, r = {r0.r:g}, {r0.law}, {r0.duration_s:g} s; error of the top floors' "
                 f"displacement (larger of the two buildings)\nagainst {r0.ref_scheme}")
        fig = error_vs_runtime_figure(df, title)
        _decade_ticks(fig.axes[0].xaxis)
        fig.savefig(png, dpi=120)
    except SystemExit as exc:  # no matplotlib
        log(str(exc))
        png = None
    log(f"wrote {csv}" + (f" and {png}" if png else ""))
    return {"table": df, "orders": orders, "ratios": ratios, "cost_ratios": cost, "csv": csv, "png": png}


def _loadavg() -> str:
    """The machine's 1/5/15-minute load (it is shared: run times are noisy, ratios are the claim)."""
    try:
        return " ".join(Path("/proc/loadavg").read_text().split()[:3])
    except OSError:
        return "n/a"


def _decade_ticks(axis):
    """Label the dt axis at decades only (12 labelled dts overlap)."""
    from matplotlib.ticker import FuncFormatter, LogLocator, NullFormatter

    axis.set_major_locator(LogLocator(base=10))
    axis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
    axis.set_minor_formatter(NullFormatter())


def contact_period_s(scene, ov) -> float:
    """Contact period 2 pi sqrt(m_eff / k_s) of the floor-3 pair [s] (divide by dt for steps)."""
    P = resolve(scene, **ov)
    m1, m2 = scene.building1.masses_kg[TOP - 1], scene.building2.masses_kg[TOP - 1]
    return 2 * math.pi * math.sqrt(m1 * m2 / (m1 + m2) / P.ks)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="smoke run: short durations, 4 dts (seconds)")
    ap.add_argument("--scene", action="append", choices=sorted(SCENES), help="scene(s) to run (default: both)")
    ap.add_argument("--ks-ratio", type=float, default=10.0, help="k_s / k_ref (default 10)")
    ap.add_argument("--r", type=float, default=None, help="coefficient of restitution (default: the scene's)")
    ap.add_argument("--repeats", type=int, default=3, help="runs per point; the least kernel time counts")
    ap.add_argument("--out-dir", type=Path, default=REPO / "results")
    ap.add_argument("--report-only", action="store_true", help="re-read the CSVs of an earlier run: table, orders, PNG")
    a = ap.parse_args(argv)
    for name in a.scene or list(SCENES):
        if a.report_only:
            csv = a.out_dir / f"bench_accuracy_{name}{'_quick' if a.quick else ''}.csv"
            report(pd.read_csv(csv, keep_default_na=False, na_values=["", "nan"]), csv)
            continue
        run_scene_ladder(name, a.quick, a.ks_ratio, a.r, 1 if a.quick else a.repeats, a.out_dir)
    return 0


if __name__ == "__main__":
    sys.exit(main())
