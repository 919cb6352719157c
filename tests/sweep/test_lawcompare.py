"""The contact laws compared on one basis (sweep/lawcompare.py).

* The issue's case: a law with 30 % less residual (misfit 5.5 against 7.9) lost by delta AIC 132 when each law's
  AIC used its own effective count; on the common count it wins.
* On a common count, AIC and BIC order laws of equal parameter count as their residuals.
* The Diebold-Mariano test's pieces: the Bartlett long-run variance against the AR(1) closed form; the test's
  size under the null (two equally good laws with correlated residuals) and its power.
* End to end: data made with the classic law, the classic, no-tension and elastic Hertz laws calibrated: the
  elastic law (no damping where the data have r = 0.5) is not among those the data cannot tell apart, the
  classic law is, and a law is chosen only if it is the classic one.
"""

from __future__ import annotations

import dataclasses
import math
from types import SimpleNamespace

import numpy as np
import pytest
from calibration_cases import exact_6hz

from pounding_sweep.scene.schema import Axis
from pounding_sweep.sweep.calibrate import calibrate, law_table
from pounding_sweep.sweep.lawcompare import dm_statistic, information_criteria, long_run_variance
from pounding_sweep.synthetic import ar1_noise
from pounding_sweep.warn import collecting


def _fit(law, misfit, n_eff, n=1000, p=4):
    return SimpleNamespace(law=law, n=n, n_eff=n_eff, rss=misfit**2 * n, names=["x"] * p)


def test_the_issue_case_before_and_after():
    """Misfit 5.5 (N_eff 99.3 from its residuals' lag-1 autocorrelation) against 7.9 (N_eff 50: more structured
    residuals), N = 1000, 4 parameters each. Before: AIC = N_eff ln(RSS / N) + 2 p with each law's own N_eff,
    and the worse law won by 132. After: both on N_c = 99.3 (the best-fitting law's), the better law wins by
    99.3 ln(7.9^2 / 5.5^2) = 71.9."""
    good, bad = _fit("good", 5.5, 99.3), _fit("bad", 7.9, 50.0)
    own = {f.law: f.n_eff * math.log(f.rss / f.n) + 2 * len(f.names) for f in (good, bad)}
    assert own["good"] - own["bad"] == pytest.approx(132.0, abs=0.5)
    nc, aic, bic = information_criteria([bad, good])
    assert nc == 99.3
    assert aic["bad"] - aic["good"] == pytest.approx(99.3 * math.log(7.9**2 / 5.5**2), rel=1e-12)
    assert bic["bad"] - bic["good"] == pytest.approx(99.3 * math.log(7.9**2 / 5.5**2), rel=1e-12)


def test_on_a_common_count_laws_of_equal_size_rank_as_their_residuals():
    rng = np.random.default_rng(4)
    for _ in range(50):
        fits = [_fit(f"law{i}", rng.uniform(0.8, 20.0), rng.uniform(10.0, 900.0)) for i in range(4)]
        _, aic, bic = information_criteria(fits)
        by_rss = [f.law for f in sorted(fits, key=lambda f: f.rss)]
        assert sorted(aic, key=aic.get) == by_rss and sorted(bic, key=bic.get) == by_rss


def test_the_long_run_variance_of_ar1_noise():
    """AR(1), rho 0.5, RMS 1, T = 200000: the long-run variance is (1 - rho^2) / (1 - rho)^2 = 3. The Bartlett
    estimate with Andrews' bandwidth (S ~ 81 here) has a bias of -sum |l| gamma_l / (S LRV) = -1.6 % and a
    relative standard deviation of sqrt(4 S / (3 T)) = 2.3 % (Andrews 1991, Table I's asymptotics); within
    1.6 % + 4 x 2.3 % = 11 % it fails with probability below 1e-4."""
    x = ar1_noise(np.random.default_rng(1), 200_000, 1.0, 0.5)
    assert abs(long_run_variance(x) / 3.0 - 1.0) <= 0.11


def test_the_diebold_mariano_test_holds_its_size_and_has_power():
    """400 pairs of independent AR(1) residual series (rho 0.7, T = 2000, RMS 1): two equally good laws. The test
    rejects (|z| > 1.96) in 6.25 % of them here (the asymptotic 5 % plus the small-sample excess of HAC tests
    with correlated losses); at most 10 % is allowed: three binomial standard deviations (0.012) above that
    size, exceeded with probability about 0.1 %. Against a law whose residual RMS is 1.2 times larger, it
    rejects in at least 95 % (it rejects in all here)."""
    rng = np.random.default_rng(0)
    null, power = 0, 0
    for _ in range(400):
        a, b = ar1_noise(rng, 2000, 1.0, 0.7), ar1_noise(rng, 2000, 1.0, 0.7)
        null += abs(dm_statistic(a, b, [2000])) > 1.959963984540054
        power += dm_statistic(a, 1.2 * b, [2000]) > 1.959963984540054
    assert null / 400 <= 0.10
    assert power / 400 >= 0.95


def test_two_channels_add_their_standard_deviations():
    """Two channels: the z statistic divides by the sum of the channels' HAC standard deviations, the bound for
    any correlation between them; two identical channels give the one channel's z."""
    rng = np.random.default_rng(2)
    a, b = ar1_noise(rng, 1000, 1.0, 0.5), 1.1 * ar1_noise(rng, 1000, 1.0, 0.5)
    one = dm_statistic(a, b, [1000])
    two = dm_statistic(np.concatenate([a, a]), np.concatenate([b, b]), [1000, 1000])
    assert two == pytest.approx(one, rel=1e-12)  # the same sums, added in another order


def test_laws_compared_end_to_end(tmp_path):
    """1.5 s of the 6 Hz test made by the engine with the classic law (k_s/k 3, r 0.5), the structure as modelled,
    0.05 mm noise; classic, no_tension and hertz (elastic) calibrated over k_s/k and r. The elastic law cannot
    dissipate what the data dissipate: it is no candidate. The classic law is one, and the only law the data may
    choose (no_tension differs only while the dashpot pulls, which the data may not resolve)."""
    bounds = {"ks_ratio": [0.1, 20.0], "r": [0.05, 1.0]}
    scene = exact_6hz(tmp_path, 3, parameters=bounds, global_points=8, starts=1, profile_points=0, noise_m=5e-5)
    scene = dataclasses.replace(scene, sweep=(Axis("law", ("classic", "no_tension", "hertz")),))
    with collecting():
        fits = calibrate(scene, 2)
    cmp = fits[0].comparison
    print(f"\n[laws] {cmp.text}\n{law_table(fits).to_string()}")
    assert "hertz" not in cmp.candidates
    assert "classic" in cmp.candidates
    assert cmp.chosen in (None, "classic")
    table = law_table(fits)
    assert set(table.contact_law) == {"classic", "no_tension", "hertz"}
    assert (table.n_effective_common == cmp.n_eff_common).all()
