"""Calibration: contact and structure fitted together to the tracked displacement, with uncertainty.

Why: a real test never matches the nominal structure, and a fit of the contact parameters alone absorbs the
structure's error into them (a 1-2 % stiffness error moved the fitted k_s/k by up to 70 %). So the parameters
of [calibrate] (contact, structure scales and damping, the experiment's clock, the excitation's scale) are fitted
together, and every answer says how certain it is and whether the data can decide it.

Method.
* Residuals: each scored channel's model value at the experiment's sample times inside the scored window
  (simulation time = experiment time - time_offset_s, minus the channel's own time_offset_s_<channel> where that
  is fitted: sensors whose clocks are not synchronised; check_channel_offsets bounds it) minus the measured one,
  divided by the channel's noise floor sigma_c, so channels weigh by their noise. Displacement: cubic Hermite interpolation of the kernel's
  displacement and velocity at dt (error ~ dt^4 |u^(4)| / 384, far below any tracking noise). Absolute
  acceleration ([experiment] acceleration channels): linear interpolation between steps, as the kernel's
  scoring samples it, or with [experiment] sensor_filter the sensor's own filter run on the acceleration at
  every step and read at the table's instants (sweep/sensor.py); then the experiment's low-pass filter
  (lowpass_Hz: the same causal sections from rest at the window's first sample) on both sides. Channels that
  [experiment] use leaves out are left out here too.
* Noise floor sigma_c: the channel's own noise where the scene gives it ([experiment] noise, in the channel's
  unit, or noise_window_s: the standard deviation in a quiet window), else the [calibrate] noise_m (displacement
  channels; m), else estimated from the data by the difference method (model/experiment.py noise_floor: an upper
  bound), times the filter's noise gain for a filtered channel.
* Start: the sweep's best cell, or with [calibrate] start_from identify's modes (identified_starts), joins the
  global stage's design as one point (_start).
* Global stage (sweep/globalsearch.py): incremental single shooting: a Sobol design of max(global_points, 16 p)
  points (scipy.stats.qmc, scrambled, fixed seed; log scale for stiffnesses) and the sweep's best cell on a
  leading horizon of the record, least squares from the best of them, carried over horizons doubling to the
  whole record; one restart from fresh points when the misfit stays above misfit_factor. Each batch of runs
  (the design, a Jacobian) goes to the grid engine at once, runs of distinct structures dealt to the threads.
* Local stage: scipy.optimize.least_squares (trust-region reflective, bounds), its Jacobian by forward
  differences of JAC_STEP of each coordinate's range, the p runs as one batch (Problem.jac).
* Uncertainty: Gauss-Newton covariance s^2 (J^T J)^-1 (s^2 = RSS / (N - p), J the Jacobian at the optimum, in
  the fit's coordinates: log for stiffnesses) inflated for the residuals' time correlation by N / N_eff, with
  N_eff = N (1 - rho) / (1 + rho) and rho the residuals' lag-1 autocorrelation (an AR(1) model of the
  residuals: the variance of a mean of AR(1) data, Bayley & Hammersley 1946, JRSS Suppl. 8:184); 95 % intervals
  with Student's t on N_eff - p degrees of freedom, mapped back through the log where used (asymmetric) and
  clipped to the bounds (a least-squares interval is local: the profiles say more where the fit is not quadratic).
  A direction the residuals do not change along (singular value below 1e-8 of the largest) gets an infinite
  standard error: the interval is the bounds.
* Profiles: each profiled parameter fixed on a ladder across its bounds, the others refitted; the values whose
  profile rises less than chi^2_1(0.95) = 3.84 above the optimum in units of the inflated residual variance
  are those the data cannot exclude (the profile-likelihood interval, Venzon & Moolgavkar 1988). A profile
  interval that reaches both bounds, or spans more than half of the (log) range, says the parameter is not
  identified by this data, with that range. A profile point below the optimum by more than 3.84 (refitting the
  others with one fixed reaches basins the search's starts missed, on a bound say) means the optimum is not the
  global one: the fit goes on from that point once (least squares, every parameter free), and its intervals,
  windows and profiles are made again there; the warnings say so (_lower_profile_point).
* Model error (sweep/uncertainty.py): when the misfit exceeds misfit_factor, beside each noise-based interval
  one that includes the model's error (a window split of the record: what fits of other parts of it give),
  and that is the one to quote (Fit.quote).
* Warnings (in the CLI summary, the result metadata and the tables): a fitted value on a bound; the best fit's
  residual RMS above misfit_factor times the noise floor (the model cannot explain the data); a parameter not
  identified.
* Laws (sweep/lawcompare.py): with a [sweep] law axis each law is calibrated on its own (Hertz, elastic, without
  r) and compared by AIC and BIC on one effective count for every law and by blocked cross-validation; "the
  data cannot decide" where they disagree or tie.
"""

from __future__ import annotations

import dataclasses
import math
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field

import numpy as np
from scipy.signal import sosfilt

from pounding_sweep import codes as C
from pounding_sweep.errors import ConfigError
from pounding_sweep.model.experiment import noise_floor
from pounding_sweep.scene import Scene
from pounding_sweep.scene.channels import building_floor, channel_unit, shown_value
from pounding_sweep.scene.parameters import channel_offset, default_profiled, is_log, member
from pounding_sweep.sweep.fitchecks import at_noise_level, reversed_channel_warnings, step_error, step_error_warning
from pounding_sweep.sweep.fitstats import NO_CONTACT, fit_label, gauss_newton, interval, local_fit, misfit_of, on_bound
from pounding_sweep.sweep.globalsearch import Search, find_basin
from pounding_sweep.sweep.lawcompare import compare_laws as compare_on_one_basis
from pounding_sweep.sweep.lawcompare import information_criteria
from pounding_sweep.sweep.prepare import Prepared, history_spec, prepare, structure_groups
from pounding_sweep.sweep.sensor import acceleration_at
from pounding_sweep.sweep.uncertainty import model_error_intervals
from pounding_sweep.warn import warn

CHI2_1_95 = 3.841458820694124  # chi^2 quantile, 1 degree of freedom, 0.95
#: forward-difference step of the Jacobian, as a share of each fit coordinate's range (Problem.jac). Its error is
#: about h |r''| / 2 + 2 eps / h (eps: the residuals' own noise: rounding, event location). Measured against
#: central differences on the stiff 6 Hz test (k_s/k 10, r 0.8; tests/sweep/test_globalsearch.py's case), the
#: worst column's relative error: 51 % at 1e-3 of the range, 25 % at 1e-4, 0.75 % at 1e-5, 0.55 % at 1e-6, 1.7 %
#: at 1e-7, 13 % at 1e-8. (The previous least squares took 1e-4 of |z|: errors of 10-30 %, and it stopped 1.5 %
#: above the optimum's residual on that test.)
JAC_STEP = 1e-5


@dataclass
class Target:
    """The experiment's fitted samples: per channel (inside the window at the scene's offset) the experiment-clock
    times and the measured values (filtered where the channel is), and the channel's noise floor."""

    codes: list[str]  # 'b1f3', 'abs_acc_b1f3', ...
    acc: list[bool]  # an absolute-acceleration channel
    time_exp: list[np.ndarray]  # experiment clock [s]
    values: list[np.ndarray]  # measured displacement [m] or acceleration [m/s^2]
    sigma: np.ndarray  # noise floor per channel
    sos: np.ndarray  # the acceleration channels' low-pass sections ((0, 6): none)

    @property
    def n(self) -> int:
        return int(sum(v.size for v in self.values))


@dataclass
class Fit:
    """One calibration (one law): the optimum, its uncertainty, profiles and warnings."""

    law: str
    names: list[str]
    bounds: dict[str, tuple[float, float]]
    estimate: dict[str, float]
    std_error: dict[str, float]
    ci95: dict[str, tuple[float, float]]
    correlation: np.ndarray
    rss: float  # sum of squared noise-normalised residuals
    n: int
    n_eff: float
    rho: float
    rms_m: dict[str, float]  # per channel RMS residual, in the channel's SI unit (m, or m/s^2 for abs_acc_)
    noise_m: dict[str, float]  # per channel noise floor, likewise
    misfit_ratio: float  # RMS residual / noise floor, over the channels
    error_pct: float  # eq. 20 relative RMS at the optimum, mean over channels
    evaluations: int
    seconds: float
    profiles: dict[str, list[dict]] = field(default_factory=dict)
    identified: dict[str, tuple[bool, float, float]] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)
    z_opt: np.ndarray | None = None  # the optimum in the fit's coordinates (log for stiffnesses)
    residuals: np.ndarray | None = None  # noise-normalised residuals at the optimum, channel after channel
    sizes: list[int] = field(default_factory=list)  # samples per channel
    ci95_model: dict[str, tuple[float, float]] = field(default_factory=dict)  # with model error (uncertainty.py)
    windows: list[dict] = field(default_factory=list)  # the window fits behind ci95_model
    quote: str = "noise"  # which interval to quote: 'noise' (ci95) or 'model_error' (ci95_model)
    search: list[dict] = field(default_factory=list)  # the global stage's horizons (globalsearch.py)
    start: dict[str, dict] = field(default_factory=dict)  # with start_from: name -> {value, from} (_start)
    problem: Problem | None = field(default=None, repr=False)  # the residual function (not stored)
    comparison: object = field(default=None, repr=False)  # lawcompare.LawComparison, several laws calibrated
    #: per channel the integration error of the fitted run [SI RMS], by halving the step (fitchecks.step_error); {}
    #: with dt_s = 'auto' (each run's step already meets its tolerance)
    step_error: dict[str, float] = field(default_factory=dict)


class Problem:
    """The residual function of a scene's experiment over named parameters (module docstring)."""

    def __init__(
        self,
        scene: Scene,
        names: list[str],
        bounds: dict,
        noise_m: float | None,
        threads: int = 1,
        window: tuple[float, float] | None = None,
        sigma: np.ndarray | None = None,
    ):
        """`window` (simulation time [s]): fit only the samples inside it, and simulate only as far as they
        need (its end, plus the largest clock shift the fitted clocks may make: _simulated); `sigma`: the channels'
        noise floors (a window of a record keeps the whole record's)."""
        self.names = list(names)
        self.bounds = {n: (float(bounds[n][0]), float(bounds[n][1])) for n in self.names}
        self.threads = threads
        self.evaluations = 0
        self.scene, self.noise_m = scene, noise_m
        floors = scene.floors
        fixed, whole = _simulated(scene, self.bounds, window)
        probe = prepare(fixed)
        exp = probe.experiment
        weights = probe.combination.weights if probe.combination is not None else None
        codes = [c for i, c in enumerate(exp.channels) if weights is None or weights[i] > 0]  # as `use` says
        acc = [exp.kinds.get(c, C.H_DISP) == C.H_ABS_ACC for c in codes]
        channels, self.slots = [], []  # the histories kept, and each channel's rows among them
        for c, a in zip(codes, acc):
            floor = c.removeprefix("abs_acc_")
            self.slots.append(tuple(range(len(channels), len(channels) + (1 if a else 2))))
            channels += [f"abs_acc_{floor}"] if a else [f"disp_{floor}", f"vel_{floor}"]
        kept = dataclasses.replace(
            fixed, output=dataclasses.replace(fixed.output, histories=tuple(channels), history_decimate=1)
        )
        hspec, hcols = history_spec(kept, floors)  # the probe with histories: the record and table read once
        self.sensor = probe.sensor  # the accelerometers' filter (sweep/sensor.py), on the step history below
        self.prep: Prepared = dataclasses.replace(probe, scene=kept, hist=hspec, hist_columns=hcols, sensor=None)
        self.base = self.prep.grid.chunk(0, 1)
        cfg = scene.experiment
        duration = self.prep.excitation.max_duration_s if whole is None else whole
        lo, hi = (0.0, duration) if cfg.window_s is None else cfg.window_s
        if window is not None:
            lo, hi = max(lo, window[0]), min(hi, window[1])
        self.window = (float(lo), float(hi))
        self.offset0 = cfg.time_offset_s
        sos = probe.score.sos if any(acc) else np.zeros((0, 6))
        gain = 1.0
        if sos.shape[0]:
            impulse = np.zeros(4096)
            impulse[0] = 1.0
            gain = float(np.sqrt(np.sum(sosfilt(sos, impulse) ** 2)))  # white noise's RMS through the filter
        times, values, sig = [], [], []
        self.noise_source: dict[str, str] = {}  # channel -> where its noise floor came from
        t_sim = exp.time_s - self.offset0
        inside = (t_sim >= lo) & (t_sim <= hi)
        for c, a in zip(codes, acc):
            y = exp.channels[c][inside]
            times.append(exp.time_s[inside])
            if a and sos.shape[0]:
                values.append(sosfilt(sos, y))
            else:
                values.append(y)
            if sigma is not None:  # a window of a record: the whole record's noise floors, as they are
                sig.append(float(sigma[len(sig)]))
                self.noise_source[c] = "the whole record's"
                continue
            if c in exp.noise:  # [experiment] noise or noise_window_s: the channel's own unit, any kind
                s0 = exp.noise[c]
                self.noise_source[c] = exp.noise_source[c]
            elif noise_m is not None and not a:
                s0 = noise_m
                self.noise_source[c] = f"[calibrate] noise_m = {noise_m!r} m"
            else:
                s0 = noise_floor(y)[0]
                self.noise_source[c] = "estimated from the data by differences (an upper bound)"
                if noise_m is not None:
                    warn(
                        "calibration",
                        f"[calibrate] noise_m = {noise_m!r} m is a displacement's noise: acceleration channel "
                        f"{exp.columns[c]} ({c}) takes its noise from the data ({shown_value(c, s0)}); give it in "
                        "[experiment] noise (its own unit) or noise_window_s",
                    )
            sig.append(s0 * (gain if a else 1.0))
        self.target = Target(codes, acc, times, values, np.asarray(sig), sos)
        if sigma is None:  # the scene's own noise floors (a window's problem keeps the whole record's: said there)
            for message in at_noise_level(self.target, exp.columns, self.noise_source, self.window):
                warn("calibration", message)
        #: (fit coordinate, channel index) of each per-channel clock offset fitted
        self.channel_offsets = _channel_slots(self.names, codes)
        if window is None and self.channel_offsets:
            check_channel_offsets(self.prep, self.bounds)
        self.dt = self.prep.dt
        self._last: tuple[bytes, np.ndarray] | None = None  # the last residual vector fun() gave (its z)

    def restricted(self, window: tuple[float, float]) -> Problem:
        """This problem on the samples inside `window` (simulation time [s]) only, with this one's noise floors."""
        return Problem(self.scene, self.names, self.bounds, self.noise_m, self.threads, window, self.target.sigma)

    def times(self) -> np.ndarray:
        """Each residual's experiment time [s], in the residual vector's order (channel after channel)."""
        return np.concatenate(self.target.time_exp)

    def sizes(self) -> list[int]:
        return [v.size for v in self.target.values]

    # ------------------------------------------------------------------ coordinates
    def to_z(self, theta: np.ndarray) -> np.ndarray:
        return np.array([math.log(v) if is_log(n) else v for n, v in zip(self.names, theta)])

    def to_theta(self, z: np.ndarray) -> np.ndarray:
        return np.array([math.exp(v) if is_log(n) else v for n, v in zip(self.names, z)])

    @property
    def z_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        lo = self.to_z(np.array([self.bounds[n][0] for n in self.names]))
        hi = self.to_z(np.array([self.bounds[n][1] for n in self.names]))
        return lo, hi

    # ------------------------------------------------------------------ runs
    def params(self, thetas: np.ndarray, extra: dict | None = None) -> dict:
        """Grid-style parameters of len(thetas) runs: the scene's values with the fitted ones set."""
        n = thetas.shape[0]
        p = {k: np.repeat(v, n) for k, v in self.base.items()}
        p["run_id"] = np.arange(n)
        for j, name in enumerate(self.names):
            if channel_offset(name):  # a channel's clock: read by residuals(), no run changes
                continue
            p[name] = thetas[:, j].astype(float)
            if name == "ks_ratio":
                p["ks_N_per_m"] = np.full(n, np.nan)
            elif name == "ks_N_per_m":
                p["ks_ratio"] = np.full(n, np.nan)
        for k, v in (extra or {}).items():
            p[k] = np.asarray(v, dtype=object if k in ("law", "record") else float)
        return p

    def residuals(self, thetas: np.ndarray, extra: dict | None = None) -> np.ndarray:
        """(runs, N) noise-normalised residuals; a non-finite one (a run that diverged) counts as 1e6 noise floors,
        so that least squares stays finite and moves away."""
        thetas = np.atleast_2d(thetas)
        params = self.params(thetas, extra)
        hist = self._histories(params)
        self.evaluations += thetas.shape[0]
        T = self.target
        out = np.empty((thetas.shape[0], T.n))
        offsets = params["time_offset_s"] if "time_offset_s" in self.names else np.full(thetas.shape[0], self.offset0)
        own = np.zeros((thetas.shape[0], len(self.slots)))  # each channel's clock on top of the table's
        for j, c in self.channel_offsets:
            own[:, c] = thetas[:, j]
        for i in range(thetas.shape[0]):
            parts = []
            for c, slot in enumerate(self.slots):
                ts = T.time_exp[c] - offsets[i] - own[i, c]
                if T.acc[c]:
                    model = acceleration_at(self.sensor, hist[i, slot[0]], self.dt, ts, T.sos)
                else:
                    model = _hermite(hist[i, slot[0]], hist[i, slot[1]], self.dt, ts)
                parts.append((model - T.values[c]) / T.sigma[c])
            row = np.concatenate(parts)
            out[i] = np.where(np.isfinite(row), row, 1e6)
        return out

    def _histories(self, params: dict) -> np.ndarray:
        """The kept histories of the runs in `params`. Runs of distinct structures are groups the engine runs one
        after another (each on its own matrices: sweep/prepare.py), one thread each; here the groups are dealt
        out to the threads, each thread running its share as the engine would (the same kernel, the same
        numbers), so a batch of distinct structures (a design, a Jacobian) uses every thread."""
        groups = structure_groups(self.prep.scene, params)
        if len(self.prep.variants) > 4096:  # one cached model per distinct structure: bounded
            self.prep.variants.clear()
        if self.threads <= 1 or groups is None or len(groups) < 2:
            return self.prep.run(params, self.threads)[2]
        shares = [np.concatenate([g[1] for g in groups[k :: self.threads]]) for k in range(self.threads)]
        shares = [s for s in shares if s.size]

        def run(idx):
            return self.prep.run({k: v[idx] for k, v in params.items()}, 1)[2]

        with ThreadPoolExecutor(max_workers=len(shares)) as pool:
            parts = list(pool.map(run, shares))
        out = np.empty((params["run_id"].size,) + parts[0].shape[1:])
        for idx, h in zip(shares, parts):
            out[idx] = h
        return out

    # ------------------------------------------------------------------ least squares in the fit's coordinates
    def fun(self, z: np.ndarray) -> np.ndarray:
        """The residual vector at fit coordinates z (kept for jac at the same z)."""
        r = self.residuals(self.to_theta(z)[None, :])[0]
        self._last = (np.asarray(z, float).tobytes(), r)
        return r

    def jac(self, z: np.ndarray, free: np.ndarray | None = None) -> np.ndarray:
        """Forward-difference Jacobian of fun at z over the `free` coordinates (all by default), its p runs as one
        batch. Step: JAC_STEP times the coordinate's range, backward where forward would leave the bounds (as
        scipy's '2-point' with that absolute step)."""
        z = np.asarray(z, float)
        free = np.arange(z.size) if free is None else np.asarray(free)
        f0 = self._last[1] if self._last is not None and self._last[0] == z.tobytes() else self.fun(z)
        lo, hi = self.z_bounds
        zf = z[free]
        h = JAC_STEP * (hi - lo)[free]
        h = np.where(zf + h > hi[free], -h, h)  # backward at the upper bound
        Z = np.repeat(z[None, :], free.size, axis=0)
        Z[np.arange(free.size), free] += h
        h = Z[np.arange(free.size), free] - z[free]  # the step as represented
        R = self.residuals(np.array([self.to_theta(zz) for zz in Z]))
        return ((R - f0[None, :]) / h[:, None]).T


def _simulated(scene: Scene, bounds: dict, window: tuple[float, float] | None) -> tuple[Scene, float | None]:
    """The scene a Problem simulates, and the scored window's end when the simulation runs past it (else None).
    Its duration covers every sample's simulation time under the fitted clocks: within `window`, its end plus the
    largest shift they may make (time_offset_s from the scene's, plus the largest per-channel offset on top); on
    the whole record, with per-channel offsets, the record's duration plus that shift (a record's acceleration is
    0 past its end: model/records.py resample), the samples scored being those of the unshifted end."""
    fixed = dataclasses.replace(scene, sweep=())
    own = [b for n, bb in bounds.items() if channel_offset(n) for b in bb]
    shift = max((abs(b - scene.experiment.time_offset_s) for b in bounds.get("time_offset_s", ())), default=0.0)
    shift += max((abs(b) for b in own), default=0.0)
    if window is None:
        if not own:
            return fixed, None
        whole = prepare(fixed).excitation.max_duration_s
        end = whole + shift + 2.0 * scene.integration.dt_s
        return dataclasses.replace(fixed, excitation=dataclasses.replace(fixed.excitation, duration_s=end)), whole
    end = window[1] + shift + 2.0 * scene.integration.dt_s
    if scene.excitation.duration_s is None or end < scene.excitation.duration_s:
        fixed = dataclasses.replace(fixed, excitation=dataclasses.replace(fixed.excitation, duration_s=end))
    if scene.experiment.window_s is not None:  # the scored window inside the shortened simulation
        w0, w1 = scene.experiment.window_s
        w = (max(w0, window[0]), max(min(w1, window[1]), max(w0, window[0])))
        fixed = dataclasses.replace(fixed, experiment=dataclasses.replace(fixed.experiment, window_s=w))
    return fixed, None


def _channel_slots(names: list[str], codes: list[str]) -> list[tuple[int, int]]:
    """(fit coordinate, channel index among `codes`) of each per-channel clock offset among `names`."""
    out = []
    for j, n in enumerate(names):
        code = channel_offset(n)
        if code is None:
            continue
        if code not in codes:  # mapped, but weighed 0 ([experiment] weights): nothing to shift
            raise ConfigError(f"[calibrate] parameters.{n}: channel {code!r} is not fitted ([experiment] weights 0)")
        out.append((j, codes.index(code)))
    return out


def check_channel_offsets(prep: Prepared, bounds: dict) -> None:
    """ConfigError naming the key when a per-channel clock offset's bounds (time_offset_s_<channel>) reach beyond
    half the first (longest) period of the channel's building, its nominal structure.

    Why that bound: a floor's response is dominated by its first mode, nearly periodic; shifting one channel by a
    whole period T1 puts that mode back in phase, so the misfit over the shift has a minimum near every multiple
    of T1 and a fit with wider bounds can lock one or more periods off (issue 27 saw three). Within +/- T1 / 2 the
    first mode's phase has one best shift; the higher modes' side minima inside it are the global stage's to
    step over (its Sobol design spans the bounds). A larger lag is a clock to align before the fit (the import's
    cross-correlation: docs/how-to/import-real-sensor-data.md)."""
    buildings = prep.model.buildings
    for name, (lo, hi) in bounds.items():
        code = channel_offset(name)
        if code is None:
            continue
        b = building_floor(code)[0]
        half = 0.5 * float(buildings[b - 1].modes().period_s.max())
        if lo < -half or hi > half:
            raise ConfigError(
                f"[calibrate] parameters.{name} = [{lo:g}, {hi:g}]: reaches beyond half the first period of "
                f"building {b} ({half:.4g} s; first mode {0.5 / half:.4g} Hz): a shift of a whole period fits that "
                f"mode again, so the fit can lock a period off; bound it inside [-{half:.4g}, {half:.4g}] s, and "
                "align a larger lag before the fit (python -m pounding_sweep import)"
            )


def _hermite(u: np.ndarray, v: np.ndarray, dt: float, t: np.ndarray) -> np.ndarray:
    """Cubic Hermite interpolation of a displacement history u (velocity v) sampled at k dt, at times t; outside
    the history (a fitted offset moving a window sample past the run's ends): its end values."""
    n = u.size
    x = np.clip(t / dt, 0.0, n - 1)
    k = np.minimum(np.floor(x).astype(np.int64), n - 2)
    s = x - k
    h00 = (1 + 2 * s) * (1 - s) ** 2
    h10 = s * (1 - s) ** 2
    h01 = s * s * (3 - 2 * s)
    h11 = s * s * (s - 1)
    return h00 * u[k] + h10 * dt * v[k] + h01 * u[k + 1] + h11 * dt * v[k + 1]


def law_label(scene: Scene) -> str:
    """The contact law a fit is for: the scene's, or NO_CONTACT for one building."""
    return NO_CONTACT if scene.contact is None else scene.contact.law


def calibrate(scene: Scene, threads: int = 1, best_cell: dict | None = None, progress=None) -> list[Fit]:
    """Calibrate the scene's [calibrate] parameters: one Fit per law (the [sweep] law axis, else the scene's law)."""
    cal = scene.calibrate
    if scene.contact is None:  # one building: no contact, no law (its fit is labelled NO_CONTACT)
        return [_calibrate_one(scene, list(cal.parameters), threads, best_cell, progress)]
    laws = scene.axis_values("law") or (scene.contact.law,)
    fits = []
    for law in laws:
        names = [n for n in cal.parameters if not (law == "hertz" and n == "r")]
        s = dataclasses.replace(scene, contact=dataclasses.replace(scene.contact, law=law))
        fits.append(_calibrate_one(s, names, threads, best_cell if len(laws) == 1 else None, progress))
    if len(fits) > 1:
        compare_laws(fits, progress)
    return fits


def identified_starts(scene: Scene, names: list[str]) -> dict[str, float]:
    """Start values from [calibrate] start_from, identify's modes file (scene/starts.py), for the fitted names it
    speaks to: modal_damping_ratio_b<b>_m<j> mode j's identified damping ratio, damping_ratio_b<b> mode 1's (a
    NaN estimate gives none); stiffness_scale_b<b>, else every fitted story_stiffness_scale_b<b>_s<k>, the
    scene's value times c = (f1 identified / f1 of the scene's model)^2, the factor on every story that puts the
    model's first mode at the identified one (identify/update.py: K scaled by c scales every eigenvalue by c).
    Each value clipped into its bounds (an identified damping below 0, unreliable, starts at the lower bound)."""
    if scene.calibrate is None or scene.calibrate.start_from is None:
        return {}
    from pounding_sweep.model.coupled import CoupledModel
    from pounding_sweep.scene.starts import read_modes
    from pounding_sweep.sweep.prepare import structure_value

    modes = read_modes(scene.calibrate.start_from)
    frames = CoupledModel.from_scene(scene).buildings
    out: dict[str, float] = {}
    for b, m in modes.items():
        if b > len(frames):
            continue
        c = (m.frequencies_Hz[0] / float(frames[b - 1].modes().frequency_Hz[0])) ** 2
        scales = [f"stiffness_scale_b{b}"] if f"stiffness_scale_b{b}" in names else []
        scales = scales or [
            n for n in names if (f := member(n)) is not None and f[0].name == f"story_stiffness_scale_b{b}"
        ]
        for n in scales:
            out[n] = structure_value(scene, n) * c
        mode = {f"modal_damping_ratio_b{b}_m{j + 1}": j for j in range(len(m.damping_ratios))}  # name -> its mode
        mode[f"damping_ratio_b{b}"] = 0
        used = {n: m.damping_ratios[j] for n, j in mode.items() if n in names and math.isfinite(m.damping_ratios[j])}
        out |= used
        doubtful = [n for n in used if m.damping_reliable and not m.damping_reliable[mode[n]]]
        if doubtful:
            from pounding_sweep.warn import warn

            warn(
                "start_unreliable",
                f"[calibrate] start_from: {', '.join(f'{n} = {used[n]:.4g}' for n in doubtful)} start from damping "
                "identify does not trust (damping_reliable = false in the modes file; clipped into the bounds): "
                "a start, not a value",
            )
    bounds = scene.calibrate.parameters
    clipped = {n: float(min(max(v, bounds[n][0]), bounds[n][1])) for n, v in out.items()}
    # (an identified damping ratio outside its bounds is usual, and said above where identify doubts it)
    far = [n for n, v in out.items() if not bounds[n][0] <= v <= bounds[n][1] and "damping_ratio" not in n]
    if far:
        from pounding_sweep.warn import warn

        warn(
            "start_outside",
            f"[calibrate] start_from {scene.calibrate.start_from}: "
            + "; ".join(
                f"{n} = {out[n]:.4g} lies outside [calibrate] parameters.{n} = {list(bounds[n])} and starts "
                f"at {clipped[n]:.4g}"
                for n in far
            )
            + ": the identified first frequency and the scene's model disagree that much (the modes file's mode 1 "
            "is not this frame's first mode, or the model's masses or stiffness are far off)",
        )
    return clipped


def _start(scene: Scene, prob: Problem, best_cell: dict | None) -> tuple[dict | None, dict]:
    """The start point the global stage adds to its design (globalsearch.find_basin's best cell; with
    global_points = 0 the local fits' start): [calibrate] start_from's values where it gives one
    (identified_starts), the grid's best cell's for the rest, the scene's own values for what neither gives (a
    channel's clock offset: 0). Without start_from, the grid's best cell as it is (a channel offset it lacks at 0:
    the design ignores a cell that lacks a fitted name), but completed so with global_points = 0, where it is the
    one start (the grid has no column of a story's, a mode's or a channel's value). Returns (the point or None,
    {name: where its value came from}: empty for the grid's cell as it is)."""
    from pounding_sweep.sweep.prepare import structure_value

    ident = identified_starts(scene, prob.names)
    cell = dict(best_cell or {})
    cell |= {n: 0.0 for n in prob.names if channel_offset(n) and n not in cell}
    complete = all(n in cell for n in prob.names)
    if not ident and (complete or scene.calibrate.global_points > 0):
        return (cell or None), {}
    own = {}  # the scene's values of what the cell lacks (it holds every channel offset, at 0 where it had none)
    for n in prob.names:
        if n in cell:
            continue
        own[n] = float(prob.base[n][0]) if n in prob.base else structure_value(scene, n)
    start = {**own, **cell, **ident}
    grid = best_cell or {}
    source = {n: "start_from" if n in ident else "grid" if n in grid else "scene" for n in prob.names}
    return start, source


def _calibrate_one(
    scene: Scene, names: list[str], threads: int, best_cell: dict | None, progress, again: tuple | None = None
) -> Fit:
    """One law's fit. `again` = (search, note, runs, seconds, start point, its source): the fit continued from a
    lower residual its first pass's profile found (_lower_profile_point), not searched again."""
    cal = scene.calibrate
    t0 = time.perf_counter()
    prob = Problem(scene, names, cal.parameters, cal.noise_m, threads)
    lo, hi = prob.z_bounds
    p = len(names)
    if again is None:
        start, start_source = _start(scene, prob, best_cell)
        search = find_basin(prob, cal, start, progress)
    else:  # the continued fit: started where the first pass's profile went lower
        search, start = again[0], again[4]
        start_source = {n: again[5] for n in names}
    z_opt = search.z
    theta = prob.to_theta(z_opt)
    r = search.result.fun
    N = r.size
    rss = float(r @ r)
    sizes = prob.sizes()
    gn = gauss_newton(search.result.jac, r, sizes, p)
    estimate, std_error, ci = {}, {}, {}
    for j, n in enumerate(names):
        estimate[n] = float(theta[j])
        std_error[n] = float(theta[j] * gn.se_z[j]) if is_log(n) else float(gn.se_z[j])  # delta method
        ci[n] = interval(prob, j, z_opt[j] - gn.tq * gn.se_z[j], z_opt[j] + gn.tq * gn.se_z[j])

    # per channel
    ends = np.cumsum([0] + sizes)
    rms_m, noise, err_pct = {}, {}, []
    for c, code in enumerate(prob.target.codes):
        rc = r[ends[c] : ends[c + 1]] * prob.target.sigma[c]
        yc = prob.target.values[c]
        rms_m[code] = float(np.sqrt(np.mean(rc * rc)))
        noise[code] = float(prob.target.sigma[c])
        err_pct.append(100.0 * rms_m[code] / float(np.sqrt(np.mean(yc * yc))))
    misfit = misfit_of(r, sizes)

    fit = Fit(
        law_label(scene),
        names,
        prob.bounds,
        estimate,
        std_error,
        ci,
        gn.corr,
        rss,
        N,
        gn.n_eff,
        gn.rho,
        rms_m,
        noise,
        misfit,
        float(np.mean(err_pct)),
        0,
        0.0,
        z_opt=z_opt,
        residuals=r,
        sizes=sizes,
        search=search.stages,
        start={n: {"value": float(start[n]), "from": w} for n, w in start_source.items()} if start else {},
        problem=prob,
    )
    # profiles (first: a lower point one finds moves the fit, and everything below is made again there)
    profiled = (list(cal.profile) or default_profiled(names)) if cal.profile_points > 0 else []
    s2_eff = gn.s2 * N / gn.n_eff
    for n in profiled:
        j = names.index(n)
        fit.profiles[n] = _profile(prob, n, z_opt, lo, hi, cal, s2_eff, rss, gn.se_z[j])
    lower = _lower_profile_point(fit, prob)
    if lower is not None and again is None:  # the search missed a basin: go on from the profile's point
        name, row, z_from = lower
        res = local_fit(prob, z_from, cal.max_evals)
        if 2.0 * res.cost < rss:
            note = (
                f"{fit_label(fit.law)}: the search's optimum was not the global one: the profile of {name} found a "
                f"residual lower by delta chi^2 {-row['delta_chi2']:.3g} at {name} = {row['value']:.4g}; the fit "
                f"went on from there (residual {fit.misfit_ratio:.3g} -> {misfit_of(res.fun, sizes):.3g} times the "
                "noise floor)"
            )
            if progress is not None:
                progress(f"{fit_label(fit.law)}: a profile found a lower residual; the fit goes on from there")
            stages = search.stages + [{"profile_restart": name, "value": row["value"], "misfit": fit.misfit_ratio}]
            moved = Search(res.z, res, stages, search.restarted)
            point = dict(zip(names, prob.to_theta(z_from)))
            done = (moved, note, prob.evaluations, time.perf_counter() - t0, point, f"the profile of {name}")
            return _calibrate_one(scene, names, threads, best_cell, progress, done)
    if misfit > cal.misfit_factor:  # the model cannot explain the data: a sign fault the fit bent around is
        fit.warnings += reversed_channel_warnings(fit)  # named (sweep/fitchecks.py); intervals with its error
        model_error_intervals(fit, prob, cal.max_evals)
        if progress is not None:
            progress(f"{fit_label(law_label(scene))}: model-error intervals from {len(fit.windows)} windows")
    if again is not None:
        fit.warnings.insert(0, again[1])
    if lower is not None:  # still (the fit from there went no lower, or this is the continued fit)
        name, row, _z = lower
        fit.warnings.append(
            f"{fit_label(fit.law)}: the profile of {name} found a residual lower than the optimum's by delta chi^2 "
            f"{-row['delta_chi2']:.3g} at {name} = {row['value']:.4g}, and the fit went no further: the optimum may "
            "not be the global one; the intervals are around it"
        )
    _identify(fit)
    _step_error(fit, scene, prob, theta)
    _warnings(fit, z_opt, lo, hi, cal)
    fit.evaluations = prob.evaluations + (again[2] if again is not None else 0)
    fit.seconds = time.perf_counter() - t0 + (again[3] if again is not None else 0.0)
    return fit


def _lower_profile_point(fit: Fit, prob: Problem) -> tuple[str, dict, np.ndarray] | None:
    """The profile point whose residual is below the optimum's by more than CHI2_1_95 (a value the data prefer to
    the optimum, not a rounding of it), the lowest of them: (its parameter, its row, its fit coordinates); None
    when there is none. A profile refits the other parameters with one fixed, so it reaches basins the search's
    starts may have missed (on a bound, say)."""
    best = None
    for name, rows in fit.profiles.items():
        for row in rows:
            if row["delta_chi2"] < -CHI2_1_95 and (best is None or row["rss"] < best[1]["rss"]):
                best = (name, row)
    if best is None:
        return None
    name, row = best
    theta = np.array([row["value"] if n == name else row[f"fit_{n}"] for n in prob.names])
    return name, row, prob.to_z(theta)


def _profile(prob: Problem, name, z_opt, lo, hi, cal, s2_eff, rss_opt, se) -> list[dict]:
    """The profile of `name`: fixed on a ladder over its bounds, and at the optimum +/- 1, 2 and 4 standard
    errors (where the 95 % profile interval lies when the parameter is identified), the rest refitted."""
    j = prob.names.index(name)
    free = [i for i in range(len(prob.names)) if i != j]
    near = z_opt[j] + np.array([-4, -2, -1, 0, 1, 2, 4]) * (se if np.isfinite(se) else 0.0)
    near = near[np.isfinite(near)]
    ladder = np.unique(np.clip(np.append(np.linspace(lo[j], hi[j], cal.profile_points), near), lo[j], hi[j]))
    rows = []
    for zj in ladder:
        z = z_opt.copy()
        z[j] = zj
        if free:
            res = local_fit(prob, z, max(20, cal.max_evals // 4), free=free)
            z = res.z
            rss = 2.0 * res.cost
        else:
            rr = prob.fun(z)
            rss = float(rr @ rr)
        theta = prob.to_theta(z)
        rows.append(
            {
                "value": float(theta[j]),
                "rss": float(rss),
                "delta_chi2": float((rss - rss_opt) / s2_eff),
                **{f"fit_{n}": float(theta[i]) for i, n in enumerate(prob.names) if i != j},
            }
        )
    return rows


def _identify(fit: Fit) -> None:
    """Per profiled parameter: the range the data cannot exclude, and whether that identifies it (judged in the
    fit's coordinate: log for stiffnesses)."""
    for name, rows in fit.profiles.items():
        fwd, back = (math.log, math.exp) if is_log(name) else (float, float)
        rows = sorted(rows, key=lambda r: r["value"])
        x = np.array([fwd(r["value"]) for r in rows])
        y = np.array([r["delta_chi2"] for r in rows])
        za, zb = _crossings(x, y, fwd(fit.estimate[name]))
        zlo, zhi = fwd(fit.bounds[name][0]), fwd(fit.bounds[name][1])
        touches_both = za - zlo <= 1e-9 * (zhi - zlo) and zhi - zb <= 1e-9 * (zhi - zlo)
        ok = not touches_both and (zb - za) / (zhi - zlo) <= 0.5
        fit.identified[name] = (ok, back(za), back(zb))


def _crossings(x: np.ndarray, y: np.ndarray, x_opt: float) -> tuple[float, float]:
    """Where a profile y(x) (delta chi^2 on an ascending ladder x) crosses CHI2_1_95 on either side of x_opt:
    linear interpolation between ladder points; the ladder's end where it stays below."""
    i0 = int(np.argmin(np.abs(x - x_opt)))
    ends = []
    for step in (-1, 1):
        i = i0
        while 0 <= i + step < x.size and y[i + step] <= CHI2_1_95:
            i += step
        if 0 <= i + step < x.size:  # crosses between i and i + step
            w = (CHI2_1_95 - y[i]) / (y[i + step] - y[i]) if y[i + step] != y[i] else 0.0
            ends.append(x[i] + max(0.0, min(1.0, w)) * (x[i + step] - x[i]))
        else:
            ends.append(x[i])
    return ends[0], ends[1]


def _warnings(fit: Fit, z_opt, lo, hi, cal) -> None:
    who = fit_label(fit.law)
    for n, side in zip(fit.names, on_bound(z_opt, lo, hi)):
        if side:
            b = fit.bounds[n][0 if side < 0 else 1]
            fit.warnings.append(
                f"{who}: {n} = {fit.estimate[n]:.4g} is on its {'lower' if side < 0 else 'upper'} "
                f"bound {b:g}: the data want a value outside the bounds, or the model cannot fit them; widen the "
                "bound or check the model"
            )
    if fit.misfit_ratio > cal.misfit_factor:
        fit.warnings.append(
            f"{who}: the best fit's residual is {fit.misfit_ratio:.1f} times the noise floor "
            f"({', '.join(f'{c} {shown_value(c, fit.rms_m[c])} vs {shown_value(c, fit.noise_m[c])}' for c in fit.rms_m)}): "
            "the model cannot explain the data; the fitted values are not to be trusted as measurements"
        )
    if fit.quote == "model_error":
        nw = len(fit.windows)

        def quoted(n, a, b):
            vals = [w[n] for w in fit.windows if w.get(f"identified_{n}")]
            if len(vals) < 2:
                why = f"the bounds: {len(vals)} of {nw} windows identify it, 2 are needed"
            else:
                j = fit.names.index(n)
                z = np.log([a, b]) if is_log(n) else np.array([a, b])
                sides = on_bound(z, np.full(2, lo[j]), np.full(2, hi[j]))
                ends = [e for e, hit in (("lower", sides[0] < 0), ("upper", sides[1] > 0)) if hit]
                clipped = f"; clipped at the {' and '.join(ends)} bound{'s' if len(ends) > 1 else ''}" if ends else ""
                why = f"{len(vals)} windows: {min(vals):.4g} .. {max(vals):.4g}{clipped}"
            return f"{n} {fit.estimate[n]:.4g} in [{a:.4g}, {b:.4g}] ({why})"

        fit.warnings.append(
            f"{who}: intervals with the model's error (fits of {nw} windows of the record; "
            "quote these, not the noise-based ones): "
            + ", ".join(quoted(n, a, b) for n, (a, b) in fit.ci95_model.items())
        )
    for n, (ok, a, b) in fit.identified.items():
        if not ok:
            fit.warnings.append(
                f"{who}: {n} is not identified by this data: any value in [{a:.4g}, {b:.4g}] fits "
                "within the noise (profile likelihood, 95 %)"
            )
    for w in fit.warnings:
        warn("calibration", w)


def compare_laws(fits: list[Fit], progress=None):
    """Compare the calibrated laws on one basis (sweep/lawcompare.py), keep the answer on every fit
    (Fit.comparison), and warn when the data cannot decide."""
    cal = fits[0].problem.scene.calibrate
    cmp = compare_on_one_basis(fits, cal.max_evals)
    for f in fits:
        f.comparison = cmp
    if progress is not None:
        progress(f"calibration: laws compared ({cmp.evaluations} runs of cross-validation)")
    if cmp.chosen is None:
        warn("calibration", f"calibration: {cmp.text}")
    return cmp


def fit_table(fits: list[Fit]):
    """One row per law and parameter: estimate, standard error, 95 % interval (noise-based; with the model error
    where the misfit called for it, and which to quote), bounds, identification."""
    import pandas as pd

    rows = []
    for f in fits:
        for n in f.names:
            ok, a, b = f.identified.get(n, (True, math.nan, math.nan))
            ma, mb = f.ci95_model.get(n, (math.nan, math.nan))
            rows.append(
                {
                    "contact_law": f.law,
                    "parameter": n,
                    "estimate": f.estimate[n],
                    "std_error": f.std_error[n],
                    "ci95_low": f.ci95[n][0],
                    "ci95_high": f.ci95[n][1],
                    "ci95_model_low": ma,
                    "ci95_model_high": mb,
                    # the windows behind ci95_model that identify the parameter (fewer than 2: it is the bounds)
                    "model_error_windows_identifying": sum(bool(w.get(f"identified_{n}")) for w in f.windows),
                    "quote": f.quote,
                    "lower_bound": f.bounds[n][0],
                    "upper_bound": f.bounds[n][1],
                    "identified": ok,
                    "profile_low": a,
                    "profile_high": b,
                }
            )
    return pd.DataFrame(rows)


def _step_error(fit: Fit, scene: Scene, prob: Problem, theta: np.ndarray) -> None:
    """The fitted run's integration error per channel (fitchecks.step_error: the same problem at half the step), and
    a warning where it is a named part of the residual. Not with dt_s = 'auto' (its own tolerance per run)."""
    if scene.integration.auto:
        return
    integ = dataclasses.replace(scene.integration, dt_s=0.5 * scene.integration.dt_s)
    half = Problem(dataclasses.replace(scene, integration=integ), prob.names, prob.bounds, prob.noise_m,
                   prob.threads, None, prob.target.sigma)  # fmt: skip
    order = 1 if scene.integration.scheme == "paper" else 2  # the paper's scheme is explicit in the force
    fit.step_error = step_error(prob, half, theta, order)
    said = step_error_warning(fit, scene.integration.dt_s, scene.calibrate.misfit_factor)
    if said is not None:
        fit.warnings.append(said)


def law_table(fits: list[Fit]):
    """One row per law: the error at its optimum, the noise floor ratio, AIC and BIC on the common effective count
    and their differences, the held-out (cross-validated) residual and its Diebold-Mariano z against the best
    (sweep/lawcompare.py), whether the law is among those the data cannot tell apart."""
    import pandas as pd

    cmp = fits[0].comparison
    nc, aic, bic = information_criteria(fits)
    rows = []
    for f in fits:
        row = {
            "contact_law": f.law,
            "parameters": len(f.names),
            "rel_rms_pct": f.error_pct,
            "misfit_over_noise": f.misfit_ratio,
            # the fitted run's integration error (by halving the step) over the noise floor, its worst channel
            "step_error_over_noise": max((e / f.noise_m[c] for c, e in f.step_error.items()), default=np.nan),
            "n_samples": f.n,
            "n_effective": f.n_eff,
            "evaluations": f.evaluations,
            "seconds": f.seconds,
        }
        row |= {
            "aic": aic[f.law],
            "bic": bic[f.law],
            "delta_aic": aic[f.law] - min(aic.values()),
            "delta_bic": bic[f.law] - min(bic.values()),
            "n_effective_common": nc,
        }
        if cmp is not None:
            row |= {
                "cv_rss": cmp.cv_rss[f.law],
                "cv_dm_z": cmp.cv_z[f.law],
                "chosen": cmp.chosen == f.law,
                "candidate": f.law in cmp.candidates,
            }
        rows.append(row)
    return pd.DataFrame(rows)


def calibration_rows(fits: list[Fit]) -> list[dict]:
    """The best table's rows of a calibration: criterion 'calibrated' (one per law), its error and optimum."""
    return [{"criterion": "calibrated", "contact_law": f.law, "error_pct": f.error_pct, **f.estimate} for f in fits]


def calibration_metadata(fits: list[Fit]) -> dict:
    """Everything a calibration found, as plain data for the best table's metadata (read_calibration)."""
    return {
        "fits": fit_table(fits).to_dict("records"),
        "laws": law_table(fits).to_dict("records"),
        "profiles": profile_table(fits).to_dict("records"),
        "per_law": {
            f.law: {
                "parameters": f.names,
                "correlation": np.where(np.isfinite(f.correlation), f.correlation, None).tolist(),
                # each channel under its unit's key: displacements [m], accelerations [m/s^2]
                **{
                    f"{what}_{unit}": {c: v for c, v in values.items() if channel_unit(c)[1] == unit}
                    for what, values in (
                        ("noise_floor", f.noise_m),
                        ("rms_residual", f.rms_m),
                        ("step_error", f.step_error),
                    )
                    for unit in ("m", "m_s2")
                },
                "misfit_over_noise": f.misfit_ratio,
                "n_samples": f.n,
                "n_effective": f.n_eff,
                "lag1_autocorrelation": f.rho,
                "warnings": f.warnings,
                "quote": f.quote,
                "model_error_windows": f.windows,
                "global_stage": f.search,
                **({"start": f.start} if f.start else {}),
            }
            for f in fits
        },
        **({"comparison": _comparison_record(fits[0].comparison)} if fits[0].comparison is not None else {}),
    }


def _comparison_record(cmp) -> dict:
    """The law comparison as plain data (the best table's metadata)."""
    return {
        "text": cmp.text,
        "chosen": cmp.chosen,
        "candidates": cmp.candidates,
        "best": cmp.best,
        "tied": cmp.tied,
        "n_effective_common": cmp.n_eff_common,
        "folds_s": cmp.folds,
    }


def read_calibration(best_path) -> dict:
    """The calibration stored in a sweep's best table: {'fits', 'laws', 'profiles'} DataFrames and 'per_law'."""
    import pandas as pd

    from pounding_sweep.sweep.results import read_metadata

    md = read_metadata(best_path).get("calibration")
    if md is None:
        raise KeyError(f"{best_path}: holds no calibration (the scene had no [calibrate])")
    return {k: pd.DataFrame(md[k]) for k in ("fits", "laws", "profiles")} | {
        "per_law": md["per_law"],
        "comparison": md.get("comparison"),
    }


def profile_table(fits: list[Fit]):
    import pandas as pd

    rows = []
    for f in fits:
        for n, prof in f.profiles.items():
            for r in prof:
                rows.append({"contact_law": f.law, "parameter": n, **r})
    return pd.DataFrame(rows)
