"""Orchestration of one scene: config -> model -> excitation -> kernel -> metrics -> Parquet.

The grid is run chunk by chunk (by an executor: local threads or Dask); each chunk's rows are
written as their own Parquet part as soon as they are done, so memory follows the chunk, not the
grid, and an interrupted sweep resumes where it stopped. When the scene has an [experiment], every run is
scored as it finishes and the best runs are kept as running minima.
"""

from __future__ import annotations

import math
import os
import threading
import time
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import pyarrow.parquet as pq

if TYPE_CHECKING:  # pandas costs 0.3 s to import: only where a table is built
    import pandas as pd

from pounding_sweep import __version__
from pounding_sweep.engine import layout as L
from pounding_sweep.engine.driver import compile_kernel
from pounding_sweep.errors import ConfigError, OutputError  # noqa: F401
from pounding_sweep.model.excitation import Excitation
from pounding_sweep.model.grid import Grid
from pounding_sweep.scene import Scene
from pounding_sweep.scene.axes import STRUCTURE_AXES
from pounding_sweep.scene.channels import is_acceleration
from pounding_sweep.scene.hashing import hash_of
from pounding_sweep.sweep.best import best_table, stored_refinement
from pounding_sweep.sweep.checks import (
    ContactTally,
    check_calibration,
    check_contact,
    check_response_size,
    check_scene,
    check_time_step,
)
from pounding_sweep.sweep.gate import pause
from pounding_sweep.sweep.metricgroups import KEY, groups_facts, left_out_columns, sweep_groups
from pounding_sweep.sweep.prepare import Prepared, drift_ratio_columns, prepare  # noqa: F401
from pounding_sweep.sweep.ranking import Ranking, Refinement, combined_meaning, score_columns, score_table_columns
from pounding_sweep.sweep.results import (
    PART_NAME,
    column_docs,
    file_metadata,
    histories_path,
    histories_table,
    meta_warnings,
    metrics_table,
    numpy_column,
    sidecar_path,
    store_warnings,
    write_part,
)
from pounding_sweep.sweep.resume import OutputFolder
from pounding_sweep.warn import collecting

HISTORY_CHUNK_BYTES = 256 * 2**20


@dataclass
class SweepSummary:
    """What ran: counts, statuses, timings, best runs and where the output went. `steps`, `kernel_s`
    cover every run of the grid (resumed ones too); `new_runs`, `new_steps`, `new_kernel_s` and `run_s`
    only those this call ran."""

    scene: str
    runs: int
    path: Path
    histories_path: Path | None
    statuses: Counter
    compile_s: float
    run_s: float
    kernel_s: float
    steps: int
    threads: int
    extremes: dict = field(default_factory=dict)
    best: pd.DataFrame | None = None
    best_path: Path | None = None
    refinement: Refinement | None = None
    parts: int = 0
    resumed_parts: int = 0
    executor: str = "local"
    new_runs: int = 0
    new_steps: int = 0
    new_kernel_s: float = 0.0
    refinement_reused: bool = False
    warnings: list[str] = field(default_factory=list)
    calibration: list | None = None  # sweep.calibrate.Fit per law, with [calibrate] (when calibrated by this call)
    calibration_summary: dict | None = None  # calibrate.calibration_metadata: new, or kept from an earlier run
    calibration_reused: bool = False


def run_scene(
    scene: Scene,
    out_path: str | Path | None = None,
    threads: int | None = None,
    progress: Callable[[int, int], None] | None = None,
    executor=None,
    overwrite: bool = False,
    confirmed: bool = False,
    kernel: str = "auto",
    contact_free: bool = False,
) -> SweepSummary:
    """Run every grid point of the scene into a Parquet dataset folder (one part per chunk); return
    a summary. Parts already in the folder from an interrupted run of the same scene (same config
    hash and package version) are kept and skipped, and so is a refinement already stored in the best
    table; other results there are refused unless `overwrite`. `executor`: one from
    executors.make_executor (default: the scene's [execution]); `kernel`: engine.driver.KERNELS
    ("scalar": every chunk on the scalar kernel); `contact_free`: the scene is separated on purpose (a study's
    contact-free runs), so no run making contact is no finding to warn of. `progress(done, total)` is called as runs finish
    (within a chunk on the local executor); when it has them, its `compiling` method is told when a
    kernel is compiled (engine.driver.Announce) and `restart(done)` when the runs start.

    Probable mistakes in the scene (pounding_sweep.warn) are collected: passed on as they happen to
    an enclosing `warn.collecting()` (the command line prints them), stored in the result metadata
    (`warnings`; part 0 holds all of them) and listed in the summary."""
    with collecting() as notes:
        summary = _run_scene(
            scene, out_path, threads, progress, executor, overwrite, confirmed, kernel, notes, contact_free
        )
    summary.warnings = notes.messages()
    return summary


def _run_scene(
    scene, out_path, threads, progress, executor, overwrite, confirmed, kernel, notes, contact_free
) -> SweepSummary:
    out_path = Path(out_path or scene.output.path)
    ex = scene.execution
    size = Grid.from_scene(scene).size
    if size > ex.max_runs and not confirmed:
        raise ConfigError(
            f"[sweep] gives {size:,} runs, more than [execution] max_runs = {ex.max_runs:,}: "
            "confirm with --yes (or raise max_runs) if that many is meant"
        )
    hpath = histories_path(out_path) if scene.output.histories else None
    best_path = sidecar_path(out_path, "best") if scene.experiment is not None else None
    # the output is claimed (locked, shown writable) before anything is read or computed, and released
    # as found when the sweep fails before its first part
    folder = OutputFolder(out_path, hpath, overwrite, best_path).claim()
    ok = False
    try:
        summary = _run_claimed(scene, folder, threads, progress, executor, kernel, size, notes, contact_free)
        ok = True
    finally:
        folder.release(ok)
    return summary


def _run_claimed(scene, folder, threads, progress, executor, kernel, size, notes, contact_free) -> SweepSummary:
    from pounding_sweep.sweep.executors import make_executor

    out_path, hpath, ex = folder.out, folder.hpath, scene.execution
    groups = sweep_groups(scene)  # the metric groups the scene asks for (sweep/metricgroups.py)
    prep = prepare(scene, kernel, groups)
    check_time_step(prep)
    check_scene(prep)
    check_calibration(prep)
    grid, model, exc = prep.grid, prep.model, prep.excitation
    chunk_runs = ex.chunk_runs
    if prep.hist.active:
        per_run = prep.hist.kinds.size * (int(exc.max_steps) // prep.hist.decimate + 1) * 8
        chunk_runs = max(1, min(chunk_runs, HISTORY_CHUNK_BYTES // per_run))
    chunks = [(i, s, e) for i, (s, e) in enumerate(grid.chunks(chunk_runs))]
    config = scene.canonical()
    manifest = {
        "config_hash": hash_of(config),
        "version": __version__,
        "scene": scene.name,
        "grid_size": grid.size,
        "chunk_runs": chunk_runs,
        "parts": len(chunks),
        "config": config,  # the canonical scene: a refused resume names the key that differs
    }
    done = folder.resume(manifest)
    todo = [c for c in chunks if c[0] not in done]

    facts = _model_facts(prep)
    # where the scene's folder lies from the results: a project moved with its results is still plotted from its
    # own files (plots.scene_of)
    facts["scene_dir_from_results"] = os.path.relpath(Path(scene.source).resolve().parent, out_path.resolve())
    facts["metric_groups"] = groups_facts(groups)
    left_out = left_out_columns(groups, model.floors, model.n_pairs)
    columns = column_docs(left_out, facts["metric_groups"]["left_out"], KEY) if left_out else None
    meta = file_metadata(scene, {**facts, "warnings": notes.messages()}, columns)
    names = L.metric_columns(model.floors, model.n_pairs)
    ranking = (
        Ranking([f"rel_rms_{c}_pct" for c in prep.score_codes] + ["rel_rms_combined_pct"]) if prep.score_codes else None
    )
    tally = _Tally(ranking)
    tally.contact.closest_computed = bool(groups & L.GROUP_CLOSEST)  # the no-contact warning says when it is not
    for i in sorted(done):
        tally.add(_read_part(out_path / PART_NAME.format(i)))
    tally.mark_resumed()
    if progress is not None and done:
        progress(tally.runs, grid.size)

    refine_wanted = ranking is not None and scene.experiment.refine
    stored = stored_refinement(folder.best, scene) if refine_wanted else None
    compile_s = 0.0
    if todo or (refine_wanted and stored is None):  # the kernel this sweep uses: compiled, or loaded from the cache
        announce = getattr(progress, "compiling", None)
        compile_s = compile_kernel(prep.sysarr, prep.opts, prep.hist, prep.score, kernel, prep.law_codes_used, announce)
    if hasattr(progress, "restart"):
        progress.restart(tally.runs)
    exe = None
    if todo:
        exe = executor or make_executor(
            ex.executor,
            threads if threads is not None else ex.threads,
            ex.dask_address,
            ex.dask_workers,
            timeout_s=ex.dask_timeout_s,
        )
    t_run = time.perf_counter()
    try:
        if todo:
            inflight = _InFlight(progress, tally, grid.size)
            for res in exe.map(prep, todo, done=inflight):
                columns = {"run_id": res.params["run_id"], **_param_columns(exc, res.params, res.derived, grid)}
                extra = (
                    score_table_columns(res.scores, prep.score_codes, prep.combination)
                    if res.scores is not None
                    else {}
                )
                extra.update(drift_ratio_columns(scene, res.metrics, names))
                table = metrics_table(columns, names, res.metrics, res.run_time, extra)
                folder.write_manifest(manifest)
                if hpath is not None:  # histories first: a finished main part implies its histories exist
                    write_part(
                        hpath,
                        res.index,
                        histories_table(
                            res.params["run_id"], res.hist, prep.dt * prep.hist.decimate, prep.hist_columns
                        ),
                        meta,
                    )
                write_part(out_path, res.index, table, meta)
                folder.wrote_part()
                pause(f"part-{folder.parts_written}")
                inflight.part_done(table)
                if progress is not None:
                    progress(tally.runs, grid.size)
    finally:
        if executor is None and exe is not None:
            exe.close()
    run_s = time.perf_counter() - t_run
    if not contact_free:
        check_contact(tally.contact, scene)
    check_response_size(tally.contact, scene)
    if notes.messages() != meta_warnings(meta):
        store_warnings(out_path, notes.messages())
    summary = SweepSummary(
        scene.name,
        grid.size,
        out_path,
        hpath,
        tally.statuses,
        compile_s,
        run_s,
        tally.kernel_s,
        tally.steps,
        exe.workers if exe is not None else 0,
        # one building: no pounding force; else the largest, the largest of the runs whose force can be trusted and
        # the flags of the run that holds the largest (a diverged run's 'force' is no answer)
        {} if scene.single else tally.forces(),
        parts=len(chunks),
        resumed_parts=len(done),
        executor=exe.name if exe is not None else ex.executor,
    )
    summary.new_runs, summary.new_steps, summary.new_kernel_s = tally.new()
    if ranking is not None:
        summary.best_path = folder.best
        workers = threads if threads is not None else ex.threads
        summary.best = best_table(
            scene, prep, ranking.frame(), tally.contact, stored, summary, progress, workers, notes, out_path.name
        )
        store_warnings(out_path, notes.messages())  # those found from the ranking and the calibration too
    return summary


def _read_part(path: Path):
    """A finished part, read whole for the tally of a resumed sweep (its footer was checked by resume)."""
    try:
        return pq.read_table(path)
    except Exception:  # noqa: BLE001 - pyarrow's errors for damaged data pages vary
        raise OutputError(
            f"{path}: cannot be read as Parquet (damaged); delete it and run the same command again to recompute it"
        ) from None


class _InFlight:
    """Progress within a chunk: runs finished by the executor's threads before their part is written."""

    def __init__(self, progress, tally, total: int):
        self.progress, self.tally, self.total = progress, tally, total
        self.runs = 0
        self.lock = threading.Lock()

    def __call__(self, n: int) -> None:
        if self.progress is None:
            return
        with self.lock:
            self.runs += n
            done = self.tally.runs + self.runs
        self.progress(min(done, self.total), self.total)

    def part_done(self, table) -> None:
        with self.lock:
            self.tally.add(table)
            self.runs = 0


#: the flags under which a run's pounding force is no answer: the run blew up, or its contact made energy
UNTRUSTED_FORCE_FLAGS = ("diverged", "energy_residual")


def untrusted_force(status: str) -> bool:
    """Whether a run's status says its pounding force is no answer (UNTRUSTED_FORCE_FLAGS); flags such as
    contact_underresolved or grazing_impact leave it an answer, with its flag."""
    return any(f in status.split("+") for f in UNTRUSTED_FORCE_FLAGS)


class _Tally:
    """Counts, timings, extremes, contact and the ranking over the parts of a sweep (new or resumed)."""

    def __init__(self, ranking: Ranking | None):
        self.ranking = ranking
        self.statuses: Counter = Counter()
        self.runs = 0
        self.steps = 0
        self.kernel_s = 0.0
        self.peak_force = 0.0
        self.peak_force_ok = math.nan  # ... of the runs whose force is trusted (untrusted_force; NaN: none is)
        self.peak_status = "ok"  # the status of the run with the largest
        self.contact = ContactTally()
        self.resumed = (0, 0, 0.0)  # runs, steps, kernel seconds of the parts kept from an earlier run

    def add(self, table) -> None:
        self.runs += table.num_rows
        status = table.column("status").to_pylist()
        self.statuses.update(status)
        self.steps += int(np.nansum(numpy_column(table, "steps")))
        self.kernel_s += float(np.nansum(numpy_column(table, "run_time_s")))
        names = [n for n in table.column_names if n.startswith("peak_force_f")]
        if names and table.num_rows:
            per_run = np.nanmax(np.column_stack([numpy_column(table, n) for n in names]), axis=1, initial=0.0)
            ok = ~np.array([untrusted_force(s) for s in status], dtype=bool)
            if ok.any():
                self.peak_force_ok = float(np.fmax(self.peak_force_ok, per_run[ok].max()))
            k = int(np.argmax(per_run))
            if per_run[k] > self.peak_force:
                self.peak_force, self.peak_status = float(per_run[k]), status[k]
        self.contact.add(table, numpy_column)
        if self.ranking is not None:
            self.ranking.update(table)

    def forces(self) -> dict:
        """The summary's pounding forces: the largest [N], the largest of the runs whose force is trusted [N] (NaN: none),
        and the status of the run that holds the largest."""
        return {"peak_force_N": self.peak_force, "peak_force_ok_N": self.peak_force_ok, "peak_status": self.peak_status}

    def mark_resumed(self) -> None:
        """What was added so far was resumed: the rest is this call's own work."""
        self.resumed = (self.runs, self.steps, self.kernel_s)

    def new(self) -> tuple[int, int, float]:
        """Runs, steps and kernel seconds added since mark_resumed."""
        r, st, k = self.resumed
        return self.runs - r, self.steps - st, self.kernel_s - k


def _model_facts(prep: Prepared) -> dict:
    model, grid, scene = prep.model, prep.grid, prep.scene
    modes = [b.modes() for b in model.buildings]
    facts = {
        "kind": "runs",
        "dt_s": "auto" if scene.integration.auto else prep.dt,
        "scheme": scene.integration.scheme,
        "contact_law": None if scene.contact is None else scene.contact.law,  # None: one building, no contact
        "grid_axes": {name: list(v) for name, v in grid.axes},
        "grid_size": grid.size,
        "buildings": [
            {
                "name": b.name,
                "masses_kg": list(b.masses_kg),
                "story_stiffness_N_per_m": list(b.story_stiffness_N_per_m),
                "rayleigh_a0_per_s": b.rayleigh_a0_per_s,
                "rayleigh_a1_s": b.rayleigh_a1_s,
                "frequencies_Hz": md.frequency_Hz.tolist(),
                "damping_ratios": md.damping_ratio.tolist(),
            }
            for b, md in zip(model.buildings, modes)
        ],
        "records": [
            {"name": r.name, "source": Path(r.source).name, "dt_s": r.dt_s, "description": r.description}
            for r in prep.excitation.records
        ],
        **prep.excitation.facts(),  # the intensity measure, the stochastic motion
    }
    if prep.score_codes:
        x = scene.experiment
        facts["experiment"] = {
            "table": Path(x.table).name if x.table else None,
            "video": Path(x.video.path).name if x.video is not None else None,
            "channels": x.channels,
            "units": x.units,
            "combine": x.combine,
            "window_s": [float(prep.score.t[0]), float(prep.score.t[-1])],
            "samples": int(prep.score.t.size),
            "score_columns": dict(score_columns(prep.score_codes))
            | {"rel_rms_combined_pct": combined_meaning(prep.combination)},
        }
        facts["experiment"].update(_acceleration_facts(prep))
    return facts


def _acceleration_facts(prep: Prepared) -> dict:
    """The experiment's acceleration channels, filter and channel weights, for the result metadata (nothing
    for a scene that uses none of them: its metadata stays as it was)."""
    x, comb = prep.scene.experiment, prep.combination
    out = {}
    if any(is_acceleration(c) for c in prep.score_codes):
        out["acc_units"] = x.acc_units
        if x.lowpass_Hz is not None:
            out["lowpass"] = {
                "kind": "Butterworth, causal (scipy.signal.sosfilt), from rest at the window's start",
                "cutoff_Hz": x.lowpass_Hz,
                "order": x.lowpass_order,
                "sos": prep.score.sos.tolist(),
                "applied_to": [c for c in prep.score_codes if is_acceleration(c)],
            }
        if prep.sensor is not None:
            out["sensor"] = prep.sensor.describe()
    if comb is not None and comb.weights is not None:
        out["use"] = x.use
        out["weights"] = dict(zip(prep.score_codes, map(float, comb.weights)))
        if comb.noise:
            out["noise"] = comb.noise
    return out


def _param_columns(exc: Excitation, params: dict, derived: dict, grid: Grid) -> dict:
    """The parameter columns of the result rows (only those that mean something for this scene; the structure's
    scales, damping ratios and the experiment's clock where they are swept)."""
    cols = {}
    contact = "ks_N_per_m" in derived  # prepare.contact_arrays derives none for one building (no contact columns)
    if contact:
        if not np.all(np.isnan(params["ks_ratio"])):
            cols["ks_ratio"] = params["ks_ratio"]
        cols["ks_N_per_m"] = derived["ks_N_per_m"]
        cols["r"] = params["r"]
        cols["gap_m"] = params["gap_m"]
    if exc.kind == "harmonic":
        cols["amplitude_m"] = params["amplitude_m"]
        cols["frequency_Hz"] = params["frequency_Hz"]
    elif exc.kind == "stochastic":
        cols["seed"] = np.asarray(params["seed"], dtype=np.int64)
    else:
        cols["record"] = np.array([exc.record_name(p) for p in params["record"]], dtype=object)
    cols["scale"] = params["scale"]
    if contact:
        cols["contact_law"] = np.asarray(params["law"], dtype=object)
    for key in ("intensity_g", "kh_N_per_m1_5", "contact_damping_ratio", "hertzdamp_a", "r_single_impact"):
        if key in derived:
            cols[key] = derived[key]
    swept = {name for name, _ in grid.axes}
    for name in STRUCTURE_AXES:
        if name in swept:
            cols[name] = params[name]
    if contact:
        cols["steps_per_contact_period"] = derived["steps_per_contact_period"]
    for key in ("dt_s", "dt_error_estimate"):  # dt = 'auto'
        if key in derived:
            cols[key] = derived[key]
    return cols
