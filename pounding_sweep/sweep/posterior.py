"""Posterior samples of a calibration's parameters: an affine-invariant ensemble sampler whose walkers' proposals
run as one batch on the grid engine, beside the Gauss-Newton and profile intervals.

Why: the intervals of sweep/calibrate.py are local (Gauss-Newton) or one parameter at a time (profiles); samples
of the joint posterior show the parameters' joint shape (a curved ridge between k_s/k and r, a bound that cuts
the distribution) and give every derived quantity an interval.

Target, in the fit's coordinates z (log for stiffnesses): a flat prior inside the bounds and the likelihood the
profiles use, log p(z) = -(RSS(z) - RSS_opt) / (2 s^2 N / N_eff) (s^2 = RSS_opt / (N - p) inflated for the
residuals' correlation: calibrate.py's docstring), so the marginal 95 % credible interval of a parameter and its
profile interval (delta chi^2 <= 3.84 on the same scale) agree where the posterior is close to normal.

Sampler: the stretch move of Goodman & Weare (2010, "Ensemble samplers with affine invariance", Comm. App. Math.
Comp. Sci. 5:65, eq. 7), in the parallel form of Foreman-Mackey et al. (2013, "emcee: the MCMC hammer", PASP
125:306, algorithm 3): the walkers split in two halves, each walker of one half proposes Y = X_j + Z (X_k - X_j)
with X_j a random walker of the other half and Z drawn from g(Z) ~ 1/sqrt(Z) on [1/a, a] (a = 2), accepted with
probability min(1, Z^(p-1) p(Y) / p(X_k)); one half's proposals are one batch of runs. Walkers start from the
Gauss-Newton normal approximation at the optimum (uniform over the bounds along directions it cannot bound).
Reported: the acceptance fraction, the integrated autocorrelation time tau of each parameter (the walkers'
autocorrelation averaged, Sokal's window c tau <= M with c = 5: Sokal 1997, "Monte Carlo methods in statistical
mechanics", sec. 3), the effective sample count (samples after burn-in / tau), and the 2.5 % and 97.5 %
quantiles. The first BURN share of the steps is discarded.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

STRETCH = 2.0  # a of the stretch move (Goodman & Weare's and emcee's default)
BURN = 0.25  # share of the steps discarded as burn-in
WALKERS_PER_PARAMETER = 4


@dataclass
class Posterior:
    """Samples (after burn-in) of the parameters, and how well the sampler mixed."""

    names: list[str]
    samples: np.ndarray  # (n, p) parameter values (not fit coordinates)
    chain_z: np.ndarray  # (steps, walkers, p) the whole chain in fit coordinates
    acceptance: float
    tau: np.ndarray  # (p,) integrated autocorrelation time [steps]
    ess: float  # effective samples: samples after burn-in / the largest tau
    runs: int
    seconds: float
    intervals: dict[str, tuple[float, float]] = field(default_factory=dict)  # 2.5 % and 97.5 % quantiles


def stretch_sampler(logp_batch, z0: np.ndarray, steps: int, rng: np.random.Generator, lo=None, hi=None):
    """The parallel stretch move (module docstring) for a log density `logp_batch((m, p) array) -> (m,)`, from the
    walkers z0 (W, p), W even; proposals outside [lo, hi] are rejected without a run. Returns (chain (steps, W, p),
    log densities (steps, W), acceptance fraction)."""
    z = np.array(z0, float)
    W, p = z.shape
    if W % 2 or W < 2 * p:
        raise ValueError(f"stretch_sampler: {W} walkers; an even count of at least 2 p = {2 * p}")
    lp = logp_batch(z)
    chain, lps = np.empty((steps, W, p)), np.empty((steps, W))
    accepted = 0
    halves = (np.arange(0, W // 2), np.arange(W // 2, W))
    for step in range(steps):
        for k in (0, 1):
            mine, other = halves[k], halves[1 - k]
            zz = ((STRETCH - 1.0) * rng.uniform(size=mine.size) + 1.0) ** 2 / STRETCH  # g(Z) ~ 1/sqrt(Z)
            partner = z[rng.choice(other, size=mine.size)]
            y = partner + zz[:, None] * (z[mine] - partner)
            inside = np.ones(mine.size, bool)
            if lo is not None:
                inside = np.all((y >= lo) & (y <= hi), axis=1)
            lp_y = np.full(mine.size, -np.inf)
            if inside.any():
                lp_y[inside] = logp_batch(y[inside])
            with np.errstate(invalid="ignore", over="ignore"):
                log_ratio = (p - 1) * np.log(zz) + lp_y - lp[mine]
            take = np.log(rng.uniform(size=mine.size)) < log_ratio
            z[mine[take]] = y[take]
            lp[mine[take]] = lp_y[take]
            accepted += int(take.sum())
        chain[step], lps[step] = z, lp
    return chain, lps, accepted / (steps * W)


def autocorrelation_time(x: np.ndarray, c: float = 5.0) -> float:
    """Integrated autocorrelation time of a chain x (steps, walkers) of one parameter: the walkers' normalised
    autocorrelation functions averaged, summed up to the first window M with M >= c tau(M) (Sokal)."""
    steps = x.shape[0]
    f = np.zeros(steps)
    for w in range(x.shape[1]):
        y = x[:, w] - x[:, w].mean()
        n = 1 << (2 * steps - 1).bit_length()
        acf = np.fft.irfft(np.abs(np.fft.rfft(y, n)) ** 2)[:steps]
        if acf[0] > 0:
            f += acf / acf[0]
    f /= x.shape[1]
    taus = 2.0 * np.cumsum(f) - 1.0
    m = np.arange(steps)
    ok = m >= c * taus
    return float(taus[np.argmax(ok)] if ok.any() else taus[-1])


def sample_posterior(fit, steps: int = 150, walkers: int | None = None, seed: int = 0, progress=None) -> Posterior:
    """Posterior samples of `fit` (a calibrate.Fit with its Problem) by the module docstring's sampler."""
    from pounding_sweep.sweep.fitstats import gauss_newton

    prob = fit.problem
    lo, hi = prob.z_bounds
    p = len(prob.names)
    W = walkers or max(2 * p + 2, WALKERS_PER_PARAMETER * p)
    W += W % 2
    N = fit.n
    gn = gauss_newton(prob.jac(fit.z_opt), fit.residuals, fit.sizes, p)
    s2_eff = gn.s2 * N / gn.n_eff
    rng = np.random.default_rng(seed)
    runs0, t0 = prob.evaluations, time.perf_counter()

    def logp(zs):
        r = prob.residuals(np.array([prob.to_theta(z) for z in zs]))
        return -(np.sum(r * r, axis=1) - fit.rss) / (2.0 * s2_eff)

    # start: the normal approximation (uniform across the bounds where it has no finite spread), inside the bounds
    se = np.where(np.isfinite(gn.se_z), gn.se_z, np.inf)
    corr = np.where(np.isfinite(gn.corr), gn.corr, 0.0)
    np.fill_diagonal(corr, 1.0)
    finite = np.isfinite(se)
    cov = corr[np.ix_(finite, finite)] * np.outer(se[finite], se[finite])
    z0 = np.empty((W, p))
    z0[:, finite] = rng.multivariate_normal(fit.z_opt[finite], cov, size=W, method="eigh")
    z0[:, ~finite] = rng.uniform(lo[~finite], hi[~finite], size=(W, int((~finite).sum())))
    z0 = np.clip(z0, lo, hi)
    done = []

    def logp_progress(zs):
        out = logp(zs)
        done.append(zs.shape[0])
        if progress is not None and len(done) % 20 == 0:
            progress(f"posterior: {sum(done)} runs")
        return out

    chain, _, acc = stretch_sampler(logp_progress, z0, steps, rng, lo, hi)
    keep = chain[int(BURN * steps) :]
    tau = np.array([autocorrelation_time(keep[:, :, j]) for j in range(p)])
    flat = keep.reshape(-1, p)
    samples = np.array([prob.to_theta(z) for z in flat])
    post = Posterior(
        list(prob.names),
        samples,
        chain,
        acc,
        tau,
        float(flat.shape[0] / max(tau.max(), 1.0)),
        prob.evaluations - runs0,
        time.perf_counter() - t0,
    )
    for j, n in enumerate(prob.names):
        post.intervals[n] = (float(np.quantile(samples[:, j], 0.025)), float(np.quantile(samples[:, j], 0.975)))
    return post


def quantile_error(ess: float, q: float = 0.025) -> float:
    """Standard error of a normal distribution's q quantile estimated from `ess` independent samples, in units of
    its standard deviation: sqrt(q (1 - q) / ess) / phi(z_q) (the asymptotic variance of a sample quantile)."""
    from scipy.stats import norm

    return math.sqrt(q * (1 - q) / ess) / float(norm.pdf(norm.ppf(q)))
