"""Per-channel clock offsets, fitted (issue 27 item 2: unsynchronised sensors): [calibrate] time_offset_s_<channel>
shifts one channel's samples on top of the table's time_offset_s. An experiment made by the engine with one floor's
sensor 40 ms late is fitted to its noise with the channel's offset and recovers the lag and the structure within
their intervals, where without it the fit is biased and misfits by two orders; names, bounds and the simulated
length are checked."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pandas as pd
import pytest
from conftest import SWEEPS

from pounding_sweep.errors import ConfigError
from pounding_sweep.scene import load_scene, validate
from pounding_sweep.scene.parameters import channel_offset, member, parameter
from pounding_sweep.scene.schema import CalibrateConfig, ExperimentConfig
from pounding_sweep.sweep.calibrate import Problem, calibrate, calibration_metadata
from pounding_sweep.sweep.simulate import simulate
from pounding_sweep.warn import collecting

HIDDEN = {"stiffness_scale_b1": 1.03, "damping_ratio_b1": 0.012}
LAG_S = 0.040  # floor 3's sensor records 40 ms late (its clock behind the others')
NOISE = 0.01  # m/s^2, white, on every sensor (the real Xsens DOTs measure 0.008-0.015 in their quiet lead-in)
FS = 120.0  # the IMUs' rate: 40 ms is 4.8 samples, not a whole number of them
CHANNELS = {f"b1f{f}_acc": f"abs_acc_b1f{f}" for f in (1, 2, 3)}


def _scene():
    """The shipped real-data scene (one 3-story frame driven by the Northridge table record), its first 8 s."""
    s = load_scene(SWEEPS / "real_northridge.toml")
    return dataclasses.replace(
        s, sweep=(), excitation=dataclasses.replace(s.excitation, duration_s=8.0), calibrate=None, experiment=None
    )


@pytest.fixture(scope="module")
def delayed(tmp_path_factory):
    """The scene's own run at HIDDEN (its dt, its linear interpolation between steps: no model error), each floor's
    absolute acceleration sampled at FS plus NOISE, floor 3's at t - LAG_S."""
    s = _scene()
    hist, _ = simulate(s, channels=list(CHANNELS.values()), **HIDDEN)
    th = hist.t_s.to_numpy()
    t = np.arange(0.0, th[-1], 1.0 / FS)
    rng = np.random.default_rng(7)
    df = pd.DataFrame({"t_s": t})
    for col, code in CHANNELS.items():
        lag = LAG_S if code == "abs_acc_b1f3" else 0.0
        df[col] = np.interp(t - lag, th, hist[f"{code}_m_s2"].to_numpy()) + rng.normal(0.0, NOISE, t.size)
    path = tmp_path_factory.mktemp("offsets") / "delayed.parquet"
    df.to_parquet(path)
    exp = ExperimentConfig(table=str(path), channels=CHANNELS, use="acceleration", noise=dict.fromkeys(CHANNELS, NOISE))
    return dataclasses.replace(s, experiment=exp)


def _fit(scene, parameters: dict):
    cal = CalibrateConfig(parameters=parameters, global_points=16, starts=2, profile_points=0)
    scene = dataclasses.replace(scene, calibrate=cal)
    validate(scene)
    with collecting():
        return calibrate(scene, 2)[0]


STRUCTURE = {"stiffness_scale_b1": [0.8, 1.2], "damping_ratio_b1": [0.001, 0.05]}


def test_the_fitted_offset_of_a_late_sensor_recovers_its_lag(delayed):
    """Without the channel's offset the fit bends the structure to the late sensor (misfit > 50 noise floors, the
    truth outside its intervals); with it the misfit is the noise's (within 1.5 of it: the residual RMS of white
    noise over N = 2877 samples is within a few 1/sqrt(2N) of 1) and every value is its truth to its noise."""
    plain = _fit(delayed, STRUCTURE)
    assert plain.misfit_ratio > 50.0
    name = "time_offset_s_abs_acc_b1f3"
    fit = _fit(delayed, {**STRUCTURE, name: [-0.06, 0.06]})
    for f in (plain, fit):
        print(f"\n{f.estimate}, intervals {f.ci95}, misfit {f.misfit_ratio:.3f}, rel RMS {f.error_pct:.2f} %")
    assert fit.misfit_ratio < 1.5
    for n, truth in {**HIDDEN, name: LAG_S}.items():  # within 4 standard errors (one noise draw in 10^4 misses)
        assert abs(fit.estimate[n] - truth) <= 4 * fit.std_error[n], (n, truth, fit.estimate[n], fit.std_error[n])
    assert not any(lo <= HIDDEN["stiffness_scale_b1"] <= hi for lo, hi in [plain.ci95["stiffness_scale_b1"]])
    row = {r["parameter"]: r for r in calibration_metadata([fit])["fits"]}[name]  # reported like any fitted value
    assert row["ci95_low"] <= row["estimate"] <= row["ci95_high"] and row["std_error"] > 0


def test_a_channel_offset_is_its_own_family():
    assert channel_offset("time_offset_s_abs_acc_b1f3") == "abs_acc_b1f3" and channel_offset("time_offset_s") is None
    assert parameter("time_offset_s_b2f1").unit == "s" and member("time_offset_s_b2f1") is None  # not a structure


def test_the_simulation_runs_on_past_the_record_for_the_shifted_samples(delayed):
    """A channel's samples near the record's end, shifted by up to the bound, still read the simulation (not its
    held end value): the simulated span is the record's plus the largest shift; the scored samples are the same."""
    bounds = {"time_offset_s_abs_acc_b1f3": (-0.05, 0.05)}
    with collecting():
        plain = Problem(delayed, [], {}, None)
        prob = Problem(delayed, list(bounds), bounds, None)
    assert prob.prep.excitation.max_duration_s >= plain.prep.excitation.max_duration_s + 0.05
    assert prob.sizes() == plain.sizes()


@pytest.mark.parametrize(
    ("parameters", "message"),
    [
        ({"time_offset_s_abs_acc_b1f4": [-0.01, 0.01]}, "maps no channel 'abs_acc_b1f4'"),
        ({"time_offset_s_b1f3": [-0.01, 0.01]}, "maps no channel 'b1f3'"),
        (
            {f"time_offset_s_{c}": [-0.01, 0.01] for c in CHANNELS.values()} | {"time_offset_s": [-0.01, 0.01]},
            "asks the data for one number twice",
        ),
    ],
)
def test_a_channel_offset_names_a_fitted_channel(delayed, parameters, message):
    scene = dataclasses.replace(delayed, calibrate=CalibrateConfig(parameters=parameters))
    with pytest.raises(ConfigError, match=message) as e:
        validate(scene)
    assert f"[calibrate] parameters.{next(iter(parameters))}" in str(e.value)


def test_an_offset_wider_than_half_the_first_period_is_refused(delayed):
    """Bounds of +/- 0.1 s reach past half the frame's first period (7.7 Hz nominal: 65 ms), where a shift of one
    period puts the first mode back in phase: refused, the limit named, before any run."""
    name = "time_offset_s_abs_acc_b1f3"
    scene = dataclasses.replace(delayed, calibrate=CalibrateConfig(parameters={name: [-0.1, 0.1]}))
    validate(scene)
    with collecting(), pytest.raises(ConfigError, match=r"half the first period of building 1 \(0\.06\d+ s") as e:
        Problem(scene, [name], {name: (-0.1, 0.1)}, None)
    assert f"[calibrate] parameters.{name} = [-0.1, 0.1]" in str(e.value)


def test_the_figures_show_the_fitted_frame_and_clock(delayed, tmp_path):
    """The measured-against-model figure re-simulates the calibrated run with every fitted value: the per-story
    factors set in the building (not run parameters) and the late channel's own clock applied, so its residuals are
    the calibration's, up to the rounding of two interpolations (tolerances.interpolation_bound) and of two RMS
    sums ((N + 2) u relative each)."""
    pytest.importorskip("matplotlib")
    from tolerances import U, interpolation_bound

    from pounding_sweep import plots
    from pounding_sweep.sweep.calibrate import NO_CONTACT, read_calibration
    from pounding_sweep.sweep.results import read_metadata
    from pounding_sweep.sweep.run import run_scene

    fitted = {f"story_stiffness_scale_b1_s{k}": [0.8, 1.2] for k in (1, 2, 3)}
    fitted |= {"damping_ratio_b1": [0.001, 0.05], "time_offset_s_abs_acc_b1f3": [-0.06, 0.06]}
    cal = CalibrateConfig(parameters=fitted, global_points=16, starts=1, profile_points=0)
    scene = dataclasses.replace(delayed, calibrate=cal)
    out = tmp_path / "frame.parquet"
    with collecting():
        run_scene(scene, out_path=out)
    best_path = out.with_name("frame.best.parquet")
    pick, label = plots.calibrated_run(pd.read_parquet(best_path))
    assert set(fitted) <= set(pick) and "time_offset_s_abs_acc_b1f3 = 0.04" in label
    with collecting():  # the table's check names the late channel again
        data = plots.measured_residuals(scene, pick, read_metadata(out))
    stored = read_calibration(best_path)["per_law"][NO_CONTACT]["rms_residual_m_s2"]
    for code, (t, _, xm, res) in data.items():
        rms = float(np.sqrt(np.mean(res * res)))
        bound = interpolation_bound(xm, t[-1], scene.integration.dt_s) + 2 * (res.size + 2) * U * rms
        assert abs(rms - stored[code]) <= bound, (code, rms, stored[code])
        assert rms < 2 * NOISE  # the late channel too: its clock applied


def test_a_real_sensor_delayed_is_found_by_its_clock(tmp_path):
    """The REAL Northridge test (the shipped table, its first 8 s): floor 3's samples moved 5 samples later (41.67
    ms at 120.005 Hz, no interpolation), fitted with floor 3's clock beside the walkthrough's stiffness, damping and
    table clock, as is the untouched table: the two clocks differ by the delay within their combined standard
    errors (4 of them: the model's error is the same in both fits, so it cancels in the difference; the noise
    floors' does not), and the delayed fit's misfit returns to within 5 % of the clean one's."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    s = load_scene(SWEEPS / "real_northridge.toml")
    s = dataclasses.replace(s, sweep=(), excitation=dataclasses.replace(s.excitation, duration_s=8.0))
    table = pq.read_table(s.experiment.table)
    cols = {n: table.column(n).to_numpy() for n in table.column_names}
    y = cols["b1f3_acc_m_s2"]
    cols["b1f3_acc_m_s2"] = np.r_[y[:5], y[:-5]]
    delay = 5 * float(np.median(np.diff(cols["t_s"])))
    late = tmp_path / "late.parquet"
    pq.write_table(pa.table(cols).replace_schema_metadata(table.schema.metadata), late)
    name = "time_offset_s_abs_acc_b1f3"
    parameters = {**s.calibrate.parameters, name: [-0.06, 0.06]}
    fits = []
    for path in (s.experiment.table, str(late)):
        scene = dataclasses.replace(s, experiment=dataclasses.replace(s.experiment, table=path))
        fits.append(_fit(scene, parameters))
    clean, moved = fits
    print(
        f"\nclock {clean.estimate[name]:.5f} -> {moved.estimate[name]:.5f} s; misfit {clean.misfit_ratio:.1f} -> "
        f"{moved.misfit_ratio:.1f}"
    )
    diff = moved.estimate[name] - clean.estimate[name]
    assert abs(diff - delay) <= 4 * math.hypot(clean.std_error[name], moved.std_error[name])
    assert moved.misfit_ratio <= 1.05 * clean.misfit_ratio


def test_with_no_global_stage_the_scene_is_the_start(delayed):
    """global_points = 0 and no grid cell: the one local start is the scene's own values, a story factor's 1 and a
    channel's clock 0 among them (the grid's parameters hold neither: the start was looked up there and failed)."""
    cal = CalibrateConfig(
        parameters={"story_stiffness_scale_b1_s2": [0.8, 1.2], "time_offset_s_abs_acc_b1f3": [-0.06, 0.06]},
        global_points=0,
        starts=1,
        max_evals=20,
        profile_points=0,
    )
    scene = dataclasses.replace(delayed, calibrate=cal)
    validate(scene)
    with collecting():
        fit = calibrate(scene, 2)[0]
    assert fit.start == {
        "story_stiffness_scale_b1_s2": {"value": 1.0, "from": "scene"},
        "time_offset_s_abs_acc_b1f3": {"value": 0.0, "from": "scene"},
    }
