"""Probabilities from an ensemble of runs, with exact sampling intervals: the probability of pounding at any
gap from the contact-free runs' required gaps, and the gap a target probability needs.

Pounding at gap g happens exactly when the run's required gap D (the largest closing relative displacement
over the floor pairs) exceeds g, so with k of n motions having D > g the estimate is k / n, a binomial
proportion. Its interval is Clopper & Pearson's (1934, "The use of confidence or fiducial limits illustrated in
the case of the binomial", Biometrika 26:404-413): the exact beta quantiles [B(a/2; k, n - k + 1),
B(1 - a/2; k + 1, n - k)], which cover the true probability with at least the stated confidence for every p
(scipy.stats.binomtest's 'exact' method gives the same).

The gap for a target probability p is the (1 - p) quantile of D: g_p = D_(r), the r-th smallest of the n values,
r = ceil(n (1 - p)) (the smallest order statistic whose exceedance fraction is at most p). Its distribution-free
interval is a pair of order statistics [D_(l), D_(u)] with P(l <= B < u) >= confidence, B ~ Binomial(n, 1 - p)
(the number of draws at or below the true quantile; Hahn & Meeker, Statistical Intervals, 1991, sec. 5.2):
exact for any continuous D, and none exists (NaN) when n is too small for the level.
"""

from __future__ import annotations

import math

import numpy as np


def clopper_pearson(k, n, confidence: float = 0.95) -> tuple[np.ndarray, np.ndarray]:
    """Exact (Clopper-Pearson) two-sided interval of a binomial proportion k / n, elementwise."""
    from scipy.stats import beta

    k, n = np.asarray(k, dtype=float), np.asarray(n, dtype=float)
    a = 1.0 - confidence
    with np.errstate(invalid="ignore", divide="ignore"):
        lo = np.where(k > 0, beta.ppf(a / 2, k, n - k + 1), 0.0)
        hi = np.where(k < n, beta.ppf(1 - a / 2, k + 1, n - k), 1.0)
    return lo, hi


def exceedance_counts(demand, gaps) -> np.ndarray:
    """k[g] = #{demand > gaps[g]} along the last axis of demand (..., n) -> (..., gaps)."""
    d = np.sort(np.asarray(demand, dtype=float), axis=-1)
    n = d.shape[-1]
    g = np.asarray(gaps, dtype=float)
    flat = d.reshape(-1, n)
    out = np.stack([n - np.searchsorted(row, g, side="right") for row in flat])
    return out.reshape(d.shape[:-1] + g.shape)


def probability_of_pounding(demand, gaps, confidence: float = 0.95) -> dict[str, np.ndarray]:
    """P(D > g) for each gap, with its Clopper-Pearson interval: columns pounding (k), motions (n), probability,
    ci_low, ci_high."""
    d = np.asarray(demand, dtype=float)
    k = exceedance_counts(d, gaps)
    n = np.full(k.shape, d.shape[-1])
    lo, hi = clopper_pearson(k, n, confidence)
    return {"pounding": k, "motions": n, "probability": k / n, "ci_low": lo, "ci_high": hi}


def quantile_rank(n: int, p: float) -> int:
    """r = ceil(n (1 - p)): D_(r) is the smallest order statistic exceeded by at most a fraction p of the n."""
    return max(1, min(n, math.ceil(n * (1.0 - p) - 1e-12)))


def order_statistic_interval(n: int, q: float, confidence: float = 0.95) -> tuple[int | None, int | None]:
    """1-based ranks (l, u) with P(D_(l) <= x_q < D_(u)) >= confidence for the q-quantile x_q of a continuous
    distribution (B ~ Binomial(n, q): P(l <= B < u)), as symmetric in tail probability as the binomial allows;
    (None, None) when even (1, n) falls short."""
    from scipy.stats import binom

    a = (1.0 - confidence) / 2.0
    # the largest l with P(B < l) <= a, the smallest u with P(B >= u) <= a
    cdf = binom.cdf(np.arange(n + 1), n, q)  # cdf[j] = P(B <= j)
    below = np.concatenate([[0.0], cdf[:-1]])  # P(B < l) for l = 0..n
    ls = np.flatnonzero(below <= a)
    l = int(ls.max()) if ls.size else 0
    us = np.flatnonzero(1.0 - below <= a)  # P(B >= u) = 1 - P(B < u)
    u = int(us.min()) if us.size else n + 1
    if l < 1 or u > n:
        return None, None
    return l, u


def required_gap_empirical(demand, p: float, confidence: float = 0.95) -> tuple[float, float, float]:
    """(g_p, low, high): the gap that leaves a fraction p of the motions pounding, and its distribution-free
    interval (module docstring; the interval NaN where n is too small for that level, all three NaN where
    n p < 1: a sample without one expected exceedance does not reach that quantile)."""
    d = np.sort(np.asarray(demand, dtype=float))
    n = d.size
    if n * p < 1.0:  # fewer than one motion expected beyond it: the largest value says nothing of that quantile
        return math.nan, math.nan, math.nan
    r = quantile_rank(n, p)
    l, u = order_statistic_interval(n, 1.0 - p, confidence)
    if l is None:
        return float(d[r - 1]), math.nan, math.nan
    return float(d[r - 1]), float(d[l - 1]), float(d[u - 1])


__all__ = [
    "clopper_pearson",
    "exceedance_counts",
    "probability_of_pounding",
    "quantile_rank",
    "order_statistic_interval",
    "required_gap_empirical",
]
