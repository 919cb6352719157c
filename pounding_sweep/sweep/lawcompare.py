"""Which contact law do the data prefer? Every calibrated law compared on one basis, by two criteria, with the
answer "the data cannot decide" where they disagree or the difference is within a tie band.

Why: the residuals of a calibrated pounding model are correlated in time (model error, tracking), so a
likelihood that counts N independent samples overstates every difference. The previous comparison deflated
it with each law's own effective count N_eff (from its own residuals' lag-1 autocorrelation); a law with more
structured, that is worse, residuals got a smaller N_eff and so a smaller AIC: a law with 30 % less residual
lost by delta AIC 132.

1. Information criteria on one effective count. AIC = N_c ln(RSS / N) + 2 p and BIC = N_c ln(RSS / N)
   + p ln N_c, N_c the same for every law: N_eff = N (1 - rho) / (1 + rho) (AR(1), calibrate.effective_count)
   of one reference residual series, the best-fitting law's (least RSS). Why that one: the count says how many
   independent samples the data hold, a property of the measurement, not of a law; the residuals closest to
   the noise estimate it best, while a worse law's extra residual is model error, correlated by nature, and
   would make the count that law's (the least count over the laws let a law that cannot fit at all set it for
   every law: 19 against the others' 275-302 on tests/sweep/test_lawcompare.py's end-to-end case). A common
   count can never reverse the order of two laws' residuals at equal p. Tie band: 2 for both (AIC: Burnham &
   Anderson 2002, Model Selection and Multimodel Inference, sec. 2.6; BIC: Kass & Raftery 1995, JASA 90:773,
   "not worth more than a bare mention").
2. Blocked cross-validation, robust to correlated residuals: the scored record cut into FOLDS contiguous blocks
   of equal duration; each law refitted (least squares from its optimum) on the samples outside a block and a
   buffer on either side of it (hv-block cross-validation: Racine 2000, J. Econometrics 99:39; the buffer one
   AR(1) correlation length (1 + rho) / (1 - rho) samples of the law's residuals), then scored on the block.
   Every sample is held out once; the criterion is the held-out sum of squared noise-normalised residuals.
   Tie band: the Diebold-Mariano test (Diebold & Mariano 1995, J. Bus. Econ. Stat. 13:253) of the held-out
   squared-error difference between each law and the best: per channel the sum of the loss differences d_t
   over its held-out samples, its variance T times the long-run variance of d_t (Bartlett kernel, bandwidth by
   Andrews' AR(1) plug-in: Andrews 1991, Econometrica 59:817, eq. 6.4), the channels' standard deviations
   added (Cauchy-Schwarz: the bound for channels correlated in any way); |z| < 1.96 (two-sided 5 %) is a tie.
Verdict: a law is chosen when AIC, BIC and cross-validation name the same best law and none of them ties it
with another; otherwise "the data cannot decide", between the laws the criteria name or tie.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from pounding_sweep.sweep.fitstats import local_fit

TIE = 2.0  # AIC and BIC tie band (module docstring)
DM_Z = 1.959963984540054  # two-sided 5 % normal quantile: the cross-validation tie band
FOLDS = 4  # cross-validation blocks


@dataclass
class LawComparison:
    """The laws compared (module docstring): per law the criteria, the best and tied laws per criterion, the
    verdict."""

    laws: list[str]
    params: dict[str, int]
    n: int
    n_eff_common: float
    n_eff_own: dict[str, float]
    rss: dict[str, float]
    aic: dict[str, float]
    bic: dict[str, float]
    cv_rss: dict[str, float]  # held-out sum of squared noise-normalised residuals
    cv_z: dict[str, float]  # Diebold-Mariano z of the law's held-out loss against the cross-validation best
    best: dict[str, str]  # criterion -> law
    tied: dict[str, list[str]]  # criterion -> laws within its tie band of its best (the best included)
    chosen: str | None  # the law the data choose, or None: they cannot decide
    candidates: list[str]  # the laws the data cannot tell apart (chosen alone when chosen)
    seconds: float = 0.0
    evaluations: int = 0
    folds: list[tuple[float, float]] = field(default_factory=list)  # the held-out blocks (experiment time [s])

    @property
    def text(self) -> str:
        """One line: the law chosen, or why the data cannot decide."""
        crit = (
            f"AIC {self.best['aic']}, BIC {self.best['bic']}, held-out {self.best['cv']} "
            f"(AIC/BIC on N_eff = {self.n_eff_common:.0f} for every law, tie 2; cross-validation {FOLDS} blocks, "
            f"tie |z| < 1.96)"
        )
        if self.chosen is not None:
            return f"the data choose {self.chosen}: {crit}"
        return f"the data cannot decide between the contact laws {', '.join(self.candidates)}: {crit}"


def compare_laws(fits, max_nfev: int, folds: int = FOLDS) -> LawComparison:
    """Compare the laws of `fits` (calibrate.Fit, each with its Problem) by the module docstring's criteria."""
    t0 = time.perf_counter()
    laws = [f.law for f in fits]
    n = fits[0].n
    if any(f.n != n for f in fits):
        raise ValueError("compare_laws: the laws were fitted to different samples")
    own = {f.law: f.n_eff for f in fits}
    nc, aic, bic = information_criteria(fits)
    evals0 = sum(f.problem.evaluations for f in fits)
    blocks = fold_edges(fits[0].problem, folds)
    held = {f.law: blocked_cv(f, max_nfev, blocks) for f in fits}
    cv = {law: float(e @ e) for law, e in held.items()}
    best_cv = min(cv, key=cv.get)
    sizes = fits[0].sizes
    cv_z = {law: (0.0 if law == best_cv else dm_statistic(held[best_cv], held[law], sizes)) for law in laws}
    best = {"aic": min(aic, key=aic.get), "bic": min(bic, key=bic.get), "cv": best_cv}
    tied = {
        "aic": [x for x in laws if aic[x] - aic[best["aic"]] <= TIE],
        "bic": [x for x in laws if bic[x] - bic[best["bic"]] <= TIE],
        "cv": [x for x in laws if cv_z[x] < DM_Z],
    }
    agree = len(set(best.values())) == 1
    alone = all(len(v) == 1 for v in tied.values())
    candidates = [x for x in laws if any(x in v for v in tied.values())]
    return LawComparison(
        laws,
        {f.law: len(f.names) for f in fits},
        n,
        nc,
        own,
        {f.law: f.rss for f in fits},
        aic,
        bic,
        cv,
        cv_z,
        best,
        tied,
        best["aic"] if agree and alone else None,
        [best["aic"]] if agree and alone else candidates,
        time.perf_counter() - t0,
        sum(f.problem.evaluations for f in fits) - evals0,
        blocks,
    )


def information_criteria(fits) -> tuple[float, dict[str, float], dict[str, float]]:
    """(N_c, AIC per law, BIC per law) on the common effective count N_c: the best-fitting law's (module
    docstring, item 1)."""
    n = fits[0].n
    nc = min(fits, key=lambda f: f.rss).n_eff
    aic = {f.law: nc * math.log(f.rss / n) + 2 * len(f.names) for f in fits}
    bic = {f.law: nc * math.log(f.rss / n) + len(f.names) * math.log(nc) for f in fits}
    return nc, aic, bic


def fold_edges(prob, folds: int) -> list[tuple[float, float]]:
    """`folds` contiguous blocks of equal duration over the scored samples' experiment times."""
    t = prob.times()
    e = np.linspace(t.min(), t.max(), folds + 1)
    return [(float(a), float(b)) for a, b in zip(e[:-1], e[1:])]


def blocked_cv(fit, max_nfev: int, blocks) -> np.ndarray:
    """Each residual held out once: refitted (from the optimum) without its block and the buffers beside it,
    the residual at that refit (module docstring)."""
    prob = fit.problem
    t = prob.times()
    spacing = float(np.median(np.diff(np.sort(np.unique(t)))))
    rho = min(max(fit.rho, 0.0), 0.999)
    buffer = math.ceil((1 + rho) / (1 - rho)) * spacing
    out = np.empty(t.size)
    for k, (a, b) in enumerate(blocks):
        last = k == len(blocks) - 1
        test = (t >= a) & ((t <= b) if last else (t < b))
        train = ~((t >= a - buffer) & (t <= b + buffer))
        res = local_fit(prob, fit.z_opt, max_nfev, cols=np.flatnonzero(train))
        out[test] = prob.fun(res.z)[test]
    return out


def dm_statistic(e_best: np.ndarray, e_other: np.ndarray, sizes: list[int]) -> float:
    """Diebold-Mariano z of the loss difference e_other^2 - e_best^2 (positive: `other` predicts worse), the
    channels' HAC standard deviations added (module docstring)."""
    total, sd = 0.0, 0.0
    k = 0
    for m in sizes:
        d = e_other[k : k + m] ** 2 - e_best[k : k + m] ** 2
        k += m
        total += float(d.sum())
        sd += math.sqrt(m * long_run_variance(d))
    return total / sd if sd > 0 else (math.inf if total > 0 else 0.0)


def long_run_variance(x: np.ndarray) -> float:
    """The long-run variance sum_l gamma_l of a series: Bartlett kernel k(l / S) = 1 - l / S, S by Andrews'
    (1991) AR(1) plug-in S = 1.1447 (alpha T)^(1/3), alpha = 4 rho^2 / ((1 - rho)^2 (1 + rho)^2), rho the
    series' lag-1 autocorrelation (capped at 0.99: S stays below about 20 T^(1/3))."""
    x = x - x.mean()
    T = x.size
    g0 = float(x @ x) / T
    if T < 3 or g0 == 0.0:
        return g0
    rho = float(x[1:] @ x[:-1]) / float(x @ x)
    rho = min(max(rho, -0.99), 0.99)
    alpha = 4 * rho * rho / ((1 - rho) ** 2 * (1 + rho) ** 2)
    S = 1.1447 * (alpha * T) ** (1.0 / 3.0)
    out = g0
    for lag in range(1, min(int(math.ceil(S)), T - 1) + 1):
        w = 1.0 - lag / S
        if w <= 0:
            break
        out += 2.0 * w * float(x[lag:] @ x[:-lag]) / T
    return max(out, 0.0)
