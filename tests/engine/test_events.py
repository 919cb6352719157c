"""The event scheme's pieces shared by every kernel (engine/events.py): the interpolant's slope that starts
the switch search, and the interpolant's first crossing (bisection, and the lane kernel's shorter search)."""

from __future__ import annotations

import numba
import numpy as np
import pytest
from tolerances import U

from pounding_sweep.engine.events import (
    bisect_crossing,
    bracket_crossing,
    hermite_indicator,
    hermite_slope,
    monotone_cubic,
)


def _herms(n: int, seed: int):
    """Random interpolants (p0, p1, m0, m1) of millimetre penetrations and slopes."""
    rng = np.random.default_rng(seed)
    return [tuple(x) for x in rng.normal(0.0, 1e-3, (n, 4))]


def test_hermite_slope_is_the_cubics_derivative():
    """Classic law: the slope is d/dtau of the Hermite cubic, against the monomial form's derivative
    3 a3 t^2 + 2 a2 t + a1 (a3 = 2 p0 + m0 - 2 p1 + m1, a2 = -3 p0 - 2 m0 + 3 p1 - m1, a1 = m0). With t in
    [0, 1] and S = |p0| + |p1| + |m0| + |m1|, the terms' magnitudes (coefficients expanded: 6 t^2 + 6 t up to
    12) sum to at most 12 S on the cubic's side and 13 S on the monomial side, and no term passes through
    more than 8 roundings, so the sides differ by at most 8 u (12 + 13) S = 200 u S (Higham's gamma_n
    bound, to first order), below the 40 u of 8 S (320 u S) used here."""
    law = (False, 1e6, 0.0)
    for p0, p1, m0, m1 in _herms(200, 3):
        a3 = 2 * p0 + m0 - 2 * p1 + m1
        a2 = -3 * p0 - 2 * m0 + 3 * p1 - m1
        for tau in (0.0, 0.13, 0.5, 0.87, 1.0):
            want = 3 * a3 * tau**2 + 2 * a2 * tau + m0
            got = hermite_slope((p0, p1, m0, m1), tau, 1e-4, law)
            scale = 8 * (abs(p0) + abs(p1) + abs(m0) + abs(m1))
            assert abs(got - want) <= 40 * U * scale


@pytest.mark.parametrize("c_over_k", [1e-6, 1e-4, 1e-3])
def test_hermite_slope_no_tension_is_the_indicators_derivative(c_over_k):
    """No-tension law: the indicator is min(p, p + (c / k_s) p' / h), and the slope is the derivative of the
    smaller one, against central differences of hermite_indicator with step e = 1e-5 away from where the
    two cross. A central difference of a cubic (or a cubic plus a quadratic) errs by e^2 / 6 |f'''|, here
    e^2 |6 a3| / 6 (f''' = p''' = 6 a3), plus the rounding of the two values divided by 2 e. The terms of
    p sum to at most 6 S and those of p' to 12 S (coefficients expanded, S = the four values' sum), so those
    of f = p + (c / k_s) p' / h to mag = 6 (1 + 2 c / (k_s h)) S; no term passes more than 10 roundings, so
    each value is within 10 u mag, and the difference quotient within 10 u mag / e of the exact one."""
    h, e = 1e-4, 1e-5
    k_s = 1e6
    law = (True, k_s, c_over_k * k_s)
    for herm in _herms(100, 5):
        a3 = 2 * herm[0] + herm[2] - 2 * herm[1] + herm[3]
        mag = 6.0 * (1.0 + 2.0 * c_over_k / h) * sum(abs(x) for x in herm)
        bound = e * e * abs(a3) + 10 * U * mag / e
        checked = 0
        for tau in np.linspace(0.05, 0.95, 19):
            if len({_branch(herm, t, h, c_over_k) for t in (tau - e, tau, tau + e)}) > 1:
                continue  # the difference straddles where the two branches cross: not a derivative there
            lo, hi = (hermite_indicator(herm, t, h, law) for t in (tau - e, tau + e))
            got = hermite_slope(herm, tau, h, law)
            assert abs(got - (hi - lo) / (2 * e)) <= bound, (herm, tau, got, bound)
            checked += 1
        assert checked >= 15


def _branch(herm, tau, h, c_over_k) -> bool:
    """Whether the no-tension indicator at tau is the penetration (True) or F / k_s (False)."""
    p = hermite_indicator(herm, tau, h, (False, 1.0, 0.0))
    return p <= hermite_indicator(herm, tau, h, (True, 1.0, c_over_k))


def test_monotone_cubic_against_the_sampled_slope():
    """monotone_cubic(herm, sign) says whether sign * the cubic never decreases on [0, 1], against the slope
    sampled at 2,001 points. Cases where the least sampled slope is within rounding of zero (20 u of the
    slope's terms, 8 S with S = |p0| + |p1| + |m0| + |m1|: test_hermite_slope_is_the_cubics_derivative's
    bound) are left out: there either answer is right."""
    law = (False, 1e6, 0.0)
    taus = np.linspace(0.0, 1.0, 2001)
    seen = {True: 0, False: 0}
    for herm in _herms(400, 11):
        scale = 8 * sum(abs(x) for x in herm)
        for sign in (1.0, -1.0):
            least = min(sign * hermite_slope(herm, t, 1e-4, law) for t in taus)
            if abs(least) <= 20 * U * scale:
                continue
            assert monotone_cubic(herm, sign) == (least > 0.0), (herm, sign, least)
            seen[least > 0.0] += 1
    assert min(seen.values()) >= 50, seen  # both answers were tested


def _three_crossings(n: int, seed: int):
    """Interpolants of cubics A (t - t1)(t - t2)(t - t3) with three roots in (0, 1) (end values and slopes)."""
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        roots = np.sort(rng.uniform(0.02, 0.98, 3))
        a = rng.choice([-1.0, 1.0]) * 10.0 ** rng.uniform(-4, -2)
        c = a * np.poly(roots)  # coefficients of t^3 .. t^0
        d = np.polyder(c)
        out.append((np.polyval(c, 0.0), np.polyval(c, 1.0), np.polyval(d, 0.0), np.polyval(d, 1.0)))
    return out


@numba.njit
def _crossings(herm, h, law, sign, f0, f1):
    """(bisect_crossing's, bracket_crossing's): both are compiled without a Python entry (jit.njit_inner)."""
    return bisect_crossing(herm, h, law, sign, f0, f1), bracket_crossing(herm, h, law, sign, f0, f1)


@pytest.mark.parametrize("no_tension", [False, True])
def test_bracket_crossing_finds_the_bisections_crossing(no_tension):
    """The lane kernel's crossing (skipping the halvings where the cubic crosses once) is bisect_crossing's
    crossing, also where the interpolant crosses several times (there both halve alike first). Both return the
    upper end of a bracket around a sign change of the computed indicator; the exact crossing lies within the
    band where rounding can flip that sign, of half-width 20 u mag / |slope| (mag: the terms' magnitude, as in
    the slope tests), so the two agree to 1e-15 (bracket_crossing's width) plus that band on both sides."""
    h, k_s = 1e-4, 1e6
    law = (no_tension, k_s, 1e-4 * k_s)
    checked = several = 0
    for herm in _herms(600, 17) + _three_crossings(200, 19):
        for sign in (1.0, -1.0):
            f0 = sign * hermite_indicator(herm, 0.0, h, law)
            f1 = sign * hermite_indicator(herm, 1.0, h, law)
            if not (f0 < 0.0 <= f1):
                continue
            a, b = _crossings(herm, h, law, sign, f0, f1)
            slope = abs(hermite_slope(herm, a, h, law))
            mag = 6.0 * (1.0 + (2.0 * law[2] / (k_s * h) if no_tension else 0.0)) * sum(abs(x) for x in herm)
            band = 20 * U * mag / max(slope, 1e-300)
            assert abs(a - b) <= 1e-15 + 2 * band, (herm, sign, a, b, band)
            checked += 1
            grid = [sign * hermite_indicator(herm, t, h, law) for t in np.linspace(0.0, 1.0, 401)]
            several += sum(1 for x, y in zip(grid, grid[1:]) if (x < 0.0) != (y < 0.0)) > 1
    assert checked >= 100 and several >= 5, (checked, several)  # crossings once and several times were tested
