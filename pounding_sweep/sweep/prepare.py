"""A scene turned into the kernels' inputs before any run: model, system matrices at dt, excitation,
grid, contact arrays per chunk, histories and experiment samples. Shared by sweeps, single runs
(simulate), the refinement and the benchmarks."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pounding_sweep.codes import CONTACT_LAWS, SCHEMES
from pounding_sweep.engine import layout as L
from pounding_sweep.engine.driver import run_chunk
from pounding_sweep.engine.inputs import HistorySpec, KernelOptions, Records, RunArrays, ScoreSpec
from pounding_sweep.model.contact import contact_period, damping_ratio_from_restitution, dashpot_coefficient
from pounding_sweep.model.coupled import CoupledModel, SystemArrays
from pounding_sweep.model.excitation import Excitation
from pounding_sweep.model.grid import Grid
from pounding_sweep.scene import Scene, contact_stiffness
from pounding_sweep.scene.channels import parse_channel


@dataclass(frozen=True)
class Prepared:
    """A scene turned into kernel inputs, before any run: shared by sweeps, single runs and refinement."""

    scene: Scene
    model: CoupledModel
    sysarr: SystemArrays
    excitation: Excitation
    grid: Grid
    opts: KernelOptions
    hist: HistorySpec
    hist_columns: list[str]
    score: ScoreSpec
    score_codes: list[str]
    auto: object | None = None  # autodt.AutoDt when dt_s = 'auto'
    kernel: str = "auto"  # engine.driver.KERNELS: which kernel runs the chunks

    @property
    def dt(self) -> float:
        return self.sysarr.dt

    def run(self, params: dict[str, np.ndarray], threads: int = 1, batch_runs: int = 0, done=None):
        """Integrate the runs described by `params` (as Grid.chunk gives them); `done(n)`: called as groups
        of n runs finish (not with dt_s = 'auto', whose runs are rerun at finer steps)."""
        if self.auto is not None:
            return self.auto.run(params, threads, batch_runs)
        runs, rec, derived = self.kernel_inputs(params)
        metrics, run_time, hist, scores = run_chunk(
            self.sysarr, runs, rec, self.hist, self.opts, threads, batch_runs, self.score, self.kernel, done
        )
        return metrics, run_time, hist, scores, derived

    def kernel_inputs(self, params: dict[str, np.ndarray]):
        """The kernel's inputs for `params` at the scene's dt: (RunArrays, record arrays, the derived
        contact columns)."""
        ks, c, xi, spp, status = contact_arrays(self.model, self.scene, params, self.dt)
        ex = self.excitation.run_arrays(params)
        runs = RunArrays(
            ks, c, params["gap_m"], ex["exc_kind"], ex["exc_amp"], ex["exc_omega"], ex["rec_id"], ex["nsteps"], status
        )
        rec = Records(self.excitation.rec_flat, self.excitation.rec_off, self.excitation.rec_len)
        return runs, rec, {"ks_N_per_m": ks, "contact_damping_ratio": xi, "steps_per_contact_period": spp}


def prepare(scene: Scene, kernel: str = "auto") -> Prepared:
    """Model, system matrices at dt, excitation, grid, history and experiment specs of a scene.
    With dt_s = 'auto' these are at dt_max_s, and runs go through the step-doubling ladder.
    `kernel`: which kernel runs its chunks (engine.driver.KERNELS; "auto": the lane kernel where it can)."""
    dt = scene.integration.first_dt_s
    model = CoupledModel.from_scene(scene)
    exc = Excitation.from_scene(scene, dt)
    opts = KernelOptions(
        SCHEMES[scene.integration.scheme], CONTACT_LAWS[scene.contact.law], scene.integration.max_contact_iterations
    )
    hspec, hcols = history_spec(scene, model.floors)
    score, codes = ScoreSpec.none(), []
    if scene.experiment is not None:
        from pounding_sweep.sweep.scoring import load_experiment, score_spec

        exp = load_experiment(scene.experiment, model.floors)
        score = score_spec(exp, scene.experiment, model.floors, exc.max_duration_s, dt)
        codes = list(exp.channels)
    auto = None
    if scene.integration.auto:
        from pounding_sweep.sweep.autodt import AutoDt

        auto = AutoDt(scene, lambda s: prepare(s, kernel))
    return Prepared(
        scene,
        model,
        model.system_arrays(dt),
        exc,
        Grid.from_scene(scene),
        opts,
        hspec,
        hcols,
        score,
        codes,
        auto,
        kernel,
    )


def contact_arrays(model: CoupledModel, scene: Scene, params: dict[str, np.ndarray], dt: float):
    """k_s, dashpot c_j (eq. 9) per run and pair, xi_s (eq. 10), steps per contact period, flags."""
    ks = contact_stiffness(params["ks_ratio"], params["ks_N_per_m"], scene.contact.k_ref_N_per_m)
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
    spec = HistorySpec(
        np.array([p[0] for p in parsed], np.int64),
        np.array([p[1] for p in parsed], np.int64),
        scene.output.history_decimate,
    )
    return spec, [p[2] for p in parsed]


def drift_ratio_columns(scene: Scene, metrics: np.ndarray, names: list[str]) -> dict[str, np.ndarray]:
    """peak_drift_ratio_b<b>s<s>: each story's peak interstory drift over its height, for the buildings whose
    story heights the scene gives (story_height_m) [-]."""
    out = {}
    for b, cfg in ((1, scene.building1), (2, scene.building2)):
        h = cfg.story_height_m
        if not h:
            continue
        n = len(cfg.masses_kg)
        heights = h * n if len(h) == 1 else h
        for s in range(1, n + 1):
            out[f"peak_drift_ratio_b{b}s{s}"] = metrics[:, names.index(f"peak_drift_b{b}s{s}_m")] / heights[s - 1]
    return out
