"""The accelerometer model ([experiment] sensor_filter, sweep/sensor.py): its filters against plain-Python
loops on the same inputs, its 'average' against the synthetic generator's own MEMS model, the sweep's scores
with it against a slow computation from the run's full history, and a small calibration with it on."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from conftest import SWEEPS
from scipy.signal import butter, sosfilt
from tolerances import U, filtered_samples_bound, interpolation_bound, rel_rms_bound, sos_rounding_bound

from pounding_sweep.errors import ExperimentError
from pounding_sweep.scene import load_scene
from pounding_sweep.scene.schema import CalibrateConfig, ExperimentConfig
from pounding_sweep.sweep.calibrate import calibrate
from pounding_sweep.sweep.prepare import prepare
from pounding_sweep.sweep.sensor import Sensor, sensor_model
from pounding_sweep.sweep.simulate import simulate
from pounding_sweep.synthetic import butter_samples, make_ivp_experiment, mems_samples, write_experiment
from pounding_sweep.warn import collecting

DISP = {"model1_floor3_mm": "b1f3", "model2_floor3_mm": "b2f3"}
ACC = {"b1f3_acc": "abs_acc_b1f3", "b2f3_acc": "abs_acc_b2f3"}


def _history(seed: int, dt: float, t_end: float) -> np.ndarray:
    """An acceleration history at every step: a few modes and short spikes (impacts), from rest."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, t_end + dt / 2, dt)
    a = sum(rng.normal() * np.sin(2 * np.pi * f * t) for f in (3.0, 17.0, 71.0, 240.0))
    for t0 in rng.uniform(0.1, t_end - 0.1, 6):  # 5 ms half-sine spikes
        a += 40.0 * np.where(np.abs(t - t0) < 2.5e-3, np.cos(np.pi * (t - t0) / 5e-3), 0.0)
    return a


def _linear(a: np.ndarray, dt: float, tau: float) -> float:
    """The step history at time tau by a plain linear interpolation; 0 before t = 0 (at rest)."""
    if tau < 0.0:
        return 0.0
    x = tau / dt
    k = min(int(math.floor(x)), a.size - 2)
    w = x - k
    return float(a[k] + w * (a[k + 1] - a[k]))


def _slow_average(a, dt, t, rate, taps):
    """Each output: the plain mean of the taps internal samples at t_m - j / rate, j = 0..taps-1."""
    return np.array([sum(_linear(a, dt, tm - j / rate) for j in range(taps)) / taps for tm in t])


def _slow_biquads(sos, x):
    """The cascade of second-order sections, each by its difference equation in direct form I, from rest."""
    y = list(x)
    for b0, b1, b2, _, a1, a2 in sos:
        out, x1, x2, y1, y2 = [], 0.0, 0.0, 0.0, 0.0
        for xn in y:
            yn = b0 * xn + b1 * x1 + b2 * x2 - a1 * y1 - a2 * y2
            out.append(yn)
            x1, x2, y1, y2 = xn, x1, yn, y1
        y = out
    return np.array(y)


def _internal_samples_bound(a, dt, t_end, taps=1):
    """|difference| of two computations of the same internal samples: each is a linear interpolation of the step
    history at an instant rounded differently (tolerances.interpolation_bound, with the instant t_m - j / rate
    computed in two ways: its own few u t_end, inside the (t_end / dt + 3) u term), then an average of `taps` of
    them (a sum of taps terms, at most taps u of its largest, Higham Lemma 3.1; 1/taps rounded: u more)."""
    return interpolation_bound(a, t_end, dt) + (taps + 1) * U * np.abs(a).max()


@pytest.mark.parametrize("offset", [0.0, 0.00437])
def test_the_average_is_a_plain_mean_of_internal_samples(offset):
    """'average' at 1 kHz, output at 100 samples/s (10 taps) on the table's instants, which sit off the simulation
    steps by `offset`: equal to a plain-Python mean of linearly interpolated internal samples, within the bound
    of both computations' rounding."""
    dt, t_end = 1e-4, 3.0
    a = _history(1, dt, t_end)
    t = np.arange(0.0, 2.95, 0.01) + offset
    got = Sensor("average", 1000.0, 10).read(a, dt, t)
    ref = _slow_average(a, dt, t, 1000.0, 10)
    bound = 2 * _internal_samples_bound(a, dt, t_end, 10)
    print(f"\n[average] max |difference| {np.abs(got - ref).max():.2e}, bound {bound:.2e}")
    assert np.abs(got - ref).max() <= bound
    # and it is not the plain sample: the spikes are spread over 10 ms
    assert np.abs(got - np.interp(t, np.arange(a.size) * dt, a)).max() > 1.0


def test_the_average_is_the_synthetic_generators_mems_model():
    """On a history given at the sensor's own internal instants (dt = 1 ms), the 'average' sensor and the
    synthetic generator's mems_samples (its own cumulative-sum code) give the same outputs: a cumulative sum's
    difference loses up to 2 L u of the running sum (L internal samples, Higham Lemma 3.1) against lfilter's
    taps u of the largest term."""
    dt = 1e-3
    a = _history(2, dt, 3.0)
    t_fine = np.arange(a.size) * dt
    t_out, want = mems_samples(t_fine, a, 100.0, 1000.0)
    got = Sensor("average", 1000.0, 10).read(a, dt, t_out)
    bound = 2 * a.size * U * np.abs(np.cumsum(np.abs(a))).max() / 10 + 2 * _internal_samples_bound(a, dt, 3.0, 10)
    assert np.abs(got - want).max() <= bound


def test_the_butterworth_is_the_synthetic_generators_butterworth():
    """On a history at the sensor's internal instants, 'butter' and the generator's butter_samples (the same
    sections through scipy, every 10th output kept) agree up to reading the output at indices computed in floating
    point: (L + 3) u relative per index, times the output's largest change between samples."""
    dt = 1e-3
    a = _history(4, dt, 3.0)
    t_fine = np.arange(a.size) * dt
    t_out, want = butter_samples(t_fine, a, 100.0, 1000.0, 2, 44.0)
    got = Sensor("butter", 1000.0, 1, 44.0, 2).read(a, dt, t_out)
    y = sosfilt(butter(2, 44.0, output="sos", fs=1000.0), a)
    bound = 2 * (a.size + 3) * U * np.abs(np.diff(y)).max() + 4 * U * np.abs(y).max()
    assert np.abs(got - want).max() <= bound


@pytest.mark.parametrize("rate, order, cutoff", [(1000.0, 2, 100.0), (1000.0, 4, 44.0), (None, 2, 94.0)])
def test_the_butterworth_is_its_difference_equations(rate, order, cutoff):
    """'butter' at the sensor's internal rate (or, without one, at the simulation step: analog), read at the
    table's instants: equal to the same sections run as plain-Python difference equations on plain-Python
    internal samples, within the filter's gain on the samples' rounding plus both filterings' own rounding
    (tolerances.filtered_samples_bound)."""
    dt, t_end = 1e-4, 2.0
    a = _history(3, dt, t_end)
    t = np.arange(0.0, 1.95, 0.01) + 0.00213
    s = Sensor("butter", rate, 1, cutoff, order)
    got = s.read(a, dt, t)
    fs = rate if rate is not None else 1.0 / dt
    sos = butter(order, cutoff, output="sos", fs=fs)
    h = 1.0 / fs
    first = -math.floor(t[0] / h)
    n = math.ceil((t[-1] - t[0]) / h) + 1
    tau = [t[0] + j * h for j in range(first, n)]
    x = np.array([_linear(a, dt, v) for v in tau])
    y = _slow_biquads(sos, x)
    ref = np.array([_linear(y, h, tm - tau[0]) for tm in t])
    bound = filtered_samples_bound(sos, x, _internal_samples_bound(a, dt, t_end)) + sos_rounding_bound(sos, x)
    bound += 4 * (t_end / h + 3) * U * np.abs(np.diff(y)).max()  # reading y between its samples, two ways
    print(
        f"\n[butter {rate} Hz, {order} poles, {cutoff} Hz] max |difference| {np.abs(got - ref).max():.2e}, bound {bound:.2e}"
    )
    assert np.abs(got - ref).max() <= bound


def test_the_sensor_must_fit_the_table():
    """An 'average' rate that is no whole multiple of the table's rate, or an analog cut-off above the step's
    Nyquist frequency: an ExperimentError naming the key and value."""
    x = ExperimentConfig(table="t.csv", channels=ACC, sensor_filter="average", sensor_rate_Hz=1050.0)
    with pytest.raises(
        ExperimentError, match=r"sensor_rate_Hz = 1050.0: not a whole multiple of the rate 100 samples/s"
    ):
        sensor_model(x, 0.01, 1e-4)
    assert sensor_model(dataclasses.replace(x, sensor_rate_Hz=1000.0), 0.01, 1e-4).taps == 10
    b = ExperimentConfig(table="t.csv", channels=ACC, sensor_filter="butter", sensor_cutoff_Hz=6000.0)
    with pytest.raises(ExperimentError, match=r"sensor_cutoff_Hz = 6000.0: at or above the Nyquist frequency 5000 Hz"):
        sensor_model(b, 0.01, 1e-4)


# ----------------------------------------------------------------------------- the sweep's scores


@pytest.fixture(scope="module")
def ivp_case(tmp_path_factory):
    """A 2 s, 6 Hz test made by the solve_ivp reference (classic law, k_s/k 3, r 0.5), top-floor accelerometers
    averaging 10 samples at 1 kHz, 100 samples/s, 0.02 m/s^2 noise; displacements 0.05 mm noise."""
    s = load_scene(SWEEPS / "paper_6hz.toml")
    s = dataclasses.replace(s, sweep=(), excitation=dataclasses.replace(s.excitation, duration_s=2.0))
    df, prov = make_ivp_experiment(s, {"ks_ratio": 3.0, "r": 0.5, "law": "classic"}, acc_noise_m_s2=0.02, seed=3)
    path = tmp_path_factory.mktemp("sensor") / "ivp.parquet"
    write_experiment(df, prov, path)
    return s, path


def _with(s, path, **kw):
    noise = {"model1_floor3_mm": 0.05, "model2_floor3_mm": 0.05, "b1f3_acc": 0.02, "b2f3_acc": 0.02}  # as made
    exp = ExperimentConfig(table=str(path), channels={**DISP, **ACC}, use="both", weights="noise", noise=noise, **kw)
    return dataclasses.replace(s, experiment=exp)


@pytest.mark.parametrize("lowpass", [None, 30.0])
def test_sweep_scores_through_the_sensor_match_a_slow_computation(ivp_case, lowpass):
    """simulate (the sweep's path, Prepared.run -> run_sensed) with the 'average' sensor: each acceleration
    channel's eq. 20 error equals one computed here from the run's full abs_acc history through the plain-Python
    average (and the experiment's low-pass filter), within the bound of both computations' rounding; the
    displacement channels' scores and the histories asked for (every 5th step) are the kernel's own, unchanged.
    At the hidden values the sensed error is a tenth of the plain sampling's or less."""
    s, path = ivp_case
    sensed = _with(s, path, sensor_filter="average", sensor_rate_Hz=1000.0, lowpass_Hz=lowpass)
    plain = _with(s, path, lowpass_Hz=lowpass)
    spec = prepare(sensed).score
    full, _ = simulate(plain, channels=["abs_acc_b1f3", "abs_acc_b2f3"], ks_ratio=3.0, r=0.5)
    h_plain, m_plain = simulate(plain, channels=["disp_b1f3", "abs_acc_b2f3"], decimate=5, ks_ratio=3.0, r=0.5)
    h_sensed, m = simulate(sensed, channels=["disp_b1f3", "abs_acc_b2f3"], decimate=5, ks_ratio=3.0, r=0.5)
    assert h_sensed.equals(h_plain)
    for code in ("b1f3", "b2f3"):
        assert m[f"rel_rms_{code}_pct"] == m_plain[f"rel_rms_{code}_pct"]
    for c, code in ((2, "b1f3"), (3, "b2f3")):
        a = full[f"abs_acc_{code}_m_s2"].to_numpy()
        xs = _slow_average(a, 1e-4, spec.t, 1000.0, 10)
        if lowpass:
            xs = _slow_biquads(spec.sos, xs)
        xe = spec.x[c]
        rel = 100.0 * np.sqrt(np.mean((xs - xe) ** 2)) / np.sqrt(np.mean(xe**2))
        d = filtered_samples_bound(spec.sos, xs, 2 * _internal_samples_bound(a, 1e-4, 2.0, 10))
        if lowpass:
            d += sos_rounding_bound(spec.sos, xs)  # the plain-Python cascade's own rounding
        got = m[f"rel_rms_abs_acc_{code}_pct"]
        print(
            f"\n[sensed score {code}, lowpass {lowpass}] {got:.6f} % vs slow {rel:.6f} %, unsensed {m_plain[f'rel_rms_abs_acc_{code}_pct']:.3f} %"
        )
        assert abs(got - rel) <= rel_rms_bound(d, xe, rel)
        assert got < 0.1 * m_plain[f"rel_rms_abs_acc_{code}_pct"]  # at the hidden values the sensor explains the data


def test_a_small_calibration_with_the_sensor_reaches_the_noise_floor(ivp_case):
    """Calibrated on displacement and both accelerometers (noise weights), k_s/k, r and both stiffness scales:
    with the sensor modelled the residual is at the noise floor (misfit < 1.5) and the hidden k_s/k and r come
    back within 5 %; without it the accelerations misfit at several times their noise (the issue's 5-11x)."""
    s, path = ivp_case
    params = {"ks_ratio": [0.5, 10.0], "r": [0.1, 0.95], "stiffness_scale_b1": [0.95, 1.05]}
    cal = CalibrateConfig(parameters=params, global_points=16, starts=1, profile_points=0)
    fits = {}
    for name, kw in (("sensor", {"sensor_filter": "average", "sensor_rate_Hz": 1000.0}), ("plain", {})):
        with collecting():  # the plain fit's misfit warning is expected
            fits[name] = calibrate(dataclasses.replace(_with(s, path, **kw), calibrate=cal), 2)[0]
        f = fits[name]
        print(
            f"\n[calibration, {name}] {f.estimate}, misfit {f.misfit_ratio:.2f}, {f.evaluations} runs, {f.seconds:.1f} s"
        )
    f = fits["sensor"]
    assert f.misfit_ratio < 1.5
    assert f.estimate["ks_ratio"] == pytest.approx(3.0, rel=0.05)
    assert f.estimate["r"] == pytest.approx(0.5, rel=0.05)
    assert fits["plain"].misfit_ratio > 3.0


def test_the_results_say_which_sensor(ivp_case):
    """The result metadata's experiment facts name the sensor and its settings (sweep/run.py)."""
    from pounding_sweep.sweep.run import _acceleration_facts

    s, path = ivp_case
    facts = _acceleration_facts(prepare(_with(s, path, sensor_filter="butter", sensor_cutoff_Hz=44.0)))
    assert facts["sensor"]["kind"] == "butter" and facts["sensor"]["rate_Hz"] is None
    assert "simulation step (analog)" in facts["sensor"]["what"]
    assert "sensor" not in _acceleration_facts(prepare(_with(s, path)))


def test_the_figures_read_the_model_through_the_sensor(ivp_case):
    """plots.measured_residuals (the measured-against-model and sub-space figures) reads an acceleration channel
    through the scene's sensor, on the same stride-1 history and at the same instants as the sweep's scoring
    (run_sensed): its eq. 20 error is the scored one, exactly; without the sensor the figures would show an error
    ten times the one the results report."""
    pytest.importorskip("matplotlib", reason="plots need the 'plot' extra (matplotlib)")
    from pounding_sweep import plots
    from pounding_sweep.engine.score import relative_rms_error_pct

    s, path = ivp_case
    sensed = _with(s, path, sensor_filter="average", sensor_rate_Hz=1000.0)
    pick = {"ks_ratio": 3.0, "r": 0.5}
    _, m = simulate(sensed, channels=["abs_acc_b1f3"], **pick)
    drawn = plots.measured_residuals(sensed, pick, {})
    plain = plots.measured_residuals(_with(s, path), pick, {})
    for code in ("abs_acc_b1f3", "abs_acc_b2f3"):
        _t, xe, xm, res = drawn[code]
        assert relative_rms_error_pct(xm, xe) == m[f"rel_rms_{code}_pct"]
        np.testing.assert_array_equal(res, xe - xm)
        _t, xe_p, xm_p, _ = plain[code]
        assert relative_rms_error_pct(xm_p, xe_p) > 10 * relative_rms_error_pct(xm, xe)
