"""Damping from one ratio per mode ([buildingN] modal_damping_ratios; Chopra, Dynamics of Structures, sec. 11.5):
the matrix damps each mode as stated and couples none, equals Rayleigh damping where the ratios are Rayleigh's,
reaches the kernel's matrices, and the scene refuses two forms of damping or a ratio per mode it lacks."""

from __future__ import annotations

import dataclasses

import numpy as np
from conftest import SWEEPS

from pounding_sweep.model.coupled import CoupledModel
from pounding_sweep.model.structure import build_shear_frame, modal_damping_matrix, shear_frame_stiffness
from pounding_sweep.scene import load_scene
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
