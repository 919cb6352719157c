"""Noise in each channel's own unit (issue 27 item 6): [experiment] noise (per column, in its units) and
noise_window_s (measured in a quiet stretch) are honoured for displacement and acceleration channels alike, by
the calibration's residual scale and by 'noise' weights; messages and metadata keys name each channel's unit."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from conftest import SWEEPS
from scipy.signal import sosfilt

from pounding_sweep.errors import ConfigError, ExperimentError
from pounding_sweep.scene import load_scene
from pounding_sweep.scene.schema import CalibrateConfig, ExperimentConfig
from pounding_sweep.sweep.calibrate import Fit, Problem, _warnings, calibration_metadata
from pounding_sweep.sweep.prepare import prepare
from pounding_sweep.synthetic import make_experiment, write_experiment

CHANNELS = {"model1_floor3_mm": "b1f3", "b1f3_acc": "abs_acc_b1f3"}


@pytest.fixture(scope="module")
def table(tmp_path_factory):
    s = load_scene(SWEEPS / "paper_6hz.toml")
    s = dataclasses.replace(s, excitation=dataclasses.replace(s.excitation, duration_s=1.0), sweep=())
    df, prov = make_experiment(s, {"ks_ratio": 3.0, "r": 0.5}, dt_s=1e-4, fps=500.0, acc_noise_m_s2=0.05)
    path = tmp_path_factory.mktemp("noise") / "acc.parquet"
    write_experiment(df, prov, path)
    return s, path, df


def _scene(s, path, **exp):
    x = ExperimentConfig(table=str(path), channels=CHANNELS, acc_units="m/s2", lowpass_Hz=50.0, **exp)
    return dataclasses.replace(s, experiment=x, calibrate=CalibrateConfig(parameters={"r": [0.1, 0.9]}))


def test_a_given_noise_is_honoured_for_every_channel_in_its_own_unit(table):
    s, path, _ = table
    scene = _scene(s, path, noise={"model1_floor3_mm": 0.05, "b1f3_acc": 0.07}, weights="noise")
    prob = Problem(scene, ["r"], {"r": (0.1, 0.9)}, noise_m=None)
    sos = prob.target.sos
    gain = float(np.sqrt(np.sum(sosfilt(sos, np.r_[1.0, np.zeros(4095)]) ** 2)))
    # 0.05 mm is 5e-5 m; 0.07 m/s^2 through the filter's noise gain
    assert prob.target.sigma.tolist() == pytest.approx([5e-5, 0.07 * gain], rel=1e-12)
    assert prob.noise_source["abs_acc_b1f3"] == "[experiment] noise.b1f3_acc = 0.07 m/s2"
    comb = prepare(scene).combination
    assert comb.noise["abs_acc_b1f3"]["unit"] == "m/s^2" and comb.noise["b1f3"]["unit"] == "m"
    assert comb.noise["abs_acc_b1f3"]["noise_floor_raw"] == pytest.approx(0.07)


def test_noise_measured_in_a_quiet_window(table):
    s, path, df = table
    scene = _scene(s, path, noise_window_s=(0.0, 0.2))
    exp = prepare(scene).experiment
    t = df["t_s"].to_numpy()
    w = (t >= 0.0) & (t <= 0.2)
    assert exp.noise["abs_acc_b1f3"] == pytest.approx(np.std(df["b1f3_acc"].to_numpy()[w], ddof=1), rel=1e-12)
    assert exp.noise_source["b1f3"] == "standard deviation in noise_window_s = [0, 0.2] s"
    with pytest.raises(ExperimentError, match=r"noise_window_s = \[5.0, 6.0\]: holds 0 sample"):
        prepare(_scene(s, path, noise_window_s=(5.0, 6.0)))


def test_noise_m_on_an_acceleration_channel_says_it_is_not_used(table, recwarn):
    s, path, _ = table
    Problem(_scene(s, path), ["r"], {"r": (0.1, 0.9)}, noise_m=5e-5)
    msgs = [str(w.message) for w in recwarn]
    assert any("noise_m = 5e-05 m is a displacement's noise: acceleration channel b1f3_acc" in m for m in msgs)


def test_a_noise_for_an_unmapped_column_is_refused(tmp_path):
    text = (SWEEPS / "scored_6hz.toml").read_text().replace('"experiments/', f'"{SWEEPS}/experiments/')
    text = text.replace("[experiment]\n", "[experiment]\nnoise = { nope = 0.1 }\n", 1)
    (tmp_path / "s.toml").write_text(text)
    with pytest.raises(ConfigError, match="noise.nope = 0.1: 'nope' is not a mapped channel"):
        load_scene(tmp_path / "s.toml")


def test_the_misfit_warning_and_metadata_name_each_channel_in_its_unit():
    fit = Fit(
        "classic",
        ["r"],
        {"r": (0.1, 0.9)},
        {"r": 0.5},
        {"r": 0.01},
        {"r": (0.48, 0.52)},
        np.eye(1),
        100.0,
        10,
        5.0,
        0.3,
        {"b1f3": 2e-3, "abs_acc_b1f3": 1.387},
        {"b1f3": 1e-4, "abs_acc_b1f3": 0.0249},
        30.0,
        5.0,
        1,
        0.1,
    )
    with pytest.warns(UserWarning, match="times the noise floor"):
        _warnings(fit, np.array([0.5]), np.array([0.1]), np.array([0.9]), CalibrateConfig(parameters={"r": [0.1, 0.9]}))
    (w,) = [w for w in fit.warnings if "noise floor" in w]
    assert "b1f3 2 mm vs 0.1 mm" in w and "abs_acc_b1f3 1.387 m/s^2 vs 0.0249 m/s^2" in w
    md = calibration_metadata([fit])["per_law"]["classic"]
    assert md["noise_floor_m"] == {"b1f3": 1e-4} and md["noise_floor_m_s2"] == {"abs_acc_b1f3": 0.0249}
    assert md["rms_residual_m_s2"] == {"abs_acc_b1f3": 1.387}
