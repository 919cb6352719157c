"""Shear frames, Rayleigh damping, modal analysis and the Kelvin-Voigt parameters (eqs. 8-10)."""

import math

import numpy as np
import pytest

from pounding_sweep.model.contact import contact_period, damping_ratio_from_restitution, dashpot_coefficient
from pounding_sweep.model.structure import (
    build_shear_frame,
    column_story_stiffness,
    rayleigh_from_ratio,
    shear_frame_stiffness,
)


def test_paper_first_frequencies_from_table_1():
    """REFERENCE_VALUES: eigen-analysis of Table 1 masses and final stiffnesses gives 4.25 and 7.17 Hz."""
    m1 = build_shear_frame("Model-1", [1.7, 1.7, 1.6], [5920.0] * 3, damping_ratio=0.0105)
    m2 = build_shear_frame("Model-2", [0.56, 0.56, 0.45], [5140.0] * 3, damping_ratio=0.0107)
    assert m1.modes().frequency_Hz[0] == pytest.approx(4.25, abs=0.005)
    assert m2.modes().frequency_Hz[0] == pytest.approx(7.17, abs=0.005)


def test_column_stiffness_is_the_papers_6830():
    """k = 4 * 12 EI / L^3 = 6.83 kN/m with EI = 5.4 N m^2 (sec. 3); L from 1000 mm / 3 stories is ~0.336 m."""
    L = (4 * 12 * 5.4 / 6830.0) ** (1 / 3)
    assert column_story_stiffness(5.4, 4, L) == pytest.approx(6830.0)
    assert 0.33 < L < 0.34


def test_stiffness_matrix_matches_eq_3():
    K = shear_frame_stiffness(np.array([1.0, 2.0, 3.0]))
    np.testing.assert_array_equal(K, [[3, -2, 0], [-2, 5, -3], [0, -3, 3]])


def test_rayleigh_damping_holds_at_the_two_matched_modes():
    b = build_shear_frame("b", [1.0, 1.0, 1.0, 1.0], [1000.0] * 4, damping_ratio=0.03, damping_modes=(1, 3))
    z = b.modes().damping_ratio
    assert z[0] == pytest.approx(0.03) and z[2] == pytest.approx(0.03)
    assert z[1] < 0.03  # between the matched modes Rayleigh damping dips below the target


def test_rayleigh_coefficients_closed_form():
    a0, a1 = rayleigh_from_ratio(10.0, 30.0, 0.05, 0.05)
    assert a0 == pytest.approx(2 * 0.05 * 10 * 30 / 40) and a1 == pytest.approx(2 * 0.05 / 40)


def test_modes_are_mass_normalised():
    b = build_shear_frame("b", [1.7, 1.7, 1.6], [5920.0] * 3, damping_ratio=0.01)
    md = b.modes()
    # LAPACK's generalised symmetric eigensolver returns vectors M-orthonormal, and diagonalising K, to
    # O(n u) of ||M|| ||Phi||^2 ~ 1 and ||K|| ||Phi||^2 ~ 1e4 (LAPACK Users' Guide, 3rd ed., sec. 4.10):
    # 1e-12 is 9000 u, 1e-8 is 9000 u of 1e4
    np.testing.assert_allclose(md.shapes.T @ b.M @ md.shapes, np.eye(3), atol=1e-12)
    np.testing.assert_allclose(md.shapes.T @ b.K @ md.shapes, np.diag(md.omega_rad_s**2), rtol=1e-10, atol=1e-8)


@pytest.mark.parametrize("r, xi", [(1.0, 0.0), (0.0, 1.0)])
def test_restitution_limits_exact(r, xi):
    assert damping_ratio_from_restitution(r) == xi


def test_restitution_formula_eq_10():
    r = 0.4
    assert damping_ratio_from_restitution(r) == pytest.approx(-math.log(r) / math.sqrt(math.pi**2 + math.log(r) ** 2))
    xs = damping_ratio_from_restitution(np.linspace(0, 1, 101))
    assert np.all(np.diff(xs) < 0) and xs[0] == 1.0 and xs[-1] == 0.0


@pytest.mark.parametrize("r", [-0.1, 1.01, float("nan")])
def test_restitution_out_of_range(r):
    with pytest.raises(ValueError, match="r must lie in"):
        damping_ratio_from_restitution(r)


def test_dashpot_eq_9_and_contact_period():
    ks, m1, m2 = 6830.0, 1.6, 0.45
    meff = m1 * m2 / (m1 + m2)
    assert dashpot_coefficient(ks, 0.0, m1, m2) == pytest.approx(2 * math.sqrt(ks * meff))
    assert dashpot_coefficient(ks, 1.0, m1, m2) == 0.0
    assert contact_period(ks, m1, m2) == pytest.approx(2 * math.pi * math.sqrt(meff / ks))
