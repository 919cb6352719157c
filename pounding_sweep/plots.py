"""Figures and tables of a sweep's result file (matplotlib, the `plot` extra).

- `heatmap_figure`: eq. 20 error per channel over (k_s/k, r), like the paper's Tables 2-3
  (without an experiment: peak displacement and pounding force);
- `error_table`, `peak_difference_table`: the same numbers as DataFrames (Tables 2-4);
- `history_figures`: the best run re-simulated from the scene stored in the file's metadata:
  its displacement over the experiment's, whole and zoomed (Figs. 13, 21), its pounding force
  (Fig. 19) and numerical-against-experimental plots (the paper's sub-space plots, SSP);
- `error_vs_runtime_figure`: error against run time over a ladder of time steps per integration
  scheme (the ladder itself: accuracy.py `accuracy_ladder`).

Figures are `matplotlib.figure.Figure`s made without pyplot: `plot_results` saves them as PNG
(no GUI backend, no global figure state), a notebook displays them inline.
"""

from __future__ import annotations

import math
import os
import stat
import tomllib
from pathlib import Path

import numpy as np
import pandas as pd

from pounding_sweep.accuracy import accuracy_ladder, ladder_duration  # the dt-ladder study; figures() draws a small one
from pounding_sweep.errors import ResultError
from pounding_sweep.scene import scene_from_dict
from pounding_sweep.scene.axes import STRUCTURE_AXES
from pounding_sweep.scene.channels import ACC_PREFIX, building_floor, is_acceleration
from pounding_sweep.scene.parameters import PARAMETERS, channel_offset, is_log, member
from pounding_sweep.scene.validate import FITTABLE
from pounding_sweep.sweep.prepare import with_structure
from pounding_sweep.sweep.results import META_KEY, part_files, read_metadata, read_schema, sidecar_path

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


def _results_folder(results: str | Path) -> Path:
    """The dataset folder of a result (given as the folder or as one of its parts)."""
    p = Path(results).resolve()
    return p if p.is_dir() else p.parent


def scene_of(results: str | Path):
    """The scene a result was made from, rebuilt from its metadata with every file it names (records, the
    experiment's table or video) checked against the SHA-256 the sweep stored: the files where the scene was, or,
    for a project folder moved or copied with its results, where they are now beside the results (the result
    keeps the scene's folder relative to its own). A file changed, or found nowhere, is a ResultError naming it:
    figures redrawn from another record or table would show another run."""
    md = read_metadata(results)
    toml = read_schema(results).metadata[b"scene_toml"].decode()
    src = Path(md["scene_file"])
    places = [src.resolve().parent]
    if md.get("scene_dir_from_results"):
        moved = Path(os.path.normpath(_results_folder(results) / md["scene_dir_from_results"]))
        if moved != places[0]:
            places.append(moved)
    reasons = []
    for base in places:
        scene = scene_from_dict(tomllib.loads(toml), base_dir=base, source=str(base / src.name), toml_text=toml)
        changed = _changed_files(md.get("config") or {}, scene.canonical())
        if not changed:
            return scene
        reasons.append(f"{changed[0]} (in {base})")
    raise ResultError(
        f"{Path(results)}: a file the sweep read is not there as it was: {'; '.join(reasons)}; figures from it would "
        "show another run than the sweep made: put the sweep's file back, or run the sweep again"
    )


def _changed_files(stored: dict, now: dict) -> list[str]:
    """The files (records, tables, videos) whose content differs between a stored canonical scene and now, each
    as '<key> = <file> (sha256 <then>... there, ... now)'; a file that cannot be read says 'unreadable'."""
    from pounding_sweep.scene.hashing import differences

    return [d for d in differences(stored, now, limit=50) if "(sha256 " in d]


def check_results(results: str | Path) -> dict:
    """The metadata of a sweep's result (its dataset folder, or one part), or a ResultError saying
    what the file is instead (a scene, a histories dataset, a best table, not ours) and what to give."""
    p = Path(results)
    if not p.exists():
        raise ResultError(f"{p}: no such file or folder (give a sweep's result, e.g. results/<scene>.parquet)")
    _refuse_special(p)
    if p.is_dir():
        for part in part_files(p):
            _refuse_special(part)
    if p.suffix.lower() == ".toml":
        raise ResultError(
            f"{p}: a scene file, not a result: run it first (python -m pounding_sweep {p}), "
            "then plot the result folder it writes"
        )
    try:
        schema = read_schema(p)
    except (OSError, ValueError, KeyError) as e:  # pyarrow's errors are OSError or ValueError (ArrowInvalid)
        msg = str(e.args[0] if isinstance(e, KeyError) and e.args else e).splitlines()[0] or type(e).__name__
        for prefix in (f"{p}: ", f"{p.resolve()}: "):
            msg = msg.removeprefix(prefix)
        msg = msg.removeprefix("not a pounding_sweep result (").removesuffix(")") if "(" in msg else msg
        raise ResultError(f"{p}: not a pounding_sweep result ({msg})") from None
    md = read_metadata(p) if META_KEY in (schema.metadata or {}) else {}
    stem = p.name.removesuffix(".parquet").rsplit(".", 1)[0] + ".parquet"
    if md.get("kind") == "best":
        raise ResultError(
            f"{p}: the best-runs table of a sweep, not its result: plot {p.with_name(stem)} (the table is read from beside it)"
        )
    if "t_s" in schema.names and "status" not in schema.names:
        raise ResultError(
            f"{p}: the time histories of a sweep, not its result: plot {p.with_name(stem)} "
            "(the histories are re-simulated from it)"
        )
    if md.get("kind") != "runs" or "run_id" not in schema.names:
        raise ResultError(f"{p}: not the result of a sweep (metadata kind {md.get('kind')!r})")
    return md


def _refuse_special(path: Path) -> None:
    """A FIFO, device or socket where a result file is expected would block its reader (a FIFO waits for a writer
    for ever): refused by name before it is opened."""
    from pounding_sweep.scene.files import kind_of

    mode = os.stat(path).st_mode
    if not (stat.S_ISREG(mode) or stat.S_ISDIR(mode)):
        raise ResultError(f"{path}: {kind_of(mode)}, not a result file or folder")


def read_best(results: str | Path, md: dict | None = None) -> pd.DataFrame | None:
    """The best-runs table beside a scored result (None without one): refused (ResultError) when it is damaged, not a
    regular file, or the best table of another result or of an earlier sweep into this folder (another config
    hash), since the figures would then mark another run as the best."""
    best_file = sidecar_path(_results_folder(results), "best")
    if not best_file.exists():
        return None
    _refuse_special(best_file)
    try:
        info = read_metadata(best_file)
        best = pd.read_parquet(best_file)
    except Exception:  # noqa: BLE001 - pyarrow's errors for a damaged file vary
        raise ResultError(
            f"{best_file}: cannot be read as a best-runs table (damaged): run the sweep again to rewrite it"
        ) from None
    md = md if md is not None else read_metadata(results)
    owner = info.get("results")
    if (owner is not None and owner != _results_folder(results).name) or info.get("config_hash") != md.get(
        "config_hash"
    ):
        raise ResultError(
            f"{best_file}: the best runs of another sweep than {Path(results)} (its results folder or scene differs): "
            "run the sweep again to rewrite it"
        )
    return best


#: how each sweep axis is labelled (axis label, short label), and the factor its values are shown with: the
#: parameters that have labels (scene/parameters.py)
AXES = {p.name: (p.label, p.short, p.factor) for p in PARAMETERS if p.label is not None}


def swept_axes(df: pd.DataFrame, md: dict) -> list[str]:
    """The axes of the sweep that take more than one value among the runs, in the grid's order."""
    return [k for k in md.get("grid_axes", {}) if k in df.columns and df[k].nunique() > 1]


def map_axes(df: pd.DataFrame, md: dict) -> tuple[str, str] | None:
    """(rows, columns) of the grid maps: (k_s/k, r) when both are swept (the paper's), else the first two
    swept axes; None when fewer than two are swept."""
    axes = swept_axes(df, md)
    if {"ks_ratio", "r"} <= set(axes):
        return "ks_ratio", "r"
    return (axes[0], axes[1]) if len(axes) >= 2 else None


def _value_text(axis: str, v) -> str:
    factor = AXES.get(axis, ("", "", 1.0))[2]
    return str(v) if factor is None else f"{float(v) * factor:g}"


def values_text(axis: str, values) -> str:
    """'k_s/k = 0.1, 1, 5, 10' (long axes shortened to their ends and count)."""
    vals = sorted(set(values), key=lambda v: str(v) if AXES.get(axis, ("", "", 1.0))[2] is None else float(v))
    shown = [_value_text(axis, v) for v in vals]
    text = ", ".join(shown) if len(shown) <= 8 else f"{shown[0]} .. {shown[-1]} ({len(shown)} values)"
    return f"{AXES.get(axis, (axis, axis, 1.0))[1]} = {text}"


def run_text(row, axes) -> str:
    """The run's value on each of `axes`: 'gap [mm] = 1, k_s/k = 10'."""
    return ", ".join(f"{AXES.get(a, (a, a, 1.0))[1]} = {_value_text(a, row[a])}" for a in axes if a in row)


def channel_label(code: str, md: dict) -> str:
    """'b1f3' -> 'Model-1, floor 3' (the building's name from the result file's metadata); 'abs_acc_b1f3' ->
    'Model-1, floor 3 (acceleration)'."""
    b, f = building_floor(code)
    name = md["buildings"][b - 1].get("name") or f"building {b}"
    return f"{name}, floor {f}" + (" (acceleration)" if is_acceleration(code) else "")


def score_codes(df: pd.DataFrame) -> list[str]:
    """The scored channels of a result table ('b1f3', 'abs_acc_b1f3', ...), in column order."""
    return [
        c.removeprefix("rel_rms_").removesuffix("_pct")
        for c in df.columns
        if c.startswith(("rel_rms_b", f"rel_rms_{ACC_PREFIX}b")) and c.endswith("_pct")
    ]


# ----------------------------------------------------------------------------- grid maps and tables


def _grid_pivot(df: pd.DataFrame, value: str, aggfunc="min", axes=("ks_ratio", "r")) -> pd.DataFrame:
    """Rows axes[0], columns axes[1] (the lowest value over any other swept axis)."""
    return df.pivot_table(index=axes[0], columns=axes[1], values=value, aggfunc=aggfunc, dropna=False)


def _other_axes(md: dict, shown=("ks_ratio", "r")) -> list[str]:
    return [k for k, v in md.get("grid_axes", {}).items() if k not in shown and len(v) > 1]


def error_table(df: pd.DataFrame, code: str, axes=("ks_ratio", "r")) -> pd.DataFrame:
    """Relative RMS error (eq. 20) [%] of channel `code` over the grid: rows k_s/k, columns r (Tables 2-3)."""
    t = _grid_pivot(df, f"rel_rms_{code}_pct", axes=axes)
    t.index.name, t.columns.name = (AXES.get(a, (a, a, 1.0))[1] for a in axes)
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
    axes=("ks_ratio", "r"),
):
    """Value over two swept axes (rows axes[0], columns axes[1]; default the paper's (k_s/k, r)),
    annotated like the paper's tables (up to 150 cells).

    The annotation's colour follows the cell's brightness and its size the cells' count (a dozen columns
    side by side); `mark_best` outlines the lowest cell; a cell holding a run whose status is not 'ok' gets a '*'.
    """
    t = _grid_pivot(df, value, axes=axes)
    v = t.to_numpy(dtype=float)
    im = ax.imshow(np.ma.masked_invalid(v), origin="lower", aspect="auto", cmap=cmap, norm=norm)
    sx, sy = max(1, math.ceil(t.shape[1] / 12)), max(1, math.ceil(t.shape[0] / 12))
    ax.set_xticks(range(0, t.shape[1], sx), [_value_text(axes[1], c) for c in t.columns[::sx]])
    ax.set_yticks(range(0, t.shape[0], sy), [_value_text(axes[0], i) for i in t.index[::sy]])
    if t.shape[1] > 6:  # side by side they run together
        ax.tick_params(axis="x", labelrotation=45)
    ax.set_xlabel(AXES.get(axes[1], (axes[1],))[0])
    ax.set_ylabel(AXES.get(axes[0], (axes[0],))[0])
    ax.set_title(title)
    if v.size <= 150:
        flagged = np.zeros(v.shape, bool)
        size = 8 if t.shape[1] <= 8 else max(5.0, 8 - 0.5 * (t.shape[1] - 8))
        if flag_cells and "status" in df:
            flags = df.assign(_flag=(df["status"] != "ok").astype(float))
            flagged = _grid_pivot(flags, "_flag", "max", axes).to_numpy() > 0
        for (i, j), x in np.ndenumerate(v):
            if np.isfinite(x):
                red, green, blue, _ = im.cmap(im.norm(x))
                color = "k" if 0.299 * red + 0.587 * green + 0.114 * blue > 0.5 else "w"
                text = fmt.format(x)
            else:
                color, text = "k", "n/a"
            ax.text(j, i, text + ("*" if flagged[i, j] else ""), ha="center", va="center", color=color, fontsize=size)
    if mark_best and np.isfinite(v).any():
        from matplotlib.patches import Rectangle

        i, j = np.unravel_index(np.nanargmin(v), v.shape)
        ax.add_patch(Rectangle((j - 0.5, i - 0.5), 1, 1, fill=False, ec="red", lw=2.2))
    return im


def _map_axis_label(axis: str, md: dict) -> str:
    """A map axis's label; a record's scale is its intensity in g where the scene scales records to an intensity
    ([excitation] scaling = 'intensity': Sa or PGA)."""
    exc = md.get("config", {}).get("excitation", {})
    if axis == "scale" and exc.get("scaling") == "intensity":
        return f"intensity, {'Sa' if exc.get('intensity') == 'sa' else 'PGA'} [g]"
    return AXES.get(axis, (axis,))[0]


def has_grid(df: pd.DataFrame, md: dict | None = None) -> bool:
    """Whether the runs span two swept axes (a map can be drawn); without `md`, k_s/k and r."""
    if md is not None:
        return map_axes(df, md) is not None
    return {"ks_ratio", "r"} <= set(df.columns) and df.ks_ratio.nunique() > 1 and df.r.nunique() > 1


def _flag_note(df: pd.DataFrame) -> str:
    bad = df.loc[df["status"] != "ok", "status"] if "status" in df else pd.Series(dtype=str)
    if bad.empty:
        return "every run ok"
    words = pd.Series([w for s in bad for w in s.split("+")]).value_counts()
    return "* cell holds a flagged run (" + ", ".join(f"{w}: {n}" for w, n in words.items()) + ")"


def _force_columns(df: pd.DataFrame) -> list[str]:
    return [c for c in df.columns if c.startswith("peak_force_f")]


def heatmap_figure(df: pd.DataFrame, md: dict, best: pd.DataFrame | None = None):
    """Eq. 20 error of each scored channel over two swept axes ((k_s/k, r) when both are swept, like
    Tables 2-3; else the first two) on one shared log colour scale, the lowest cell outlined; without an
    experiment, the first building's top-floor peak displacement and, where any run made contact, the
    top pair's peak pounding force. The swept values are listed in the title."""
    from matplotlib.colors import LogNorm, Normalize

    axes = map_axes(df, md) or ("ks_ratio", "r")
    codes = score_codes(df)
    other = _other_axes(md, axes)
    over = f" (lowest over {', '.join(other)})" if other else ""
    notes = [_flag_note(df)]
    if codes:
        vals = np.concatenate([df[f"rel_rms_{c}_pct"].to_numpy(float) for c in codes])
        vals = vals[np.isfinite(vals) & (vals > 0)]
        lo, hi = (vals.min(), vals.max()) if vals.size else (1.0, 100.0)
        norm = LogNorm(lo, hi) if hi > 3 * lo else Normalize(lo, hi)
        maps = [(f"rel_rms_{c}_pct", channel_label(c, md), norm, True) for c in codes]
        unit = "relative RMS error, eq. 20 [%]"
        quantities = sorted({channel_quantity(c)[0] for c in codes})
        what = f"relative RMS error of the {' and '.join(quantities)} against the experiment (eq. 20){over}"
    else:
        nf1 = len(md["buildings"][0]["masses_kg"])
        df = df.assign(**{f"peak_disp_b1f{nf1}_mm": df[f"peak_disp_b1f{nf1}_m"] * 1e3})
        maps = [(f"peak_disp_b1f{nf1}_mm", f"{channel_label(f'b1f{nf1}', md)}: peak displacement [mm]", None, False)]
        forces = _force_columns(df)
        if not forces:
            notes.append("one building: no pounding-force map")
        elif np.nanmax(df[forces].to_numpy(float), initial=0.0) > 0:
            j = forces[-1].removeprefix("peak_force_f").removesuffix("_N")
            maps.append((forces[-1], f"floor {j}: peak pounding force [N]", None, False))
        else:
            notes.append("no run made contact: no pounding-force map")
        unit = None
        what = f"peak response over the grid{over}"
    ncols = df[axes[1]].nunique() if axes[1] in df else 1
    fig = _figure(figsize=(max(5.6, 2.6 + 0.62 * ncols) * len(maps), 4.8))
    panels = fig.subplots(1, len(maps), squeeze=False)[0]
    labels = [_map_axis_label(a, md) for a in axes]
    for ax, (col, title, norm, is_err) in zip(panels, maps):
        im = heatmap(ax, df, col, title, "{:.3g}", norm=norm, mark_best=is_err, axes=axes)
        ax.set_ylabel(labels[0])
        ax.set_xlabel(labels[1])
        cb = fig.colorbar(im, ax=ax, label=unit or title.rsplit(": ", 1)[-1])
        if isinstance(norm, LogNorm):
            _plain_log(cb.ax.yaxis, _nice_log_ticks(norm.vmin, norm.vmax))
    import textwrap

    swept = "; ".join(values_text(a, df[a]) for a in swept_axes(df, md))
    width = int(fig.get_figwidth() * 12)  # characters of the title's font across the figure
    lines = textwrap.wrap(f"{md['scene_name']}: {what}; {len(df)} runs", width) + (
        textwrap.wrap(f"swept: {swept}", width, max_lines=3, placeholder=" ...") if swept else ["nothing swept"]
    )
    if codes:
        notes.insert(0, "red box: lowest error")
        ref = best[best.criterion == "refined_combined"] if best is not None and "criterion" in best else ()
        if len(ref):
            r0 = ref.iloc[0]
            opt = ", ".join(f"{AXES[k][1]} = {r0[k]:.3g}" for k in ("ks_ratio", "r") if k in r0 and pd.notna(r0[k]))
            notes.append(
                f"refined optimum {opt}: {md.get('experiment', {}).get('combine', 'combined')} error {r0.error_pct:.2f} %"
            )
    fig.suptitle("\n".join(lines), fontsize=11)
    fig.supxlabel("; ".join(notes), fontsize=9)
    return fig


def experiment_peaks(scene, md: dict) -> dict[str, tuple[float, float]]:
    """Largest |experimental displacement| [m] and its simulation time [s] per channel, in the scored window."""
    from pounding_sweep.sweep.scoring import load_experiment

    floors = scene.floors
    exp = load_experiment(scene.experiment, floors)
    t = exp.time_s - scene.experiment.time_offset_s
    lo, hi = md["experiment"]["window_s"]
    keep = (t >= lo - 1e-9) & (t <= hi + 1e-9)
    out = {}
    for code, x in exp.displacements.items():
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
    codes = [c for c in score_codes(df) if not is_acceleration(c)]  # Table 4: displacements
    if not codes:
        raise ValueError("peak_difference_table: the result file was not scored against a displacement")
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
    """(parameters to re-simulate, a label naming its value on every swept axis, its result row): the best
    grid run against the experiment (lowest combined eq. 20 error), or without one the run with the
    largest pounding force (run 0 when no run made contact)."""
    md = read_metadata(results)
    best = read_best(results, md)
    rows = best[best.criterion == "rel_rms_combined_pct"] if best is not None and "criterion" in best else ()
    swept = swept_axes(df, md)
    if len(rows) > 0:
        b = rows.iloc[0]
        row = df[df.run_id == int(b.run_id)].iloc[0]
        how = md.get("experiment", {}).get("combine", "combined")
        label = f"best grid run, {run_text(row, swept)} ({how} eq. 20 error {b.error_pct:.1f} %)"
    else:
        forces = df[_force_columns(df)].to_numpy(float).max(axis=1, initial=0.0)  # one building: no force columns
        if np.nanmax(forces, initial=0.0) > 0:
            row = df.iloc[int(np.nanargmax(forces))]
            label = "run with the largest pounding force"
        else:
            row = df.iloc[0]
            label = f"run {int(row.run_id)}; " + ("one building" if not _force_columns(df) else "no run made contact")
        label += f": {run_text(row, swept)}" if swept else ""
    pick = {
        k: float(row[k])
        for k in ("ks_ratio", "r", "gap_m", "amplitude_m", "frequency_Hz", "scale", *STRUCTURE_AXES)
        if k in row and np.isfinite(row[k])
    }
    if "ks_ratio" not in pick and "ks_N_per_m" in row:
        pick["ks_N_per_m"] = float(row["ks_N_per_m"])
    records = md.get("grid_axes", {}).get("record", [])
    if len(records) > 1:  # a swept record: re-simulate the row's own
        pick["record"] = next(p for p in records if Path(p).stem == row["record"])
    return pick, label, row


def calibrated_run(best: pd.DataFrame | None) -> tuple[dict, str] | None:
    """(parameters to re-simulate, a label) of the calibrated optimum in a best table (with several laws the one of
    least error), or None when the sweep was not calibrated. The fitted values only: the rest is the scene's."""
    if best is None or "criterion" not in best:
        return None
    rows = best[best.criterion == "calibrated"]
    if rows.empty:
        return None
    row = rows.sort_values("error_pct").iloc[0]
    fitted = [k for k in row.index if k in FITTABLE or member(k) is not None or channel_offset(k) is not None]
    pick = {k: float(row[k]) for k in fitted if pd.notna(row[k])}  # a per-story, per-mode or per-channel one too
    law = row.get("contact_law")
    from pounding_sweep.sweep.calibrate import NO_CONTACT

    if isinstance(law, str) and law != NO_CONTACT:
        pick["law"] = law
    values = [f"{k} = {v:.4g}" for k, v in pick.items() if k != "law"]
    fitted = ",\n".join(", ".join(values[i : i + 3]) for i in range(0, len(values), 3))  # 3 a line: titles fit
    how = f"{law} law, " if "law" in pick else ""
    return pick, f"calibrated run ({how}{fitted}; relative RMS error {row.error_pct:.1f} %)"


def _time_text(t: float) -> str:
    """A time [s] to the hundredth, trailing zeros dropped (a rounded zero without its sign: '0', not '-0')."""
    text = f"{t:.2f}".rstrip("0").rstrip(".")
    return "0" if text == "-0" else text


def zoom_window(scene, t_end: float, exp=None, x=None, width_s: float = 0.5) -> tuple[float, float]:
    """The zoomed interval: 2-2.5 s for harmonic motion (the paper's), else `width_s` around the
    largest experimental (or, without one, numerical `x`) displacement; its ends at 0.01 s."""
    if t_end <= width_s:
        return 0.0, t_end
    if scene.excitation.type == "harmonic" and t_end >= 2.0 + width_s:
        return 2.0, 2.0 + width_s
    if exp is not None:
        code, xe = next(iter((exp.displacements or exp.channels).items()))  # accelerations only: theirs
        te = exp.time_s - scene.experiment.time_offset_s
        keep = (te >= 0) & (te <= t_end)
        tp = float(te[keep][np.argmax(np.abs(xe[keep]))])
    else:
        tp = float(np.argmax(np.abs(x)) / max(len(x) - 1, 1) * t_end) if x is not None else t_end / 2
    return around(tp, t_end, width_s)


def around(tp: float, t_end: float, width_s: float = 0.5) -> tuple[float, float]:
    """A `width_s` window holding time tp, centred on it where the run allows, its ends on 0.01 s."""
    lo = min(max(0.0, round(tp - width_s / 2, 2)), t_end - width_s)
    return lo, lo + width_s


def force_zoom(zoom: tuple[float, float], t_peak: float, t_end: float) -> tuple[float, float]:
    """The force figure's zoom: the displacement's where it holds the peak force, else around the peak."""
    if zoom[0] <= t_peak <= zoom[1] and zoom[1] - zoom[0] < t_end:
        return zoom
    return around(t_peak, t_end, zoom[1] - zoom[0]) if t_end > zoom[1] - zoom[0] else (0.0, t_end)


def force_caption(m: dict, top: int, law: str) -> str:
    """The force figure's facts: peak, phases, and the pull where the law has one (the classic law's
    dashpot pulls just before separation; 'no_tension' never pulls). A negative least force smaller
    than 1e-6 of the peak is the event scheme's switch residue, not a pull."""
    facts = (
        f"floor {top}: peak {m[f'peak_force_f{top}_N']:.1f} N at {m[f'peak_force_time_f{top}_s']:.2f} s, "
        f"{int(m[f'compression_phases_f{top}'])} compression phases, median "
        f"{m[f'median_compression_phase_f{top}_s'] * 1e3:.1f} ms"
    )
    least = m[f"min_force_f{top}_N"]
    if law == "no_tension":
        return facts + "; no_tension law: the force never pulls"
    if least < -1e-6 * m[f"peak_force_f{top}_N"]:
        facts += f"; least {least:.3g} N (the classic law's pull before separation)"
    return facts


def history_figures(
    scene,
    pick: dict,
    label: str,
    md: dict | None = None,
    skipped: dict | None = None,
    compared: dict | None = None,
    exp=None,
) -> dict:
    """Re-simulate one run and draw {'displacement_history', 'pounding_force'[, 'ssp']} figures. A run
    without contact gets no force figure: `skipped` (a dict, when given) is told why; `compared` (a dict, when
    given) is filled with the samples the SSP drew (measured_residuals), for measured_figure, so the run is
    simulated once. `exp`: the scene's experiment when the caller has read it (load_experiment)."""
    from pounding_sweep.sweep.scoring import load_experiment
    from pounding_sweep.sweep.simulate import simulate

    floors = scene.floors
    names = [b.name or f"building {i}" for i, b in enumerate((scene.building1, scene.building2), 1) if b is not None]
    md = md or {"buildings": [{"name": n} for n in names]}
    top = min(floors)  # 0: one building, no pairs
    if exp is None and scene.experiment is not None:
        exp = load_experiment(scene.experiment, floors)
    codes = list(exp.channels) if exp is not None else []  # displacements here, every channel in the SSP
    disp_codes = list(exp.displacements) if exp is not None else []
    tops = [f"b{b}f{n}" for b, n in zip((1, 2), floors) if n]
    shown = tops + [c for c in disp_codes if c not in tops]
    model_of = {c: c if is_acceleration(c) else f"disp_{c}" for c in codes}
    channels = list(dict.fromkeys([f"disp_{c}" for c in shown] + [model_of[c] for c in codes]))
    run_scene, params = _run(scene, pick)
    hist, m = simulate(run_scene, channels=channels + ([f"force_f{top}"] if top else []), **params)
    t = hist.t_s.to_numpy()
    zoom = zoom_window(scene, t[-1], exp, hist[f"disp_{shown[0]}_m"].to_numpy())
    zoom_text = f"zoom {_time_text(zoom[0])}-{_time_text(zoom[1])} s"
    out = {}

    # displacement, whole and zoomed (Figs. 13, 21)
    fig = _figure(figsize=(12, 2.9 * len(shown) + 0.9))
    axes = fig.subplots(len(shown), 2, squeeze=False, gridspec_kw={"width_ratios": [3, 1]})
    for i, code in enumerate(shown):
        x = hist[f"disp_{code}_m"].to_numpy() * 1e3
        for ax, lim in ((axes[i, 0], None), (axes[i, 1], zoom)):
            ax.plot(t, x, lw=0.9, color="C0", label="numerical")
            if code in disp_codes:
                ax.plot(
                    sample_times(scene, pick, exp, code),
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
        axes[i, 0].axvspan(*zoom, color="0.85", zorder=0, label=zoom_text)
        title = channel_label(code, md)
        if code in disp_codes:
            pn, diff = m[f"peak_num_{code}_m"] * 1e3, m[f"peak_diff_{code}_pct"]
            title += (
                f": eq. 20 error {m[f'rel_rms_{code}_pct']:.1f} %; peak {pn:.2f} mm, experiment "
                f"{pn / (1 - diff / 100):.2f} mm (Table 4 difference {diff:+.1f} %)"
            )
        axes[i, 0].set_title(title, loc="left", fontsize=10)
        axes[i, 1].set_title(zoom_text, fontsize=10)
    handles, labels = axes[0, 0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="outside lower center", ncols=3, fontsize=9)
    fig.suptitle(f"{scene.name}: displacement relative to the table\n{label}", x=0.01, ha="left", fontsize=11)
    out["displacement_history"] = fig

    # pounding force (Fig. 19)
    f = hist[f"force_f{top}_N"].to_numpy() if top else np.zeros(0)
    if not top:
        if skipped is not None:
            skipped["pounding_force"] = "one building (no [building2]): no contact, so no pounding force to draw"
    elif not np.any(f != 0.0):
        if skipped is not None:
            skipped["pounding_force"] = f"no contact at floor {top} in the run shown, so no force to draw ({label})"
    else:
        fzoom = force_zoom(zoom, m[f"peak_force_time_f{top}_s"], t[-1])
        fig = _figure(figsize=(12, 4.0))
        axes = fig.subplots(1, 2, gridspec_kw={"width_ratios": [3, 1]})
        for ax, lim in ((axes[0], None), (axes[1], fzoom)):
            ax.plot(t, f, lw=0.9, color="C3")
            ax.axhline(0, color="k", lw=0.5)
            ax.set_xlim(*(lim or (t[0], t[-1])))
            ax.set_xlabel("time [s]")
            ax.set_ylabel(f"pounding force $F_{{1{top}}} = F_{{2{top}}}$ [N]")
            ax.grid(alpha=0.3)
        axes[0].axvspan(*fzoom, color="0.85", zorder=0)
        axes[1].set_title(f"zoom {_time_text(fzoom[0])}-{_time_text(fzoom[1])} s", fontsize=10)
        axes[0].set_title(force_caption(m, top, scene.contact.law), loc="left", fontsize=9)
        fig.suptitle(
            f"{scene.name}: pounding force (compression > 0, {scene.contact.law} law); {label}",
            x=0.01,
            ha="left",
        )
        out["pounding_force"] = fig

    # numerical against experimental (SSP), every channel in its own quantity: the samples the scoring and the
    # calibration compare (measured_residuals: the window, the fitted clock offsets, the low-pass filter)
    if codes:
        from pounding_sweep.engine.score import lagged_correlation, relative_rms_error_pct

        data = measured_residuals(scene, pick, md, hist, exp)
        if compared is not None:
            compared.update(data)
        fig = _figure(figsize=(4.4 * len(codes), 5.6))  # tall enough for square boxes
        axes = fig.subplots(1, len(codes), squeeze=False)[0]
        for ax, code in zip(axes, codes):
            quantity, unit, factor = channel_quantity(code)
            _tk, xe_si, xd_si, _res = data[code]
            xe, xd = xe_si * factor, xd_si * factor
            lim = float(np.max(np.abs(np.r_[xe, xd]))) * 1.05
            ax.plot([-lim, lim], [-lim, lim], "k--", lw=0.8, label="numerical = experimental")
            ax.plot(xe, xd, "o", ms=2, alpha=0.6, color="C0", label=f"{xe.size} samples")
            ax.set_xlim(-lim, lim)
            ax.set_ylim(-lim, lim)
            ax.set_xlabel(f"experimental {quantity} [{unit}]")
            ax.set_ylabel(f"numerical {quantity} [{unit}]")
            corr = lagged_correlation(xd_si, xe_si, 0)  # the scored corr_<c> (NaN below 2 samples)
            ax.set_title(
                f"{channel_label(code, md)}\neq. 20 error {relative_rms_error_pct(xd_si, xe_si):.1f} %, "
                f"correlation {corr:.4f}",
                fontsize=10,
            )
            ax.set_box_aspect(1)
            ax.legend(fontsize=8, loc="upper left")
            ax.grid(alpha=0.3)
        fig.suptitle(f"{scene.name}: numerical against experimental (sub-space plot)\n{label}", fontsize=11)
        out["ssp"] = fig
    return out


def _run(scene, pick: dict) -> tuple:
    """(the scene, the run parameters) of the run `pick`: a fitted story's or mode's value set in the scene's
    building (prepare.with_structure: not a run parameter), a per-channel clock offset left out (it shifts that
    channel's samples and changes no run: measured_residuals applies it)."""
    members = {k: v for k, v in pick.items() if member(k) is not None}
    params = {k: v for k, v in pick.items() if member(k) is None and channel_offset(k) is None}
    return (with_structure(scene, members) if members else scene), params


def sample_times(scene, pick: dict, exp, code: str | None = None) -> np.ndarray:
    """The experiment table's instants at the run's simulation clock [s]: shifted by the run's clock offset (a
    fitted time_offset_s, else the scene's) and, for a channel, by its own fitted offset on top, as the
    calibration shifts them (sweep/calibrate.py Problem). The figures' one rule for it."""
    t = exp.time_s - pick.get("time_offset_s", scene.experiment.time_offset_s)
    return t if code is None else t - pick.get(f"time_offset_s_{code}", 0.0)


def measured_residuals(scene, pick: dict, md: dict, hist=None, exp=None) -> dict:
    """Every measured channel of the scene against the run `pick` over the compared window, in SI: code -> (t [s],
    measured, model, residual = measured - model). The model is sampled at the table's instants by linear
    interpolation between steps (the calibration interpolates displacements by cubic Hermite from the step's
    velocities: sweep/calibrate.py; the two differ by O(dt^2) of the curvature); an acceleration channel of a scene
    that models its accelerometer ([experiment] sensor_filter) is read through that sensor (sweep/sensor.py), as
    scored and calibrated; and, where the scene low-passes the acceleration channels, both are filtered with the
    scoring's sections from rest at the window's start, as scored. `hist` (simulate's histories of `pick` at every
    step, holding every channel's column) and `exp` (the loaded experiment): a caller's own, not run or read again."""
    from scipy.signal import sosfilt

    from pounding_sweep.sweep.scoring import load_experiment
    from pounding_sweep.sweep.sensor import acceleration_at, sensor_model
    from pounding_sweep.sweep.simulate import simulate

    exp = load_experiment(scene.experiment, scene.floors) if exp is None else exp
    codes = list(exp.channels)
    if hist is None:
        run_scene, params = _run(scene, pick)
        hist, _ = simulate(run_scene, channels=[history_column(c).rsplit("_m", 1)[0] for c in codes], **params)
    t = hist.t_s.to_numpy()  # every step (simulate's default decimation)
    sensor = sensor_model(scene.experiment, exp.dt_sample, float(t[1] - t[0])) if t.size > 1 else None
    # the samples the calibration compares (sweep/calibrate.py Problem): those inside the window at the scene's own
    # clock offset, each at its simulation time under the run's (a fitted time_offset_s)
    lo, hi = scene.experiment.window_s or (0.0, t[-1])
    t0 = exp.time_s - scene.experiment.time_offset_s
    keep = (t0 >= lo) & (t0 <= hi)
    tk = sample_times(scene, pick, exp)[keep]
    lowpass = md.get("experiment", {}).get("lowpass")
    sos = np.asarray(lowpass["sos"], float) if lowpass else np.zeros((0, 6))
    out = {}
    for code in codes:
        xe = exp.channels[code][keep]
        ts = sample_times(scene, pick, exp, code)[keep]
        model = hist[history_column(code)].to_numpy()
        if is_acceleration(code):
            xm = acceleration_at(sensor, model, float(t[1] - t[0]), ts, sos)
            xe = sosfilt(sos, xe) if sos.shape[0] else xe
        else:
            xm = np.interp(ts, t, model)
        out[code] = (tk, xe, xm, xe - xm)
    return out


def measured_figure(scene, pick: dict, label: str, md: dict, noise: dict | None = None, data: dict | None = None):
    """The run `pick` (the calibrated one where there is a calibration) against every measured channel, each in its
    own quantity (displacement in mm, absolute acceleration in m/s^2; measured_residuals): measured and model
    (left whole, right a 1 s zoom around the largest measured value), and under each its residual with the
    channel's noise band +/- 2 sigma (`noise`: code -> sigma in SI, the calibration's noise floor, else the scene's
    [experiment] noise or noise_window_s); each title the
    eq. 20 error and the residual's RMS against that noise. `data`: measured_residuals' result when the caller
    has it (figures: history_figures' run)."""
    from pounding_sweep.engine.score import relative_rms_error_pct

    data = data or measured_residuals(scene, pick, md)
    codes = list(data)
    t0, first = data[codes[0]][0], data[codes[0]][1]
    zoom = around(float(t0[np.argmax(np.abs(first))]), float(t0[-1]), 1.0)
    noise = noise or {}
    fig = _figure(figsize=(12, 2.4 * 2 * len(codes) + 1.2))
    axes = fig.subplots(2 * len(codes), 2, squeeze=False, gridspec_kw={"width_ratios": [3, 1]})
    for i, code in enumerate(codes):
        tk, xe, xm, res = data[code]
        quantity, unit, factor = channel_quantity(code)
        rms, sigma = float(np.sqrt(np.mean(res * res))), noise.get(code)
        head = (  # two lines: one ran into the zoom panel's title (a helper's trial)
            f"{channel_label(code, md)}: eq. 20 error {float(relative_rms_error_pct(xm, xe)):.1f} %;\n"
            f"RMS residual {rms * factor:.4g} {unit}"
        )
        head += (
            f", {rms / sigma:.1f} times the channel's noise {sigma * factor:.3g} {unit}"
            if sigma
            else " (no noise value for this channel: give [experiment] noise or noise_window_s)"
        )
        top, bottom = axes[2 * i], axes[2 * i + 1]
        for col, lim in ((0, None), (1, zoom)):
            top[col].plot(tk, xe * factor, color="C1", lw=0.8, label="measured")
            top[col].plot(tk, xm * factor, color="C0", lw=0.8, label="model")
            bottom[col].plot(tk, res * factor, color="C3", lw=0.7, label="residual (measured - model)")
            if sigma:
                bottom[col].axhspan(-2 * sigma * factor, 2 * sigma * factor, color="tab:green", alpha=0.35, lw=0)
            for ax, what in ((top[col], quantity), (bottom[col], "residual")):
                ax.set_xlim(*(lim or (tk[0], tk[-1])))
                ax.set_xlabel("time [s]")
                ax.set_ylabel(f"{what} [{unit}]")
                ax.grid(alpha=0.3)
        top[0].axvspan(*zoom, color="0.9", zorder=0)
        top[0].set_title(head, loc="left", fontsize=9)
        top[1].set_title(f"zoom {_time_text(zoom[0])}-{_time_text(zoom[1])} s", fontsize=9)
    handles, labels = [], []
    for ax in (axes[0, 0], axes[1, 0]):
        h, lab = ax.get_legend_handles_labels()
        handles += h
        labels += lab
    from matplotlib.patches import Patch

    if noise:  # green, not the zoom window's grey (a helper read the one for the other where the band is thin)
        handles.append(Patch(color="tab:green", alpha=0.35))
        labels.append("+/- 2 x the channel's noise (sigma)")
    handles.append(Patch(color="0.9"))
    labels.append("the window zoomed on the right")
    fig.legend(handles, labels, loc="outside lower center", ncols=5, fontsize=9)
    lowpass = md.get("experiment", {}).get("lowpass")
    filt = f"; accelerations low-passed at {lowpass['cutoff_Hz']:g} Hz as scored" if lowpass else ""
    fig.suptitle(
        f"{scene.name}: measured against model, each channel in its own quantity, over the scored window "
        f"{_time_text(t0[0])}-{_time_text(t0[-1])} s{filt}\n{label}",
        x=0.01,
        ha="left",
        fontsize=10,
    )
    return fig


def channel_quantity(code: str) -> tuple[str, str, float]:
    """(quantity, unit shown, factor from SI) of an experiment channel: displacements in mm, absolute
    accelerations in m/s^2 (each in its own quantity, as the messages show them: scene/channels.shown_value)."""
    if is_acceleration(code):
        return "absolute acceleration", "m/s^2", 1.0
    return "displacement", "mm", 1e3


def history_column(code: str) -> str:
    """The simulate() history column of an experiment channel's model side."""
    return f"{code}_m_s2" if is_acceleration(code) else f"disp_{code}_m"


# ----------------------------------------------------------------------------- error against run time


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


#: a marker per time step in the error-against-run-time figure (labels beside the points overlapped where
#: the schemes' points lie close, as they do at fine steps)
DT_MARKERS = ("o", "s", "^", "D", "v", "P", "X", "*", "h", "<", ">", "p")


def _ladder_channel(scene) -> str | None:
    """The history the accuracy ladder measures its error on: a scored acceleration's floor where the scene scores
    accelerations only (a helper's acceleration-scored calibration showed the error of a displacement it never
    scored), else the ladder's default (building 1's top-floor displacement)."""
    x = scene.experiment
    if x is None:
        return None
    # by (building, floor): building 1's top floor, f10 above f9
    acc = sorted(
        (c for c in x.channels.values() if c.startswith("abs_acc_")),
        key=lambda c: (-building_floor(c)[0], building_floor(c)[1]),
    )
    if acc and (len(acc) == len(x.channels) or x.use == "acceleration"):
        return acc[-1]
    return None


def error_vs_runtime_figure(table: pd.DataFrame, title: str = ""):
    """Two log-log panels per scheme: error against dt, and error against run time. A scheme has one
    colour; a time step one marker shape (the legend lists both), so no label can cover another."""
    from matplotlib.lines import Line2D

    fig = _figure(figsize=(11, 4.6))
    ax_dt, ax_t = fig.subplots(1, 2)
    bad = []
    dts = sorted(table.dt_s.unique())
    marker = {d: DT_MARKERS[i % len(DT_MARKERS)] for i, d in enumerate(dts)}
    schemes = []
    for k, (scheme, g) in enumerate(table.groupby("scheme", sort=False)):
        g = g.sort_values("dt_s")
        ok = np.isfinite(g.rel_rms_pct) & (g.rel_rms_pct > 0)
        bad += [f"{scheme} dt = {d:g} s" for d in g.dt_s[~ok]]
        g = g[ok]
        color = f"C{k}"
        schemes.append(Line2D([], [], color=color, label=f"scheme '{scheme}'"))
        ax_dt.loglog(g.dt_s, g.rel_rms_pct, color=color, label=f"scheme '{scheme}'")
        ax_t.loglog(g.run_time_s * 1e3, g.rel_rms_pct, color=color, label=f"scheme '{scheme}'")
        for d, x_ms, e in zip(g.dt_s, g.run_time_s * 1e3, g.rel_rms_pct):
            for ax, x in ((ax_dt, d), (ax_t, x_ms)):
                ax.plot(x, e, marker[d], color=color, ms=6, mec="k", mew=0.4, ls="none")
    steps = [
        Line2D([], [], marker=marker[d], color="0.5", mec="k", mew=0.4, ls="none", label=f"dt = {d:g} s") for d in dts
    ]
    _plain_log(ax_dt.xaxis, dts if len(dts) <= 6 else None)
    ms = table.run_time_s.to_numpy(float) * 1e3
    ms = ms[np.isfinite(ms) & (ms > 0)]
    _plain_log(ax_t.xaxis, _nice_log_ticks(ms.min(), ms.max()) if ms.size else None)
    ax_dt.set_xlabel("time step dt [s]")
    ax_t.set_xlabel("run time of one run in the kernel [ms]")
    for ax in (ax_dt, ax_t):
        ax.set_ylabel("relative RMS error, eq. 20 [%]")
        _plain_log(ax.yaxis)
        ax.grid(alpha=0.3, which="both")
    ax_dt.legend(handles=schemes, fontsize=9, loc="upper left")
    ax_t.legend(handles=steps, fontsize=8, loc="upper right", ncols=2 if len(steps) > 6 else 1)
    ref = ""
    if {"ref_dt_s", "channel"} <= set(table.columns):
        scheme = f"'{table.ref_scheme.iloc[0]}' scheme" if "ref_scheme" in table else "reference"
        ref = f"error of {table.channel.iloc[0]} against the {scheme} at dt = {table.ref_dt_s.iloc[0]:g} s"
    fig.suptitle("\n".join(s for s in (title or "error against run time", ref) if s), fontsize=11)
    if bad:
        fig.supxlabel("not shown (diverged or no error): " + ", ".join(bad), fontsize=8)
    return fig


# ----------------------------------------------------------------------------- all of it, as PNGs


def figures(
    results: str | Path, accuracy: str | Path | pd.DataFrame | None = None, skipped: dict | None = None
) -> dict:
    """Every figure of a result file, by name. `accuracy`: an error-against-run-time table (or its
    CSV/Parquet file); None computes a small `accuracy_ladder` of the best run. A figure with nothing to
    show is left out, and `skipped` (a dict, when given) is told why. A file that is no sweep's result
    is a ResultError (check_results)."""
    results = Path(results)
    md = check_results(results)
    scene = scene_of(results)  # its files checked before anything is drawn
    df = pd.read_parquet(results)
    best = read_best(results, md)
    best_file = sidecar_path(_results_folder(results), "best")
    out = {}
    if has_grid(df, md):
        out["heatmaps"] = heatmap_figure(df, md, best)
    elif skipped is not None:
        swept = swept_axes(df, md)
        skipped["heatmaps"] = (
            f"no map: the sweep varies {' and '.join(swept) if swept else 'nothing'}, a map needs two axes"
        )
    calibrated = calibrated_run(best)
    if calibrated is not None:
        profiled = calibration_profile_figure(best_file)
        if profiled is not None:
            out["calibration_profiles"] = profiled
        elif skipped is not None:
            skipped["calibration_profiles"] = (
                "the calibration profiled no parameter ([calibrate] profile, or profile_points = 0): no curve to draw"
            )
    pick, label, _ = best_run(results, df)
    if calibrated is not None:  # the calibrated run, not the best grid run, is the one the figures show
        pick = {**{k: v for k, v in pick.items() if k in ("record",)}, **calibrated[0]}
        label = calibrated[1]
    compared: dict = {}
    exp = None
    if scene.experiment is not None:  # read once: the figures' runs and the noise below
        from pounding_sweep.sweep.scoring import load_experiment

        exp = load_experiment(scene.experiment, scene.floors)
    out.update(history_figures(scene, pick, label, md, skipped, compared, exp))
    if exp is not None:
        # the calibration's noise floor, else the scene's own ([experiment] noise or noise_window_s: the experiment's)
        noise = (calibration_noise(best_file, pick) if calibrated is not None else {}) or dict(exp.noise)
        out["measured_vs_model"] = measured_figure(scene, pick, label, md, noise, compared)
    ladder_scene, pick = _run(scene, pick)
    pick = {k: v for k, v in pick.items() if k != "time_offset_s"}  # the ladder runs without the experiment
    if accuracy is None:
        # one building: the schemes differ only at contact, so one of them (the reference's) says it all
        schemes = None if scene.contact is not None else ["event"]
        window = ladder_duration(ladder_scene, pick.get("record"))
        table = accuracy_ladder(
            ladder_scene, schemes=schemes, duration_s=window, channel=_ladder_channel(scene), **pick
        )
    else:
        table = accuracy if isinstance(accuracy, pd.DataFrame) else read_accuracy_table(accuracy)
    swept = swept_axes(df, md)
    shown = [a for a in ("gap_m", "ks_ratio", "ks_N_per_m", "r") if a in pick and (a in swept or a != "gap_m")]
    what = run_text(pd.Series(pick), shown + [a for a in swept if a in pick and a not in shown])
    dur = table.duration_s.iloc[0] if "duration_s" in table and np.isfinite(table.duration_s.iloc[0]) else None
    alone = "; one building: the schemes coincide" if scene.contact is None else ""  # they differ only at contact
    out["error_vs_runtime"] = error_vs_runtime_figure(
        table,
        f"{scene.name}: error against run time" + (f", first {dur:.4g} s" if dur else "") + f"{alone}\n({what})",
    )
    return out


def calibration_profile_figure(best_path: str | Path):
    """Profile curves of a calibration (sweep/calibrate.py): per profiled parameter and law, the increase of
    the residual (delta chi^2, the rest refitted) against the parameter, the 95 % threshold 3.84 and the
    fitted value; the law comparison in the title when several laws were calibrated. None when the calibration
    profiled nothing."""
    from pounding_sweep.sweep.calibrate import CHI2_1_95, NO_CONTACT, read_calibration

    cal = read_calibration(best_path)
    prof, fits, laws = cal["profiles"], cal["fits"], cal["laws"]
    names = list(dict.fromkeys(prof.parameter)) if not prof.empty else []
    if not names:  # nothing profiled: no figure rather than empty axes
        return None
    fig = _figure(figsize=(5.2 * max(1, len(names)), 4.0))
    axes = fig.subplots(1, max(1, len(names)), squeeze=False)
    for ax, name in zip(axes[0], names):
        for law, rows in prof[prof.parameter == name].groupby("contact_law", sort=False):
            rows = rows.sort_values("value")
            shown = "profile" if law == NO_CONTACT else law  # one building's fit has no law
            line = ax.plot(rows.value, np.maximum(rows.delta_chi2, 1e-3), marker="o", ms=3, label=shown)[0]
            f = fits[(fits.contact_law == law) & (fits.parameter == name)]
            if not f.empty:
                ax.axvline(f.estimate.iloc[0], color=line.get_color(), lw=0.8, ls=":")
                ax.axvspan(f.profile_low.iloc[0], f.profile_high.iloc[0], color=line.get_color(), alpha=0.12)
                lo, hi = f.ci95_model_low.iloc[0], f.ci95_model_high.iloc[0]
                if f["quote"].iloc[0] == "model_error" and np.isfinite(lo) and np.isfinite(hi):
                    # the interval to quote where the model misfits the data: the noise-based profile band
                    # understates it (a helper read a 1.298-1.3 band as the answer beside 0.7-1.3 quoted)
                    ax.axvspan(
                        lo,
                        hi,
                        facecolor="none",
                        edgecolor=line.get_color(),
                        hatch="//",
                        lw=0.8,
                        label=("" if law == NO_CONTACT else f"{shown}: ") + "with model error, 95 % (quote this)",
                    )
        ax.axhline(CHI2_1_95, color="k", lw=0.8, ls="--", label="95 % (3.84)")
        ax.set_yscale("log")
        if is_log(name):
            ax.set_xscale("log")
        ax.set_xlabel(name)
        ax.set_ylabel("delta chi^2 (others refitted)")
        ax.legend(fontsize=8)
    if len(laws) > 1:
        order = laws.sort_values("aic")
        text = ", ".join(f"{r.contact_law} dAIC {r.delta_aic:.1f}" for r in order.itertuples())
        cmp = cal.get("comparison") or {}
        verdict = f"chosen: {cmp['chosen']}" if cmp.get("chosen") else "the data cannot decide"
        fig.suptitle(f"calibration profiles; laws: {text} (one N_eff, tie 2); {verdict}", fontsize=9)
    else:
        fig.suptitle(
            "calibration profiles (shaded: the values the noise cannot exclude, 95 %; hatched: with model error)",
            fontsize=9,
        )
    return fig


def calibration_noise(best_path: str | Path, pick: dict) -> dict:
    """Each channel's noise floor (SI) the calibration scaled its residuals by, of the law `pick` shows."""
    from pounding_sweep.sweep.calibrate import NO_CONTACT, read_calibration

    per_law = read_calibration(best_path).get("per_law") or {}
    one = per_law.get(pick.get("law", NO_CONTACT)) or next(iter(per_law.values()), {})
    return {**one.get("noise_floor_m", {}), **one.get("noise_floor_m_s2", {})}


def posterior_corner_figure(post, fit=None):
    """Corner plot of posterior samples (sweep/posterior.py): each parameter's histogram with its 95 % credible
    interval (dashed) and, given the calibration `fit`, its profile interval where profiled, else its Gauss-Newton
    one (shaded); below the diagonal the pairs' samples."""
    names, x = post.names, post.samples
    p = len(names)
    fig = _figure(figsize=(2.2 * p + 1, 2.2 * p + 0.6))
    axes = fig.subplots(p, p, squeeze=False)
    for i in range(p):
        for j in range(p):
            ax = axes[i][j]
            if j > i:
                ax.set_axis_off()
                continue
            if i == j:
                ax.hist(x[:, i], bins=30, color="0.4")
                for v in post.intervals[names[i]]:
                    ax.axvline(v, color="k", ls="--", lw=0.8)
                if fit is not None:
                    ok, a, b = fit.identified.get(names[i], (None, *fit.ci95[names[i]]))
                    ax.axvspan(a, b, color="tab:orange", alpha=0.25, lw=0)
                ax.set_yticks([])
            else:
                ax.plot(x[:, j], x[:, i], ".", ms=1.5, alpha=0.3, color="0.2")
            if i == p - 1:
                ax.set_xlabel(names[j], fontsize=8)
            if j == 0 and i > 0:
                ax.set_ylabel(names[i], fontsize=8)
            ax.tick_params(labelsize=6)
    fig.suptitle(
        f"posterior ({post.samples.shape[0]} samples, ~{post.ess:.0f} effective; dashed: 95 % credible; "
        "shaded: profile or Gauss-Newton 95 %)",
        fontsize=8,
    )
    return fig


#: the PNG text chunk that marks a figure as written by plot_results (an existing PNG without it is a user's)
PNG_MARK = "pounding_sweep"


def _ours_png(path: Path) -> bool:
    try:
        with open(path, "rb") as f:
            head = f.read(1 << 16)  # matplotlib writes its text chunks before the image data
    except OSError:
        return False
    return head.startswith(b"\x89PNG") and b"tEXt" + PNG_MARK.encode() + b"\x00" in head


def check_plot_folder(results: Path, out_dir: Path, names) -> None:
    """Refuse (ResultError) an output folder inside the result's own folders (PNGs among the parts make the dataset
    unreadable) and a PNG there, of a name a figure takes, that plot did not write (a user's file)."""
    inside = [_results_folder(results)]
    inside.append(sidecar_path(inside[0], "histories"))
    target = out_dir.resolve()
    for folder in inside:
        if target == folder or folder in target.parents:
            raise ResultError(
                f"{out_dir}: inside the result folder {folder}, whose every file readers take for a part: give "
                "another --out"
            )
    if out_dir.exists() and not out_dir.is_dir():
        raise ResultError(f"{out_dir}: exists and is not a folder (the figures go into a folder): give another --out")
    for name in names:
        png = out_dir / f"{name}.png"
        if (png.exists() or png.is_symlink()) and not (png.is_file() and _ours_png(png)):
            raise ResultError(
                f"{png}: exists and is not a figure plot wrote; plot never replaces another file: give another "
                "--out, or move it away"
            )


def plot_results(
    results: str | Path,
    out_dir: str | Path | None = None,
    accuracy: str | Path | pd.DataFrame | None = None,
    skipped: dict | None = None,
) -> list[Path]:
    """Write the figures of one result file as PNGs; return their paths (`skipped`: as in `figures`). Each is
    written whole to a hidden temporary name and renamed, marked as plot's own (PNG_MARK) so that a later plot may
    replace it; nothing is written when the output folder is refused (check_plot_folder)."""
    results = Path(results)
    check_results(results)
    out_dir = Path(out_dir) if out_dir else results.with_suffix("").with_name(results.stem + "_plots")
    check_plot_folder(results, out_dir, FIGURE_NAMES)
    figs = figures(results, accuracy, skipped)
    out_dir.mkdir(parents=True, exist_ok=True)
    written = []
    for name, fig in figs.items():
        path = out_dir / f"{name}.png"
        tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
        try:
            fig.savefig(tmp, dpi=DPI, format="png", metadata={PNG_MARK: f"plot of {results.name}"})
            os.replace(tmp, path)
        finally:
            tmp.unlink(missing_ok=True)
        written.append(path)
    return written


#: every figure plot_results may write (figures' names)
FIGURE_NAMES = (
    "heatmaps",
    "calibration_profiles",
    "displacement_history",
    "pounding_force",
    "ssp",
    "measured_vs_model",
    "error_vs_runtime",
)
