"""Orchestration of one scene: config -> model -> excitation -> kernel -> metrics -> Parquet.

The grid is run chunk by chunk: each chunk's rows are written as soon as they are done, so
memory follows the chunk, not the grid.
"""

from __future__ import annotations

import time
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

from . import metrics_layout as L
from .channels import parse_channel
from .config import Scene
from .contact import CONTACT_LAWS, contact_period, damping_ratio_from_restitution, dashpot_coefficient
from .driver import HistorySpec, KernelOptions, RunArrays, compile_kernel, resolve_threads, run_chunk
from .excitation import Excitation
from .grid import Grid
from .kernel import SCHEMES
from .model import CoupledModel
from .results import AtomicParquetWriter, file_metadata, histories_path, histories_table, metrics_table

HISTORY_CHUNK_BYTES = 256 * 2**20


@dataclass
class SweepSummary:
    """What ran: counts, statuses, timings and where the output went."""

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


def contact_arrays(model: CoupledModel, scene: Scene, params: dict[str, np.ndarray], dt: float):
    """k_s, dashpot c_j (eq. 9) per run and pair, xi_s (eq. 10), steps per contact period, flags."""
    ks = np.where(np.isnan(params["ks_N_per_m"]), params["ks_ratio"] * scene.contact.k_ref_N_per_m, params["ks_N_per_m"])
    m1, m2 = model.pair_masses()
    xi = np.atleast_1d(damping_ratio_from_restitution(params["r"]))
    c = dashpot_coefficient(ks[:, None], params["r"][:, None], m1[None, :], m2[None, :])
    steps_per_period = contact_period(ks[:, None], m1[None, :], m2[None, :]).min(axis=1) / dt
    status = np.where(steps_per_period < scene.integration.min_steps_per_contact_period, L.STATUS_UNDERRESOLVED, 0)
    return ks, np.ascontiguousarray(c), xi, steps_per_period, status.astype(np.int64)


def history_spec(scene: Scene, floors: tuple[int, int]) -> tuple[HistorySpec, list[str]]:
    if not scene.output.histories:
        return HistorySpec.none(), []
    parsed = [parse_channel(ch, floors) for ch in scene.output.histories]
    spec = HistorySpec(np.array([p[0] for p in parsed], np.int64), np.array([p[1] for p in parsed], np.int64),
                       scene.output.history_decimate)
    return spec, [p[2] for p in parsed]


def run_scene(scene: Scene, out_path: str | Path | None = None, threads: int | None = None,
              progress: Callable[[int, int], None] | None = None) -> SweepSummary:
    """Run every grid point of the scene and write the result table(s); return a summary."""
    t_all = time.perf_counter()
    out_path = Path(out_path or scene.output.path)
    dt = scene.integration.dt_s
    model = CoupledModel.from_scene(scene)
    sysarr = model.system_arrays(dt)
    exc = Excitation.from_scene(scene, dt)
    grid = Grid.from_scene(scene)
    opts = KernelOptions(SCHEMES[scene.integration.scheme], CONTACT_LAWS[scene.contact.law],
                         scene.integration.max_contact_iterations)
    hspec, hcols = history_spec(scene, model.floors)
    n_threads = resolve_threads(threads if threads is not None else scene.execution.threads)
    compile_s = compile_kernel(sysarr, opts)

    if hspec.active:
        max_steps = int(exc.rec_len.max()) if exc.kind == "record" else int(round(exc.duration_s / dt)) + 1
        per_run = hspec.kinds.size * (max_steps // hspec.decimate + 1) * 8
        chunk_runs = max(1, min(4096, HISTORY_CHUNK_BYTES // per_run))
    else:
        chunk_runs = 4096
    modes = [b.modes() for b in (model.b1, model.b2)]
    meta = file_metadata(scene, {
        "kind": "runs",
        "dt_s": dt,
        "scheme": scene.integration.scheme,
        "contact_law": scene.contact.law,
        "grid_axes": {name: list(v) for name, v in grid.axes},
        "grid_size": grid.size,
        "buildings": [
            {"name": b.name, "masses_kg": list(b.masses_kg), "story_stiffness_N_per_m": list(b.story_stiffness_N_per_m),
             "rayleigh_a0_per_s": b.rayleigh_a0_per_s, "rayleigh_a1_s": b.rayleigh_a1_s,
             "frequencies_Hz": md.frequency_Hz.tolist(), "damping_ratios": md.damping_ratio.tolist()}
            for b, md in zip((model.b1, model.b2), modes)
        ],
        "records": [{"name": r.name, "source": Path(r.source).name, "dt_s": r.dt_s, "description": r.description}
                    for r in exc.records],
    })
    from .metrics_layout import metric_columns

    names = metric_columns(model.floors, model.n_pairs)
    statuses: Counter = Counter()
    kernel_s = 0.0
    steps = 0
    extremes = {"peak_force_N": 0.0}
    hpath = histories_path(out_path) if hspec.active else None
    t_run = time.perf_counter()
    with AtomicParquetWriter(out_path, meta) as writer, _maybe_writer(hpath, meta) as hwriter:
        done = 0
        for s, e in grid.chunks(chunk_runs):
            params = grid.chunk(s, e)
            ks, c, xi, spp, status = contact_arrays(model, scene, params, dt)
            ex = exc.run_arrays(params)
            runs = RunArrays(ks, c, params["gap_m"], ex["exc_kind"], ex["exc_amp"], ex["exc_omega"], ex["rec_id"],
                             ex["nsteps"], status)
            metrics, run_time, hist = run_chunk(sysarr, runs, (exc.rec_flat, exc.rec_off, exc.rec_len), hspec, opts,
                                                n_threads, scene.execution.batch_runs)
            table_params = {"run_id": params["run_id"], **_param_columns(scene, exc, params, ks)}
            table_params["contact_damping_ratio"] = xi
            table_params["steps_per_contact_period"] = spp
            table = metrics_table(table_params, names, metrics, run_time)
            writer.write(table)
            if hwriter is not None:
                hwriter.write(histories_table(params["run_id"], hist, dt * hspec.decimate, hcols))
            statuses.update(table.column("status").to_pylist())
            kernel_s += float(run_time.sum())
            steps += int(metrics[:, names.index("steps")].sum())
            pf = [i for i, nme in enumerate(names) if nme.startswith("peak_force_f")]
            extremes["peak_force_N"] = max(extremes["peak_force_N"], float(metrics[:, pf].max(initial=0.0)))
            done = e
            if progress is not None:
                progress(done, grid.size)
    return SweepSummary(scene.name, grid.size, out_path, hpath, statuses, compile_s, time.perf_counter() - t_run,
                        kernel_s, steps, n_threads, extremes)


def _param_columns(scene: Scene, exc: Excitation, params: dict, ks: np.ndarray) -> dict:
    """The parameter columns of the result rows (only those that mean something for this scene)."""
    cols = {}
    if not np.all(np.isnan(params["ks_ratio"])):
        cols["ks_ratio"] = params["ks_ratio"]
    cols["ks_N_per_m"] = ks
    cols["r"] = params["r"]
    cols["gap_m"] = params["gap_m"]
    if exc.kind == "harmonic":
        cols["amplitude_m"] = params["amplitude_m"]
        cols["frequency_Hz"] = params["frequency_Hz"]
    else:
        cols["record"] = np.array([exc.record_name(p) for p in params["record"]], dtype=object)
    cols["scale"] = params["scale"]
    return cols


class _NullCtx:
    def __enter__(self):
        return None

    def __exit__(self, *a):
        return False


def _maybe_writer(path, meta):
    if path is None:
        return _NullCtx()
    hmeta = dict(meta)
    return AtomicParquetWriter(path, hmeta)
