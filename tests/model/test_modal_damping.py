"""Damping from one ratio per mode ([buildingN] modal_damping_ratios; Chopra, Dynamics of Structures, sec. 11.5):
the matrix damps each mode as stated and couples none, equals Rayleigh damping where the ratios are Rayleigh's,
reaches the kernel's matrices, and the scene refuses two forms of damping or a ratio per mode it lacks."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from conftest import SWEEPS

from pounding_sweep.model.coupled import CoupledModel
from pounding_sweep.model.structure import build_shear_frame, modal_damping_matrix, shear_frame_stiffness
from pounding_sweep.scene import ConfigError, load_scene, validate
from pounding_sweep.scene.schema import CalibrateConfig, ExperimentConfig
from pounding_sweep.sweep.prepare import with_structure

EPS = np.finfo(float).eps
MASSES, STORIES = [1.7, 1.7, 1.6], [5920.0, 6100.0, 5800.0]


def _rounding(M, K) -> float:
    """Rounding bound of Phi^T C Phi against diag(2 zeta omega): a few products of n x n matrices of mass-
    normalised shapes (n u per product: Higham, Accuracy and Stability, eq. 3.4) and the eigensolver's backward
    error (a modest multiple of u ||K||, scaled by the largest 2 omega): 64 n u times the largest 2 omega."""
    w = np.sqrt(np.linalg.eigvalsh(np.linalg.solve(M, K)).max())
    return 64 * M.shape[0] * EPS * 2 * w


def test_each_mode_is_damped_as_stated_and_none_is_coupled():
    zeta = np.array([0.002, 0.01, 0.03])
    frame = build_shear_frame("b", MASSES, STORIES, modal_damping_ratios=zeta)
    md = frame.modes()
    P = md.shapes
    D = P.T @ frame.C @ P
    tol = _rounding(frame.M, frame.K)
    np.testing.assert_allclose(np.diag(D), 2 * zeta * md.omega_rad_s, rtol=0, atol=tol)
    assert np.max(np.abs(D - np.diag(np.diag(D)))) <= tol
    np.testing.assert_allclose(md.damping_ratio, zeta, rtol=0, atol=tol / (2 * md.omega_rad_s.min()))
    assert frame.rayleigh_a0_per_s == 0.0 and frame.rayleigh_a1_s == 0.0


def test_rayleigh_ratios_give_the_rayleigh_matrix():
    """Modal ratios set to what Rayleigh damping gives at every mode: the same matrix, to rounding (a few products
    of n x n matrices and the eigensolver's backward error: 64 n u of the matrix's largest entry)."""
    ray = build_shear_frame("b", MASSES, STORIES, damping_ratio=0.02, damping_modes=(1, 3))
    M, K = ray.M, shear_frame_stiffness(np.asarray(STORIES))
    C = modal_damping_matrix(M, K, ray.modes().damping_ratio)
    assert np.max(np.abs(C - ray.C)) <= 64 * len(MASSES) * EPS * np.abs(ray.C).max()


def _scene():
    s = load_scene(SWEEPS / "paper_6hz.toml")
    return dataclasses.replace(s, sweep=())


def test_the_scene_key_reaches_the_kernel_matrices():
    s = _scene()
    b1 = dataclasses.replace(s.building1, damping_ratio=None, modal_damping_ratios=(0.002, 0.01, 0.03))
    m = CoupledModel.from_scene(dataclasses.replace(s, building1=b1))
    np.testing.assert_array_equal(m.matrices()[1][:3, :3], m.b1.C)
    frame = build_shear_frame(
        "b", b1.masses_kg, b1.story_stiffness_N_per_m * 3, modal_damping_ratios=(0.002, 0.01, 0.03)
    )
    np.testing.assert_array_equal(m.b1.C, frame.C)
    moved = with_structure(dataclasses.replace(s, building1=b1), {"modal_damping_ratio_b1_m2": 0.02})
    assert moved.building1.modal_damping_ratios == (0.002, 0.02, 0.03)


@pytest.mark.parametrize(
    ("change", "says"),
    [
        (
            {"modal_damping_ratios": (0.01, 0.01, 0.01)},
            "[building1]: give modal_damping_ratios, damping_ratio or rayleigh_a0_per_s/rayleigh_a1_s, one form of "
            "damping",
        ),
        (
            {"damping_ratio": None, "modal_damping_ratios": (0.01, 0.01)},
            "[building1] modal_damping_ratios = [0.01, 0.01]: one ratio per mode, 3 here (mode 1 first)",
        ),
        (
            {"damping_ratio": None, "modal_damping_ratios": (0.01, 1.0, 0.01)},
            "[building1] modal_damping_ratios = 1.0: must lie in [0, 1)",
        ),
    ],
)
def test_the_scene_refuses_what_cannot_be_meant(change, says):
    s = _scene()
    bad = dataclasses.replace(s, building1=dataclasses.replace(s.building1, **change))
    with pytest.raises(ConfigError) as e:
        validate(bad)
    assert str(e.value) == says


def test_a_mode_ratio_is_fitted_only_where_the_scene_lists_them(tmp_path):
    s = _scene()
    exp = ExperimentConfig(table=str(tmp_path / "none.csv"), channels={"x": "b1f3"})
    cal = CalibrateConfig(parameters={"modal_damping_ratio_b1_m2": (0.0, 0.1)})
    with pytest.raises(ConfigError, match=r"\[building1\] gives no modal_damping_ratios to fit"):
        validate(dataclasses.replace(s, experiment=exp, calibrate=cal))
    b1 = dataclasses.replace(s.building1, damping_ratio=None, modal_damping_ratios=(0.01, 0.01, 0.01))
    cal = CalibrateConfig(parameters={"modal_damping_ratio_b1_m4": (0.0, 0.1)})
    with pytest.raises(ConfigError, match=r"\[building1\] has 3 modes, no mode 4"):
        validate(dataclasses.replace(s, building1=b1, experiment=exp, calibrate=cal))


def test_mode_ratios_made_by_the_reference_are_recovered(tmp_path):
    """Building 1 damped 2 % in mode 1 and 0.5 % in mode 2 (3 % in mode 3, not fitted), the buildings apart, made
    by solve_ivp (reference/softening.py: no discretisation shared with the kernels) from a model that starts
    at 1 % in every mode; 1.5 s of the 6 Hz table motion, every floor of building 1 at 100 samples/s with 0.02 mm
    of noise. Fitting modes 1 and 2: each inside its 95 % interval, the residual at the noise floor."""
    from pounding_sweep.sweep.calibrate import calibrate
    from pounding_sweep.synthetic import make_ivp_experiment, write_experiment
    from pounding_sweep.warn import collecting

    s = _scene()
    s = dataclasses.replace(
        s,
        excitation=dataclasses.replace(s.excitation, duration_s=1.5),
        contact=dataclasses.replace(s.contact, gap_m=0.05),
        building1=dataclasses.replace(s.building1, damping_ratio=None, modal_damping_ratios=(0.01, 0.01, 0.01)),
    )
    truth = (0.02, 0.005, 0.03)
    df, prov = make_ivp_experiment(
        s, {}, stiffness_factor=(1.0, 1.0), damping_factor=((2.0, 0.5, 3.0), 1.0), noise_mm=0.02, seed=11
    )
    path = tmp_path / "modes.parquet"
    write_experiment(df, prov, path)
    channels = {f"model1_floor{f}_mm": f"b1f{f}" for f in (1, 2, 3)}
    names = ["modal_damping_ratio_b1_m1", "modal_damping_ratio_b1_m2"]
    cal = CalibrateConfig(parameters={n: (0.0, 0.1) for n in names}, global_points=16, starts=2, profile_points=0)
    scene = dataclasses.replace(s, experiment=ExperimentConfig(table=str(path), channels=channels), calibrate=cal)
    validate(scene)
    with collecting() as notes:
        fit = calibrate(scene, 2)[0]
    print(f"\n[mode ratios] {fit.estimate}, intervals {fit.ci95}, misfit {fit.misfit_ratio:.2f}")
    for n, v in zip(names, truth):
        lo, hi = fit.ci95[n]
        assert lo <= v <= hi, (n, v, lo, hi)
    assert fit.estimate[names[0]] == pytest.approx(truth[0], rel=0.05)
    assert fit.misfit_ratio < 1.5
    assert not [m for m in notes.messages() if "cannot explain" in m], notes.messages()
