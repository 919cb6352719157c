"""The accelerometer as the scene states it ([experiment] sensor_filter): the filter a sensor applies before it
outputs a sample, run on a model's absolute acceleration recorded at every simulation step, then read at the
table's instants. The experiment's samples went through the real sensor; this puts the model's through the
same arithmetic, so that the two are compared as the sensor records them (issue 28, item 1).

The sensors.
* 'average': the sensor samples at its internal rate f_s (sensor_rate_Hz) and outputs, at each of the table's
  instants t_m, the mean of its n most recent internal samples, a(t_m - j / f_s) for j = 0..n-1, with
  n = f_s / f_out (f_out the table's rate): a boxcar decimation filter, the simplest of the MEMS parts'
  digital low-passes (e.g. the averaging of the ADXL345's and LIS3DH's output data rates; in general the
  decimating filter of a sigma-delta converter, Oppenheim & Schafer, Discrete-Time Signal Processing, 3rd ed.,
  sec. 4.6). Its gain is |sin(pi f n / f_s) / (n sin(pi f / f_s))|, 0 at every multiple of f_out: what aliases
  into the output band is attenuated, and an impact's spike is spread over one output interval, not sampled.
* 'butter': a Butterworth low-pass of sensor_order poles and cut-off sensor_cutoff_Hz (scipy.signal.butter,
  bilinear transform, second-order sections), run causally on the internal samples at f_s and read at the
  table's instants; without sensor_rate_Hz, at the simulation step (the bilinear transform at 1 / dt: an analog
  filter, whose frequency warping tan(pi f_c dt) / (pi f_c dt) - 1 ~ (pi f_c dt)^2 / 3 is below 1e-4 for
  f_c dt < 0.005). A datasheet's digital low-pass "bandwidth" setting (e.g. the MPU-6050's DLPF_CFG) is the
  cut-off to state here; the parts do not publish their filter's form, so its order is the user's assumption.
Both start from rest: before t = 0 the structure and its table do not move, so every earlier internal sample is 0.
Internal samples between simulation steps are linear interpolations of the step history (error <= dt^2 |a''| / 8);
a step coarser than the internal interval is warned about (prepare's sensor_model).

Why outside the kernel: the kernels are being reworked in parallel (engine/**), so this runs on the history the
kernel already records, at stride 1 for the acceleration channels it filters, in the sweep layer (run_sensed for
sweeps and single runs; sweep/calibrate.py's residuals for calibrations, which record that history anyway).
Cost per run: 8 bytes per step and acceleration channel (a 4 s test at dt = 1e-4 s: 320 kB per channel), held
for a batch of runs at a time (SENSOR_BATCH_BYTES), and the filter: O(samples x taps) for the average,
O(samples x order) for the Butterworth, at the sensor's rate: far below the integration itself.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.signal import butter, lfilter, sosfilt

from pounding_sweep import codes as C
from pounding_sweep.errors import ExperimentError
from pounding_sweep.warn import warn

#: the step histories held at once by run_sensed (runs are batched below it): 128 MiB
SENSOR_BATCH_BYTES = 128 * 2**20
#: a sensor rate within this share of a whole multiple of the table's rate is that multiple ('average': the
#: table's interval is the median of its time steps, which a logger's jitter moves by well under 1 %)
RATE_TOLERANCE = 0.01


@dataclass(frozen=True)
class Sensor:
    """One accelerometer model, shared by every acceleration channel of an experiment (module docstring)."""

    kind: str  # 'average' or 'butter'
    rate_Hz: float | None  # internal sample rate; None ('butter' only): the filter runs at the simulation step
    taps: int = 1  # 'average': internal samples averaged per output
    cutoff_Hz: float | None = None  # 'butter'
    order: int = 2  # 'butter'

    def sections(self, dt: float) -> np.ndarray:
        """The Butterworth's second-order sections at the internal rate (or at 1 / dt)."""
        fs = self.rate_Hz if self.rate_Hz is not None else 1.0 / dt
        return butter(self.order, self.cutoff_Hz, btype="low", output="sos", fs=fs)

    def read(self, a: np.ndarray, dt: float, t: np.ndarray) -> np.ndarray:
        """The sensor's output at the ascending simulation instants t [s] for acceleration histories a
        (..., steps), a[..., k] at k dt; returns (..., t.size). Instants past the history hold its last value."""
        a = np.asarray(a, float)
        t = np.asarray(t, float)
        if self.rate_Hz is None:  # the filter at the simulation step, then read between steps
            y = sosfilt(self.sections(dt), a, axis=-1)
            return _at(y, t / dt)
        h = 1.0 / self.rate_Hz
        first = -math.floor(t[0] / h) if t[0] > 0 else 0  # internal instants t[0] + j h from just after 0
        last = math.ceil((t[-1] - t[0]) / h * (1.0 + 1e-12)) + 1
        j = np.arange(first, last)
        tau = t[0] + j * h
        x = _at(a, tau / dt)
        x[..., tau < 0.0] = 0.0  # at rest before the excitation starts
        if self.kind == "average":
            y = lfilter(np.full(self.taps, 1.0 / self.taps), [1.0], x, axis=-1)  # zeros before: at rest
        else:
            y = sosfilt(self.sections(dt), x, axis=-1)
        return _at(y, (t - t[0]) / h - first)

    def describe(self) -> dict:
        """Plain data for the result metadata."""
        if self.kind == "average":
            what = (
                f"moving average of {self.taps} internal samples at {self.rate_Hz:g} Hz, output at the table's instants"
            )
        else:
            at = f"{self.rate_Hz:g} Hz" if self.rate_Hz is not None else "the simulation step (analog)"
            what = f"Butterworth low-pass, {self.order} poles, cut-off {self.cutoff_Hz:g} Hz, run at {at}"
        return {
            "kind": self.kind,
            "what": what + "; causal, from rest at t = 0, on the model's acceleration at every step",
            "rate_Hz": self.rate_Hz,
            "taps": self.taps,
            "cutoff_Hz": self.cutoff_Hz,
            "order": self.order,
        }


def _at(y: np.ndarray, x: np.ndarray) -> np.ndarray:
    """y (..., n) sampled at index 0..n-1, read at fractional indices x by linear interpolation (clamped to the
    ends)."""
    n = y.shape[-1]
    x = np.clip(x, 0.0, n - 1)
    k = np.minimum(np.floor(x).astype(np.int64), max(n - 2, 0))
    w = x - k
    if n == 1:
        return np.broadcast_to(y[..., :1], y.shape[:-1] + x.shape).copy()
    return y[..., k] * (1.0 - w) + y[..., k + 1] * w


def acceleration_at(sensor: Sensor | None, a: np.ndarray, dt: float, ts: np.ndarray, sos: np.ndarray) -> np.ndarray:
    """A model's acceleration history a (a[k] at k dt, every step) as the experiment's table holds it at the
    simulation instants ts [s]: read through the accelerometer where the scene models one (Sensor.read), else
    interpolated linearly between steps; then through the experiment's low-pass sections sos (rows of 6; none:
    unfiltered), causally from rest, as the scoring filters it. The calibration's residuals and the figures."""
    model = sensor.read(a, dt, ts) if sensor is not None else np.interp(ts / dt, np.arange(a.size), a)
    return sosfilt(sos, model) if sos.shape[0] else model


def sensor_model(cfg, dt_sample: float, dt: float, table: str = "the table") -> Sensor | None:
    """The scene's sensor (None for sensor_filter = 'none'), checked against the table's sample interval
    dt_sample [s] and the simulation step dt [s]; a rate that does not fit is an ExperimentError naming it."""
    if cfg.sensor_filter == "none":
        return None
    rate = cfg.sensor_rate_Hz
    if cfg.sensor_filter == "average":
        ratio = rate * dt_sample
        taps = round(ratio)
        if taps < 1 or abs(ratio - taps) > RATE_TOLERANCE * taps:
            raise ExperimentError(
                f"[experiment] sensor_rate_Hz = {rate!r}: not a whole multiple of the rate {1.0 / dt_sample:.6g} "
                f"samples/s of {table} (a sample every {dt_sample:.6g} s); the sensor averages its internal samples "
                "over one output interval"
            )
        sensor = Sensor("average", float(rate), int(taps))
    else:
        sensor = Sensor("butter", rate, 1, float(cfg.sensor_cutoff_Hz), int(cfg.sensor_order))
        if rate is None and not cfg.sensor_cutoff_Hz < 0.5 / dt:
            raise ExperimentError(
                f"[experiment] sensor_cutoff_Hz = {cfg.sensor_cutoff_Hz!r}: at or above the Nyquist frequency "
                f"{0.5 / dt:.6g} Hz of the simulation step dt = {dt:.6g} s (give sensor_rate_Hz, or a finer dt_s)"
            )
    if rate is not None and dt > 1.0 / rate * (1.0 + 1e-9):
        warn(
            "sensor",
            f"[experiment] sensor_rate_Hz = {rate:g}: the simulation step dt = {dt:.6g} s is coarser than the sensor's internal interval "
            f"{1.0 / rate:.6g} s: its internal samples are interpolated between steps; "
            "a finer dt_s models the sensor better",
        )
    return sensor


def run_sensed(prep, params: dict, threads: int = 1, batch_runs: int = 0, done=None):
    """Prepared.run for a scene whose accelerometers are modelled (prep.sensor): the kernel records each
    scored acceleration channel at every step (beside the scene's own histories), in batches of runs whose
    histories fit SENSOR_BATCH_BYTES; each acceleration channel is then read through the sensor at the
    experiment's instants, low-pass filtered as the experiment's samples are (lowpass_Hz), and scored by the
    kernel's own score_channel, in place of the kernel's unfiltered score. Returns what Prepared.run returns,
    the scene's histories at their own decimation."""
    from pounding_sweep.engine.driver import merge_rows, run_chunk
    from pounding_sweep.engine.inputs import HistorySpec
    from pounding_sweep.engine.score import score_channel

    score, user = prep.score, prep.hist
    acc = np.flatnonzero(score.kind == C.H_ABS_ACC)
    nu = user.kinds.size
    full = HistorySpec(
        np.concatenate([user.kinds, np.full(acc.size, C.H_ABS_ACC)]).astype(np.int64),
        np.concatenate([user.index, score.dof[acc]]).astype(np.int64),
        1,
    )
    steps = int(math.ceil(prep.excitation.max_duration_s / prep.dt)) + 2
    n = params["run_id"].size
    batch = max(1, min(n, SENSOR_BATCH_BYTES // (8 * full.kinds.size * steps)))
    sos = score.sos
    parts = []
    for s0 in range(0, n, batch):
        idx = np.arange(s0, min(n, s0 + batch))
        sub = {k: v[idx] for k, v in params.items()}
        runs, rec, derived = prep.kernel_inputs(sub, threads)
        metrics, run_time, hist, scores = run_chunk(
            prep.sysarr, runs, rec, full, prep.opts, threads, batch_runs, score, prep.kernel, done
        )
        for j, c in enumerate(acc):
            model = prep.sensor.read(hist[:, nu + j], prep.dt, score.t)
            if sos.shape[0]:
                model = sosfilt(sos, model, axis=-1)
            for i in range(idx.size):
                if np.isnan(scores[i, c]).all() or not np.isfinite(model[i]).all():
                    scores[i, c] = np.nan  # unscored by the kernel (it stopped early), or diverged: as the kernel
                    continue
                score_channel(model[i], score.x[c], score.t, score.max_lag, score.dt_sample, scores[i, c])
        kept = hist[:, :nu, :: user.decimate] if nu else None
        parts.append((idx, (metrics, run_time, kept, scores, derived)))
    return merge_rows(n, parts)
