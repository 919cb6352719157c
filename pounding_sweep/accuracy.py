"""Error against run time, observed orders, and the stability of runs: what `benchmarks/bench_accuracy.py`
and `benchmarks/stability_map.py` report, and what the plots draw. The one home of the dt-ladder study: `ladder`
against the continuous reference, `accuracy_ladder` against a fine run of the kernel itself (no reference solver:
what `plot` draws for any scene); both run their points through `kernel_run`.

Every (scheme, dt) run of a scene's point is compared with the converged continuous-time reference
(reference.ivp.continuous_reference) on a common 5 ms grid: eq. 20 of the top floors' displacement,
the peak displacement and the peak floor-3 force. Orders are least-squares slopes of log error against
log dt over a scheme's asymptotic range. A run's stability is read from its energy balance: the balance
gap (input work minus every stored and dissipated term, over the absolute input work) and its flags.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pandas as pd

from pounding_sweep.engine.score import relative_rms_error_pct
from pounding_sweep.reference.ivp import REF_ATOL, SAMPLE_DT, TOP, Reference, continuous_reference
from pounding_sweep.scene import validate
from pounding_sweep.sweep.simulate import simulate

SCHEMES = ("event", "implicit", "paper")
DTS = (5e-3, 2.5e-3, 1e-3, 5e-4, 2.5e-4, 1e-4, 5e-5, 2.5e-5, 1e-5, 5e-6, 2.5e-6, 1e-6)
ENERGY_TERMS = [
    "kinetic_energy_end_J",
    "strain_energy_end_J",
    "structural_damping_energy_J",
    "contact_damping_energy_J",
    "contact_spring_energy_end_J",
]
MADE_TOL = 1e-6  # balance_gap below -MADE_TOL: energy made by the numerics


def reference_self_check(scene, ref: Reference, **overrides) -> dict:
    """The reference against itself at 10x tighter rtol and atol: how much of it is tolerance."""
    tight = continuous_reference(scene, rtol=ref.rtol / 10, atol=REF_ATOL / 10, **overrides)
    same_events = [ev[1:] for ev in ref.events] == [ev[1:] for ev in tight.events]
    dt_ev = max((abs(a[0] - b[0]) for a, b in zip(ref.events, tight.events)), default=0.0)
    return {
        "rtol": ref.rtol,
        "rtol_check": tight.rtol,
        "rel_rms_pct": max(float(relative_rms_error_pct(ref.top[:, c], tight.top[:, c])) for c in (0, 1)),
        "peak_disp_pct": float(np.max(np.abs(ref.peak_disp / tight.peak_disp - 1))) * 100,
        "peak_force_pct": float(np.max(np.abs(ref.peak_force / tight.peak_force - 1))) * 100,
        "same_events": same_events,
        "event_time_s": dt_ev,
        "events": len(ref.events),
        "wall_s": ref.wall_s,
        "wall_check_s": tight.wall_s,
    }


def check_against_ivp_reference(scene, ref: Reference, **overrides) -> dict:
    """reference.ivp.ivp_reference (harmonic only) at the same tolerance, on the same grid."""
    from pounding_sweep.reference import ivp_reference

    other = ivp_reference(scene, rtol=ref.rtol, atol=REF_ATOL, dt_out=SAMPLE_DT, **overrides)
    n = other["u"].shape[1]
    top = other["u"][:, [TOP - 1, n // 2 + TOP - 1]]
    m = min(top.shape[0], ref.top.shape[0])
    return {
        "rel_rms_pct": max(float(relative_rms_error_pct(ref.top[:m, c], top[:m, c])) for c in (0, 1)),
        "same_impacts": other["impacts"].tolist() == ref.impacts.tolist(),
    }


def kernel_run(
    scene, dt: float, scheme: str, repeats: int = 3, channels=None, sample_dt=SAMPLE_DT, **overrides
) -> dict:
    """One (scheme, dt) point: the histories of `channels` (default: both top floors' displacement) every
    `sample_dt` seconds, which dt must divide, the metrics, and the least run time of `repeats` runs."""
    n = sample_dt / dt
    if abs(n - round(n)) > 1e-9 * n:  # n = sample / dt carries one rounding (~1e-16 n): far inside 1e-9 n
        raise ValueError(
            f"dt = {dt:g} s does not divide the {sample_dt:g} s sampling step: use time steps that are whole "
            "fractions of it"
        )
    chans = [f"disp_b1f{TOP}", f"disp_b2f{TOP}"] if channels is None else list(channels)
    times = []
    for _ in range(max(1, repeats)):
        hist, m = simulate(scene, channels=chans, decimate=int(round(n)), dt_s=dt, scheme=scheme, **overrides)
        times.append(m["run_time_s"])
    m["run_time_s"] = min(times)
    return {"top": hist.iloc[:, 1:].to_numpy(), "metrics": m}  # t_s first, then the channels in order


def error_row(run: dict, ref: Reference, scheme: str, dt: float) -> dict:
    """The errors of one kernel run against the reference (NaN where the run diverged)."""
    m = run["metrics"]
    x = run["top"]
    k = min(x.shape[0], ref.top.shape[0])
    rr = [
        float(relative_rms_error_pct(x[:k, c], ref.top[:k, c])) if np.all(np.isfinite(x[:k, c])) else np.nan
        for c in (0, 1)
    ]
    diverged = "diverged" in m["status"]
    if diverged:
        rr = [np.nan, np.nan]
    n_dof = ref.peak_disp.size
    pk = np.array([m[f"peak_disp_b1f{TOP}_m"], m[f"peak_disp_b2f{TOP}_m"]])
    pk_ref = ref.peak_disp[[TOP - 1, n_dof // 2 + TOP - 1]]
    pf, pf_ref = m[f"peak_force_f{TOP}_N"], ref.peak_force[TOP - 1]
    nan = np.nan
    return {
        "scheme": scheme,
        "dt_s": dt,
        "steps": int(m["steps"]),
        "run_time_s": m["run_time_s"],
        "rel_rms_pct": max(rr) if not diverged else nan,
        "rel_rms_b1f3_pct": rr[0],
        "rel_rms_b2f3_pct": rr[1],
        "peak_disp_err_pct": nan if diverged else float(np.max(np.abs(pk / pk_ref - 1))) * 100,
        "peak_force_err_pct": nan if diverged else abs(pf / pf_ref - 1) * 100,
        "impacts_f3": int(m[f"impacts_f{TOP}"]),
        "ref_impacts_f3": int(ref.impacts[TOP - 1]),
        "steps_per_contact_period": nan,
        "status": m["status"],
    }


def ladder(scene, ref: Reference, dts=DTS, schemes=SCHEMES, repeats: int = 3, log=print, **overrides) -> pd.DataFrame:
    """Every (scheme, dt) point against the reference, one row each (see the module docstring)."""
    kernel_run(scene, dts[0], schemes[0], repeats=1, **overrides)  # compile / cache load before any timing
    rows = []
    for scheme in schemes:
        for dt in dts:
            row = error_row(kernel_run(scene, dt, scheme, repeats, **overrides), ref, scheme, dt)
            rows.append(row)
            log(
                f"  {scheme:8s} dt {dt:8.1e} s  {row['run_time_s'] * 1e3:9.2f} ms  rel RMS {row['rel_rms_pct']:.3e} %"
                f"  {row['status']}"
            )
    return pd.DataFrame(rows)


def local_orders(g: pd.DataFrame, col: str = "rel_rms_pct") -> np.ndarray:
    """Order between neighbouring dts of one scheme (NaN for the first / where an error is missing)."""
    g = g.sort_values("dt_s", ascending=False)
    e, h = g[col].to_numpy(float), g.dt_s.to_numpy(float)
    out = np.full(e.size, np.nan)
    with np.errstate(divide="ignore", invalid="ignore"):
        out[1:] = np.log(e[:-1] / e[1:]) / np.log(h[:-1] / h[1:])
    return out


def observed_order(
    df: pd.DataFrame, scheme: str, col: str = "rel_rms_pct", dt_max: float = 2.5e-4
) -> tuple[float, float, float, int]:
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


def equal_time_ratios(
    df: pd.DataFrame, fast: str = "event", slow: str = "paper", col: str = "rel_rms_pct"
) -> pd.DataFrame:
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
        rows.append(
            {
                "dt_s": r.dt_s,
                "run_time_s": t,
                f"{fast}_pct": r[col],
                f"{slow}_at_same_time_pct": e_slow,
                "ratio": e_slow / r[col] if np.isfinite(e_slow) else np.nan,
            }
        )
    return pd.DataFrame(rows)


def cost_per_step(df: pd.DataFrame, scheme: str, dt_max: float = 2.5e-4) -> float:
    """Median kernel time per step [s] of a scheme over the resolved rungs (dt <= dt_max): one number
    from many runs, steadier on a shared machine than any single run time."""
    g = df[(df.scheme == scheme) & (df.dt_s <= dt_max * (1 + 1e-9)) & (df.steps > 0)]
    return float(np.median(g.run_time_s / g.steps))


def equal_cost_ratios(
    df: pd.DataFrame, fast: str = "event", slow: str = "paper", col: str = "rel_rms_pct"
) -> pd.DataFrame:
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
        rows.append(
            {
                "dt_s": r.dt_s,
                f"{slow}_dt_s": dt_s,
                f"{fast}_pct": r[col],
                f"{slow}_at_same_cost_pct": e,
                "ratio": e / r[col] if np.isfinite(e) else np.nan,
                "cost_ratio": c_slow / c_fast,
            }
        )
    return pd.DataFrame(rows)


def richardson_check(scene, ref: Reference, dt: float, **overrides) -> dict:
    """Event scheme at dt and 2 dt, extrapolated as second order (u_h + (u_h - u_2h) / 3): if the
    reference is converged the extrapolation lies far closer to it than the dt run does."""
    fine = kernel_run(scene, dt, "event", 1, **overrides)["top"]
    coarse = kernel_run(scene, 2 * dt, "event", 1, **overrides)["top"]
    k = min(fine.shape[0], ref.top.shape[0])
    rich = fine[:k] + (fine[:k] - coarse[:k]) / 3.0
    e = lambda x: max(float(relative_rms_error_pct(x[:, c], ref.top[:k, c])) for c in (0, 1))  # noqa: E731
    return {"dt_s": dt, "event_err_pct": e(fine[:k]), "richardson_err_pct": e(rich)}


# ----------------------------------------------------------------------------- stability of runs


def classify(df: pd.DataFrame) -> pd.DataFrame:
    """The map's per-run columns (see the module docstring)."""
    df = df.copy()
    num = df.select_dtypes("number").drop(
        columns=[c for c in ("amplitude_m", "scale", "frequency_Hz") if c in df.columns and df[c].isna().any()]
    )
    df["diverged"] = df.status.str.contains("diverged")
    df["nonfinite"] = ~np.isfinite(num.to_numpy(float)).all(axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        df["balance_gap"] = (df.input_energy_J - df[ENERGY_TERMS].sum(axis=1)) / df.input_work_abs_J
    df["energy_made"] = df.balance_gap < -MADE_TOL
    df["energy_flag"] = df.status.str.contains("energy_residual")
    df["blown_up"] = df.diverged | ~(df.balance_gap.abs() <= 1.0)
    df["unsettled"] = df.status.str.contains("contact_unsettled")
    df["underresolved"] = df.status.str.contains("contact_underresolved")
    df["category"] = np.where(
        df.diverged | df.nonfinite, "diverged", np.where(df.energy_flag | df.energy_made, "energy", "ok")
    )
    return df


def paper_boundary(df: pd.DataFrame, scheme: str = "paper") -> pd.DataFrame:
    """Per k_s/k: the smallest dt at which a run diverges (and at which a run diverges or is energy-flagged),
    the largest dt at which none does, and the steps per contact period at those dts."""
    d = df[df.scheme == scheme]
    rows = []
    for ks, g in d.groupby("ks_ratio"):
        spp = g.groupby("dt_s").steps_per_contact_period.min()
        div = g[g.diverged].dt_s
        bad = g[g.diverged | g.energy_flag].dt_s
        ok_dts = sorted(set(g.dt_s) - set(div))
        rows.append(
            {
                "ks_ratio": ks,
                "smallest_dt_diverged_s": div.min() if len(div) else np.nan,
                "steps_per_period_there": spp.get(div.min(), np.nan) if len(div) else np.nan,
                "largest_dt_stable_s": max(
                    [t for t in ok_dts if t < (div.min() if len(div) else np.inf)], default=np.nan
                ),
                "smallest_dt_diverged_or_energy_s": bad.min() if len(bad) else np.nan,
                "diverged_per_dt": " ".join(
                    f"{int(g[g.dt_s == t].diverged.sum())}/{int((g.dt_s == t).sum())}" for t in sorted(g.dt_s.unique())
                ),
            }
        )
    return pd.DataFrame(rows)


def threshold_in_steps(df: pd.DataFrame, scheme: str = "paper") -> pd.DataFrame:
    """Does divergence follow one variable, steps per contact period (spp = 2 pi sqrt(m_eff / k_s) / dt,
    the same thing as k_s dt^2 / m_eff = (2 pi / spp)^2)? Per r: the largest spp of a diverged run and the
    smallest spp of a stable run below it (a clean threshold: every run with more steps is stable)."""
    d = df[df.scheme == scheme]
    rows = []
    for r, g in d.groupby("r"):
        div = g[g.diverged]
        spp_div = div.steps_per_contact_period.max() if len(div) else np.nan
        stable_below = g[~g.diverged & (g.steps_per_contact_period <= spp_div)] if len(div) else g.iloc[:0]
        rows.append(
            {
                "r": r,
                "diverged": len(div),
                "runs": len(g),
                "max_spp_diverged": spp_div,
                "stable_runs_with_fewer_steps": len(stable_below),
                "min_spp_stable": g[~g.diverged].steps_per_contact_period.min(),
                "ks_dt2_over_meff_at_max_spp_diverged": (2 * math.pi / spp_div) ** 2 if len(div) else np.nan,
            }
        )
    return pd.DataFrame(rows)


def divergence_by_steps(df: pd.DataFrame, scheme: str = "paper", what: str = "diverged") -> pd.DataFrame:
    """Runs with `what` per value of steps per contact period (rows; the (k_s/k, dt) cells that have it) and r
    (columns): if divergence follows k_s dt^2 / m_eff, cells of equal steps at different (k_s, dt) agree."""
    d = df[df.scheme == scheme].assign(spp=lambda x: x.steps_per_contact_period.round(3))
    t = d.pivot_table(index="spp", columns="r", values=what, aggfunc="sum").astype(int)
    t.columns = [f"r={c:g}" for c in t.columns]
    n = d.groupby("spp").size()
    t["all"] = t.sum(axis=1).astype(str) + "/" + n.astype(str)
    t["cells (k_s/k, dt)"] = d.groupby("spp").apply(
        lambda g: " ".join(f"({k:g},{t_:g})" for k, t_ in sorted(set(zip(g.ks_ratio, g.dt_s)))), include_groups=False
    )
    t["ks_dt2/m_eff"] = [(2 * math.pi / v) ** 2 for v in t.index]
    return t.sort_index(ascending=False)


#: the accuracy figure's window [s]: the first LADDER_S s of a harmonic test; of a record, up to half of it past
#: the record's strongest sample (at least LADDER_S s), so that the window holds strong motion, not a quiet lead-in
LADDER_S = 2.0


def ladder_duration(scene, record: str | None = None) -> float:
    """How long the accuracy figure's runs last (LADDER_S); `record`: the run's record, its path or its name (a
    result's `record` column) where the scene sweeps several, else its first."""
    e = scene.excitation
    if e.type != "record":
        return LADDER_S
    from pounding_sweep.model.excitation import record_paths, scene_record

    paths = record_paths(scene)
    # the run's record by its path or its name (a result's record column holds the file's stem)
    path = next((q for q in paths if record is not None and Path(q).stem == Path(record).stem), paths[0])
    rec = scene_record(scene, path)
    acc = rec.acc_m_s2
    end = rec.dt_s * (acc.size - 1)
    if e.duration_s is not None:
        end = min(end, float(e.duration_s))
    return min(max(LADDER_S, float(np.argmax(np.abs(acc))) * rec.dt_s + LADDER_S / 2), end)


def accuracy_ladder(
    scene,
    dts=None,
    schemes=None,
    ref_dt: float | None = None,
    ref_scheme: str | None = None,
    duration_s: float | None = LADDER_S,
    channel: str | None = None,
    repeats: int = 3,
    **params,
) -> pd.DataFrame:
    """Error against run time over a ladder of time steps, per integration scheme.

    Each (scheme, dt) run of `scene` (its base point with `params`, e.g. ks_ratio=5, r=0.4; no
    sweep, no experiment; the first `duration_s` seconds) is compared with a reference run of
    `ref_scheme` (default: 'event' where the kernel has it, else 'implicit') at `ref_dt` (default:
    the smallest dt / 4) by the relative RMS error (eq. 20) of `channel` (default: building 1's
    top-floor displacement), sampled every max(dts) seconds, which every dt must divide. Run
    time: the kernel's `run_time_s`, the least of `repeats` runs. Defaults: dts 8, 4, 2, 1 and
    0.5 times the scene's dt; every scheme the kernel has. Columns: scheme, dt_s, steps,
    run_time_s, rel_rms_pct, status, then ref_scheme, ref_dt_s, channel, duration_s.
    """
    from pounding_sweep.codes import SCHEMES as KERNEL_SCHEMES

    dt0 = scene.integration.dt_s
    dts = sorted((dt0 * k for k in (8, 4, 2, 1, 0.5)) if dts is None else dts, reverse=True)
    ref_dt = ref_dt or dts[-1] / 4
    if ref_dt >= dts[-1]:
        raise ValueError(f"accuracy_ladder: ref_dt = {ref_dt:g} s must be below the smallest dt {dts[-1]:g} s")
    exc = scene.excitation
    if duration_s is not None:
        exc = dataclasses.replace(exc, duration_s=float(duration_s))
    if exc.type == "record" and exc.record is None:  # the records are a [sweep] axis only: the run's, else the first
        from pounding_sweep.model.excitation import record_paths

        exc = dataclasses.replace(exc, record=params.get("record") or record_paths(scene)[0])
    base = dataclasses.replace(scene, experiment=None, calibrate=None, sweep=(), excitation=exc)
    validate(base)
    floors = scene.floors
    channel = channel or f"disp_b1f{floors[0]}"
    sample = dts[0]

    def run(dt: float, scheme: str, repeats: int = 1):
        k = kernel_run(base, dt, scheme, repeats, channels=[channel], sample_dt=sample, **params)
        return k["top"][:, 0], k["metrics"]

    schemes = list(KERNEL_SCHEMES) if schemes is None else list(schemes)
    ref_scheme = ref_scheme or ("event" if "event" in KERNEL_SCHEMES else "implicit")
    ref, _ = run(ref_dt, ref_scheme)
    rows = []
    for scheme in schemes:
        for dt in dts:
            x, m = run(dt, scheme, repeats)
            n = min(x.size, ref.size)
            err = float(relative_rms_error_pct(x[:n], ref[:n])) if np.all(np.isfinite(x[:n])) else np.nan
            rows.append(
                {
                    "scheme": scheme,
                    "dt_s": dt,
                    "steps": int(m["steps"]),
                    "run_time_s": m["run_time_s"],
                    "rel_rms_pct": err,
                    "status": m["status"],
                }
            )
    out = pd.DataFrame(rows)
    out["ref_scheme"], out["ref_dt_s"], out["channel"] = ref_scheme, ref_dt, channel
    out["duration_s"] = duration_s if duration_s is not None else np.nan
    return out
