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
from pathlib import Path

import numpy as np
import pandas as pd

REPO = Path(__file__).resolve().parents[1]

from pounding_sweep.accuracy import (
    DTS,
    SCHEMES,
    check_against_ivp_reference,
    cost_per_step,
    equal_cost_ratios,  # noqa: E402
    equal_time_ratios,
    ladder,
    local_orders,
    observed_order,
    reference_self_check,
    richardson_check,
)
from pounding_sweep.reference import resolve  # noqa: E402
from pounding_sweep.reference.ivp import REF_ATOL, REF_RTOL, SAMPLE_DT, TOP, continuous_reference  # noqa: E402,F401
from pounding_sweep.scene import load_scene  # noqa: E402

SCENES = {"paper_6hz": REPO / "sweeps" / "paper_6hz.toml", "paper_duzce": REPO / "sweeps" / "paper_duzce.toml"}
DURATION_S = {"paper_6hz": 5.0, "paper_duzce": 6.68}
QUICK_DTS = (1e-3, 5e-4, 2.5e-4, 1e-4)
QUICK_DURATION_S = {"paper_6hz": 0.5, "paper_duzce": 1.0}
RICHARDSON_DT_MIN = 5e-6  # finer, the kernel's rounding floor (Newmark in total form) spoils the extrapolation


def base_scene(name: str, duration_s: float):
    """The shipped scene's base point, no sweep, the given duration."""
    s = load_scene(SCENES[name])
    return dataclasses.replace(
        s, sweep=(), experiment=None, excitation=dataclasses.replace(s.excitation, duration_s=float(duration_s))
    )


# ----------------------------------------------------------------------------- what the table says


def format_table(df: pd.DataFrame) -> str:
    """The ladder as a fixed-width table (orders between neighbouring dts per scheme)."""
    lines = [
        f"{'scheme':8s} {'dt [s]':>8s} {'steps':>8s} {'time [ms]':>10s} {'relRMS b1f3%':>13s} {'relRMS b2f3%':>13s} "
        f"{'order':>6s} {'peak u err%':>11s} {'peak F3 err%':>12s} {'imp f3':>6s} {'ref':>4s}  status"
    ]
    for scheme, g in df.groupby("scheme", sort=False):
        g = g.sort_values("dt_s", ascending=False)
        orders = local_orders(g)
        for (_, r), o in zip(g.iterrows(), orders):
            lines.append(
                f"{scheme:8s} {r.dt_s:8.1e} {r.steps:8d} {r.run_time_s * 1e3:10.3f} {r.rel_rms_b1f3_pct:13.3e} "
                f"{r.rel_rms_b2f3_pct:13.3e} {o:6.2f} {r.peak_disp_err_pct:11.3e} {r.peak_force_err_pct:12.3e} "
                f"{r.impacts_f3:6d} {r.ref_impacts_f3:4d}  {r.status}"
            )
    return "\n".join(lines)


# ----------------------------------------------------------------------------- main


def run_scene_ladder(
    name: str, quick: bool, ks_ratio: float, r: float | None, repeats: int, out_dir: Path, log=print
) -> dict:
    dur = (QUICK_DURATION_S if quick else DURATION_S)[name]
    dts = QUICK_DTS if quick else DTS
    scene = base_scene(name, dur)
    ov = {"ks_ratio": ks_ratio, "r": scene.contact.r if r is None else r}
    log(f"\n[load average before: {_loadavg()}]")
    log(
        f"=== {name}: k_s/k = {ov['ks_ratio']:g}, r = {ov['r']:g}, law {scene.contact.law}, {dur:g} s, "
        f"dt {dts[0]:g} .. {dts[-1]:g} s ==="
    )
    ref = continuous_reference(scene, **ov)
    log(
        f"reference: DOP853 rtol {ref.rtol:g} atol {REF_ATOL:g}, {len(ref.events)} contact events "
        f"(impacts per pair {ref.impacts.tolist()}), peak F3 {ref.peak_force[TOP - 1]:.6f} N, {ref.wall_s:.1f} s wall"
    )
    check = reference_self_check(scene, ref, **ov)
    log(
        f"reference vs itself at rtol {check['rtol_check']:g}: rel RMS {check['rel_rms_pct']:.1e} %, peak u "
        f"{check['peak_disp_pct']:.1e} %, peak F {check['peak_force_pct']:.1e} %, event times {check['event_time_s']:.1e} s, "
        f"same event sequence: {check['same_events']}"
    )
    if scene.excitation.type == "harmonic":
        iv = check_against_ivp_reference(scene, ref, **ov)
        log(
            f"reference vs tests/reference.py ivp_reference (same tolerance): rel RMS {iv['rel_rms_pct']:.1e} %, "
            f"same impacts: {iv['same_impacts']}"
        )
    df = ladder(scene, ref, dts, SCHEMES, repeats, log=log, **ov)
    df["scene"], df["ks_ratio"], df["r"], df["law"], df["duration_s"] = (
        name,
        ov["ks_ratio"],
        ov["r"],
        scene.contact.law,
        dur,
    )
    df["ref_scheme"] = f"solve_ivp DOP853 rtol {ref.rtol:g} (continuous time)"
    df["steps_per_contact_period"] = contact_period_s(scene, ov) / df.dt_s
    df["ref_selfcheck_rel_rms_pct"] = check["rel_rms_pct"]
    log(f"[load average after the ladder: {_loadavg()}]")
    rich_dt = min(d for d in dts if d >= RICHARDSON_DT_MIN)
    rich = richardson_check(scene, ref, rich_dt, **ov)
    log(
        f"Richardson check (event, dt {rich_dt:g} and {2 * rich_dt:g} s): event {rich['event_err_pct']:.2e} %, "
        f"extrapolated {rich['richardson_err_pct']:.2e} % off the reference"
    )
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
    log(
        "paper scheme's error / event scheme's, at equal run time (the paper curve interpolated at the event run's "
        "time) and at equal dt:"
    )
    for _, rr in ratios.iterrows():
        e_dt = same_dt.get(rr.dt_s, np.nan)
        log(
            f"  event dt {rr.dt_s:8.1e} s, {rr.run_time_s * 1e3:8.3f} ms: event {rr.event_pct:.3e} %, paper at that time "
            f"{rr.paper_at_same_time_pct:.3e} % (ratio {rr.ratio:6.3g}); paper at that dt {e_dt:.3e} % "
            f"(ratio {e_dt / rr.event_pct:6.3g})"
        )
    cost = equal_cost_ratios(df)
    log(
        f"the same with run time modelled as cost per step x steps (median kernel time per step over dt <= 2.5e-4 s: "
        f"event {cost_per_step(df, 'event') * 1e9:.0f} ns, paper {cost_per_step(df, 'paper') * 1e9:.0f} ns, implicit "
        f"{cost_per_step(df, 'implicit') * 1e9:.0f} ns):"
    )
    for _, rr in cost.iterrows():
        log(
            f"  event dt {rr.dt_s:8.1e} s: paper at equal cost runs dt {rr.paper_dt_s:8.2e} s, error "
            f"{rr.paper_at_same_cost_pct:.3e} % (ratio {rr.ratio:6.3g})"
        )
    png = csv.with_suffix(".png")
    r0 = df.iloc[0]
    try:
        from pounding_sweep.plots import error_vs_runtime_figure

        title = (
            f"{r0.scene}: k_s/k = {r0.ks_ratio:g}, r = {r0.r:g}, {r0.law}, {r0.duration_s:g} s; error of the top floors' "
            f"displacement (larger of the two buildings)\nagainst {r0.ref_scheme}"
        )
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
