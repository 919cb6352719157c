"""Figures of a sweep's result file (matplotlib, the `plot` extra): error heatmaps over
(k_s/k, r) like the paper's Tables 2-3, peak force and displacement maps, and the best run's
histories over the experiment's (Figs. 13, 19, 21), re-simulated from the scene stored in the
file's metadata."""

from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np
import pandas as pd

from .config import scene_from_dict
from .results import read_metadata, sidecar_path


def _mpl():
    try:
        import matplotlib
    except ImportError:
        raise SystemExit("error: plotting needs matplotlib: python -m pip install '.[plot]'") from None
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def scene_of(results: str | Path):
    """The scene a result file was made from, rebuilt from its metadata (paths as in the original)."""
    md = read_metadata(results)
    import pyarrow.parquet as pq

    toml = pq.read_schema(results).metadata[b"scene_toml"].decode()
    src = Path(md["scene_file"])
    return scene_from_dict(tomllib.loads(toml), base_dir=src.resolve().parent, source=str(src), toml_text=toml)


def heatmap(ax, df: pd.DataFrame, value: str, title: str, fmt: str = "{:.1f}"):
    """Value over the (k_s/k, r) grid, annotated like the paper's tables."""
    t = df.pivot_table(index="ks_ratio", columns="r", values=value, aggfunc="min")
    im = ax.imshow(t.to_numpy(), origin="lower", aspect="auto", cmap="viridis_r")
    ax.set_xticks(range(t.shape[1]), [f"{c:g}" for c in t.columns])
    ax.set_yticks(range(t.shape[0]), [f"{i:g}" for i in t.index])
    ax.set_xlabel("coefficient of restitution r [-]")
    ax.set_ylabel("stiffness ratio k_s/k [-]")
    ax.set_title(title)
    for (i, j), v in np.ndenumerate(t.to_numpy()):
        ax.text(j, i, fmt.format(v), ha="center", va="center", color="w", fontsize=8)
    return im


def plot_results(results: str | Path, out_dir: str | Path | None = None) -> list[Path]:
    """Write the figures of one result file as PNGs; return their paths."""
    plt = _mpl()
    results = Path(results)
    out_dir = Path(out_dir) if out_dir else results.with_suffix("").with_name(results.stem + "_plots")
    out_dir.mkdir(parents=True, exist_ok=True)
    df = pd.read_parquet(results)
    md = read_metadata(results)
    names = [b["name"] for b in md["buildings"]]
    written = []
    grid = {"ks_ratio", "r"} <= set(df.columns) and df.ks_ratio.nunique() > 1 and df.r.nunique() > 1
    top = [c for c in df.columns if c.startswith("peak_force_f")][-1]
    if grid:
        rel = [c for c in df.columns if c.startswith("rel_rms_b")]
        top_floor_b1 = len(md["buildings"][0]["masses_kg"])
        maps = [(c, f"relative RMS error, eq. 20 [%]: {c.removeprefix('rel_rms_').removesuffix('_pct')}") for c in rel] or [
            (f"peak_disp_b1f{top_floor_b1}_m", f"{names[0]}: peak top-floor displacement [m]"),
            (top, f"peak pounding force {top.removeprefix('peak_force_').removesuffix('_N')} [N]"),
        ]
        fig, axes = plt.subplots(1, len(maps), figsize=(5.5 * len(maps), 4.2), squeeze=False)
        for ax, (col, title) in zip(axes[0], maps):
            fig.colorbar(heatmap(ax, df, col, title, "{:.3g}"), ax=ax)
        fig.suptitle(f"{md['scene_name']}: {len(df)} runs")
        fig.tight_layout()
        written.append(_save(fig, out_dir / "heatmaps.png", plt))
    # best (or first) run re-simulated with its histories
    best_file = sidecar_path(results, "best")
    if best_file.exists():
        best = pd.read_parquet(best_file)
        row = best[best.criterion == "rel_rms_combined_pct"].iloc[0]
        pick = {"ks_ratio": float(row.ks_ratio), "r": float(row.r)}
        label = f"best grid run: k_s/k = {row.ks_ratio:g}, r = {row.r:g} ({row.error_pct:.1f} % eq. 20)"
    else:
        first = df.iloc[int(np.argmax(df[top].to_numpy()))]
        pick = {k: float(first[k]) for k in ("ks_ratio", "r") if k in df.columns}
        label = "run with the largest pounding force: " + ", ".join(f"{k} = {v:g}" for k, v in pick.items())
    written += _history_figures(scene_of(results), pick, label, names, out_dir, plt)
    return written


def _history_figures(scene, pick, label, names, out_dir, plt):
    from .experiment import load_experiment
    from .simulate import simulate

    floors = (len(scene.building1.masses_kg), len(scene.building2.masses_kg))
    top = min(floors)
    exp = load_experiment(scene.experiment, floors) if scene.experiment is not None else None
    chans = [f"disp_b1f{floors[0]}", f"disp_b2f{floors[1]}", f"force_f{top}"]
    chans += [f"disp_{c}" for c in (exp.channels if exp is not None else ()) if f"disp_{c}" not in chans]
    hist, _ = simulate(scene, channels=chans, **pick)
    t = hist.t_s.to_numpy()
    zoom = (2.0, 2.5) if t[-1] >= 2.5 else (0.0, t[-1])
    out = []
    fig, axes = plt.subplots(2, 2, figsize=(12, 6.5), gridspec_kw={"width_ratios": [3, 1]})
    for i, (b, nf) in enumerate(zip((1, 2), floors)):
        x = hist[f"disp_b{b}f{nf}_m"].to_numpy() * 1e3
        for ax, lim in ((axes[i, 0], None), (axes[i, 1], zoom)):
            ax.plot(t, x, lw=0.9, label="numerical")
            code = f"b{b}f{nf}"
            if exp is not None and code in exp.channels:
                ax.plot(exp.time_s - scene.experiment.time_offset_s, exp.channels[code] * 1e3, ".", ms=2.5,
                        label="experiment (tracked)")
            if lim:
                ax.set_xlim(*lim)
            ax.set_xlabel("time [s]")
            ax.set_ylabel(f"{names[i]} floor {nf} [mm]")
            ax.grid(alpha=0.3)
        axes[i, 0].legend(loc="upper right", fontsize=8)
    fig.suptitle(f"{scene.name}: displacement relative to the table; {label}")
    fig.tight_layout()
    out.append(_save(fig, out_dir / "displacement_history.png", plt))
    fig, axes = plt.subplots(1, 2, figsize=(12, 3.8), gridspec_kw={"width_ratios": [3, 1]})
    f = hist[f"force_f{top}_N"].to_numpy()
    for ax, lim in ((axes[0], None), (axes[1], zoom)):
        ax.plot(t, f, lw=0.9, color="C3")
        if lim:
            ax.set_xlim(*lim)
        ax.set_xlabel("time [s]")
        ax.set_ylabel(f"pounding force, floor {top} [N]")
        ax.grid(alpha=0.3)
    fig.suptitle(f"{scene.name}: Kelvin-Voigt force (compression > 0); {label}")
    fig.tight_layout()
    out.append(_save(fig, out_dir / "pounding_force.png", plt))
    if exp is not None:
        fig, axes = plt.subplots(1, len(exp.channels), figsize=(4.5 * len(exp.channels), 4.2), squeeze=False)
        for ax, (code, xe) in zip(axes[0], exp.channels.items()):
            b, nf = int(code[1]), int(code.split("f")[1])
            te = exp.time_s - scene.experiment.time_offset_s
            keep = (te >= 0) & (te <= t[-1])
            xd = np.interp(te[keep], t, hist[f"disp_b{b}f{nf}_m"].to_numpy())
            ax.plot(xe[keep] * 1e3, xd * 1e3, ".", ms=2)
            lim = np.max(np.abs(np.r_[xe[keep], xd])) * 1e3 * 1.05
            ax.plot([-lim, lim], [-lim, lim], "k--", lw=0.8, label="numerical = experimental")
            ax.set_xlabel(f"experimental {code} [mm]")
            ax.set_ylabel(f"numerical {code} [mm]")
            ax.set_aspect("equal")
            ax.legend(fontsize=8)
            ax.grid(alpha=0.3)
        fig.suptitle(f"{scene.name}: numerical against experimental (sub-space plot); {label}")
        fig.tight_layout()
        out.append(_save(fig, out_dir / "ssp.png", plt))
    return out


def _save(fig, path: Path, plt) -> Path:
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
