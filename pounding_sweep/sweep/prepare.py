"""A scene turned into the kernels' inputs before any run: model, system matrices at dt, excitation,
grid, contact arrays per chunk, histories and experiment samples. Shared by sweeps, single runs
(simulate), the refinement and the benchmarks."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from pounding_sweep.codes import (
    CONTACT_LAWS,
    H_ABS_ACC,
    HERTZ_LAWS,
    LAW_CLASSIC,
    LAW_HERTZDAMP,
    LAW_JANKOWSKI,
    LAW_NO_TENSION,
    SCHEMES,
)
from pounding_sweep.engine import layout as L
from pounding_sweep.engine.driver import merge_rows, run_chunk
from pounding_sweep.engine.inputs import HistorySpec, KernelOptions, Records, RunArrays, ScoreSpec
from pounding_sweep.model.contact import contact_period
from pounding_sweep.model.coupled import CoupledModel, SystemArrays
from pounding_sweep.model.excitation import Excitation
from pounding_sweep.model.grid import Grid
from pounding_sweep.model.laws import hertz_stiffness, law_arrays
from pounding_sweep.scene import SWEEPABLE, ContactConfig, Scene, contact_stiffness
from pounding_sweep.scene.axes import STRUCTURE_AXES
from pounding_sweep.scene.channels import parse_channel
from pounding_sweep.scene.parameters import member

LAW_NAMES = {code: name for name, code in CONTACT_LAWS.items()}


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
    combination: object | None = None  # sweep.scoring.Combination: how the channels' errors combine
    experiment: object | None = None  # the loaded experiment (model.experiment.Experiment), for variants
    variants: dict = field(default_factory=dict, compare=False, repr=False)  # structure values -> Prepared
    sensor: object | None = None  # sweep.sensor.Sensor: the accelerometers' own filter (scored via run_sensed)

    @property
    def dt(self) -> float:
        return self.sysarr.dt

    def run(self, params: dict[str, np.ndarray], threads: int = 1, batch_runs: int = 0, done=None):
        """Integrate the runs described by `params` (as Grid.chunk gives them); `done(n)`: called as groups
        of n runs finish (not with dt_s = 'auto', whose runs are rerun at finer steps)."""
        if self.auto is not None:
            return self.auto.run(params, threads, batch_runs)
        groups = structure_groups(self.scene, params)
        if groups is not None:
            return self._run_groups(groups, params, threads, batch_runs, done)
        if self.sensor is not None and self.score.active:
            from pounding_sweep.sweep.sensor import run_sensed

            return run_sensed(self, params, threads, batch_runs, done)
        runs, rec, derived = self.kernel_inputs(params, threads)
        metrics, run_time, hist, scores = run_chunk(
            self.sysarr,
            runs,
            rec,
            self.hist,
            self.opts,
            threads,
            batch_runs,
            self.score,
            self.kernel,
            done,
        )
        return metrics, run_time, hist, scores, derived

    def _run_groups(self, groups, params, threads, batch_runs, done):
        """run() for runs whose structure differs from the scene's: each distinct structure (and experiment
        clock) as its own group on its own system matrices, the rows put back in order. A group is a plain
        chunk to the engine, so a grid over the structure stays on the lane kernel where the scene allows."""
        parts = []
        for values, idx in groups:
            sub = {k: v[idx] for k, v in params.items()}
            parts.append((idx, self.variant(values).run(sub, threads, batch_runs, done)))
        return merge_rows(params["run_id"].size, parts)

    def variant(self, values: tuple) -> Prepared:
        """This scene with the structure values ((name, value) pairs: structure_groups) of a group of runs: its
        own model, matrices and experiment samples; the excitation, histories and kernel shared (cached per
        values)."""
        if values not in self.variants:
            scene = with_structure(self.scene, dict(values))
            model = CoupledModel.from_scene(scene)
            score = self.score
            if scene.experiment is not None and scene.experiment.time_offset_s != self.scene.experiment.time_offset_s:
                from pounding_sweep.sweep.scoring import score_spec

                score = score_spec(self.experiment, scene.experiment, self.excitation.max_duration_s, self.dt)[
                    0
                ]  # the same channels and weights: only the samples' clock moved
            self.variants[values] = dataclasses.replace(
                self, scene=scene, model=model, sysarr=model.system_arrays(self.dt), score=score, variants={}
            )
        return self.variants[values]

    def kernel_inputs(self, params: dict[str, np.ndarray], threads: int = 1):
        """The kernel's inputs for `params` at the scene's dt: (RunArrays, record arrays, the derived
        contact columns). Each run's law: law_codes(params)."""
        k, c, derived, status = contact_arrays(self.model, self.scene, params, self.dt)
        ex, rec = self.excitation.chunk_inputs(params, threads)  # a stochastic chunk's motions are generated here
        runs = RunArrays(
            k,
            c,
            params["gap_m"] if self.model.n_pairs else np.zeros(k.size),
            ex["exc_kind"],
            ex["exc_amp"],
            ex["exc_omega"],
            ex["rec_id"],
            ex["nsteps"],
            status,
            law_codes(params),
        )
        if "intensity_g" in ex:
            derived["intensity_g"] = ex["intensity_g"]
        return runs, Records(*rec), derived

    @property
    def law_codes_used(self) -> list[int]:
        """The codes.LAW_* of every law the grid runs (what compile_kernel compiles for)."""
        if self.scene.contact is None:  # one building: no pair, the law is never evaluated (law_codes)
            return [LAW_CLASSIC]
        return sorted({CONTACT_LAWS[x] for x in self.scene.axis_values("law") or (self.scene.contact.law,)})


def prepare(scene: Scene, kernel: str = "auto", groups: int = L.GROUPS_ALL) -> Prepared:
    """Model, system matrices at dt, excitation, grid, history and experiment specs of a scene.
    With dt_s = 'auto' these are at dt_max_s, and runs go through the step-doubling ladder.
    `kernel`: which kernel runs its chunks (engine.driver.KERNELS; "auto": the lane kernel where it can);
    `groups`: the metric groups the caller reads (engine.layout.GROUP_* bits; the others are NaN)."""
    dt = scene.integration.first_dt_s
    model = CoupledModel.from_scene(scene)
    exc = Excitation.from_scene(scene, dt)
    opts = KernelOptions(
        SCHEMES[scene.integration.scheme],
        scene.integration.max_contact_iterations,
        # one building: no impact, the floor is never read; [contact]'s default stands in
        ContactConfig.min_impact_speed_m_s if scene.contact is None else scene.contact.min_impact_speed_m_s,
        groups,
    )
    hspec, hcols = history_spec(scene, model.floors)
    score, codes, comb, sensor = ScoreSpec.none(), [], None, None
    if scene.experiment is not None:
        from pounding_sweep.sweep.scoring import ready_experiment

        ready = ready_experiment(scene.experiment, model, exc, dt)
        exp, score, comb, codes = ready.experiment, ready.score, ready.combination, ready.codes
        if (score.kind == H_ABS_ACC).any():
            from pounding_sweep.sweep.sensor import sensor_model

            sensor = sensor_model(scene.experiment, exp.dt_sample, dt, Path(exp.path).name)
    else:
        exp = None
    auto = None
    if scene.integration.auto:
        from pounding_sweep.sweep.autodt import AutoDt

        auto = AutoDt(scene, lambda s: prepare(s, kernel, groups))
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
        comb,
        exp,
        sensor=sensor,
    )


def structure_names(params: dict) -> tuple[str, ...]:
    """The structure parameters of runs: STRUCTURE_AXES, then the per-story ones `params` holds (a calibration
    fitting story_stiffness_scale_b1_s2, say: scene/parameters.py FAMILIES)."""
    return STRUCTURE_AXES + tuple(sorted(k for k in params if member(k) is not None))


def structure_value(scene: Scene, name: str) -> float:
    """The scene's own value of a structure parameter (NaN where unset: no damping_ratio, no experiment; a
    family member where the scene gives no list: the family's neutral value, a story factor's 1)."""
    found = member(name)
    if found is not None:
        fam, index = found
        values = getattr(getattr(scene, fam.section), fam.key)
        if values is None:
            return np.nan if fam.neutral is None else fam.neutral
        return float(values[index - 1])
    section, key = SWEEPABLE[name]
    part = getattr(scene, section)
    v = None if part is None else getattr(part, key)
    return np.nan if v is None else float(v)


def structure_values(scene: Scene, names: tuple[str, ...] = STRUCTURE_AXES) -> tuple:
    """The scene's own values of the structure parameters `names` (structure_value)."""
    return tuple(structure_value(scene, n) for n in names)


def structure_groups(scene: Scene, params: dict[str, np.ndarray]):
    """[(((name, value), ...), run indices)] of the runs in `params` grouped by their structure values
    (structure_names), or None when every run has the scene's own structure (the common case: one group, no
    work)."""
    names = structure_names(params) if params else STRUCTURE_AXES
    base = np.array(structure_values(scene, names))
    cols = np.column_stack([np.asarray(params[name], float) for name in names]) if params else None
    if cols is None or not cols.size:
        return None
    same = (cols == base) | (np.isnan(cols) & np.isnan(base))
    if same.all():
        return None
    keys, inverse = np.unique(np.where(np.isnan(cols), np.inf, cols), axis=0, return_inverse=True)
    keys = np.where(np.isinf(keys), np.nan, keys)
    return [
        (tuple(zip(names, (float(x) for x in keys[g]))), np.flatnonzero(inverse.ravel() == g))
        for g in range(keys.shape[0])
    ]


def with_structure(scene: Scene, values: dict) -> Scene:
    """The scene with structure parameters set (NaN: left as the scene has it); a per-story or per-mode one sets
    its entry of the building's list."""
    sections: dict = {}
    for name, v in values.items():
        if v is None or (isinstance(v, float) and np.isnan(v)):
            continue
        found = member(name)
        if found is None:
            section, key = SWEEPABLE[name]
            sections.setdefault(section, {})[key] = float(v)
            continue
        fam, index = found  # validate: a family without a neutral value is fitted only where the scene lists it
        part = getattr(scene, fam.section)
        kv = sections.setdefault(fam.section, {})
        values = list(kv.get(fam.key) or getattr(part, fam.key) or (fam.neutral,) * len(part.masses_kg))
        values[index - 1] = float(v)
        kv[fam.key] = tuple(values)
    new = {s: dataclasses.replace(getattr(scene, s), **kv) for s, kv in sections.items()}
    return dataclasses.replace(scene, **new)


def law_codes(params: dict[str, np.ndarray]) -> np.ndarray:
    """codes.LAW_* of each run (params["law"] holds the laws' names; None in a single-building scene, which has
    no pair to apply a law to: the classic code, so the chunk goes to a kernel that runs P = 0 models)."""
    names = params["law"]
    out = np.empty(names.size, np.int64)
    for name in set(names):
        out[names == name] = LAW_CLASSIC if name is None else CONTACT_LAWS[name]
    return out


def contact_arrays(model: CoupledModel, scene: Scene, params: dict[str, np.ndarray], dt: float):
    """Per run: the kernels' stiffness (k_s [N/m] for the linear laws, k_h [N/m^1.5] for the Hertz-type ones),
    the law coefficient per pair (model/laws.py: the dashpot c_j of eq. 9 for the linear laws), the derived
    contact columns, and the status bits known before the run (too few steps per contact period)."""
    c = scene.contact
    codes_ = law_codes(params)
    if c is None:  # one building: no pairs, no contact columns, nothing to flag before the run
        n = codes_.size
        return np.zeros(n), np.zeros((n, 0)), {}, np.zeros(n, np.int64)
    hertz = np.isin(codes_, HERTZ_LAWS)
    ks = contact_stiffness(params["ks_ratio"], params["ks_N_per_m"], c.k_ref_N_per_m)
    kh = np.where(
        np.isnan(params["kh_N_per_m1_5"]), hertz_stiffness(ks, c.reference_penetration_m), params["kh_N_per_m1_5"]
    )
    k = np.where(hertz, kh, ks)
    m1, m2 = model.pair_masses()
    coef, param, produced = law_arrays(codes_, k, params["r"], c.restitution_relation, m1, m2, LAW_NAMES)
    # a contact's period: 2 pi sqrt(m_eff / k) with the linear k_s, or the Hertz law's tangent stiffness
    # 1.5 k_h sqrt(delta_ref) at the reference penetration (an impact's duration depends on its speed)
    k_lin = np.where(hertz, 1.5 * kh * np.sqrt(c.reference_penetration_m), ks)
    steps_per_period = contact_period(k_lin[:, None], m1[None, :], m2[None, :]).min(axis=1) / dt
    status = np.where(steps_per_period < scene.integration.min_steps_per_contact_period, L.STATUS_UNDERRESOLVED, 0)
    kv_damped = np.isin(codes_, (LAW_CLASSIC, LAW_NO_TENSION, LAW_JANKOWSKI))
    derived = {
        "ks_N_per_m": ks,
        "contact_damping_ratio": np.where(kv_damped, param, np.nan),
        "steps_per_contact_period": steps_per_period,
        "r_single_impact": produced,
    }
    if hertz.any():
        derived["kh_N_per_m1_5"] = np.where(hertz, kh, np.nan)
    if (codes_ == LAW_HERTZDAMP).any():
        derived["hertzdamp_a"] = np.where(codes_ == LAW_HERTZDAMP, param, np.nan)
    return k, np.ascontiguousarray(coef), derived, status.astype(np.int64)


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
        if cfg is None:
            continue
        heights = cfg.story_heights()
        if heights is None:
            continue
        for s in range(1, len(heights) + 1):
            out[f"peak_drift_ratio_b{b}s{s}"] = metrics[:, names.index(f"peak_drift_b{b}s{s}_m")] / heights[s - 1]
    return out
