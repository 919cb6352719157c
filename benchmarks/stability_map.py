"""Stability map: where each integration scheme diverges, makes energy or flags its contact.

Usage (from the repository root, after `pip install ".[test]"`):

    python benchmarks/stability_map.py [--quick] [--scene paper_6hz|paper_duzce ...] [--threads 2]

Grid, per scene, law (classic, no_tension), scheme (event, implicit, paper) and dt (1e-5, 1e-4,
1e-3, 5e-3 s): k_s/k in {1e-2, 1e-1, 1, 10, 1e2, 1e3, 1e4} x r in {0, 1e-3, 0.2, 0.6, 1} x a large
excitation (harmonic: amplitude 2 and 10 mm; Duzce: record scale 1 and 5), 70 runs each, run by
`pounding_sweep.sweep.run_scene` on scenes built with `dataclasses.replace` (as
tests/engine/test_energy.py does). Durations: the 6 Hz scene 1 s (its first 6 cycles: the runs pound from
the first cycle on), the Duzce record its whole 6.68 s (its strong motion is at 1-3 s); the same
for every dt, so a dt = 1e-5 s Duzce run has 668 000 steps.

Per run (columns added to the sweep's rows):
  diverged: status 'diverged' (non-finite state or |u| > 1 km: the kernel stops the run);
  nonfinite: any non-finite number in the row;
  balance_gap: (input_energy_J - (kinetic + strain + structural_damping + contact_damping +
      contact_spring)) / input_work_abs_J, signed: < 0 means the numerics made energy (it equals
      energy_residual_J / input_work_abs_J: the bookkeeping closes to rounding);
  energy_made: balance_gap < -1e-6 (the run ended with more energy than the input and the
      dissipation account for, by more than a millionth of the input work);
  energy_flag: status 'energy_residual' (|balance_gap| > 1 %);
  blown_up: diverged, or |balance_gap| > 1 (an energy error larger than all the input work: a run
      that exploded without reaching the kernel's 1 km limit within the duration);
  unsettled / underresolved: status 'contact_unsettled' / 'contact_underresolved' (fewer than 20
      steps per contact period 2 pi sqrt(m_eff / k_s): the `steps_per_contact_period` column).
Prints per scheme, law and dt the counts; per scheme a k_s/k x dt table of diverged and energy
runs; the paper scheme's failure boundary in dt and k_s/k with the steps per contact period there.
Writes results/stability_map.parquet (every run), results/stability_map_summary.csv and
results/stability_map.png (k_s/k against dt per scheme: diverged / energy / ok).

The implicit scheme's sweeps go through the scalar kernel (kernel.py) unless `--kernel default`:
the working tree's driver may route metrics-only implicit chunks to another kernel.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd

REPO = Path(__file__).resolve().parents[1]

from pounding_sweep.accuracy import (
    MADE_TOL,
    classify,
    divergence_by_steps,
    paper_boundary,  # noqa: E402,F401
    threshold_in_steps,
)
from pounding_sweep.scene import Axis, load_scene  # noqa: E402
from pounding_sweep.sweep.run import run_scene  # noqa: E402

SCENES = {
    # name: (scene file, amplitude axis, its values, duration [s])
    "paper_6hz": (REPO / "sweeps" / "paper_6hz.toml", "amplitude_m", (0.002, 0.01), 1.0),
    "paper_duzce": (REPO / "sweeps" / "paper_duzce.toml", "scale", (1.0, 5.0), 6.68),
}
KS = (1e-2, 1e-1, 1.0, 10.0, 1e2, 1e3, 1e4)
R = (0.0, 1e-3, 0.2, 0.6, 1.0)
DTS = (1e-5, 1e-4, 1e-3, 5e-3)
LAWS = ("classic", "no_tension")
SCHEMES = ("event", "implicit", "paper")
QUICK = dict(
    scenes=("paper_6hz",),
    ks=(1e-2, 1.0, 1e4),
    r=(0.0, 1.0),
    amps={"paper_6hz": (0.01,)},
    dts=(1e-4, 5e-3),
    duration={"paper_6hz": 0.2},
)


def grid_scene(
    name: str,
    ks=KS,
    r=R,
    amps=None,
    duration: float | None = None,
    dt: float = 1e-4,
    scheme: str = "event",
    law: str = "classic",
):
    """The shipped scene with the map's sweep axes, one dt, scheme and law (threads from run_scene)."""
    path, amp_axis, amp_values, dur = SCENES[name]
    s = load_scene(path)
    s = dataclasses.replace(
        s,
        experiment=None,
        sweep=(Axis("ks_ratio", tuple(ks)), Axis("r", tuple(r)), Axis(amp_axis, tuple(amps or amp_values))),
        excitation=dataclasses.replace(s.excitation, duration_s=float(duration or dur)),
        contact=dataclasses.replace(s.contact, law=law),
        integration=dataclasses.replace(s.integration, dt_s=float(dt), scheme=scheme),
    )
    return s


def run_map(
    scenes=tuple(SCENES),
    ks=KS,
    r=R,
    dts=DTS,
    laws=LAWS,
    schemes=SCHEMES,
    amps=None,
    duration=None,
    threads: int = 2,
    kernel: str = "scalar",
    log=print,
) -> pd.DataFrame:
    """Every (scene, law, scheme, dt) grid through run_scene; one row per run, with the map's columns."""
    frames = []
    with tempfile.TemporaryDirectory() as tmp:
        for name in scenes:
            for law in laws:
                for scheme in schemes:
                    for dt in dts:
                        s = grid_scene(name, ks, r, (amps or {}).get(name), (duration or {}).get(name), dt, scheme, law)
                        t0 = time.perf_counter()
                        out = Path(tmp) / f"{name}_{law}_{scheme}_{dt:g}.parquet"
                        summary = run_scene(s, out_path=out, threads=threads, overwrite=True, kernel=kernel)
                        df = pd.read_parquet(summary.path)
                        df.insert(0, "dt_s", dt)
                        df.insert(0, "scheme", scheme)
                        df.insert(0, "law", law)
                        df.insert(0, "scene", name)
                        df["duration_s"] = s.excitation.duration_s
                        df["amplitude"] = df[SCENES[name][1]]
                        frames.append(df)
                        d = classify(df)
                        log(
                            f"  {name:11s} {law:10s} {scheme:8s} dt {dt:6.0e} s: {len(df):3d} runs, diverged "
                            f"{int(d.diverged.sum()):3d}, energy made {int(d.energy_made.sum()):3d}, flagged "
                            f"{int(d.energy_flag.sum()):3d}, max |gap| {np.nanmax(np.abs(d.balance_gap)):.1e} "
                            f"({time.perf_counter() - t0:.1f} s)"
                        )
    cols = None
    for f in frames:  # the amplitude axis differs between scenes: keep the union of columns
        cols = list(f.columns) if cols is None else cols + [c for c in f.columns if c not in cols]
    return classify(pd.concat(frames, ignore_index=True)[cols])


def summary(df: pd.DataFrame, by=("scheme", "law", "dt_s")) -> pd.DataFrame:
    """Counts per group: runs, diverged, nonfinite, energy made / flagged, unsettled, under-resolved, and the
    largest |balance gap| over the runs that did not diverge."""
    g = df.groupby(list(by), sort=False)
    out = g.agg(
        runs=("status", "size"),
        diverged=("diverged", "sum"),
        blown_up=("blown_up", "sum"),
        nonfinite=("nonfinite", "sum"),
        energy_made=("energy_made", "sum"),
        energy_flag=("energy_flag", "sum"),
        unsettled=("unsettled", "sum"),
        underresolved=("underresolved", "sum"),
    )
    fin = df[~df.diverged].assign(abs_gap=lambda d: d.balance_gap.abs())
    out["max_abs_gap"] = fin.groupby(list(by), sort=False).abs_gap.max()
    out["min_gap"] = fin.groupby(list(by), sort=False).balance_gap.min()
    return out.reset_index()


def ks_dt_table(df: pd.DataFrame, scheme: str, what: str = "diverged") -> pd.DataFrame:
    """k_s/k (rows) x dt (columns): runs of `scheme` with `what` set, over every scene, law, r and amplitude."""
    d = df[df.scheme == scheme]
    return d.pivot_table(index="ks_ratio", columns="dt_s", values=what, aggfunc="sum").astype(int)


def format_counts(t: pd.DataFrame) -> str:
    head = "k_s/k \\ dt " + " ".join(f"{c:>8g}" for c in t.columns)
    return "\n".join(
        [head] + [f"{i:>11g} " + " ".join(f"{v:>8d}" for v in row) for i, row in zip(t.index, t.to_numpy())]
    )


def map_figure(df: pd.DataFrame, title: str = ""):
    """k_s/k against dt per scheme; each cell coloured by its worst run (diverged > energy flagged >
    energy made > ok) and labelled 'diverged / flagged / made'; lines of equal steps per contact
    period (20: the under-resolved flag; 1)."""
    from matplotlib.figure import Figure
    from matplotlib.patches import Patch, Rectangle

    schemes = [s for s in SCHEMES if s in set(df.scheme)]
    fig = Figure(figsize=(4.6 * len(schemes), 5.0), layout="constrained")
    axes = fig.subplots(1, len(schemes), squeeze=False)[0]
    colours = {
        "diverged": "#d62728",
        "energy flagged (> 1 %)": "#ff7f0e",
        f"energy made (> {MADE_TOL:g})": "#ffd966",
        "ok": "#8fd18f",
    }
    names = list(colours)
    dts = np.array(sorted(df.dt_s.unique()))
    kss = np.array(sorted(df.ks_ratio.unique()))

    def edges(v):
        lv = np.log10(v)
        half = np.diff(lv) / 2 if v.size > 1 else np.array([0.5])
        return 10 ** np.concatenate([[lv[0] - half[0]], lv[:-1] + half, [lv[-1] + half[-1]]])

    ex, ey = edges(dts), edges(kss)
    # contact period (the shortest pair's) at one k_s/k, from the rows (spp * dt); it scales as k_s^-1/2
    row = df.iloc[0]
    t_ref, ks_ref = row.steps_per_contact_period * row.dt_s, row.ks_ratio
    per_cell = len(df[df.scheme == schemes[0]]) // max(
        1, df[df.scheme == schemes[0]].groupby(["ks_ratio", "dt_s"]).ngroups
    )
    for ax, scheme in zip(axes, schemes):
        d = df[df.scheme == scheme]
        for i, dt in enumerate(dts):
            for j, ks in enumerate(kss):
                c = d[(d.dt_s == dt) & (d.ks_ratio == ks)]
                if c.empty:
                    continue
                div = c.diverged | c.nonfinite
                flag = c.energy_flag & ~div
                made = c.energy_made & ~div & ~c.energy_flag
                k = 0 if div.any() else 1 if flag.any() else 2 if made.any() else 3
                ax.add_patch(
                    Rectangle(
                        (ex[i], ey[j]),
                        ex[i + 1] - ex[i],
                        ey[j + 1] - ey[j],
                        facecolor=colours[names[k]],
                        edgecolor="white",
                    )
                )
                ax.text(
                    math.sqrt(ex[i] * ex[i + 1]),
                    math.sqrt(ey[j] * ey[j + 1]),
                    f"{int(div.sum())}/{int(flag.sum())}/{int(made.sum())}",
                    ha="center",
                    va="center",
                    fontsize=7,
                )
        k_line = np.geomspace(ey[0], ey[-1], 50)
        period = t_ref * np.sqrt(ks_ref / k_line)
        for spp, ls in ((20, "--"), (1, ":")):
            ax.plot(
                period / spp, k_line, "k", ls=ls, lw=1, label=f"{spp} step{'s' if spp > 1 else ''} per contact period"
            )
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlim(ex[0], ex[-1])
        ax.set_ylim(ey[0], ey[-1])
        ax.set_xticks(dts, [f"{v:g}" for v in dts])
        ax.set_yticks(kss, [f"{v:g}" for v in kss])
        ax.minorticks_off()
        ax.set_xlabel("time step dt [s]")
        ax.set_ylabel("k_s / k")
        ax.set_title(f"scheme '{scheme}'", fontsize=10)
    handles = [Patch(color=colours[k], label=k) for k in names] + axes[0].get_legend_handles_labels()[0]
    fig.legend(handles=handles, loc="outside lower center", ncol=6, fontsize=8)
    fig.suptitle(
        (title or "stability map") + f"\ncell: runs diverged / energy-flagged / energy made, of {per_cell} "
        "(the worst run colours the cell)",
        fontsize=10,
    )
    return fig


def report(df: pd.DataFrame, out_dir: Path, stem: str, log=print) -> dict:
    """Print the counts and the paper scheme's boundary; write the summary CSV and the PNG."""
    summ = summary(df)
    with pd.option_context("display.width", 200, "display.max_rows", 500, "display.max_columns", 30):
        log("\nper scheme, law and dt (all scenes, r, amplitudes):")
        log(summ.to_string(index=False, float_format=lambda v: f"{v:.2g}"))
        log("\nper scheme and scene:")
        log(summary(df, ("scheme", "scene")).to_string(index=False, float_format=lambda v: f"{v:.2g}"))
        log("\nper scheme:")
        log(summary(df, ("scheme",)).to_string(index=False, float_format=lambda v: f"{v:.2g}"))
        for scheme in SCHEMES:
            if scheme in set(df.scheme):
                d = df[df.scheme == scheme]
                log(
                    f"\n'{scheme}': diverged runs, k_s/k x dt (of {len(d) // max(1, d.groupby(['ks_ratio', 'dt_s']).ngroups)} per cell)"
                )
                log(format_counts(ks_dt_table(df, scheme, "diverged")))
                log(f"'{scheme}': energy made (gap < -{MADE_TOL:g}) or flagged, not diverged")
                log(
                    format_counts(
                        ks_dt_table(df.assign(e=(df.energy_made | df.energy_flag) & ~df.diverged), scheme, "e")
                    )
                )
        if "paper" in set(df.scheme):
            log("\npaper scheme's failure boundary per k_s/k:")
            log(paper_boundary(df).to_string(index=False, float_format=lambda v: f"{v:.3g}"))
            log("\npaper scheme: divergence against steps per contact period, per r:")
            log(threshold_in_steps(df).to_string(index=False, float_format=lambda v: f"{v:.3g}"))
            for what in ("diverged", "blown_up"):
                log(f"\npaper scheme: runs {what} per steps per contact period (rows) and r:")
                log(divergence_by_steps(df, "paper", what).to_string(float_format=lambda v: f"{v:.3g}"))
    out_dir.mkdir(parents=True, exist_ok=True)
    csv = out_dir / f"{stem}_summary.csv"
    summ.to_csv(csv, index=False)
    png = out_dir / f"{stem}.png"
    try:
        scenes = ", ".join(sorted(df.scene.unique()))
        map_figure(
            df,
            f"stability map: {scenes}; laws {', '.join(sorted(df.law.unique()))}; r "
            f"{', '.join(f'{v:g}' for v in sorted(df.r.unique()))}; two amplitudes each",
        ).savefig(png, dpi=120)
    except ImportError as exc:
        log(f"no PNG: {exc}")
        png = None
    log(f"wrote {csv}" + (f" and {png}" if png else ""))
    return {"summary": summ, "csv": csv, "png": png}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument(
        "--quick", action="store_true", help="smoke run: 6 Hz, 0.2 s, 3 k_s/k x 2 r x 10 mm, dt 1e-4 and 5e-3"
    )
    ap.add_argument("--scene", action="append", choices=sorted(SCENES), help="scene(s) (default: both)")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument(
        "--kernel",
        choices=("scalar", "default"),
        default="scalar",
        help="scalar: kernel.py for every scheme; default: whatever the driver picks",
    )
    ap.add_argument("--out-dir", type=Path, default=REPO / "results")
    ap.add_argument("--report-only", action="store_true", help="re-read results/stability_map.parquet")
    a = ap.parse_args(argv)
    stem = "stability_map_quick" if a.quick else "stability_map"
    path = a.out_dir / f"{stem}.parquet"
    if a.report_only:
        df = classify(pd.read_parquet(path))
    else:
        t0 = time.perf_counter()
        print(f"[load average before: {' '.join(Path('/proc/loadavg').read_text().split()[:3])}]")
        if a.quick:
            q = QUICK
            df = run_map(
                q["scenes"],
                q["ks"],
                q["r"],
                q["dts"],
                amps=q["amps"],
                duration=q["duration"],
                threads=a.threads,
                kernel=a.kernel,
            )
        else:
            df = run_map(tuple(a.scene or SCENES), threads=a.threads, kernel=a.kernel)
        print(
            f"[{len(df)} runs in {time.perf_counter() - t0:.0f} s; load average after: "
            f"{' '.join(Path('/proc/loadavg').read_text().split()[:3])}]"
        )
        a.out_dir.mkdir(parents=True, exist_ok=True)
        df.to_parquet(path, index=False)
        print(f"wrote {path}")
    report(df, a.out_dir, stem)
    return 0


if __name__ == "__main__":
    sys.exit(main())
