"""Intensity measures (model/intensity.py): the filter form of Nigam & Jennings' exact recursion against the plain
recursion and against an ODE solver restarted at every sample (the input linear within each interval), and the
limits Sa(T -> 0) = PGA and linearity in the motion."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from tolerances import SAFETY, floor_steps

from pounding_sweep.model.intensity import (
    geometric_mean_period,
    intensity,
    oscillator_displacement,
    oscillator_step,
    peak_ground_acceleration,
    spectral_acceleration,
)


def motion(n: int = 600, seed: int = 4) -> np.ndarray:
    """A broadband test acceleration [m/s^2] with a non-zero first sample (the start the filter corrects)."""
    rng = np.random.default_rng(seed)
    a = np.cumsum(rng.standard_normal(n)) * 0.1 + rng.standard_normal(n)
    return a - a.mean() + 0.7


def plain_recursion(a, dt, period, zeta):
    """x[n+1] = Phi x[n] + F1 a[n] + F2 (a[n+1] - a[n]) from rest, one sample at a time (the obvious form)."""
    phi, f1, f2 = oscillator_step(period, zeta, dt)
    x = np.zeros(2)
    out = np.zeros(a.size)
    for k in range(a.size - 1):
        x = phi @ x + f1 * a[k] + f2 * (a[k + 1] - a[k])
        out[k + 1] = x[0]
    return out


@pytest.mark.parametrize("period, zeta, dt", [(0.7, 0.05, 0.01), (0.1, 0.05, 0.01), (3.0, 0.02, 0.005)])
def test_filter_form_equals_the_plain_recursion(period, zeta, dt):
    """Equal in exact arithmetic; the recursion is non-expanding (spectral radius exp(-zeta w dt) < 1), so
    rounding adds up at most linearly: SAFETY x n_steps x 2 states x u of the peak (tests/tolerances.py)."""
    a = motion()
    u = oscillator_displacement(a, dt, period, zeta)
    ref = plain_recursion(a, dt, period, zeta)
    tol = SAFETY * floor_steps(a.size, 2) * np.abs(ref).max()
    assert np.abs(u - ref).max() <= tol
    assert u[0] == 0.0  # at rest at t = 0 although a[0] != 0


def test_exact_for_piecewise_linear_input_against_an_ode_solver():
    """DOP853 restarted at every sample (so the input it sees is linear, smooth, within each step) with rtol
    1e-12: its error per interval is about rtol of the state, over 300 intervals at most 300 x 1e-12 of
    the peak, ample below the 1e-8 asked; the exact recursion has only rounding."""
    a, dt, period, zeta = motion(300), 0.02, 0.5, 0.05
    w = 2 * math.pi / period
    x = np.zeros(2)
    ref = [0.0]
    for k in range(a.size - 1):
        slope = (a[k + 1] - a[k]) / dt

        def rhs(t, y, k=k, slope=slope):
            return [y[1], -w * w * y[0] - 2 * zeta * w * y[1] - (a[k] + slope * t)]

        x = solve_ivp(rhs, (0.0, dt), x, method="DOP853", rtol=1e-12, atol=1e-15).y[:, -1]
        ref.append(x[0])
    u = oscillator_displacement(a, dt, period, zeta)
    assert np.abs(u - np.array(ref)).max() <= 1e-8 * np.abs(ref).max()


def test_short_period_sa_is_the_pga():
    """A rigid oscillator follows the ground: u -> -a / w^2, so Sa -> PGA; the lag of a stiff oscillator is of
    order 2 zeta / w per unit slope, here below 1e-3 of the PGA (T = 1 ms against samples 10 ms apart)."""
    a = motion()
    sa = float(spectral_acceleration(a, 0.01, 0.001, 0.05))
    assert sa == pytest.approx(float(peak_ground_acceleration(a)), rel=1e-3)


def test_intensity_is_linear_in_the_motion_and_rows_are_independent():
    """Sa(c a) = c Sa(a) to rounding (the recursion is linear), and a batch of motions gives each row's own."""
    a = np.stack([motion(seed=s) for s in range(3)])
    one = np.array([float(intensity(row, 0.01, "sa", 0.7)) for row in a])
    both = intensity(a, 0.01, "sa", 0.7)
    assert np.array_equal(one, both)
    assert intensity(2.5 * a, 0.01, "sa", 0.7) == pytest.approx(2.5 * both, rel=1e-13)
    assert np.array_equal(intensity(a, 0.01, "pga"), np.abs(a).max(axis=1))


def test_geometric_mean_period():
    assert geometric_mean_period([0.9, 0.4]) == pytest.approx(0.6, rel=1e-15)
