"""Stochastic ground motion (model/stochastic.py): the spectrum, the stationary variance and the lag covariance of
the generated samples against closed forms, determinism from the seed, the envelope.

Statistical tolerances: each test fails with probability at most 1e-6 when the code is right (the quantiles
below), so the suite can assert on random samples without flaking."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import quad
from scipy.stats import chi2, norm

from pounding_sweep.model.stochastic import Envelope, GroundFilter, StochasticMotion

#: the failure probability each statistical assertion is held to
P_FAIL = 1e-6
Z = norm.isf(P_FAIL / 2)  # two-sided normal quantile, 4.89

KT = GroundFilter("kanai_tajimi", 5 * math.pi, 0.6, 0.02)
CP = GroundFilter("clough_penzien", 5 * math.pi, 0.6, 0.02, 0.5 * math.pi, 0.6)


@pytest.mark.parametrize("g", [KT, CP], ids=["kanai_tajimi", "clough_penzien"])
def test_variance_is_the_spectrum_integral(g):
    """The Lyapunov variance C P C' and the integral of the closed-form spectrum (Kanai 1957; Clough & Penzien
    1975) agree to the quadrature's 1e-9."""
    total = sum(quad(g.psd, a, b, limit=500, epsabs=0, epsrel=1e-11)[0] for a, b in ((0, 50), (50, np.inf)))
    assert 2 * total == pytest.approx(g.variance(), rel=1e-9)


@pytest.mark.parametrize("g", [KT, CP], ids=["kanai_tajimi", "clough_penzien"])
def test_samples_have_the_stationary_variance_and_lag_covariance(g):
    """4000 realisations started stationary: at each of three sample times sum a^2 / var ~ chi-square with 4000
    degrees of freedom (Gaussian, mean 0); the lag-one product mean against C Phi P C' within Z standard errors
    (the CLT: its variance estimated from the samples)."""
    m = StochasticMotion(g, Envelope(), 0.01, 401)
    a = m.generate(range(4000))
    var = g.variance()
    lo, hi = chi2.ppf(P_FAIL / 6, 4000), chi2.isf(P_FAIL / 6, 4000)  # three times, Bonferroni
    for k in (0, 200, 400):
        assert lo <= (a[:, k] ** 2).sum() / var <= hi
    phi, _, C, _ = m.discrete()
    lag = float(C @ phi @ g.stationary_covariance() @ C)
    prod = a[:, 100] * a[:, 101]
    assert abs(prod.mean() - lag) <= Z * prod.std(ddof=1) / math.sqrt(prod.size)


def test_a_realisation_depends_on_its_seed_only():
    """Bit-identical whatever the other seeds of the chunk and their order; different seeds differ."""
    m = StochasticMotion(CP, Envelope("jennings", 1.0, 3.0, 0.5), 0.005, 1001)
    a = m.generate([7, 3, 11])
    b = m.generate([11, 7])
    assert np.array_equal(a[0], b[1]) and np.array_equal(a[2], b[0])
    assert not np.array_equal(a[0], a[1])
    assert np.array_equal(m.generate([3])[0], a[1])


def test_envelope_and_start_at_rest():
    """Jennings-Housner-Tsai: (t / t1)^2, 1, exp(-c (t - t2)); a start at rest has a[0] = 0 exactly."""
    e = Envelope("jennings", 2.0, 5.0, 0.4)
    assert e(np.array([0.0, 1.0, 2.0, 4.0, 5.0, 7.5])) == pytest.approx([0, 0.25, 1, 1, 1, math.exp(-1.0)], rel=1e-15)
    m = StochasticMotion(KT, Envelope(), 0.01, 101, start="rest")
    assert (m.generate([1, 2])[:, 0] == 0.0).all()
