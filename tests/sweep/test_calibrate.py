"""Calibration (sweep/calibrate.py) and the structure as sweep axes.

* Structure axes: a grid over stiffness scales runs each structure on its own matrices, bit-identical to the
  perturbed scene run alone.
* The noise floor estimator on signals of known noise.
* Recovery: on a synthetic experiment with the structure perturbed, the contact parameters and the structure
  come back, where the contact-only fit is pulled off.
* Coverage: over 50 noise seeds the 95 % intervals cover the hidden values at about the stated rate, with
  white and with correlated (AR(1)) noise.
* Warnings fire where they should (a bound, a misfit far above the noise, a parameter the data cannot
  decide) and not on a good fit.
"""

from __future__ import annotations

import dataclasses
import functools
import math

import numpy as np
import pytest
from conftest import SWEEPS

from pounding_sweep.errors import ConfigError
from pounding_sweep.model.experiment import noise_floor
from pounding_sweep.scene import load_scene
from pounding_sweep.scene.schema import Axis, CalibrateConfig, ExperimentConfig
from pounding_sweep.sweep.calibrate import calibrate
from pounding_sweep.sweep.prepare import prepare, with_structure
from pounding_sweep.synthetic import make_experiment, write_experiment
from pounding_sweep.warn import collecting

CHANNELS = {"model1_floor3_mm": "b1f3", "model2_floor3_mm": "b2f3"}


@functools.cache
def scene_6hz(duration_s: float):
    s = load_scene(SWEEPS / "paper_6hz.toml")
    return dataclasses.replace(s, excitation=dataclasses.replace(s.excitation, duration_s=duration_s), sweep=())


def _scored(scene, table, **cal):
    exp = ExperimentConfig(table=str(table), channels=CHANNELS)
    return dataclasses.replace(scene, experiment=exp, calibrate=CalibrateConfig(**cal) if cal else None)


# ----------------------------------------------------------------------------- structure axes


def test_a_grid_over_the_structure_equals_each_structure_run_alone():
    s = scene_6hz(0.5)
    grid = dataclasses.replace(
        s, sweep=(Axis("stiffness_scale_b1", (0.97, 1.0, 1.03)), Axis("damping_ratio_b2", (0.01, 0.02)))
    )
    prep = prepare(grid)
    params = prep.grid.chunk(0, prep.grid.size)
    metrics, *_ = prep.run(params)
    for i in range(prep.grid.size):
        one = with_structure(
            s,
            {"stiffness_scale_b1": params["stiffness_scale_b1"][i], "damping_ratio_b2": params["damping_ratio_b2"][i]},
        )
        p1 = prepare(one)
        m1, *_ = p1.run(p1.grid.chunk(0, 1))
        np.testing.assert_array_equal(m1[0], metrics[i])  # the same kernel on the same matrices
    assert len({tuple(m) for m in metrics}) == prep.grid.size  # every structure gave its own answer


@pytest.mark.parametrize(
    "sweep, words",
    [
        ("stiffness_scale_b1 = [0.0, 1.0]", "stiffness_scale_b1 = 0.0"),
        ("damping_ratio_b2 = [0.01, 1.5]", "damping_ratio_b2 = 1.5"),
        ("time_offset_s = [0.0, 0.01]", "no [experiment]"),
    ],
)
def test_bad_structure_axes(tmp_path, sweep, words):
    text = (SWEEPS / "paper_6hz.toml").read_text().replace("r = [0.2, 0.4, 0.6, 0.8, 1.0]", sweep)
    (tmp_path / "s.toml").write_text(text)
    with pytest.raises(ConfigError) as e:
        load_scene(tmp_path / "s.toml")
    assert words in str(e.value)


@pytest.mark.parametrize(
    "block, words",
    [
        ("parameters = { ks_ratio = [0.1, 10], law = [1, 2] }", "parameters.law: not a parameter"),
        ('parameters = { ks_ratio = "wide" }', "expected a number"),
        ("parameters = { ks_ratio = [10, 0.1] }", "low < high"),
        ("parameters = { r = [0.1, 1.5] }", "lies in [0, 1]"),
        ("parameters = { ks_ratio = [0.1, 10], ks_N_per_m = [1e3, 1e5] }", "one form of the contact stiffness"),
        ('parameters = { r = [0.1, 0.9] }\nprofile = ["ks_ratio"]', "'ks_ratio' is not among the fitted"),
    ],
)
def test_bad_calibrate_sections(tmp_path, block, words):
    text = (SWEEPS / "scored_6hz.toml").read_text().replace(
        '"experiments/', f'"{SWEEPS}/experiments/'
    ) + f"\n[calibrate]\n{block}\n"
    (tmp_path / "s.toml").write_text(text)
    with pytest.raises(ConfigError) as e:
        load_scene(tmp_path / "s.toml")
    assert words in str(e.value), str(e.value)


def test_calibrate_needs_an_experiment(tmp_path):
    text = (SWEEPS / "paper_6hz.toml").read_text() + "\n[calibrate]\nparameters = { r = [0.1, 0.9] }\n"
    (tmp_path / "s.toml").write_text(text)
    with pytest.raises(ConfigError, match="no \\[experiment\\]"):
        load_scene(tmp_path / "s.toml")


# ----------------------------------------------------------------------------- the noise floor


@pytest.mark.parametrize("f_hz", [1.0, 6.0])
def test_the_noise_floor_of_a_smooth_signal_with_white_noise(f_hz):
    """A 5 mm sine sampled at 100 Hz plus 0.05 mm of white noise: the estimate lies within 10 % of 0.05 mm (the
    median absolute deviation of 5000 samples has a relative standard error of about 1.1 / sqrt(5000 / 2) ~ 2 %
    per difference order; the signal left in the 6th difference at 6 Hz is (2 sin(pi 0.06))^6 5 mm / sqrt(924)
    = 5e-4 mm)."""
    rng = np.random.default_rng(1)
    t = np.arange(5000) / 100.0
    y = 5e-3 * np.sin(2 * np.pi * f_hz * t) + rng.normal(0, 5e-5, t.size)
    assert noise_floor(y)[0] == pytest.approx(5e-5, rel=0.1)


# ----------------------------------------------------------------------------- fits


def _experiment(tmp_path, scene, hidden, name="exp", **kw):
    df, prov = make_experiment(scene, hidden, **kw)
    path = tmp_path / f"{name}.parquet"
    write_experiment(df, prov, path)
    return path


PERTURBED = dict(stiffness_factor=(1.02, 0.975), damping_factor=(1.0, 1.0), dt_s=1e-4, seed=3)
HIDDEN = {"ks_ratio": 3.0, "r": 0.5}


@functools.cache
def _perturbed_fits(tmp_path_factory_dir):
    from pathlib import Path

    tmp = Path(tmp_path_factory_dir)
    s = scene_6hz(1.5)
    table = _experiment(tmp, s, HIDDEN, **PERTURBED)
    contact = {"ks_ratio": [0.1, 20.0], "r": [0.05, 1.0]}
    both = {**contact, "stiffness_scale_b1": [0.9, 1.1], "stiffness_scale_b2": [0.9, 1.1]}
    out = {}
    for key, params in (("contact", contact), ("both", both)):
        with collecting() as notes:
            fit = calibrate(_scored(s, table, parameters=params, global_points=16, starts=2, profile_points=5), 2)[0]
        out[key] = (fit, notes.messages())
    return out


@pytest.fixture(scope="module")
def perturbed_fits(tmp_path_factory):
    return _perturbed_fits(str(tmp_path_factory.mktemp("cal")))


def test_fitting_the_structure_recovers_contact_and_stiffness(perturbed_fits):
    """Stiffness +2 % / -2.5 % hidden in the experiment: fitted with the structure, k_s/k and r come back within
    2 % and the scales within 0.2 %, each inside its 95 % interval, with no warning; the residual is at the noise
    floor (the noise floor estimate is an upper bound: below 1.5 times it)."""
    fit, warnings = perturbed_fits["both"]
    print(f"\n[calibrate with structure] {fit.estimate}, intervals {fit.ci95}, misfit {fit.misfit_ratio:.2f}")
    assert fit.estimate["ks_ratio"] == pytest.approx(3.0, rel=0.02)
    assert fit.estimate["r"] == pytest.approx(0.5, rel=0.02)
    assert fit.estimate["stiffness_scale_b1"] == pytest.approx(1.02, rel=2e-3)
    assert fit.estimate["stiffness_scale_b2"] == pytest.approx(0.975, rel=2e-3)
    truth = {**HIDDEN, "stiffness_scale_b1": 1.02, "stiffness_scale_b2": 0.975}
    for n, v in truth.items():
        lo, hi = fit.ci95[n]
        assert lo <= v <= hi, (n, v, lo, hi)
    assert fit.misfit_ratio < 1.5
    assert all(ok for ok, _, _ in fit.identified.values())
    assert warnings == []


def test_a_contact_only_fit_of_the_same_data_is_pulled_off_and_says_so(perturbed_fits):
    """The same data fitted over (k_s/k, r) alone: the structure's error goes into the contact parameters and
    the residual stays well above the noise (and so its misfit ratio is larger than with the structure)."""
    c, _ = perturbed_fits["contact"]
    b, _ = perturbed_fits["both"]
    print(f"\n[contact only] {c.estimate}, misfit {c.misfit_ratio:.2f}; with structure misfit {b.misfit_ratio:.2f}")
    assert c.misfit_ratio > 2 * b.misfit_ratio
    assert c.rho > b.rho  # structured residuals: the signature of model error


# ----------------------------------------------------------------------------- warnings


def test_a_bound_that_excludes_the_truth_is_said(tmp_path):
    s = scene_6hz(1.0)
    table = _experiment(tmp_path, s, HIDDEN, stiffness_factor=(1.0, 1.0), damping_factor=(1.0, 1.0), dt_s=1e-4)
    with collecting() as notes:
        calibrate(_scored(s, table, parameters={"ks_ratio": [0.1, 20.0], "r": [0.6, 1.0]}, global_points=8), 2)
    msgs = notes.messages()
    assert any("r = 0.6 is on its lower bound 0.6" in m for m in msgs), msgs


def test_a_model_that_cannot_explain_the_data_is_said(tmp_path):
    """A 6 % stiffness error left out of the fit: the residual is many times the noise floor."""
    s = scene_6hz(1.0)
    table = _experiment(tmp_path, s, HIDDEN, stiffness_factor=(1.06, 0.94), damping_factor=(1.0, 1.0), dt_s=1e-4)
    with collecting() as notes:
        calibrate(_scored(s, table, parameters={"ks_ratio": [0.1, 20.0], "r": [0.05, 1.0]}, global_points=8), 2)
    assert any("the model cannot explain the data" in m for m in notes.messages()), notes.messages()


def test_a_parameter_the_data_cannot_decide_is_said(tmp_path):
    """A 50 mm gap the buildings never close: k_s/k and r change nothing, and the profiles say so."""
    s = dataclasses.replace(scene_6hz(1.0), contact=dataclasses.replace(scene_6hz(1.0).contact, gap_m=0.05))
    table = _experiment(tmp_path, s, HIDDEN, stiffness_factor=(1.0, 1.0), damping_factor=(1.0, 1.0), dt_s=1e-4)
    with collecting() as notes:
        fits = calibrate(
            _scored(
                s, table, parameters={"ks_ratio": [0.1, 20.0], "r": [0.05, 1.0]}, global_points=4, profile_points=5
            ),
            2,
        )
    assert not fits[0].identified["ks_ratio"][0] and not fits[0].identified["r"][0]
    assert sum("is not identified by this data" in m for m in notes.messages()) == 2


# ----------------------------------------------------------------------------- coverage


def _coverage(tmp_path, rho: float, seeds: int = 50):
    """Share of seeds whose 95 % intervals cover the hidden k_s/k and r: no model error (truth simulated as the
    fit simulates), so the intervals' only job is the noise (white, or AR(1) with lag-1 correlation rho)."""
    s = scene_6hz(1.0)
    covered = {"ks_ratio": 0, "r": 0}
    truth_run = None
    for seed in range(seeds):
        df, prov = make_experiment(
            s, HIDDEN, stiffness_factor=(1.0, 1.0), damping_factor=(1.0, 1.0), dt_s=1e-4, seed=seed, noise_rho=rho
        )
        if truth_run is None:
            truth_run = df
        path = tmp_path / f"c{seed}.parquet"
        write_experiment(df, prov, path)
        fit = calibrate(
            _scored(
                s,
                path,
                parameters={"ks_ratio": [0.5, 20.0], "r": [0.05, 1.0]},
                global_points=0,
                starts=1,
                profile_points=0,
                noise_m=5e-5,
            ),
            2,
        )[0]
        for n in covered:
            lo, hi = fit.ci95[n]
            covered[n] += lo <= HIDDEN[n] <= hi
    return {n: c / seeds for n, c in covered.items()}


@pytest.mark.parametrize("rho", [0.0, 0.7])
def test_the_95_percent_intervals_cover_the_truth_over_50_noise_seeds(tmp_path, rho):
    """Coverage at least 0.86 per parameter: with a true rate of 0.95, 50 seeds fall below 0.86 with probability
    about 1 % (binomial); intervals that ignored the noise's correlation (rho = 0.7: N / N_eff ~ 5.7, intervals
    2.4 times too narrow) cover about 0.55."""
    cov = _coverage(tmp_path, rho)
    print(f"\n[coverage, noise lag-1 correlation {rho}] {cov}")
    for n, c in cov.items():
        assert c >= 0.86, (n, c)


def test_the_shipped_calibration_scene_runs_end_to_end(tmp_path):
    """sweeps/calibrate_6hz.toml through run_scene: the best table gains a 'calibrated' row and the metadata the
    full answer (read_calibration)."""
    from pounding_sweep.sweep.calibrate import read_calibration
    from pounding_sweep.sweep.run import run_scene

    s = load_scene(SWEEPS / "calibrate_6hz.toml")
    s = dataclasses.replace(
        s,
        excitation=dataclasses.replace(s.excitation, duration_s=1.0),
        calibrate=dataclasses.replace(s.calibrate, global_points=8, starts=1, profile_points=3),
    )
    summary = run_scene(s, tmp_path / "out.parquet", threads=2)
    assert "calibrated" in set(summary.best.criterion)
    got = read_calibration(summary.best_path)
    assert set(got["fits"].parameter) == set(s.calibrate.parameters)
    assert math.isfinite(got["laws"].aic.iloc[0])


def test_acceleration_channels_enter_the_calibration_filtered_like_the_kernel(tmp_path):
    """A synthetic test with top-floor accelerometers (500 samples/s, 0.05 m/s^2 noise) and displacements, the
    stiffness perturbed: calibrated on both, through the experiment's 30 Hz low-pass filter, the hidden values
    come back (k_s/k and r within 3 %, the scales within 0.3 %), and the fit's residual is at the noise floor."""
    s = scene_6hz(1.0)
    df, prov = make_experiment(
        s, HIDDEN, stiffness_factor=(1.02, 0.975), damping_factor=(1.0, 1.0), dt_s=1e-4, fps=500.0, acc_noise_m_s2=0.05
    )
    path = tmp_path / "acc.parquet"
    write_experiment(df, prov, path)
    exp = ExperimentConfig(
        table=str(path),
        channels={**CHANNELS, "b1f3_acc": "abs_acc_b1f3", "b2f3_acc": "abs_acc_b2f3"},
        acc_units="m/s2",
        lowpass_Hz=30.0,
        use="both",
    )
    params = {
        "ks_ratio": [0.1, 20.0],
        "r": [0.05, 1.0],
        "stiffness_scale_b1": [0.9, 1.1],
        "stiffness_scale_b2": [0.9, 1.1],
    }
    scene = dataclasses.replace(
        s, experiment=exp, calibrate=CalibrateConfig(parameters=params, global_points=16, starts=2, profile_points=0)
    )
    fit = calibrate(scene, 2)[0]
    print(
        f"\n[calibrate on displacement and acceleration] {fit.estimate}, misfit {fit.misfit_ratio:.2f}, noise {fit.noise_m}"
    )
    assert set(fit.noise_m) == {"b1f3", "b2f3", "abs_acc_b1f3", "abs_acc_b2f3"}
    assert fit.estimate["ks_ratio"] == pytest.approx(3.0, rel=0.03)
    assert fit.estimate["r"] == pytest.approx(0.5, rel=0.03)
    assert fit.estimate["stiffness_scale_b1"] == pytest.approx(1.02, rel=3e-3)
    assert fit.estimate["stiffness_scale_b2"] == pytest.approx(0.975, rel=3e-3)
    assert fit.misfit_ratio < 1.5


def test_calibrate_with_an_automatic_time_step_is_one_error(tmp_path):
    text = (SWEEPS / "scored_6hz.toml").read_text().replace('"experiments/', f'"{SWEEPS}/experiments/')
    text = text.replace("dt_s = 1e-4", 'dt_s = "auto"') + "\n[calibrate]\nparameters = { r = [0.1, 0.9] }\n"
    (tmp_path / "s.toml").write_text(text)
    with pytest.raises(ConfigError, match="dt_s = 'auto'"):
        load_scene(tmp_path / "s.toml")
