"""Probabilities, intervals and fragility fits (risk/probability.py, fragility.py, hazard.py): exact intervals
against scipy and their exact coverage; a known lognormal fragility recovered from samples drawn from it; the
bootstrap's coverage; the hazard integral against its closed form.

Statistical assertions fail with probability at most P_FAIL when the code is right."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.special import ndtr
from scipy.stats import binom, binomtest, chi2

from pounding_sweep.risk.analysis import annual_rate_table
from pounding_sweep.risk.fragility import (
    bootstrap_interval,
    bootstrap_multiplicities,
    fit_lognormal,
    gap_for_probability,
    percentile_interval,
    weighted_exceedance,
)
from pounding_sweep.risk.hazard import Hazard, annual_rate, power_law_rate, read_hazard
from pounding_sweep.risk.probability import (
    clopper_pearson,
    exceedance_counts,
    order_statistic_interval,
    required_gap_empirical,
)

P_FAIL = 1e-6


def test_clopper_pearson_is_scipys_exact_interval_and_covers():
    """Equal to scipy.stats.binomtest's 'exact' interval; its coverage, summed exactly over the binomial, is at
    least the level for every p of a grid (Clopper & Pearson 1934: conservative by construction)."""
    n = 30
    k = np.arange(n + 1)
    lo, hi = clopper_pearson(k, n, 0.95)
    for kk in (0, 1, 7, 29, 30):
        ci = binomtest(kk, n).proportion_ci(confidence_level=0.95, method="exact")
        assert lo[kk] == pytest.approx(ci.low, abs=1e-12) and hi[kk] == pytest.approx(ci.high, abs=1e-12)
    for p in np.linspace(0.001, 0.999, 199):
        cover = binom.pmf(k, n, p)[(lo <= p) & (p <= hi)].sum()
        assert cover >= 0.95 - 1e-12


def test_order_statistic_interval_has_exact_coverage():
    """P(D_(l) <= x_q < D_(u)) = P(l <= B < u), B ~ Binomial(n, q): at least the level; none where n is too small."""
    for n, q in ((100, 0.9), (1000, 0.98), (60, 0.5)):
        l, u = order_statistic_interval(n, q, 0.95)
        assert binom.cdf(u - 1, n, q) - binom.cdf(l - 1, n, q) >= 0.95
    assert order_statistic_interval(20, 0.98, 0.95) == (None, None)
    d = np.arange(1, 101, dtype=float)  # D_(r) = r
    g, lo, hi = required_gap_empirical(d, 0.1, 0.95)
    assert g == 90.0 and lo < 90.0 < hi
    assert all(math.isnan(v) for v in required_gap_empirical(d[:20], 0.02))  # 20 x 0.02 < 1


def test_exceedance_counts_are_strict():
    """Pounding at gap g needs a required gap strictly above g (a penetration of 0 is no contact)."""
    assert exceedance_counts([1.0, 2.0, 2.0, 3.0], [0.5, 2.0, 3.0]).tolist() == [4, 1, 0]


def fisher_information(x, n, theta, beta):
    """Expected information of (ln theta, beta) for binomial stripes at x with n trials each."""
    z = np.log(np.asarray(x) / theta) / beta
    p = ndtr(z)
    dens = np.exp(-z * z / 2) / math.sqrt(2 * math.pi)
    w = np.asarray(n) * dens**2 / (p * (1 - p))
    # dz / d ln theta = -1 / beta, dz / d beta = -z / beta
    g = np.stack([-np.ones_like(z) / beta, -z / beta])
    return (w * g) @ g.T


@pytest.mark.parametrize("design", ["stripes", "cloud"])
def test_recovers_a_known_lognormal(design):
    """Outcomes drawn from P = Phi(ln(x / 0.5) / 0.4): independent stripes (multiple-stripe analysis, 60 motions at
    each of 12 levels) or a cloud (3000 motions at log-uniform intensities). The MLE's error in (ln theta, beta),
    standardised by the expected Fisher information at the truth, is chi-square with 2 degrees of freedom
    asymptotically: below its 1 - P_FAIL quantile (27.6)."""
    theta, beta = 0.5, 0.4
    rng = np.random.default_rng(11 if design == "stripes" else 12)
    if design == "stripes":
        x = np.geomspace(0.15, 1.6, 12)
        n = np.full(x.size, 60)
        k = rng.binomial(n, ndtr(np.log(x / theta) / beta))
    else:
        x = np.exp(rng.uniform(math.log(0.1), math.log(2.5), 3000))
        n = np.ones(x.size)
        k = (rng.uniform(size=x.size) < ndtr(np.log(x / theta) / beta)).astype(float)
    fit = fit_lognormal(x, k, n)
    assert fit.status == "ok"
    err = np.array([math.log(float(fit.theta) / theta), float(fit.beta) - beta])
    info = fisher_information(x, n, theta, beta)
    assert err @ info @ err <= chi2.isf(P_FAIL, 2), (fit.theta, fit.beta)


def test_incremental_dynamic_analysis_gives_the_capacities_lognormal():
    """IDA of motions with lognormal capacities x_c (pounding at x when x >= x_c): a dense ladder of stripes holds
    the capacities' own distribution, so the fit approaches the capacities' sample log-mean and log-sd (Baker 2015's
    IDA estimate): within the ladder's half step in ln x (0.02) plus the fit's own resolution."""
    rng = np.random.default_rng(5)
    cap = 0.5 * np.exp(0.4 * rng.standard_normal(400))
    x = np.exp(np.arange(math.log(0.1), math.log(3.0), 0.04))
    k = (x[:, None] >= cap[None, :]).sum(1)
    fit = fit_lognormal(x, k, np.full(x.size, cap.size))
    assert math.log(float(fit.theta)) == pytest.approx(np.log(cap).mean(), abs=0.03)
    assert float(fit.beta) == pytest.approx(np.log(cap).std(), abs=0.03)


def test_degenerate_data_are_flagged_not_fitted():
    none = fit_lognormal([0.1, 0.2, 0.4], [0, 0, 0], [5, 5, 5])
    every = fit_lognormal([0.1, 0.2, 0.4], [5, 5, 5], [5, 5, 5])
    sep = fit_lognormal([0.1, 0.2, 0.4], [0, 0, 5], [5, 5, 5])
    assert (none.status, every.status, sep.status) == ("none", "all", "separated")
    assert none.probability([0.3])[0] == 0.0 and every.probability([0.3])[0] == 1.0
    assert np.isnan(sep.probability([0.3])).all()  # not identified: no curve


def test_a_quasi_separated_fit_reports_the_likelihood_the_data_allow():
    """A helper's trial: 0/200, 0/200, 63/200 at 0.2, 0.4, 0.8 g. The likelihood's supremum is a step at 0.8 g
    (beta -> 0) with P = 63/200 there: log L = 63 ln(0.315) + 137 ln(0.685) = -124.6, which the table now gives
    (it gave 0.0, a perfect fit). A strict separation's step fits every point: 0."""
    quasi = fit_lognormal([0.2, 0.4, 0.8], [0, 0, 63], [200, 200, 200])
    assert quasi.status == "separated"
    assert float(quasi.loglik) == pytest.approx(63 * math.log(63 / 200) + 137 * math.log(137 / 200), rel=1e-12)
    assert float(quasi.loglik) == pytest.approx(-124.6, abs=0.05)
    assert float(fit_lognormal([0.1, 0.2, 0.4], [0, 0, 5], [5, 5, 5]).loglik) == 0.0
    # a cloud with two runs at the boundary intensity, one pounding: pooled there, 1 of 2 (a review's case)
    tie = fit_lognormal([0.1, 0.2, 0.2, 0.4], [0, 1, 0, 1], [1, 1, 1, 1])
    assert tie.status == "separated" and float(tie.loglik) == pytest.approx(2 * math.log(0.5), rel=1e-12)
    # pounding falling with the intensity: no curve; the supremum a curve that does not rise allows is the pooled
    # binomial, 9 of 30
    flat = fit_lognormal([0.1, 0.2, 0.4], [5, 3, 1], [10, 10, 10])
    assert flat.status == "flat" and float(flat.loglik) == pytest.approx(9 * math.log(0.3) + 21 * math.log(0.7))


def test_a_bootstrap_interval_needs_its_estimate_and_enough_replicates():
    """The percentile interval of the replicates, given only with an estimate and where at most (1 - 0.95) / 2 of
    the replicates have no value: a helper's trial found 95 % intervals built from 11.5 % and 65.6 % of them (the
    missing ones could all lie in one tail), and intervals beside a NaN estimate."""
    reps = np.arange(1000, dtype=float)
    lo, hi, found = bootstrap_interval(reps, 500.0)
    assert (lo, hi, found) == (pytest.approx(24.975), pytest.approx(974.025), 1.0)
    assert all(np.isnan(bootstrap_interval(reps, np.nan)[:2]))
    some = reps.copy()
    some[:26] = np.nan  # 2.6 % missing: more than the 2.5 % a tail may lose
    assert all(np.isnan(bootstrap_interval(some, 500.0)[:2])) and bootstrap_interval(some, 500.0)[2] == 0.974
    # 2.5 % missing, which could all lie in either tail: the interval of all 1000 then reaches the others' ends
    some[25] = 25.0
    assert bootstrap_interval(some, 500.0)[:2] == (25.0, 999.0)
    # 1 % missing: the others' (2.5 - 1) / 99 and 97.5 / 99 % quantiles, which hold 95 % of all wherever those lie
    some = reps.copy()
    some[:10] = np.nan
    lo, hi, _ = bootstrap_interval(some, 500.0)
    assert (lo, hi) == (
        pytest.approx(np.quantile(reps[10:], 0.015 / 0.99)),
        pytest.approx(np.quantile(reps[10:], 0.975 / 0.99)),
    )
    below = np.sum(reps[10:] < lo) + 10  # the missing ones all below: at most 2.5 % of the 1000 under the interval
    assert below <= 25 and np.sum(reps[10:] > hi) + 10 <= 25


def test_the_annual_rate_is_not_a_number_where_the_study_did_not_reach_it():
    """No motion pounding at any level (or every one at every level) gives P = 0 (or 1) on the levels studied, and
    the hazard integral then read 0 per year (return period inf) or the curve's own rate at its lowest row
    (21.3 per year): numbers the data do not have. NaN, the status and a note; an identified fit is integrated."""
    hz = Hazard(np.array([0.02, 0.1, 1.0, 3.0]), np.array([20.0, 1.0, 0.002, 1e-4]), "test")
    gaps = np.array([0.01, 0.1, 1.0])
    x = np.array([0.1, 0.2, 0.4, 0.8])
    fit = fit_lognormal(np.broadcast_to(x, (3, 4)), [[10, 10, 10, 10], [1, 3, 6, 9], [0, 0, 0, 0]], np.full((3, 4), 10))
    assert list(fit.status) == ["all", "ok", "none"]
    t = annual_rate_table(hz, fit, None, gaps, 0.95, annual_rate, [0.1, 0.2, 0.4, 0.8])
    assert np.isnan(t.annual_rate_per_yr[0]) and np.isnan(t.annual_rate_per_yr[2]) and t.annual_rate_per_yr[1] > 0
    assert np.isnan(t.return_period_yr[2])
    assert "down to the lowest (the lowest level, 0.1 g)" in t.note[0] and "up to 0.8 g" in t.note[2]
    assert t.note[1] == "" and list(t.status) == ["all", "ok", "none"]


def test_weighted_exceedance_is_the_bootstrap_count():
    """k[r, s, g] = sum_m mult[r, m] [D[s, m] > g], against the direct sum."""
    rng = np.random.default_rng(2)
    d = rng.uniform(size=(3, 50))
    gaps = np.linspace(0, 1, 7)
    mult = bootstrap_multiplicities(50, 9, 4)
    assert (mult.sum(1) == 50).all()
    direct = np.einsum("rm,smg->rsg", mult, (d[:, :, None] > gaps[None, None, :]).astype(float))
    assert np.array_equal(weighted_exceedance(d, gaps, mult, block_values=100), direct)


def test_bootstrap_interval_covers_the_median():
    """200 IDA studies of 60 motions (lognormal capacities, median 0.5, beta 0.4), each with a 95 % percentile
    bootstrap interval of the median from 300 resamples of the motions: the count covering 0.5 at least the
    P_FAIL quantile of Binomial(200, 0.92) (the percentile bootstrap's coverage falls a little short of nominal
    at this size: Efron & Tibshirani 1993, ch. 14; 0.92 is that allowance)."""
    rng = np.random.default_rng(8)
    x = np.geomspace(0.1, 2.5, 14)
    covered = 0
    for rep in range(200):
        cap = 0.5 * np.exp(0.4 * rng.standard_normal(60))
        demand = x[:, None] / cap[None, :]  # D > 1 exactly when x > cap: the "gap" 1
        mult = bootstrap_multiplicities(60, 300, rep)
        k = weighted_exceedance(demand, [1.0], mult)[:, :, 0]
        fits = fit_lognormal(np.broadcast_to(x, k.shape), k, np.full(k.shape, 60.0))
        lo, hi = percentile_interval(np.where(fits.status == "ok", fits.theta, np.nan))
        covered += bool(lo <= 0.5 <= hi)
    assert covered >= binom.ppf(P_FAIL, 200, 0.92)


def test_gap_for_probability_inverts_the_fragilities():
    """Fragilities of gaps with median proportional to the gap (theta(g) = g / 0.1 g^-1, beta 0.3): P(g | x) = p
    at g = 0.1 x exp(-beta Phi^-1(p)); on a grid of 400 gaps the log-linear interpolation is within 1e-4."""
    from scipy.special import ndtri

    from pounding_sweep.risk.fragility import Fit

    gaps = np.geomspace(0.01, 1.0, 400)
    fit = Fit(gaps / 0.1, np.full(gaps.size, 0.3), np.zeros(gaps.size), np.full(gaps.size, "ok", dtype=object))
    for x, p in ((1.0, 0.1), (2.0, 0.02), (0.5, 0.5)):
        want = 0.1 * x * math.exp(-0.3 * ndtri(p))
        assert float(gap_for_probability(fit, gaps, x, p)) == pytest.approx(want, rel=1e-4)
    assert math.isnan(float(gap_for_probability(fit, gaps, 100.0, 0.01)))  # beyond the gaps studied


def test_annual_rate_matches_the_power_law_closed_form(tmp_path):
    """lambda = k0 x^-k and a lognormal fragility: k0 theta^-k exp(k^2 beta^2 / 2) (the integral over all x); the
    table covers 1e-3..1e2 g, where the fragility is 0 and 1 to 1e-30: the log-trapezoid's error dominates,
    (Delta ln x)^2 / 12 times the integrand's curvature, about 1e-5 here."""
    k0, k, theta, beta = 1.2e-3, 2.5, 0.6, 0.45
    x = np.geomspace(1e-3, 1e2, 30)
    path = tmp_path / "h.csv"
    path.write_text(
        "# a test curve\nintensity_g,annual_rate\n" + "".join(f"{float(a)!r},{float(k0 * a**-k)!r}\n" for a in x)
    )
    hz = read_hazard(str(path))
    numeric = annual_rate(hz, lambda xs: ndtr(np.log(xs / theta) / beta))
    assert numeric == pytest.approx(power_law_rate(k0, k, theta, beta), rel=1e-4)
    assert isinstance(hz, Hazard)


@pytest.mark.parametrize(
    "text, message",
    [
        ("a,b\n1,2\n", "no column 'intensity_g'"),
        ("intensity_g,annual_rate\n0.1,0.01\n0.2,0.02\n", "must decrease"),
        ("intensity_g,annual_rate\n0.1,0.01\n", "at least 2"),
        ("intensity_g,annual_rate\n0.1,x\n0.2,0.001\n", "row 2"),
    ],
)
def test_bad_hazard_tables_are_refused(tmp_path, text, message):
    from pounding_sweep.errors import InputError

    path = tmp_path / "h.csv"
    path.write_text(text)
    with pytest.raises(InputError, match=message):
        read_hazard(str(path))


def test_a_clouds_bootstrap_fitted_in_blocks_is_the_bootstrap_fitted_at_once(monkeypatch):
    """risk/analysis.py FragilityData.fit takes a cloud's replicates a block at a time (a helper's default study,
    1000 replicates x 100 gaps x 4000 runs at once, filled 24 GiB). Blocks of 7 replicates give the fits of all
    at once, to the iteration's stopping rule: Fisher scoring stops when every fit's step in (a, b) = (-ln theta /
    beta, 1 / beta) is below TOL (1 + |a| + |b|), and a block may stop one step earlier than the whole (quadratic
    convergence: the step after is far smaller), so a and b agree within that."""
    import pandas as pd

    from pounding_sweep.risk import analysis
    from pounding_sweep.risk.fragility import TOL, bootstrap_multiplicities

    rng = np.random.default_rng(5)
    n = 300
    pga = np.exp(rng.normal(np.log(0.3), 0.4, n))
    demand = pd.DataFrame(
        {
            "motion_index": np.arange(n),
            "intensity_g": pga,
            "required_gap_m": 0.1 * pga * np.exp(rng.normal(0.0, 0.5, n)),
        }
    )
    data = analysis.FragilityData(demand, "factor")
    gaps = np.array([0.02, 0.03, 0.05])
    mult = bootstrap_multiplicities(n, 40, seed=1)
    whole = data.fit(gaps, mult)
    monkeypatch.setattr(analysis, "CLOUD_BLOCK_VALUES", 7 * gaps.size * n)
    told: list[tuple[int, int]] = []
    blocks = data.fit(gaps, mult, lambda done, total: told.append((done, total)))
    assert told == [(min(d, 40), 40) for d in range(7, 47, 7)]  # the replicates done after each block of 7
    assert (blocks.status == whole.status).all() and (whole.status == "ok").mean() > 0.9
    ok = whole.status == "ok"

    def ab(f):
        return -np.log(f.theta[ok]) / f.beta[ok], 1.0 / f.beta[ok]

    (a, b), (a_blocks, b_blocks) = ab(whole), ab(blocks)
    bound = TOL * (1.0 + np.abs(a) + np.abs(b))
    assert np.all(np.abs(a_blocks - a) <= bound) and np.all(np.abs(b_blocks - b) <= bound)


def test_the_gap_for_a_probability_is_exact_on_a_coarse_grid_where_the_demand_is_lognormal():
    """gap_for_probability interpolates the probit of P in ln gap: with lognormal required gaps (median 0.1 x g,
    beta 0.3: P(pounding | x, gap) = Phi((ln(0.1 x) - ln gap) / 0.3)) that is a straight line, so 8 gaps 20 mm apart
    give the closed form up to rounding (1e-12 relative: a few ulps through ndtri and exp), where interpolating P
    itself missed by about 1 % (a helper's 20 mm grid: 98.19 mm against 97.35 on a fine one); and
    analysis.interpolation_error, the grid's own error by a third gap, is rounding too."""
    from scipy.special import ndtri

    from pounding_sweep.risk.analysis import interpolation_error
    from pounding_sweep.risk.fragility import Fit

    gaps = np.arange(0.05, 0.21, 0.02)
    # a fragility per gap: P(demand > gap | x) = Phi(ln(x / (gap / 0.1)) / 0.3), i.e. median theta = gap / 0.1 g
    fit = Fit(gaps / 0.1, np.full(gaps.size, 0.3), np.zeros(gaps.size), np.full(gaps.size, "ok", dtype=object))
    for x, p in ((1.0, 0.1), (1.0, 0.02), (1.2, 0.5)):
        want = 0.1 * x * math.exp(-0.3 * ndtri(p))
        got = float(gap_for_probability(fit, gaps, x, p))
        assert got == pytest.approx(want, rel=1e-12)
        assert interpolation_error(fit, gaps, x, p, got) <= 1e-12 * want


def test_the_grid_error_is_not_given_where_the_fits_do_not_fall_with_the_gap():
    """analysis.interpolation_error on fits whose probability does not fall with the gap (weakly identified: a
    reviewer's P = .30, .12, .08, .125 on a 10 mm grid) is NaN, not a 30 mm 'error' or an overflow; and a fit far in
    its tail (z = 9: P = 1.0 in double precision) is interpolated by its probit, not by P."""
    from scipy.special import ndtri

    from pounding_sweep.risk.analysis import interpolation_error
    from pounding_sweep.risk.fragility import Fit

    gaps = np.array([0.04, 0.05, 0.06, 0.07])
    for last in (0.125, 0.1201, 0.1199999):
        z = ndtri(np.array([0.30, 0.12, 0.08, last]))
        fit = Fit(np.exp(-z * 0.5), np.full(4, 0.5), np.zeros(4), np.full(4, "ok", dtype=object))  # P(x = 1) as given
        est = float(gap_for_probability(fit, gaps, 1.0, 0.1))
        assert 0.05 < est < 0.06 and math.isnan(interpolation_error(fit, gaps, 1.0, 0.1, est))
    # median theta = gap / 0.1 g, beta 0.05: at x = 1 g the smallest gap's z = ln(1 / 0.4) / 0.05 = 18 (P = 1.0)
    gaps = np.array([0.04, 0.08, 0.12])
    fit = Fit(gaps / 0.1, np.full(3, 0.5), np.zeros(3), np.full(3, "ok", dtype=object))
    want = 0.1 * math.exp(-0.5 * ndtri(0.5))  # P = 0.5 at 0.1 m
    assert float(gap_for_probability(fit, gaps, 1.0, 0.5)) == pytest.approx(want, rel=1e-12)
    steep = Fit(gaps / 0.1, np.full(3, 0.05), np.zeros(3), np.full(3, "ok", dtype=object))
    assert float(steep.probability(np.array([1.0]))[0, 0]) == 1.0 and steep.probit(np.array([1.0]))[0, 0] > 18
    assert float(gap_for_probability(steep, gaps, 1.0, 0.5)) == pytest.approx(0.1, rel=1e-12)
