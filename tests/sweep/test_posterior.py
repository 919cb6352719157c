"""Posterior samples (sweep/posterior.py).

* The stretch-move ensemble sampler on a correlated normal target (closed form): the samples' means and standard
  deviations within their Monte Carlo errors, the acceptance in the sampler's usual range.
* The autocorrelation time of AR(1) chains against its closed form (1 + rho) / (1 - rho).
* On a calibration (1.5 s of the 6 Hz test, k_s/k and r, no model error) the 95 % credible intervals agree with
  the profile intervals within the Monte Carlo error of a 2.5 % quantile from the effective samples (the
  posterior is close to normal here: the two intervals are the same in that limit).
"""

from __future__ import annotations

import math

import numpy as np
from calibration_cases import exact_6hz

from pounding_sweep.sweep.calibrate import calibrate
from pounding_sweep.sweep.posterior import autocorrelation_time, quantile_error, sample_posterior, stretch_sampler
from pounding_sweep.synthetic import ar1_noise


def test_the_stretch_sampler_samples_a_correlated_normal():
    """3-D normal, correlations 0.9 and -0.5, scales 1 to 100: 24 walkers x 2000 steps, the first 500 dropped.
    Each mean within 5 Monte Carlo standard errors sigma sqrt(tau / n) of the truth (failure probability below
    6e-7 each), each standard deviation within 5 sigma sqrt(tau / (2 n)) (its error for normal samples);
    the affine-invariant move does not care about the scales and correlation."""
    rng = np.random.default_rng(3)
    sd = np.array([1.0, 10.0, 100.0])
    corr = np.array([[1.0, 0.9, -0.5], [0.9, 1.0, -0.3], [-0.5, -0.3, 1.0]])
    cov = corr * np.outer(sd, sd)
    prec = np.linalg.inv(cov)
    mean = np.array([1.0, -2.0, 30.0])

    def logp(z):
        d = z - mean
        return -0.5 * np.einsum("ij,jk,ik->i", d, prec, d)

    z0 = mean + rng.normal(size=(24, 3)) * sd * 0.1
    chain, _, acc = stretch_sampler(logp, z0, 2000, rng)
    keep = chain[500:]
    x = keep.reshape(-1, 3)
    n = x.shape[0]
    for j in range(3):
        tau = autocorrelation_time(keep[:, :, j])
        assert abs(x[:, j].mean() - mean[j]) <= 5 * sd[j] * math.sqrt(tau / n), j
        assert abs(x[:, j].std() - sd[j]) <= 5 * sd[j] * math.sqrt(tau / (2 * n)), j
    assert 0.2 <= acc <= 0.8


def test_the_autocorrelation_time_of_ar1_chains():
    """16 chains of 4000 AR(1) steps, rho 0.8: tau = (1 + rho) / (1 - rho) = 9. The windowed estimator's bias is
    below 1 % at the window c tau (the tail rho^M beyond it: rho^45 = 4e-5) and its relative standard deviation
    sqrt(2 (2 M + 1) / N) = 0.04 (Sokal 1997, eq. 3.19; N = 64000 steps in all): within 20 % (5 deviations)."""
    rng = np.random.default_rng(5)
    x = np.array([ar1_noise(rng, 4000, 1.0, 0.8) for _ in range(16)]).T
    assert abs(autocorrelation_time(x) / 9.0 - 1.0) <= 0.2


def test_credible_intervals_agree_with_the_profiles(tmp_path):
    bounds = {"ks_ratio": [0.1, 20.0], "r": [0.05, 1.0]}
    scene = exact_6hz(tmp_path, 4, parameters=bounds, global_points=8, profile_points=9, noise_m=5e-5)
    fit = calibrate(scene, 2)[0]
    post = sample_posterior(fit, steps=120, walkers=8, seed=2)
    tol = 4 * quantile_error(post.ess)  # in standard errors; 4 Monte Carlo errors: fails with probability < 1e-4
    print(f"\n[posterior] acceptance {post.acceptance:.2f}, tau {post.tau}, ess {post.ess:.0f}, tolerance {tol:.2f} se")
    for n in ("ks_ratio", "r"):
        ok, a, b = fit.identified[n]
        ca, cb = post.intervals[n]
        se = fit.std_error[n]
        print(f"  {n}: credible [{ca:.5g}, {cb:.5g}], profile [{a:.5g}, {b:.5g}], se {se:.3g}")
        assert ok
        assert abs(ca - a) <= tol * se and abs(cb - b) <= tol * se
