"""The experiment a sweep scores against, made ready in one place (ready_experiment): its table read (or its
video tracked, once per process) and checked against the model's modes and the record, turned into the kernel's
ScoreSpec (the samples inside the scored window on the simulation clock, the acceleration channels low-pass
filtered) and the weights that combine the channels' errors (with each channel's noise floor)."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from pounding_sweep import codes
from pounding_sweep.engine.inputs import ScoreSpec
from pounding_sweep.errors import ExperimentError, VideoError
from pounding_sweep.model.experiment import (
    Experiment,
    experiment_from_table,
    noise_floor,
    read_table,
)
from pounding_sweep.scene import ExperimentConfig
from pounding_sweep.scene.channels import building_floor, channel_unit
from pounding_sweep.scene.schema import USES
from pounding_sweep.warn import warn


@dataclass(frozen=True)
class ReadyExperiment:
    """An [experiment] ready to score runs against: the table as read (channels, kinds, noise), the kernel's
    samples and filter (ScoreSpec) and how the channels' errors combine (weights, noise floors)."""

    experiment: Experiment
    score: ScoreSpec
    combination: Combination

    @property
    def codes(self) -> list[str]:
        """The scored channels ('b1f3', 'abs_acc_b2f1', ...), in the table's order."""
        return list(self.experiment.channels)


def ready_experiment(cfg: ExperimentConfig, model, excitation, dt: float) -> ReadyExperiment:
    """The experiment of a scene, read, checked against the model and the record (warnings), and turned into the
    kernel's samples and the channels' combination at time step dt (sweep/prepare.py calls it)."""
    exp = load_experiment(cfg, model.floors)
    for kind, message in sensor_warnings(exp, cfg, model, excitation):
        warn(kind, message)
    score, comb = score_spec(exp, cfg, excitation.max_duration_s, dt)
    return ReadyExperiment(exp, score, comb)


def load_experiment(cfg: ExperimentConfig, floors: tuple[int, int]) -> Experiment:
    """Read and check the table of an [experiment] section, or track its [experiment.video] into one."""
    if cfg.video is not None:
        df, md, where = _tracked(cfg.video)
    else:
        df, md = read_table(cfg.table)
        where = cfg.table
    return experiment_from_table(df, md, where, cfg, floors)


_TRACKED: dict = {}  # (spec, file size, mtime) -> (table, provenance): a video is tracked once per process


def _tracked(spec) -> tuple:
    """Track the video of an [experiment.video] section (OpenCV, lazily imported) into the table
    format above; a video that cannot give one is an ExperimentError naming the file."""
    from pounding_sweep.video.tracker import tracked_table

    try:
        st = Path(spec.path).stat()
        key = (spec, st.st_size, st.st_mtime_ns)
        if key not in _TRACKED:
            from pounding_sweep.progress import Progress

            df, md = tracked_table(spec, progress=Progress(unit="frames"))
            _TRACKED.clear()
            _TRACKED[key] = (df, md)
        df, md = _TRACKED[key]
    except FileNotFoundError:
        raise ExperimentError(f"{spec.path}: video not found ([experiment.video] path)") from None
    except VideoError as e:
        raise ExperimentError(str(e)) from None
    return df, {"tracking": md}, spec.path


def score_spec(
    exp: Experiment, cfg: ExperimentConfig, sim_duration_s: float, dt: float
) -> tuple[ScoreSpec, Combination]:
    """The samples inside the scored window, on the simulation clock, as kernel arrays, and how the
    channels' errors combine (combination).

    Simulation time = experiment time - time_offset_s. The window defaults to all of the
    experiment that the simulation covers; a window outside that is an error.

    The acceleration channels' low-pass filter (lowpass_Hz) is a causal one, applied from rest at the
    window's first sample, here to the experiment's samples (scipy.signal.sosfilt) and in the kernel to each
    run's samples of the same instants (engine/score.py sos_filter, the same sections in the same
    transposed direct form): the same linear filter on the same sample instants, so the filtered error is
    the filter applied to the error, and a run equal to the experiment scores 0 with or without it. A
    zero-phase filter (forward and backward) would need the whole run before it and scipy's edge padding
    reproduced in the kernel; a filter run at the integration step instead would be another filter than
    the experiment's. The causal filter delays both signals alike, at low frequencies by
    1 / (2 pi f_c sin(pi / (2 n))) for n poles (a Butterworth's group delay at 0 Hz: 14 ms for 4 poles at
    30 Hz), which the comparison does not see. The model's acceleration is sampled as the displacement is,
    by linear interpolation between the steps around each sample instant, with no anti-alias filter
    before it, unless [experiment] sensor_filter states the accelerometer's own filter: then the sweep layer
    (sweep/sensor.py run_sensed) rescores those channels from the step history through it. Without it, record
    accelerations at a rate that resolves the impacts, which last 6-23 ms here (500-1000 samples/s; at
    100 samples/s even their noise floor cannot be told from the signal: noise_floor).
    """
    ts = exp.time_s - cfg.time_offset_s
    lo, hi = (0.0, sim_duration_s) if cfg.window_s is None else cfg.window_s
    if cfg.window_s is not None and (lo < 0 or hi > sim_duration_s + 1e-9):
        raise ExperimentError(
            f"[experiment] window_s = [{lo}, {hi}]: outside the simulation, which covers 0 .. {sim_duration_s:.6g} s"
        )
    tol = 1e-12 * dt  # the kernel fills samples up to t_step + 1e-12 dt: the same tolerance here
    keep = (ts >= lo - tol) & (ts <= hi + tol) & (ts >= 0) & (ts <= sim_duration_s + tol)
    if keep.sum() < 2:
        raise ExperimentError(
            f"{exp.path}: its time range {exp.time_s[0]:.6g} .. {exp.time_s[-1]:.6g} s (offset {cfg.time_offset_s} s) "
            f"leaves {int(keep.sum())} sample(s) (at least 2 needed) in the simulation 0 .. {sim_duration_s:.6g} s "
            f"within the window [{lo}, {hi}]"
        )
    codes_ = list(exp.channels)
    raw = np.ascontiguousarray(np.stack([exp.channels[c][keep] for c in codes_]))
    kind = np.array([exp.kinds[c] for c in codes_], dtype=np.int64)
    dof = np.array([exp.dofs[c] for c in codes_], dtype=np.int64)
    sos = lowpass_sections(cfg, exp)
    x = raw.copy()
    if sos.shape[0]:
        from scipy.signal import sosfilt

        for c in np.flatnonzero(kind == codes.H_ABS_ACC):
            x[c] = sosfilt(sos, raw[c])
    max_lag = int(min(round(cfg.max_lag_s / exp.dt_sample), keep.sum() - 2))  # at most the window
    spec = ScoreSpec(np.ascontiguousarray(ts[keep]), x, dof, max_lag, exp.dt_sample, kind, sos)
    return spec, combination(exp, cfg, spec, raw)


def lowpass_sections(cfg: ExperimentConfig, exp: Experiment) -> np.ndarray:
    """The acceleration channels' low-pass filter: a Butterworth filter (maximally flat pass band:
    S. Butterworth, "On the theory of filter amplifiers", Wireless Engineer 7, 1930) of order
    cfg.lowpass_order and cut-off cfg.lowpass_Hz at the table's sample rate, designed by the bilinear
    transform with the cut-off pre-warped (scipy.signal.butter), as second-order sections [b0, b1, b2, 1, a1,
    a2]; (0, 6) when the scene asks for none. The cut-off must lie below the Nyquist frequency 1 / (2 dt)."""
    if cfg.lowpass_Hz is None:
        return np.zeros((0, 6))
    fs = 1.0 / exp.dt_sample
    if not cfg.lowpass_Hz < fs / 2:
        raise ExperimentError(
            f"[experiment] lowpass_Hz = {cfg.lowpass_Hz!r}: at or above the Nyquist frequency {fs / 2:.6g} Hz of "
            f"{Path(exp.path).name} (a sample every {exp.dt_sample:.6g} s); a digital low-pass filter needs a "
            "cut-off below it"
        )
    from scipy.signal import butter

    sos = np.ascontiguousarray(butter(cfg.lowpass_order, cfg.lowpass_Hz, btype="low", output="sos", fs=fs))
    assert np.all(sos[:, 3] == 1.0)  # normalised sections: the kernel's sos_filter takes a0 = 1
    return sos


@dataclass(frozen=True)
class Combination:
    """How the channels' eq. 20 errors make one error per run (rel_rms_combined_pct): `how` ('mean', 'max',
    'rms') over the channels with a weight > 0 (sweep/ranking.py combine_errors)."""

    how: str
    weights: np.ndarray | None  # per channel, summing to 1 (0: left out by `use`); None: all, equally
    noise: dict = field(default_factory=dict)  # weights = 'noise': channel code -> what set its weight

    @classmethod
    def plain(cls, how: str = "mean") -> Combination:
        return cls(how, None)


def combination(exp: Experiment, cfg: ExperimentConfig, spec: ScoreSpec, raw: np.ndarray) -> Combination:
    """The channels' weights from [experiment] use and weights (`raw`: the window's samples before any filter).

    'equal' over every channel is the plain mean, max or rms. 'noise' weights channel c by
    w_c = (RMS_c / sigma_c)^2, its signal-to-noise ratio squared, with RMS_c the root mean square of the
    experiment's (filtered) samples and sigma_c the noise floor in them: the scene's per-channel noise where
    it gives one ([experiment] noise or noise_window_s), else model/experiment.py noise_floor on the raw samples, times sqrt(sum h_k^2) for a filtered channel (white noise through a filter of impulse
    response h). Why: under independent white Gaussian noise the log-likelihood of a run is
    -sum_c ||x_num,c - x_exp,c||^2 / (2 sigma_c^2), and ||x_num,c - x_exp,c||^2 = N (eps_c / 100)^2 RMS_c^2
    (eq. 20, N samples per channel, the same for all on one time axis), so sum_c w_c eps_c^2 orders runs
    as the likelihood does: combine = 'rms' with these weights is the least-squares fit weighted by the
    inverse noise variance (Tarantola, Inverse Problem Theory, SIAM 2005, ch. 3, the least-squares criterion). Where model error
    rather than noise dominates the residuals this is a scale-free weighting, not a likelihood."""
    kinds = [exp.kinds.get(c, codes.H_DISP) for c in exp.channels]
    wanted = USES[cfg.use]
    used = np.array([wanted is None or k == wanted for k in kinds])
    if isinstance(cfg.weights, dict):
        w = np.array([cfg.weights.get(exp.columns[c], 0.0) if u else 0.0 for c, u in zip(exp.channels, used)])
        return Combination(cfg.combine, w / w.sum())
    if cfg.weights == "equal":
        if used.all():
            return Combination.plain(cfg.combine)
        w = used.astype(float)
        return Combination(cfg.combine, w / w.sum())
    w = np.zeros(len(kinds))
    noise = {}
    for c, code in enumerate(exp.channels):
        if not used[c]:
            continue
        if code in exp.noise:  # the scene's: [experiment] noise or noise_window_s
            sigma, order, source = exp.noise[code], 0, exp.noise_source[code]
        else:
            sigma, order = noise_floor(raw[c])
            source = "estimated from the table by differences"
        gain = 1.0
        if kinds[c] == codes.H_ABS_ACC and spec.sos.shape[0]:
            from scipy.signal import sosfilt

            impulse = np.zeros(raw.shape[1])
            impulse[0] = 1.0
            gain = float(np.sqrt(np.sum(sosfilt(spec.sos, impulse) ** 2)))
        rms = float(np.sqrt(np.mean(spec.x[c] ** 2)))
        if not sigma > 0:
            raise ExperimentError(
                f"[experiment] weights = 'noise': column '{exp.columns[code]}' ({code}) shows no noise to weight it "
                f"by ({raw.shape[1]} samples in the window; "
                + ("too few" if order == 0 else "most differences are 0")
                + "); give weights as column -> weight"
            )
        w[c] = (rms / (sigma * gain)) ** 2
        noise[code] = {
            "unit": channel_unit(code)[0],
            "source": source,
            "noise_floor": float(sigma * gain),
            "noise_floor_raw": float(sigma),
            "difference_order": order,
            "rms": rms,
            "snr": float(rms / (sigma * gain)),
        }
    w = w / w.sum()
    for c, code in enumerate(exp.channels):
        if code in noise:
            noise[code]["weight"] = float(w[c])
    return Combination(cfg.combine, w, noise)


def _building(code: str) -> int:
    """The building a channel code measures ('b1f3', 'abs_acc_b2f1' -> 1, 2)."""
    return building_floor(code)[0]


def _sensor_rates(exp: Experiment) -> dict[str, float]:
    """Channel code -> the sample rate [Hz] of the sensor that made it, where the table is an import's
    (its 'sensor_import' metadata: cli/import_.py); a sensor slower than the table was interpolated onto it."""
    sensors = exp.sensor_import.get("sensors", {})
    if not isinstance(sensors, dict):
        return {}
    out = {}
    for code, column in exp.columns.items():
        rate = sensors.get(column.removesuffix("_acc_m_s2"), {}).get("rate_Hz")
        if isinstance(rate, (int, float)) and rate > 0:
            out[code] = float(rate)
    return out


def sensor_warnings(exp: Experiment, cfg: ExperimentConfig, model, excitation) -> list[tuple[str, str]]:
    """(kind, message) for what the experiment's sampling and the scene's record say against each other
    (model/sensors/checks.py): a sample rate below twice a building's modes (aliasing), and the lowest
    acceleration channel of each building reversed or lagging against the record that drives it (its
    absolute acceleration follows the table's in the band where the two move together)."""
    from pounding_sweep.model.sensors.assemble import slower
    from pounding_sweep.model.sensors.checks import aliasing_problems, pair_problems

    out = []
    fs = 1.0 / exp.dt_sample
    seen = {_building(c) for c in exp.channels}  # buildings measured
    modes = {
        f"building {b}": list(frame.modes().frequency_Hz) for b, frame in ((1, model.b1), (2, model.b2)) if b in seen
    }
    rates = _sensor_rates(exp)
    for b, fr in modes.items():  # per building, at the rate of its slowest sensor where it is slower than the table
        mine = {c: r for c, r in rates.items() if f"building {_building(c)}" == b and slower(r, fs)}
        where, fs_b = f"{Path(exp.path).name}", fs
        if mine:
            slow = min(mine, key=mine.get)
            where = f"{where} column '{exp.columns[slow]}' (its sensor's own rate; the table's {fs:.6g} Hz)"
            fs_b = mine[slow]
        out += [("aliasing", w) for w in aliasing_problems(where, fs_b, {b: fr})]
    if excitation.kind != "record" or len(excitation.records) != 1:
        return out
    rec = excitation.records[0]
    t_sim = exp.time_s - cfg.time_offset_s
    inside = (t_sim >= 0) & (t_sim <= rec.duration_s)
    if inside.sum() < 16:
        return out
    ground = np.interp(t_sim[inside], rec.time_s, rec.acc_m_s2)
    lowest: dict[int, str] = {}
    for code in exp.channels:
        if exp.kinds.get(code) == codes.H_ABS_ACC:
            b, f = building_floor(code)
            if b not in lowest or f < building_floor(lowest[b])[1]:
                lowest[b] = code
    for code in lowest.values():
        name = f"{exp.path}: column '{exp.columns[code]}' ({code})"
        out += pair_problems(name, exp.channels[code][inside], f"the record {Path(rec.source).name}", ground, fs)
    return out
