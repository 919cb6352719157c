"""After the grid: the best table. The ranking's best runs per criterion, the continuous refinement of (k_s/k, r)
from the best cell ([experiment] refine), the grid-edge and scale checks, the calibration ([calibrate]), each
reused from the stored best table where an earlier run of the very same sweep made it, and the table written
whole (sweep/run.py calls best_table once the grid's runs are in)."""

from __future__ import annotations

import dataclasses
import os
import time
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import pyarrow.parquet as pq

from pounding_sweep import __version__
from pounding_sweep.model.grid import Grid
from pounding_sweep.scene import Scene
from pounding_sweep.scene.hashing import file_digest, hash_of
from pounding_sweep.scene.parameters import default_profiled
from pounding_sweep.sweep.checks import check_scale
from pounding_sweep.sweep.gate import pause
from pounding_sweep.sweep.prepare import Prepared
from pounding_sweep.sweep.ranking import Refinement, refine, score_table_columns
from pounding_sweep.sweep.results import file_metadata, read_metadata, write_table_atomic
from pounding_sweep.warn import warn

if TYPE_CHECKING:  # pandas costs 0.3 s to import: only where a table is built
    import pandas as pd


def best_table(scene: Scene, prep: Prepared, best, contact, stored, summary, progress, threads: int, notes, results):
    """The best table of a finished grid: `best` the ranking's frame, `contact` the grid's ContactTally, `stored`
    the refinement an earlier run stored (stored_refinement) or None; `summary` (a SweepSummary) gains the
    refinement and the calibration; `notes` the sweep's warnings, `results` its results folder's name. Written to
    summary.best_path and returned."""
    import pandas as pd

    if best.empty:  # every run diverged or ended before the window: nothing to rank
        best = pd.DataFrame(columns=["criterion", "error_pct", "run_id"])
    elif scene.experiment.refine:
        grid_best = best[best.criterion == "rel_rms_combined_pct"]
        if stored is not None and stored.start_error_pct == float(grid_best.error_pct.iloc[0]):
            # the same sweep, the same best cell: the stored refinement is what refining again would give
            start = {n: float(grid_best[n].iloc[0]) for n in stored.optimum if n in grid_best}
            summary.refinement = dataclasses.replace(stored, start=start)
            summary.refinement_reused = True
        else:
            summary.refinement = refine_best(prep, best)
        if summary.refinement is not None:
            best = pd.concat([best, pd.DataFrame([refinement_row(summary.refinement)])], ignore_index=True)
    if not best.empty:
        _grid_edge_warnings(best, prep.grid)
    check_scale(contact, prep, best)
    meta = {"kind": "best", "results": results, "warnings": notes.messages()}
    if scene.calibrate is not None and not best.empty:
        best, meta = _calibrated(scene, best, meta, summary, progress, threads)
    best["run_id"] = best["run_id"].astype("Int64")
    _write_best(summary.best_path, best, scene, {**meta, "warnings": notes.messages()})
    return best


def _grid_edge_warnings(best, grid: Grid) -> None:
    """Warn when the best cell (combined error) lies on the edge of a swept numeric axis of 3 or more values:
    the optimum may lie beyond the grid."""
    rows = best[best.criterion == "rel_rms_combined_pct"]
    if rows.empty:
        return
    row = rows.iloc[0]
    for name, values in grid.axes:
        if name in ("law", "record") or len(values) < 3 or name not in row or not np.isfinite(row[name]):
            continue
        v = float(row[name])
        for side, edge in (("lowest", min(values)), ("highest", max(values))):
            if v == edge:
                warn(
                    "grid_edge",
                    f"the best cell lies on the grid's edge: {name} = {v:g} is the {side} swept value; the optimum "
                    f"may lie beyond it (extend [sweep] {name})",
                )


def _write_best(path: Path, best, scene: Scene, meta: dict) -> None:
    """The best table, written whole and renamed into place (the test gate 'best' waits before the rename)."""
    import pyarrow as pa

    best = best.copy()
    best["run_id"] = best["run_id"].astype("Int64")
    write_table_atomic(
        path,
        pa.Table.from_pandas(best, preserve_index=False),
        file_metadata(scene, meta),
        before_rename=lambda: pause("best"),
    )


def calibration_key(scene: Scene) -> str:
    """What a stored calibration must match to be reused: the scene's config hash (the grid and the experiment:
    [calibrate] is left out of it, so that the grid's parts resume when only [calibrate] changes), [calibrate]
    itself and the package version."""
    cal = dataclasses.asdict(scene.calibrate)
    if cal.get("start_from") is not None:  # identify's modes file: by content (a rerun of identify changes it)
        cal["start_from"] = {"file": Path(cal["start_from"]).name, "sha256": file_digest(cal["start_from"])}
    return hash_of({"config_hash": scene.config_hash(), "calibrate": cal, "version": __version__})


def _calibrated(scene: Scene, best, meta: dict, summary, progress, threads: int):
    """The best table and its metadata with the calibration: the one stored by an earlier run of this very
    calibration (calibration_key), else a new one. Before a new one starts, the best table is written with the
    grid's answer alone, so that a calibration interrupted (or a changed [calibrate] whose rerun is) never leaves
    an older calibration in a table that claims this scene."""
    import pandas as pd

    from pounding_sweep.sweep.calibrate import calibrate, calibration_metadata, calibration_rows

    key = calibration_key(scene)
    stored = _stored_calibration(summary.best_path, key)
    if stored is not None:
        rows, md, said = stored
        for w in said:  # its warnings, said (and stored) again as on the run that made it
            warn("calibration", w)
        summary.calibration_summary, summary.calibration_reused = md, True
        return pd.concat([best, rows], ignore_index=True), {**meta, "calibration": md, "calibration_key": key}
    _write_best(summary.best_path, best, scene, meta)
    pause("calibrate")
    say = getattr(progress, "stage", None)
    grid_best = best[best.criterion == "rel_rms_combined_pct"]
    cell = {n: float(grid_best[n].iloc[0]) for n in scene.calibrate.parameters if n in grid_best}
    if say is not None:
        say(calibration_plan(scene))
    t0 = time.perf_counter()
    summary.calibration = calibrate(scene, threads=threads or os.cpu_count() or 1, best_cell=cell, progress=say)
    if say is not None:
        say(f"  calibrated in {time.perf_counter() - t0:.0f} s")
    md = calibration_metadata(summary.calibration)
    summary.calibration_summary = md
    best = pd.concat([best, pd.DataFrame(calibration_rows(summary.calibration))], ignore_index=True)
    return best, {**meta, "calibration": md, "calibration_key": key}


def calibration_plan(scene: Scene) -> str:
    """One line saying what the calibration is about to do (it runs for a minute or more, silent otherwise)."""
    cal = scene.calibrate
    laws = () if scene.contact is None else scene.axis_values("law") or (scene.contact.law,)
    profiled = list(cal.profile) or default_profiled(cal.parameters)
    from pounding_sweep.sweep.globalsearch import design_size

    n_design = design_size(cal.global_points, len(cal.parameters))
    what = [
        f"{cal.global_points} global points (a design of {n_design} on the record's leading part)"
        if n_design
        else "no global stage"
    ]
    what.append(f"least squares from up to {cal.starts} start(s) of at most {cal.max_evals} runs")
    if cal.profile_points and profiled:
        what.append(f"profiles of {', '.join(profiled)} ({cal.profile_points} points each)")
    return (
        f"calibrating {len(cal.parameters)} parameter(s) against the experiment"
        + (f" for law {', '.join(laws)}" if laws else " (one building, no contact)")
        + ": "
        f"{'; '.join(what)} (kept in the best table: a rerun of this scene reuses it)"
    )


def _stored_calibration(best_path: Path, key: str):
    """(the 'calibrated' rows, the calibration metadata, its warnings) of the best table an earlier run of this
    very calibration wrote (calibration_key), or None."""
    if not best_path.is_file():
        return None
    try:
        md = read_metadata(best_path)
        if md.get("calibration_key") != key or "calibration" not in md:
            return None
        df = pq.read_table(best_path).to_pandas()
    except (OSError, KeyError, ValueError):
        return None
    rows = df[df.criterion == "calibrated"]
    said = [w for w in md.get("warnings", []) if w.startswith("calibration")]  # calibrate.py's all begin so
    return (rows, md["calibration"], said) if len(rows) else None


REFINED = "refined_combined"  # the best table's criterion of the refined optimum


def refinement_row(rf: Refinement) -> dict:
    """The best table's row of a refinement (what a resumed sweep reads back: stored_refinement)."""
    return {
        "criterion": REFINED,
        "error_pct": rf.error_pct,
        **rf.optimum,
        "evaluations": rf.evaluations,
        "start_error_pct": rf.start_error_pct,
    }


def stored_refinement(best_path: Path, scene: Scene) -> Refinement | None:
    """The refinement in the best table of an earlier run of this very sweep (same config hash and
    package version), or None."""
    if not best_path.is_file():
        return None
    try:
        md = read_metadata(best_path)
        if md.get("config_hash") != scene.config_hash() or md.get("version") != __version__:
            return None
        t = pq.read_table(best_path)
        rows = [r for r in t.to_pylist() if r.get("criterion") == REFINED]
    except (OSError, KeyError, ValueError):
        return None
    if not rows or rows[0].get("evaluations") is None or rows[0].get("start_error_pct") is None:
        return None
    r = rows[0]
    optimum = {n: float(r[n]) for n in ("ks_ratio", "r") if r.get(n) is not None and np.isfinite(r[n])}
    return Refinement({}, float(r["start_error_pct"]), optimum, float(r["error_pct"]), int(r["evaluations"]), "stored")


def refine_best(prep: Prepared, best: pd.DataFrame) -> Refinement | None:
    """Continuous (k_s/k, r) search from the best grid cell, within the swept ranges."""
    axes = dict(prep.grid.axes)
    bounds = {n: (min(axes[n]), max(axes[n])) for n in ("ks_ratio", "r") if n in axes and len(axes[n]) > 1}
    if not bounds:
        return None
    rows = best[best.criterion == "rel_rms_combined_pct"]
    if rows.empty:
        return None
    start_row = rows.iloc[0]
    base = prep.grid.chunk(int(start_row.run_id), int(start_row.run_id) + 1)

    def objective(p: dict) -> float:
        params = {k: v.copy() for k, v in base.items()}
        for k, v in p.items():
            params[k][:] = v
        _, _, _, scores, _ = prep.run(params)
        err = score_table_columns(scores, prep.score_codes, prep.combination)["rel_rms_combined_pct"][0]
        return float(err) if np.isfinite(err) else 1e300

    start = {n: float(start_row[n]) for n in bounds}
    return refine(objective, start, float(start_row.error_pct), bounds, prep.scene.experiment.refine_max_evals)
