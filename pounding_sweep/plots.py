"""Figures and tables of a sweep's result file (matplotlib, the `plot` extra).

- `heatmap_figure`: eq. 20 error per channel over (k_s/k, r), like the paper's Tables 2-3
  (without an experiment: peak displacement and pounding force);
- `error_table`, `peak_difference_table`: the same numbers as DataFrames (Tables 2-4);
- `history_figures`: the best run re-simulated from the scene stored in the file's metadata:
  its displacement over the experiment's, whole and zoomed (Figs. 13, 21), its pounding force
  (Fig. 19) and numerical-against-experimental plots (the paper's sub-space plots, SSP);
- `accuracy_ladder`, `error_vs_runtime_figure`: error against run time over a ladder of time
  steps per integration scheme.

Figures are `matplotlib.figure.Figure`s made without pyplot: `plot_results` saves them as PNG
(no GUI backend, no global figure state), a notebook displays them inline.
"""

from __future__ import annotations

import dataclasses
import math
import tomllib
from pathlib import Path

import numpy as np
import pandas as pd

from pounding_sweep.scene import scene_from_dict, validate
from pounding_sweep.sweep.results import read_metadata, read_schema, sidecar_path

DPI = 120
#: columns an error-against-run-time table needs (one row per scheme and dt); `accuracy_ladder` writes them
ACCURACY_COLUMNS = ("scheme", "dt_s", "run_time_s", "rel_rms_pct")


def _figure(**kw):
    try:
        from matplotlib.figure import Figure
    except ImportError:
        raise SystemExit("error: plotting needs matplotlib: python -m pip install '.[plot]'") from None
    return Figure(layout="constrained", **kw)


def _plain_log(axis, ticks=None):
    """Log axis labelled 0.1, 1, 10 (not 10^-1) on its major ticks only; `ticks`: put them there."""
    from matplotlib.ticker import FuncFormatter, NullFormatter

    if ticks is not None:
        axis.set_ticks(ticks)
    axis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
    axis.set_minor_formatter(NullFormatter())


def _nice_log_ticks(lo: float, hi: float) -> list[float]:
    """1-2-5 ticks within [lo, hi]."""
    out = [m * 10.0**e for e in range(math.floor(math.log10(lo)), math.ceil(math.log10(hi)) + 1) for m in (1, 2, 5)]
    return [v for v in out if lo <= v <= hi] or [lo, hi]


def scene_of(results: str | Path):
    """The scene a result file was made from, rebuilt from its metadata (paths as in the original)."""
    md = read_metadata(results)

    toml = read_schema(results).metadata[b"scene_toml"].decode()
    src = Path(md["scene_file"])
    return scene_from_dict(tomllib.loads(toml), base_dir=src.resolve().parent, source=str(src), toml_text=toml)


def channel_label(code: str, md: dict) -> str:
    """'b1f3' -> 'Model-1, floor 3' (the building's name from the result file's metadata)."""
    b, f = int(code[1]), int(code.split("f")[1])
    name = md["buildings"][b - 1].get("name") or f"building {b}"
    return f"{name}, floor {f}"


def score_codes(df: pd.DataFrame) -> list[str]:
    """The scored channels of a result table ('b1f3', ...), in column order."""
    return [
        c.removeprefix("rel_rms_").removesuffix("_pct")
        for c in df.columns
        if c.startswith("rel_rms_b") and c.endswith("_pct")
    ]


# ----------------------------------------------------------------------------- grid maps and tables


def _grid_pivot(df: pd.DataFrame, value: str, aggfunc="min") -> pd.DataFrame:
    """Rows k_s/k, columns r (the lowest value over any other swept axis)."""
    return df.pivot_table(index="ks_ratio", columns="r", values=value, aggfunc=aggfunc, dropna=False)


def _other_axes(md: dict) -> list[str]:
    return [k for k, v in md.get("grid_axes", {}).items() if k not in ("ks_ratio", "r") and len(v) > 1]


def error_table(df: pd.DataFrame, code: str) -> pd.DataFrame:
    """Relative RMS error (eq. 20) [%] of channel `code` over the grid: rows k_s/k, columns r (Tables 2-3)."""
    t = _grid_pivot(df, f"rel_rms_{code}_pct")
    t.index.name, t.columns.name = "k_s/k", "r"
    return t


def heatmap(
    ax,
    df: pd.DataFrame,
    value: str,
    title: str,
    fmt: str = "{:.1f}",
    *,
    norm=None,
    cmap="viridis_r",
    mark_best: bool = False,
    flag_cells: bool = True,
):
    """Value over the (k_s/k, r) grid, annotated like the paper's tables (up to 150 cells).

    The annotation's colour follows the cell's brightness; `mark_best` outlines the lowest cell;
    a cell holding a run whose status is not 'ok' gets a '*'.
    """
    t = _grid_pivot(df, value)
    v = t.to_numpy(dtype=float)
    im = ax.imshow(np.ma.masked_invalid(v), origin="lower", aspect="auto", cmap=cmap, norm=norm)
    sx, sy = max(1, math.ceil(t.shape[1] / 12)), max(1, math.ceil(t.shape[0] / 12))
    ax.set_xticks(range(0, t.shape[1], sx), [f"{c:g}" for c in t.columns[::sx]])
    ax.set_yticks(range(0, t.shape[0], sy), [f"{i:g}" for i in t.index[::sy]])
    ax.set_xlabel("coefficient of restitution r [-]")
    ax.set_ylabel("contact stiffness ratio $k_s/k$ [-]")
    ax.set_title(title)
    if v.size <= 150:
        flagged = np.zeros(v.shape, bool)
        if flag_cells and "status" in df:
            flags = df.assign(_flag=(df["status"] != "ok").astype(float))
            flagged = _grid_pivot(flags, "_flag", "max").to_numpy() > 0
        for (i, j), x in np.ndenumerate(v):
            if np.isfinite(x):
                red, green, blue, _ = im.cmap(im.norm(x))
                color = "k" if 0.299 * red + 0.587 * green + 0.114 * blue > 0.5 else "w"
                text = fmt.format(x)
            else:
                color, text = "k", "n/a"
            ax.text(j, i, text + ("*" if flagged[i, j] else ""), ha="center", va="center", color=color, fontsize=8)
    if mark_best and np.isfinite(v).any():
        from matplotlib.patches import Rectangle

        i, j = np.unravel_index(np.nanargmin(v), v.shape)
        ax.add_patch(Rectangle((j - 0.5, i - 0.5), 1, 1, fill=False, ec="red", lw=2.2))
    return im


def has_grid(df: pd.DataFrame) -> bool:
    """Whether the runs span more than one k_s/k and more than one r (a map can be drawn)."""
    return {"ks_ratio", "r"} <= set(df.columns) and df.ks_ratio.nunique() > 1 and df.r.nunique() > 1


def _flag_note(df: pd.DataFrame) -> str:
    bad = df.loc[df["status"] != "ok", "status"] if "status" in df else pd.Series(dtype=str)
    if bad.empty:
        return "every run ok"
    words = pd.Series([w for s in bad for w in s.split("+")]).value_counts()
    return "* cell holds a flagged run (" + ", ".join(f"{w}: {n}" for w, n in words.items()) + ")"


def heatmap_figure(df: pd.DataFrame, md: dict, best: pd.DataFrame | None = None):
    """Eq. 20 error of each scored channel over (k_s/k, r) on one shared log colour scale, the
    lowest cell outlined (Tables 2-3); without an experiment, the first building's top-floor
    peak displacement and the top pair's peak pounding force."""
    from matplotlib.colors import LogNorm, Normalize

    codes = score_codes(df)
    other = _other_axes(md)
    over = f" (lowest over {', '.join(other)})" if other else ""
    if codes:
        vals = np.concatenate([df[f"rel_rms_{c}_pct"].to_numpy(float) for c in codes])
        vals = vals[np.isfinite(vals) & (vals > 0)]
        lo, hi = (vals.min(), vals.max()) if vals.size else (1.0, 100.0)
        norm = LogNorm(lo, hi) if hi > 3 * lo else Normalize(lo, hi)
        maps = [(f"rel_rms_{c}_pct", channel_label(c, md), norm, True) for c in codes]
        unit = "relative RMS error, eq. 20 [%]"
        what = f"relative RMS error of the displacement against the experiment (eq. 20){over}"
    else:
        nf1 = len(md["buildings"][0]["masses_kg"])
        top = [c for c in df.columns if c.startswith("peak_force_f")][-1]
        j = top.removeprefix("peak_force_f").removesuffix("_N")
        df = df.assign(**{f"peak_disp_b1f{nf1}_mm": df[f"peak_disp_b1f{nf1}_m"] * 1e3})
        maps = [
            (f"peak_disp_b1f{nf1}_mm", f"{channel_label(f'b1f{nf1}', md)}: peak displacement [mm]", None, False),
            (top, f"floor {j}: peak pounding force [N]", None, False),
        ]
        unit = None
        what = f"peak response over the grid{over}"
    fig = _figure(figsize=(5.6 * len(maps), 4.6))
    axes = fig.subplots(1, len(maps), squeeze=False)[0]
    for ax, (col, title, norm, is_err) in zip(axes, maps):
        im = heatmap(ax, df, col, title, "{:.3g}", norm=norm, mark_best=is_err)
        cb = fig.colorbar(im, ax=ax, label=unit or title.rsplit(": ", 1)[-1])
        if isinstance(norm, LogNorm):
            _plain_log(cb.ax.yaxis, _nice_log_ticks(norm.vmin, norm.vmax))
    lines = [f"{md['scene_name']}: {what}; {len(df)} runs"]
    notes = [_flag_note(df)]
    if codes:
        notes.insert(0, "red box: lowest error")
        ref = best[best.criterion == "refined_combined"] if best is not None and "criterion" in best else ()
        if len(ref):
            r0 = ref.iloc[0]
            notes.append(
                f"refined optimum k_s/k = {r0.ks_ratio:.3g}, r = {r0.r:.3g}: "
                f"{md.get('experiment', {}).get('combine', 'combined')} error {r0.error_pct:.2f} %"
            )
    fig.suptitle("\n".join(lines))
    fig.supxlabel("; ".join(notes), fontsize=9)
    return fig


def experiment_peaks(scene, md: dict) -> dict[str, tuple[float, float]]:
    """Largest |experimental displacement| [m] and its simulation time [s] per channel, in the scored window."""
    from pounding_sweep.sweep.scoring import load_experiment

    floors = (len(scene.building1.masses_kg), len(scene.building2.masses_kg))
    exp = load_experiment(scene.experiment, floors)
    t = exp.time_s - scene.experiment.time_offset_s
    lo, hi = md["experiment"]["window_s"]
    keep = (t >= lo - 1e-9) & (t <= hi + 1e-9)
    out = {}
    for code, x in exp.channels.items():
        k = int(np.argmax(np.abs(x[keep])))
        out[code] = (float(abs(x[keep][k])), float(t[keep][k]))
    return out


def peak_difference_table(
    df: pd.DataFrame, md: dict, peaks: dict | None = None, r_values=None, ks_values=None, layout: str = "long"
) -> pd.DataFrame:
    """The paper's Table 4: numerical peak displacement [mm] and its difference from the experimental
    peak, (experimental - numerical) / experimental [%] (negative: the model overshoots), per channel.

    layout 'long': rows (k_s/k, r, then any other swept axis), columns (channel, Disp./Diff.):
    readable for any grid; 'paper': rows k_s/k, columns (channel, r, Disp./Diff.), as printed.
    `peaks` (from `experiment_peaks`) adds the experimental peak's time to the headers; without it
    the experimental peak is recovered from the columns. `r_values` / `ks_values` pick a subset.
    """
    codes = score_codes(df)
    if not codes:
        raise ValueError("peak_difference_table: the result file was not scored against an experiment")
    if layout not in ("long", "paper"):
        raise ValueError(f"peak_difference_table: layout {layout!r}: use 'long' or 'paper'")
    keep = np.ones(len(df), bool)
    if r_values is not None:
        keep &= np.isclose(df.r.to_numpy(float)[:, None], np.asarray(r_values, float)[None, :]).any(axis=1)
    if ks_values is not None:
        keep &= np.isclose(df.ks_ratio.to_numpy(float)[:, None], np.asarray(ks_values, float)[None, :]).any(axis=1)
    d = df[keep]
    cols = {}
    for code in codes:
        pn = d[f"peak_num_{code}_m"] * 1e3
        diff = d[f"peak_diff_{code}_pct"]
        if peaks and code in peaks:
            pe, te = peaks[code]
            head = f"{channel_label(code, md)} (experiment {pe * 1e3:.2f} mm at {te:.2f} s)"
        else:
            est = df[f"peak_num_{code}_m"] * 1e3 / (1 - df[f"peak_diff_{code}_pct"] / 100)
            head = f"{channel_label(code, md)} (experiment {est.replace([np.inf, -np.inf], np.nan).median():.2f} mm)"
        cols[(head, "Disp. [mm]")] = pn.to_numpy()
        cols[(head, "Diff. [%]")] = diff.to_numpy()
    axes = ["ks_ratio", "r"] + [a for a in _other_axes(md) if a in d]
    out = pd.DataFrame(cols, index=pd.MultiIndex.from_frame(d[axes])).sort_index()
    out.columns = pd.MultiIndex.from_tuples(out.columns)
    out.index.names = ["k_s/k", "r"] + axes[2:]
    if layout == "paper":
        heads = list(dict.fromkeys(h for h, _ in out.columns))
        out = out.unstack("r")
        order = sorted(out.columns, key=lambda c: (heads.index(c[0]), c[2], c[1] != "Disp. [mm]"))
        out = out[order]
        out.columns = pd.MultiIndex.from_tuples([(h, f"r = {r:g}", q) for h, q, r in order])
    return out


# ----------------------------------------------------------------------------- the best run's histories


def _params_text(pick: dict) -> str:
    names = {"ks_ratio": "k_s/k", "ks_N_per_m": "k_s [N/m]", "r": "r"}
    return ", ".join(f"{names[k]} = {v:g}" for k, v in pick.items() if k in names)


def best_run(results: str | Path, df: pd.DataFrame) -> tuple[dict, str, pd.Series]:
    """(parameters to re-simulate, a label, its result row): the best grid run against the experiment
    (lowest combined eq. 20 error), or without one the run with the largest pounding force."""
    best_file = sidecar_path(results, "best")
    best = pd.read_parquet(best_file) if best_file.exists() else None
    rows = best[best.criterion == "rel_rms_combined_pct"] if best is not None and "criterion" in best else ()
    named = len(rows) > 0
    if named:
        b = rows.iloc[0]
        row = df[df.run_id == int(b.run_id)].iloc[0]
        how = read_metadata(results).get("experiment", {}).get("combine", "combined")
        label = f"best grid run k_s/k = {b.ks_ratio:g}, r = {b.r:g} ({how} eq. 20 error {b.error_pct:.1f} %)"
    else:
        top = [c for c in df.columns if c.startswith("peak_force_f")][-1]
        row = df.iloc[int(np.nanargmax(df[top].to_numpy()))]
        label = "run with the largest pounding force"
    pick = {
        k: float(row[k])
        for k in ("ks_ratio", "r", "gap_m", "amplitude_m", "frequency_Hz", "scale")
        if k in row and np.isfinite(row[k])
    }
    if "ks_ratio" not in pick and "ks_N_per_m" in row:
        pick["ks_N_per_m"] = float(row["ks_N_per_m"])
    records = read_metadata(results).get("grid_axes", {}).get("record", [])
    if len(records) > 1:  # a swept record: re-simulate the row's own
        pick["record"] = next(p for p in records if Path(p).stem == row["record"])
        label += f", record {row['record']}"
    if not named:
        label += ": " + _params_text(pick)
    return pick, label, row


def zoom_window(scene, t_end: float, exp=None, x=None, width_s: float = 0.5) -> tuple[float, float]:
    """The zoomed interval: 2-2.5 s for harmonic motion (the paper's), else `width_s` around the
    largest experimental (or, without one, numerical `x`) displacement."""
    if t_end <= width_s:
        return 0.0, t_end
    if scene.excitation.type == "harmonic" and t_end >= 2.0 + width_s:
        return 2.0, 2.0 + width_s
    if exp is not None:
        code, xe = next(iter(exp.channels.items()))
        te = exp.time_s - scene.experiment.time_offset_s
        keep = (te >= 0) & (te <= t_end)
        tp = float(te[keep][np.argmax(np.abs(xe[keep]))])
    else:
        tp = float(np.argmax(np.abs(x)) / max(len(x) - 1, 1) * t_end) if x is not None else t_end / 2
    lo = min(max(0.0, tp - width_s / 2), t_end - width_s)
    return lo, lo + width_s


def history_figures(scene, pick: dict, label: str, md: dict | None = None) -> dict:
    """Re-simulate one run and draw {'displacement_history', 'pounding_force'[, 'ssp']} figures."""
    from pounding_sweep.sweep.scoring import load_experiment
    from pounding_sweep.sweep.simulate import simulate

    floors = (len(scene.building1.masses_kg), len(scene.building2.masses_kg))
    names = [scene.building1.name or "building 1", scene.building2.name or "building 2"]
    md = md or {"buildings": [{"name": n} for n in names]}
    top = min(floors)
    exp = load_experiment(scene.experiment, floors) if scene.experiment is not None else None
    codes = list(exp.channels) if exp is not None else []
    shown = [f"b1f{floors[0]}", f"b2f{floors[1]}"] + [
        c for c in codes if c not in (f"b1f{floors[0]}", f"b2f{floors[1]}")
    ]
    hist, m = simulate(scene, channels=[f"disp_{c}" for c in shown] + [f"force_f{top}"], **pick)
    t = hist.t_s.to_numpy()
    te = exp.time_s - scene.experiment.time_offset_s if exp is not None else None
    zoom = zoom_window(scene, t[-1], exp, hist[f"disp_{shown[0]}_m"].to_numpy())
    out = {}

    # displacement, whole and zoomed (Figs. 13, 21)
    fig = _figure(figsize=(12, 2.9 * len(shown) + 0.9))
    axes = fig.subplots(len(shown), 2, squeeze=False, gridspec_kw={"width_ratios": [3, 1]})
    for i, code in enumerate(shown):
        x = hist[f"disp_{code}_m"].to_numpy() * 1e3
        for ax, lim in ((axes[i, 0], None), (axes[i, 1], zoom)):
            ax.plot(t, x, lw=0.9, color="C0", label="numerical")
            if code in codes:
                ax.plot(
                    te,
                    exp.channels[code] * 1e3,
                    "o",
                    ms=2.2,
                    color="C1",
                    label=f"experiment (tracked, {1 / exp.dt_sample:.4g} samples/s)",
                )
            ax.set_xlim(*(lim or (t[0], t[-1])))
            ax.set_xlabel("time [s]")
            ax.set_ylabel("displacement [mm]")
            ax.grid(alpha=0.3)
        axes[i, 0].axvspan(*zoom, color="0.85", zorder=0, label=f"zoom {zoom[0]:g}-{zoom[1]:g} s")
        title = channel_label(code, md)
        if code in codes:
            pn, diff = m[f"peak_num_{code}_m"] * 1e3, m[f"peak_diff_{code}_pct"]
            title += (
                f": eq. 20 error {m[f'rel_rms_{code}_pct']:.1f} %; peak {pn:.2f} mm, experiment "
                f"{pn / (1 - diff / 100):.2f} mm (Table 4 difference {diff:+.1f} %)"
            )
        axes[i, 0].set_title(title, loc="left", fontsize=10)
        axes[i, 1].set_title(f"zoom {zoom[0]:g}-{zoom[1]:g} s", fontsize=10)
    handles, labels = axes[0, 0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="outside lower center", ncols=3, fontsize=9)
    fig.suptitle(f"{scene.name}: displacement relative to the table; {label}", x=0.01, ha="left")
    out["displacement_history"] = fig

    # pounding force (Fig. 19)
    fig = _figure(figsize=(12, 4.0))
    axes = fig.subplots(1, 2, gridspec_kw={"width_ratios": [3, 1]})
    f = hist[f"force_f{top}_N"].to_numpy()
    for ax, lim in ((axes[0], None), (axes[1], zoom)):
        ax.plot(t, f, lw=0.9, color="C3")
        ax.axhline(0, color="k", lw=0.5)
        ax.set_xlim(*(lim or (t[0], t[-1])))
        ax.set_xlabel("time [s]")
        ax.set_ylabel(f"pounding force $F_{{1{top}}} = F_{{2{top}}}$ [N]")
        ax.grid(alpha=0.3)
    axes[0].axvspan(*zoom, color="0.85", zorder=0)
    axes[1].set_title(f"zoom {zoom[0]:g}-{zoom[1]:g} s", fontsize=10)
    facts = (
        f"floor {top}: peak {m[f'peak_force_f{top}_N']:.1f} N at {m[f'peak_force_time_f{top}_s']:.2f} s, "
        f"{int(m[f'compression_phases_f{top}'])} compression phases, median "
        f"{m[f'median_compression_phase_f{top}_s'] * 1e3:.1f} ms"
    )
    if m[f"min_force_f{top}_N"] < 0:
        facts += f"; least {m[f'min_force_f{top}_N']:.1f} N (the classic law's pull before separation)"
    axes[0].set_title(facts, loc="left", fontsize=9)
    fig.suptitle(f"{scene.name}: Kelvin-Voigt pounding force (compression > 0); {label}", x=0.01, ha="left")
    out["pounding_force"] = fig

    # numerical against experimental (SSP)
    if codes:
        keep = (te >= 0) & (te <= t[-1])
        fig = _figure(figsize=(4.4 * len(codes), 5.6))  # tall enough for square boxes
        axes = fig.subplots(1, len(codes), squeeze=False)[0]
        for ax, code in zip(axes, codes):
            xe = exp.channels[code][keep] * 1e3
            xd = np.interp(te[keep], t, hist[f"disp_{code}_m"].to_numpy()) * 1e3
            lim = float(np.max(np.abs(np.r_[xe, xd]))) * 1.05
            ax.plot([-lim, lim], [-lim, lim], "k--", lw=0.8, label="numerical = experimental")
            ax.plot(xe, xd, "o", ms=2, alpha=0.6, color="C0", label=f"{keep.sum()} samples")
            ax.set_xlim(-lim, lim)
            ax.set_ylim(-lim, lim)
            ax.set_xlabel("experimental displacement [mm]")
            ax.set_ylabel("numerical displacement [mm]")
            ax.set_title(
                f"{channel_label(code, md)}\neq. 20 error {m[f'rel_rms_{code}_pct']:.1f} %, "
                f"correlation {m[f'corr_{code}']:.4f}",
                fontsize=10,
            )
            ax.set_box_aspect(1)
            ax.legend(fontsize=8, loc="upper left")
            ax.grid(alpha=0.3)
        fig.suptitle(f"{scene.name}: numerical against experimental (sub-space plot)\n{label}", fontsize=11)
        out["ssp"] = fig
    return out


# ----------------------------------------------------------------------------- error against run time


def accuracy_ladder(
    scene,
    dts=None,
    schemes=None,
    ref_dt: float | None = None,
    ref_scheme: str | None = None,
    duration_s: float | None = 2.0,
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
    from pounding_sweep.codes import SCHEMES
    from pounding_sweep.engine.score import relative_rms_error_pct
    from pounding_sweep.sweep.simulate import simulate

    dt0 = scene.integration.dt_s
    dts = sorted((dt0 * k for k in (8, 4, 2, 1, 0.5)) if dts is None else dts, reverse=True)
    ref_dt = ref_dt or dts[-1] / 4
    if ref_dt >= dts[-1]:
        raise ValueError(f"accuracy_ladder: ref_dt = {ref_dt:g} s must be below the smallest dt {dts[-1]:g} s")
    exc = scene.excitation
    if duration_s is not None:
        exc = dataclasses.replace(exc, duration_s=float(duration_s))
    base = dataclasses.replace(scene, experiment=None, sweep=(), excitation=exc)
    validate(base)
    floors = (len(scene.building1.masses_kg), len(scene.building2.masses_kg))
    channel = channel or f"disp_b1f{floors[0]}"
    sample = dts[0]

    def run(dt: float, scheme: str):
        n = sample / dt
        if abs(n - round(n)) > 1e-6 * n:
            raise ValueError(
                f"accuracy_ladder: dt = {dt:g} s does not divide the sampling step {sample:g} s "
                "(the largest dt): use dts that are whole fractions of it"
            )
        hist, m = simulate(base, channels=[channel], decimate=int(round(n)), dt_s=dt, scheme=scheme, **params)
        return hist.iloc[:, 1].to_numpy(), m

    schemes = list(SCHEMES) if schemes is None else list(schemes)
    ref_scheme = ref_scheme or ("event" if "event" in SCHEMES else "implicit")
    ref, _ = run(ref_dt, ref_scheme)
    rows = []
    for scheme in schemes:
        for dt in dts:
            times = []
            for _ in range(max(1, repeats)):
                x, m = run(dt, scheme)
                times.append(m["run_time_s"])
            n = min(x.size, ref.size)
            err = float(relative_rms_error_pct(x[:n], ref[:n])) if np.all(np.isfinite(x[:n])) else np.nan
            rows.append(
                {
                    "scheme": scheme,
                    "dt_s": dt,
                    "steps": int(m["steps"]),
                    "run_time_s": min(times),
                    "rel_rms_pct": err,
                    "status": m["status"],
                }
            )
    out = pd.DataFrame(rows)
    out["ref_scheme"], out["ref_dt_s"], out["channel"] = ref_scheme, ref_dt, channel
    out["duration_s"] = duration_s if duration_s is not None else np.nan
    return out


def read_accuracy_table(path: str | Path) -> pd.DataFrame:
    """An error-against-run-time table (CSV or Parquet) with at least the ACCURACY_COLUMNS."""
    path = Path(path)
    df = pd.read_parquet(path) if path.suffix.lower() == ".parquet" else pd.read_csv(path)
    missing = [c for c in ACCURACY_COLUMNS if c not in df.columns]
    if missing:
        raise ValueError(
            f"{path}: an error-against-run-time table needs the columns {', '.join(ACCURACY_COLUMNS)}; "
            f"missing {', '.join(missing)} (has {', '.join(map(str, df.columns))})"
        )
    return df


def error_vs_runtime_figure(table: pd.DataFrame, title: str = ""):
    """Two log-log panels per scheme: error against dt, and error against run time (each point labelled by dt)."""
    fig = _figure(figsize=(11, 4.4))
    ax_dt, ax_t = fig.subplots(1, 2)
    bad = []
    for k, (scheme, g) in enumerate(table.groupby("scheme", sort=False)):
        g = g.sort_values("dt_s")
        ok = np.isfinite(g.rel_rms_pct) & (g.rel_rms_pct > 0)
        bad += [f"{scheme} dt = {d:g} s" for d in g.dt_s[~ok]]
        g = g[ok]
        style = {"marker": "o", "color": f"C{k}", "label": f"scheme '{scheme}'"}
        ax_dt.loglog(g.dt_s, g.rel_rms_pct, **style)
        ax_t.loglog(g.run_time_s * 1e3, g.rel_rms_pct, **style)
        every = max(1, math.ceil(len(g) / 6))  # at most about 6 labels per scheme
        for _, row in g.iloc[::-1].iloc[::every].iterrows():
            ax_t.annotate(
                f"{row.dt_s:.3g} s",
                (row.run_time_s * 1e3, row.rel_rms_pct),
                textcoords="offset points",
                xytext=(4, 4 if k % 2 == 0 else -11),
                fontsize=7,
                color=f"C{k}",
            )
    dts = sorted(table.dt_s.unique())
    _plain_log(ax_dt.xaxis, dts if len(dts) <= 6 else None)
    _plain_log(ax_t.xaxis)
    ax_dt.set_xlabel("time step dt [s]")
    ax_t.set_xlabel("run time of one run in the kernel [ms]")
    for ax in (ax_dt, ax_t):
        ax.set_ylabel("relative RMS error, eq. 20 [%]")
        _plain_log(ax.yaxis)
        ax.grid(alpha=0.3, which="both")
        ax.legend(fontsize=9)
    ref = ""
    if {"ref_dt_s", "channel"} <= set(table.columns):
        scheme = f"'{table.ref_scheme.iloc[0]}' scheme" if "ref_scheme" in table else "reference"
        ref = f"error of {table.channel.iloc[0]} against the {scheme} at dt = {table.ref_dt_s.iloc[0]:g} s"
    fig.suptitle("\n".join(s for s in (title or "error against run time", ref) if s), fontsize=11)
    if bad:
        fig.supxlabel("not shown (diverged or no error): " + ", ".join(bad), fontsize=8)
    return fig


# ----------------------------------------------------------------------------- all of it, as PNGs


def figures(results: str | Path, accuracy: str | Path | pd.DataFrame | None = None) -> dict:
    """Every figure of a result file, by name. `accuracy`: an error-against-run-time table (or its
    CSV/Parquet file); None computes a small `accuracy_ladder` of the best run."""
    results = Path(results)
    df = pd.read_parquet(results)
    md = read_metadata(results)
    best_file = sidecar_path(results, "best")
    best = pd.read_parquet(best_file) if best_file.exists() else None
    out = {}
    if has_grid(df):
        out["heatmaps"] = heatmap_figure(df, md, best)
    scene = scene_of(results)
    pick, label, _ = best_run(results, df)
    out.update(history_figures(scene, pick, label, md))
    if accuracy is None:
        table = accuracy_ladder(scene, **pick)
    else:
        table = accuracy if isinstance(accuracy, pd.DataFrame) else read_accuracy_table(accuracy)
    what = _params_text(pick)
    dur = table.duration_s.iloc[0] if "duration_s" in table and np.isfinite(table.duration_s.iloc[0]) else None
    out["error_vs_runtime"] = error_vs_runtime_figure(
        table, f"{scene.name}: error against run time ({what}" + (f", first {dur:g} s)" if dur else ")")
    )
    return out


def plot_results(
    results: str | Path, out_dir: str | Path | None = None, accuracy: str | Path | pd.DataFrame | None = None
) -> list[Path]:
    """Write the figures of one result file as PNGs; return their paths."""
    results = Path(results)
    out_dir = Path(out_dir) if out_dir else results.with_suffix("").with_name(results.stem + "_plots")
    figs = figures(results, accuracy)
    out_dir.mkdir(parents=True, exist_ok=True)
    written = []
    for name, fig in figs.items():
        path = out_dir / f"{name}.png"
        fig.savefig(path, dpi=DPI)
        written.append(path)
    return written
