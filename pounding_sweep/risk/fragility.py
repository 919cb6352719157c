"""Lognormal fragility curves by maximum likelihood, many at once, with intervals from a bootstrap over motions.

A fragility P(pounding | x) = Phi(ln(x / theta) / beta) (median theta, dispersion beta) is fitted to binary
outcomes at intensities x by maximising the binomial likelihood, Baker (2015, "Efficient analytical fragility
function fitting using dynamic structural analysis", Earthq. Spectra 31(1):579-599, eq. 11):

    L = prod_i C(n_i, k_i) p_i^k_i (1 - p_i)^(n_i - k_i),   p_i = Phi((ln x_i - ln theta) / beta),

with k_i of n_i motions pounding at x_i: a stripe of an incremental dynamic analysis (n_i = the motions), or
one motion of a cloud (n_i = 1). It is a probit regression of the outcome on ln x, p = Phi(a + b ln x) with
b = 1 / beta and a = -ln(theta) / beta, solved here by Fisher scoring (iteratively reweighted least squares:
McCullagh & Nelder, Generalized Linear Models, 2nd ed. 1989, sec. 2.5), vectorised over any number of
fragilities (one per gap, per bootstrap replicate). The maximum exists only when the outcomes overlap in x:
all-or-nothing stripes that separate (every pounding above every non-pounding) drive beta to 0 (Baker 2015,
sec. "Potential problems"; quasi-separation too: every pounding at or above every non-pounding, with both at one
intensity at most, where the likelihood's supremum is a step at that intensity), and no pounding at all (or
pounding everywhere) drives theta out of the data's range; those fits are flagged, not reported as numbers they
are not: their log-likelihood is the supremum the data allow (0 for a perfect step, the mixed intensity's own
binomial term for a quasi-separated one), not a fitted curve's.

Intervals: the motions are resampled with replacement (each replicate a multiset of the motions, all their
stripes kept together: the stripes of an IDA share their motions and are not independent) and every
fragility refitted; the percentile interval of the replicates (Efron & Tibshirani, An Introduction to the
Bootstrap, 1993, sec. 13.3), given only where the estimate itself exists and where at most (1 - confidence) / 2
of the replicates fail to give a value (bootstrap_interval): a replicate that fails (its target beyond the gaps
studied, its fit not identified) has no value, and the missing ones could all lie in one tail, so past that share
the percentile interval of the others is not a `confidence` interval.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: Fisher-scoring iterations and the step below which a fit has converged (in a and b)
MAX_ITER = 100
TOL = 1e-10
#: a fit whose beta falls below this is separated data (the MLE is at beta = 0): not identified
MIN_BETA = 1e-3
#: the probit argument is clipped here in the iterations (Phi(-40) underflows to 1e-350: saturated either way)
EDGE = 40.0


@dataclass(frozen=True)
class Fit:
    """Lognormal fragilities, elementwise over the leading shape: median theta (in the intensity's unit),
    dispersion beta, log-likelihood, and whether the data identify them: 'ok'; 'separated' (beta -> 0);
    'none' or 'all' (no point pounded, every point did); 'flat' (pounding does not grow with x)."""

    theta: np.ndarray
    beta: np.ndarray
    loglik: np.ndarray
    status: np.ndarray  # str

    def probit(self, x) -> np.ndarray:
        """Phi^-1(P(pounding | x)) on the fitted curves, ln(x / theta) / beta, straight from the fit (a round trip
        through P saturates at 1 beyond z = 8.3): (..., len(x)); -inf where no point pounded, +inf where every point
        did, NaN for separated data (no fragility is identified)."""
        x = np.asarray(x, dtype=float)
        th, be = self.theta[..., None], self.beta[..., None]
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            z = np.log(x / th) / be
        z = np.where(self.status[..., None] == "none", -np.inf, z)
        z = np.where(self.status[..., None] == "all", np.inf, z)
        bad = (self.status[..., None] == "separated") | (self.status[..., None] == "flat")
        return np.where(bad, np.nan, z)  # not identified: no curve to give

    def probability(self, x) -> np.ndarray:
        """P(pounding | x) on the fitted curves: (..., len(x)); 0 where no point pounded, 1 where every point did,
        NaN for separated data (no fragility is identified)."""
        from scipy.special import ndtr

        return ndtr(self.probit(x))


def fit_lognormal(x, k, n, weights=None) -> Fit:
    """MLE of lognormal fragilities (module docstring). x: (..., m) intensities (> 0); k, n: (..., m) outcomes
    pounding and trials (n may be 0: a point that carries no data); `weights` multiply k and n (bootstrap
    multiplicities). Every leading index is its own fit."""
    from scipy.special import log_ndtr, ndtr

    x = np.asarray(x, dtype=float)
    k = np.asarray(k, dtype=float)
    n = np.asarray(n, dtype=float)
    if weights is not None:
        k, n = k * weights, n * weights
    x, k, n = np.broadcast_arrays(x, k, n)
    lx = np.log(x)
    shape = x.shape[:-1]
    ktot, ntot = k.sum(-1), n.sum(-1)
    status = np.full(shape, "ok", dtype=object)
    status[ktot == 0] = "none"
    status[ktot == ntot] = "all"
    # separated: every point with a pounding lies above every point without one (no overlap in ln x)
    has_k = k > 0
    has_not = (n - k) > 0
    lo_k = np.where(has_k, lx, np.inf).min(-1)
    hi_not = np.where(has_not, lx, -np.inf).max(-1)
    # (quasi-)separated: every pounding at or above every non-pounding; both at one intensity at most (ties in a
    # cloud pooled there)
    separated = hi_not <= lo_k
    status[(status == "ok") & separated] = "separated"
    ok = status == "ok"
    # start: least squares of the probit of the empirical fractions (clipped), or a unit slope
    frac = np.clip((k + 0.5) / (n + 1.0), 1e-3, 1 - 1e-3)
    from scipy.special import ndtri

    zf = ndtri(frac)
    w0 = n
    sw = np.maximum(w0.sum(-1), 1e-300)
    mx = (w0 * lx).sum(-1) / sw
    mz = (w0 * zf).sum(-1) / sw
    sxx = (w0 * (lx - mx[..., None]) ** 2).sum(-1)
    sxz = (w0 * (lx - mx[..., None]) * (zf - mz[..., None])).sum(-1)
    b = np.where(sxx > 0, sxz / np.where(sxx > 0, sxx, 1.0), 1.0)
    b = np.where(b > 0.1, b, 1.0)
    a = mz - b * mx

    def loglik(a, b):
        eta = np.clip(a[..., None] + b[..., None] * lx, -EDGE, EDGE)
        return np.where(ok, (k * log_ndtr(eta) + (n - k) * log_ndtr(-eta)).sum(-1), 0.0)

    ll = loglik(a, b)
    for _ in range(MAX_ITER):
        eta = np.clip(a[..., None] + b[..., None] * lx, -EDGE, EDGE)
        mu = np.clip(ndtr(eta), 1e-300, 1 - 1e-16)
        dens = np.exp(-0.5 * eta * eta) / math.sqrt(2.0 * math.pi)
        w = n * dens * dens / (mu * (1.0 - mu))
        score = dens * (k - n * mu) / (mu * (1.0 - mu))  # d loglik / d eta
        ga, gb = score.sum(-1), (score * lx).sum(-1)
        haa, hab, hbb = w.sum(-1), (w * lx).sum(-1), (w * lx * lx).sum(-1)
        det = haa * hbb - hab * hab
        det = np.where(np.abs(det) > 0, det, 1.0)
        da = np.where(ok, (hbb * ga - hab * gb) / det, 0.0)
        db = np.where(ok, (haa * gb - hab * ga) / det, 0.0)
        # step halving: the likelihood never decreases (Fisher scoring from a poor start can overshoot)
        for _ in range(40):
            trial = loglik(a + da, b + db)
            worse = trial < ll - 1e-12 * np.abs(ll)
            if not worse.any():
                break
            da, db = np.where(worse, 0.5 * da, da), np.where(worse, 0.5 * db, db)
        a, b, ll = a + da, b + db, loglik(a + da, b + db)
        if np.all(np.abs(da) + np.abs(db) <= TOL * (1.0 + np.abs(a) + np.abs(b))):
            break
    # a slope at or below 0 (pounding not growing with x) or a median beyond any intensity: no fragility
    log_theta = np.where(ok & (b > 0), -a / np.where(ok & (b > 0), b, 1.0), np.inf)
    flat = ok & ~((b > 0) & (np.abs(log_theta) < 700.0))
    status[flat] = "flat"
    ok = ok & ~flat
    beta = np.where(ok, 1.0 / np.where(ok, b, 1.0), np.nan)
    theta = np.where(ok, np.exp(np.where(ok, log_theta, 0.0)), np.nan)
    status[ok & ~(beta >= MIN_BETA)] = "separated"
    # the separated and degenerate fits: where the data put them, for what they are
    mid = 0.5 * (np.where(np.isfinite(lo_k), lo_k, 0.0) + np.where(np.isfinite(hi_not), hi_not, 0.0))
    theta = np.where(status == "separated", np.exp(np.where(status == "separated", mid, 0.0)), theta)
    theta = np.where(status == "none", np.inf, np.where(status == "all", 0.0, theta))
    beta = np.where(status == "ok", beta, np.where(status == "separated", 0.0, np.nan))
    eta = np.log(x / np.where(status == "ok", theta, 1.0)[..., None]) / np.where(status == "ok", beta, 1.0)[..., None]
    # the supremum the data allow where no curve is fitted: a separated step fits every point but those at the one
    # intensity where both outcomes meet (pooled: their own binomial maximum); a flat fit's is the pooled binomial
    # of every point (a curve that does not rise); 'none' and 'all' fit every point (0)
    at_edge = (lx == lo_k[..., None]) & (hi_not == lo_k)[..., None]
    ll = np.where(
        status == "ok",
        (k * log_ndtr(eta) + (n - k) * log_ndtr(-eta)).sum(-1),
        np.where(
            status == "separated",
            _binomial_max((k * at_edge).sum(-1), (n * at_edge).sum(-1)),
            np.where(status == "flat", _binomial_max(ktot, ntot), 0.0),
        ),
    )
    return Fit(theta, beta, ll, status)


def _binomial_max(k, n) -> np.ndarray:
    """k ln(k / n) + (n - k) ln(1 - k / n): the largest binomial log-likelihood of k of n (0 where k is 0 or n)."""
    k, n = np.asarray(k, dtype=float), np.asarray(n, dtype=float)
    with np.errstate(divide="ignore", invalid="ignore"):
        q = np.where(n > 0, k / np.where(n > 0, n, 1.0), 0.0)
        return np.where((k > 0) & (k < n), k * np.log(q) + (n - k) * np.log1p(-q), 0.0)


def bootstrap_multiplicities(n_motions: int, replicates: int, seed: int) -> np.ndarray:
    """(replicates, n_motions) counts of each motion in each bootstrap replicate (a multinomial draw of
    n_motions from n_motions, by resampling indices), from numpy's PCG64 seeded by `seed`."""
    rng = np.random.Generator(np.random.PCG64(np.random.SeedSequence(seed)))
    out = np.empty((replicates, n_motions), dtype=np.int64)
    for r in range(replicates):
        out[r] = np.bincount(rng.integers(0, n_motions, n_motions), minlength=n_motions)
    return out


def weighted_exceedance(demand, gaps, mult, block_values: int = 2**23) -> np.ndarray:
    """k[r, s, g] = sum over motions m of mult[r, m] [demand[s, m] > gaps[g]]: each replicate's count of
    poundings per stripe s and gap g (demand: (stripes, motions); mult: (replicates, motions)). Sorted once per
    stripe; the replicates' counts are suffix sums of their multiplicities in that order, taken a block of
    replicates at a time (at most `block_values` numbers in memory)."""
    demand = np.asarray(demand, dtype=float)
    gaps = np.asarray(gaps, dtype=float)
    mult = np.asarray(mult)
    r_all, m = mult.shape
    out = np.empty((r_all, demand.shape[0], gaps.size))
    step = max(1, block_values // max(m, 1))
    for s, row in enumerate(demand):
        order = np.argsort(row, kind="stable")
        pos = np.searchsorted(row[order], gaps, side="right")  # motions above gap g: sorted positions pos[g]..m-1
        for r0 in range(0, r_all, step):
            block = mult[r0 : r0 + step][:, order]
            tail = np.zeros((block.shape[0], m + 1))
            tail[:, :m] = np.cumsum(block[:, ::-1], axis=1)[:, ::-1]  # tail[:, i] = sum over positions >= i
            out[r0 : r0 + step, s, :] = tail[:, pos]
    return out


def percentile_interval(values, confidence: float = 0.95, axis: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """The bootstrap percentile interval along `axis` (NaN replicates ignored; NaN where none is finite)."""
    a = (1.0 - confidence) / 2.0
    v = np.asarray(values, dtype=float)
    with np.errstate(invalid="ignore"):
        import warnings

        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            lo = np.nanquantile(v, a, axis=axis)
            hi = np.nanquantile(v, 1.0 - a, axis=axis)
    return lo, hi


def bootstrap_interval(replicates, estimate, confidence: float = 0.95) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(low, high, found): the percentile interval of all the replicates (along axis 0) whatever the values of
    those that give none, and the share that give one. With a share f of them missing (their values unknown, all
    possibly in one tail), the a = (1 - confidence) / 2 quantile of all lies at or above the (a - f) / (1 - f)
    quantile of the others, and the 1 - a quantile at or below their (1 - a) / (1 - f) quantile: that interval
    holds at least `confidence` of all. NaN where the estimate is not finite or f > a (module docstring)."""
    v = np.asarray(replicates, dtype=float)
    found = np.isfinite(v).mean(axis=0)
    a = (1.0 - confidence) / 2.0
    f = np.clip(1.0 - found, 0.0, a)
    ok = np.isfinite(np.asarray(estimate, dtype=float)) & (1.0 - found <= a + 1e-12)
    lo, hi = _column_quantiles(v, (a - f) / (1.0 - f)), _column_quantiles(v, (1.0 - a) / (1.0 - f))
    return np.where(ok, lo, np.nan), np.where(ok, hi, np.nan), found


def _column_quantiles(v: np.ndarray, q) -> np.ndarray:
    """np.nanquantile of each column of v (axis 0) at its own level q (broadcast over the other axes; a 1-D v is
    one column); NaN for a column without a finite value."""
    q = np.broadcast_to(np.asarray(q, dtype=float), v.shape[1:])
    out = np.empty(v.shape[1:])
    for idx in np.ndindex(*v.shape[1:]):
        col = v[(slice(None), *idx)]
        out[idx] = np.nanquantile(col, q[idx]) if np.isfinite(col).any() else np.nan
    return out


def gap_for_probability(fit: Fit, gaps, x: float, p: float) -> np.ndarray:
    """The gap at which the fitted fragilities (one per gap along the last axis, gaps increasing) give
    P(pounding | x) = p, by linear interpolation of the probability's probit Phi^-1(P) in ln(gap) between the two
    grid gaps that bracket p: exact where the required gaps at x are lognormal (P = Phi((ln median - ln gap) /
    beta): the probit is linear in ln gap), where P itself falls convexly (a helper's 20 mm grid, interpolated in
    P, put a 10 % gap at 98.19 mm, a 2.5 mm grid at 97.35; in the probit: 97.1). The probits come from the fits
    (Fit.probit), not back from P. Linear in P where a bracketing fit is 'none' or 'all' (P exactly 0 or 1). NaN
    where the grid does not bracket p (the target lies beyond the gaps studied) or a bracketing fit is not
    identified (separated data)."""
    from scipy.special import ndtr, ndtri

    g = np.asarray(gaps, dtype=float)
    zg = fit.probit(np.array([x]))[..., 0]  # (..., gaps)
    prob = ndtr(zg)
    # P decreases with the gap: the first grid gap at which it drops to p or below
    below = prob <= p
    first = np.argmax(below, axis=-1)
    found = below.any(-1) & (first > 0)
    i1 = np.clip(first, 1, g.size - 1)
    i0 = i1 - 1
    p0 = np.take_along_axis(prob, i0[..., None], -1)[..., 0]
    p1 = np.take_along_axis(prob, i1[..., None], -1)[..., 0]
    found &= np.isfinite(p0) & np.isfinite(p1)
    lg = np.log(g)
    z0 = np.take_along_axis(zg, i0[..., None], -1)[..., 0]
    z1 = np.take_along_axis(zg, i1[..., None], -1)[..., 0]
    with np.errstate(divide="ignore", invalid="ignore"):
        zt = ndtri(p)
        probit = np.isfinite(z0) & np.isfinite(z1) & (z0 != z1)
        t = np.where(probit, (z0 - zt) / (z0 - z1), np.where(p0 != p1, (p0 - p) / (p0 - p1), 0.0))
    out = np.exp(lg[i0] + np.clip(np.nan_to_num(t), 0.0, 1.0) * (lg[i1] - lg[i0]))
    return np.where(found, out, np.nan)


__all__ = [
    "Fit",
    "fit_lognormal",
    "bootstrap_multiplicities",
    "weighted_exceedance",
    "percentile_interval",
    "bootstrap_interval",
    "gap_for_probability",
]
