"""The event scheme's pieces shared by every kernel (engine/events.py): the interpolant's slope that starts
the switch search."""

from __future__ import annotations

import numpy as np
import pytest
from tolerances import U

from pounding_sweep.engine.events import hermite_indicator, hermite_slope


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
