"""The Monte Carlo of the engine against the closed-form oracles (risk/oracle.py), on the paper's two models at full
scale without contact under Kanai-Tajimi filtered white noise started stationary, from rest:

* the covariance of each pair's relative displacement and of its rate: the exact covariance of the engine's own
  scheme (Newmark driven by the exact sampled filter) against the continuous Lyapunov solution, within the
  scheme's discretisation bound; the Monte Carlo against the exact one within its chi-square sampling bound;
* the mean number of up-crossings of a gap against Rice's formula, within its sampling error;
* the probability of pounding (the closest-approach metric, from the lane kernel) never above Rice's rigorous
  bound E N, and at high thresholds within Vanmarcke's (1975) approximation's stated error.

Each statistical assertion is held to a failure probability (P_FAIL, Bonferroni over a test's assertions), so a
correct engine fails a test with probability below 1e-6.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from risk_scenes import stochastic_scene
from scipy.stats import beta as beta_dist
from scipy.stats import chi2, norm

from pounding_sweep.engine import layout as L
from pounding_sweep.model.coupled import CoupledModel
from pounding_sweep.model.excitation import Excitation
from pounding_sweep.risk import oracle as O
from pounding_sweep.scene import Axis
from pounding_sweep.sweep.prepare import prepare

P_FAIL = 1e-6
#: the error this project states for Vanmarcke's approximation of the first-passage probability at high
#: thresholds (r = b / sigma >= 3), relative to it: the formula is calibrated on single oscillators (his
#: delta^1.2); for the two-mode relative displacement of these frames (delta 0.25-0.29) it measured 22-26 % above
#: 80,000 runs at r = 3 and 9-15 % at r = 3.5 (docs/how-to/probabilistic-pounding.md): conservative, converging as the threshold rises
VANMARCKE_ERROR = 0.3


def oracle_scene(seeds: int, duration_s: float, histories=(), envelope: bool = False):
    """Kanai-Tajimi, stationary from t = 0 (or enveloped), every realisation at its own S0 level (no scaling)."""
    s = stochastic_scene(seeds=seeds, levels=(1.0,), duration_s=duration_s, filter="kanai_tajimi", envelope=envelope)
    return dataclasses.replace(
        s,
        risk=None,
        excitation=dataclasses.replace(s.excitation, intensity="none", scaling="factor"),
        integration=dataclasses.replace(s.integration, min_steps_per_contact_period=0.0),
        contact=dataclasses.replace(s.contact, gap_m=100.0),
        sweep=(Axis("seed", tuple(float(i) for i in range(seeds))),),
        output=dataclasses.replace(s.output, histories=tuple(histories)),
    )


def run_all(scene, threads: int = 2):
    prep = prepare(scene)
    return prep, prep.run(prep.grid.chunk(0, prep.grid.size), threads)


def oracles(scene, n_steps: int):
    """(motion, continuous (var d, var v, cov) histories, Newmark-exact (var d, var v) histories, system)."""
    model = CoupledModel.from_scene(scene)
    motion = Excitation.from_scene(scene, scene.integration.dt_s).motion
    sys = O.linear_system(model, motion.ground)
    t = np.arange(n_steps + 1) * motion.dt_s
    P = O.covariance_history(sys, O.initial_covariance(sys, motion.ground), t, motion.envelope)
    cont = O.pair_moments(sys, P)
    disc = O.newmark_covariance_history(model, motion, n_steps) if motion.envelope.kind == "none" else None
    return model, motion, t, cont, disc, sys


def discretisation_bound(model: CoupledModel, h: float) -> float:
    """Relative error of a response variance from Newmark average acceleration and the linear interpolation of the
    input between samples, at the highest frequency w of the frames: the scheme's period error (w h)^2 / 12
    (Chopra, Dynamics of Structures, sec. 5.5) moves a resonant variance (proportional to 1 / w^3) by three times
    that, and the linear interpolation passes the input's power at w with gain sinc^4(w h / 2) = 1 - (w h)^2 / 6."""
    w = max(float(b.modes().omega_rad_s.max()) for b in (model.b1, model.b2))
    return (w * h) ** 2 / 4 + (w * h) ** 2 / 6


def test_covariance_and_upcrossings_match_lyapunov_and_rice():
    n_runs, duration = 2000, 10.0
    chans = ("disp_b1f1", "disp_b2f1", "disp_b1f3", "disp_b2f3", "vel_b1f1", "vel_b2f1", "vel_b1f3", "vel_b2f3")
    scene = oracle_scene(n_runs, duration, chans)
    prep, (m, _, hist, _, _) = run_all(scene)
    n_steps = hist.shape[2] - 1
    model, motion, t, (vd, vv, cov), disc, sys = oracles(scene, n_steps)
    # the engine's scheme against the continuous system: its discretisation error, within the bound (relative
    # to the stationary variance: the variances themselves start from 0)
    bound = discretisation_bound(model, motion.dt_s)
    sd, sv, _ = O.pair_moments(sys, O.stationary_covariance(sys))
    rel = np.abs(disc[:, :, 0] - vd).max(axis=0) / sd, np.abs(disc[:, :, 1] - vv).max(axis=0) / sv
    assert max(rel[0].max(), rel[1].max()) <= bound, (rel, bound)
    # the Monte Carlo against the scheme's exact covariance: sum x^2 / var ~ chi-square(n) (mean 0, Gaussian)
    checks = []
    for k in (n_steps // 2, n_steps):
        for p, (i1, i2) in ((0, (0, 1)), (2, (2, 3))):
            d = hist[:, i1, k] - hist[:, i2, k]
            v = hist[:, i1 + 4, k] - hist[:, i2 + 4, k]
            checks += [((d * d).sum() / disc[k, p, 0]), ((v * v).sum() / disc[k, p, 1])]
    a = P_FAIL / len(checks) / 2
    lo, hi = chi2.ppf(a, n_runs), chi2.isf(a, n_runs)
    assert all(lo <= c <= hi for c in checks), (lo, hi, checks)
    # up-crossings of r sigma by the top pair against Rice's nonstationary rate integrated over the run; the
    # count per run has an unknown variance (crossings cluster): the CLT with the sample variance
    sig = math.sqrt(vd[-1, 2])
    d = hist[:, 2, :] - hist[:, 3, :]
    z = norm.isf(P_FAIL / 3 / 2)
    for r in (1.0, 2.0, 3.0):
        b = r * sig
        count = ((d[:, :-1] <= b) & (d[:, 1:] > b)).sum(axis=1)
        expected = float(O.expected_upcrossings(t, O.upcrossing_rate(b, vd[:, 2], vv[:, 2], cov[:, 2])))
        se = count.std(ddof=1) / math.sqrt(n_runs)
        # the rate's discretisation bias: exp(-r^2 / 2) moves by r^2 / 2 x the variance's relative error
        assert abs(count.mean() - expected) <= z * se + (1 + r * r / 2) * bound * expected, (r, count.mean(), expected)


def test_enveloped_covariance_matches_the_time_varying_lyapunov_equation():
    """Jennings-Housner-Tsai envelope: the Lyapunov equation with a time-varying coupling, integrated, against 1000
    runs at three times (rise, strong phase, decay); chi-square bounds widened by the discretisation bound."""
    n_runs = 1000
    scene = oracle_scene(n_runs, 8.0, ("disp_b1f3", "disp_b2f3"), envelope=True)
    _, (_, _, hist, _, _) = run_all(scene)
    n_steps = hist.shape[2] - 1
    model, motion, t, (vd, _, _), _, _ = oracles(scene, n_steps)
    bound = discretisation_bound(model, motion.dt_s)
    a = P_FAIL / 3 / 2
    lo, hi = chi2.ppf(a, n_runs) * (1 - bound), chi2.isf(a, n_runs) * (1 + bound)
    for time_s in (1.5, 6.0, 8.0):
        k = int(round(time_s / motion.dt_s))
        d = hist[:, 0, k] - hist[:, 1, k]
        assert lo <= (d * d).sum() / vd[k, 2] <= hi, time_s


def test_probability_of_pounding_within_rice_bound_and_vanmarcke():
    """10,000 contact-free runs on the lane kernel; pounding at gap b when the closest approach goes below 0 at
    gap b, i.e. the required gap exceeds b. Rigorous: P <= E N (Rice), the Monte Carlo's exact (Clopper-Pearson)
    lower limit below it. Approximate: at r = 3 and 3.5 the Monte Carlo within VANMARCKE_ERROR of Vanmarcke's
    probability, beyond its sampling interval."""
    n_runs, duration = 10_000, 20.0
    scene = oracle_scene(n_runs, duration)
    prep, (m, _, _, _, _) = run_all(scene)
    names = L.metric_columns(prep.model.floors, prep.model.n_pairs)
    n_steps = int(round(duration / scene.integration.dt_s))
    model, motion, t, (vd, vv, cov), _, _ = oracles(scene, n_steps)
    sys = O.linear_system(model, motion.ground)
    sd, _, _ = O.pair_moments(sys, O.stationary_covariance(sys))
    tests = [(p, r) for p in (1, 3) for r in (2.0, 3.0, 3.5)]
    a = P_FAIL / (2 * len(tests))
    for p, r in tests:
        required = 100.0 - m[:, names.index(f"closest_approach_f{p}_m")]
        b = r * math.sqrt(sd[p - 1])
        k = int((required > b).sum())
        lo = beta_dist.ppf(a, k, n_runs - k + 1) if k else 0.0
        hi = beta_dist.isf(a, k + 1, n_runs - k) if k < n_runs else 1.0
        expected = float(O.expected_upcrossings(t, O.upcrossing_rate(b, vd[:, p - 1], vv[:, p - 1], cov[:, p - 1])))
        assert lo <= expected, (p, r, k / n_runs, expected)
        if r >= 3.0:
            delta = O.bandwidth(O.spectral_moments(model, motion.ground, p - 1))
            pv = float(O.vanmarcke_first_passage(t, b, vd[:, p - 1], vv[:, p - 1], delta, cov[:, p - 1]))
            assert pv * (1 - VANMARCKE_ERROR) <= hi and lo <= pv * (1 + VANMARCKE_ERROR), (p, r, k / n_runs, pv)


def test_lyapunov_variance_is_the_spectral_integral():
    """The two oracles of the stationary variance agree: Lyapunov and the integral of |H|^2 S (quadrature 1e-10)."""
    scene = oracle_scene(2, 4.0)
    model = CoupledModel.from_scene(scene)
    g = Excitation.from_scene(scene, scene.integration.dt_s).motion.ground
    sys = O.linear_system(model, g)
    sd, sv, _ = O.pair_moments(sys, O.stationary_covariance(sys))
    for p in range(3):
        mo = O.spectral_moments(model, g, p)
        assert mo[0] == pytest.approx(sd[p], rel=1e-8) and mo[2] == pytest.approx(sv[p], rel=1e-8)
        assert 0 < O.bandwidth(mo) < 1


def test_rice_rate_stationary_limit():
    """With cov(x, x') = 0 the general formula is Rice's classical nu+ = sv / (2 pi sx) exp(-b^2 / (2 sx^2))."""
    for b in (0.0, 0.5, 2.0):
        assert O.upcrossing_rate(b, 0.25, 9.0) == pytest.approx(
            3 / (2 * math.pi * 0.5) * math.exp(-2 * b * b), rel=1e-14
        )
