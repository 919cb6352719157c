"""The least-squares pieces the calibration's stages share (sweep/calibrate.py's fit, globalsearch.py's horizons,
uncertainty.py's windows, lawcompare.py's cross-validation): a local fit on some of the residuals with some
parameters fixed, the noise-based uncertainty at an optimum, the misfit ratio, intervals mapped back from the
fit's coordinates. `prob` is a calibrate.Problem (its residuals, Jacobian, bounds and coordinates)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from pounding_sweep.scene.parameters import is_log

#: the law label of a single-building scene's fit (it has no contact; Fit.law, the contact_law column of its rows)
NO_CONTACT = "none"


def fit_label(law: str) -> str:
    """How a message names a fit: 'calibration (law)', or 'calibration' for one building's (NO_CONTACT)."""
    return "calibration" if law == NO_CONTACT else f"calibration ({law})"


#: a fitted value this close to a bound (fraction of the fit-coordinate range) is on it: the data want a value
#: outside the bounds, and the noise-based interval there (a normal approximation at an interior optimum) is void
BOUND_FRACTION = 1e-3


def on_bound(z: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Per fit coordinate: -1 where z is on its lower bound, +1 on its upper one, 0 inside (BOUND_FRACTION)."""
    tol = BOUND_FRACTION * (np.asarray(hi) - np.asarray(lo))
    return np.where(np.abs(z - lo) <= tol, -1, np.where(np.abs(z - hi) <= tol, 1, 0))


def local_fit(prob, z0: np.ndarray, max_nfev: int, free=None, cols=None):
    """Least squares (scipy.optimize.least_squares: trust-region reflective, bounds, the batched forward-difference
    Jacobian Problem.jac) from z0 over the `free` coordinates (all by default; the others stay at z0's values),
    on the residuals `cols` (a boolean mask or indices; all by default). The result gains .z: the full
    coordinates at the optimum."""
    from scipy.optimize import least_squares

    z0 = np.asarray(z0, float)
    lo, hi = prob.z_bounds
    free = np.arange(z0.size) if free is None else np.asarray(free)
    sel = slice(None) if cols is None else cols

    def full(zf):
        z = z0.copy()
        z[free] = zf
        return z

    res = least_squares(
        lambda zf: prob.fun(full(zf))[sel],
        np.clip(z0[free], lo[free], hi[free]),
        jac=lambda zf: prob.jac(full(zf), free)[sel],
        bounds=(lo[free], hi[free]),
        x_scale=(hi - lo)[free],
        max_nfev=max_nfev,
    )
    res.z = full(res.x)
    return res


@dataclass
class GaussNewton:
    """The noise-based uncertainty at an optimum (module docstring): standard errors in the fit's coordinates,
    their correlation, the residuals' lag-1 autocorrelation and effective count, s^2 and the t quantile."""

    se_z: np.ndarray
    corr: np.ndarray
    rho: float
    n_eff: float
    s2: float
    tq: float


def gauss_newton(J: np.ndarray, r: np.ndarray, sizes: list[int], p: int) -> GaussNewton:
    """s^2 (J^T J)^-1 inflated by N / N_eff (module docstring); a direction the residuals do not change along
    (singular value below 1e-8 of the largest: a parameter with no effect, no contact say) has no finite
    variance: the parameters it involves get an infinite standard error (their interval: the bounds)."""
    from scipy.stats import t as student_t

    N = r.size
    rho = lag1(r, sizes)  # pooled over channels (each channel's series on its own)
    n_eff = effective_count(N, rho)
    s2 = float(r @ r) / max(N - p, 1)
    _, sv, Vt = np.linalg.svd(J, full_matrices=False)
    keep = sv > 1e-8 * sv.max() if sv.size and sv.max() > 0 else np.zeros(sv.size, bool)
    inv_s2 = np.where(keep, 1.0 / np.where(keep, sv, 1.0) ** 2, 0.0)
    cov_z = (Vt.T * inv_s2) @ Vt * s2 * (N / n_eff)
    se_z = np.sqrt(np.clip(np.diag(cov_z), 0, None))
    null = np.any(np.abs(Vt[~keep]) > 1e-6, axis=0) if (~keep).any() else np.zeros(p, bool)
    se_z[null] = np.inf
    with np.errstate(invalid="ignore", divide="ignore"):
        corr = cov_z / np.outer(se_z, se_z)
    tq = float(student_t.ppf(0.975, max(n_eff - p, 1)))
    return GaussNewton(se_z, corr, rho, n_eff, s2, tq)


def misfit_of(r: np.ndarray, sizes: list[int]) -> float:
    """The misfit ratio: RMS of the noise-normalised residuals r per channel (`sizes` samples each, in order),
    then the RMS over channels (residual RMS / noise floor, channels weighted alike)."""
    ends = np.cumsum([0] + list(sizes))
    return float(np.sqrt(np.mean([np.mean(r[a:b] ** 2) for a, b in zip(ends[:-1], ends[1:])])))


def effective_count(n: int, rho: float) -> float:
    """N_eff = N (1 - rho) / (1 + rho) of N AR(1) residuals of lag-1 autocorrelation rho (N when rho <= 0)."""
    return n * (1 - rho) / (1 + rho) if rho > 0 else float(n)


def interval(prob, j: int, z_a: float, z_b: float) -> tuple[float, float]:
    """[z_a, z_b] in fit coordinate j, clipped to the bounds and mapped back (through exp where log-scaled)."""
    lo, hi = prob.z_bounds
    za, zb = max(z_a, lo[j]), min(z_b, hi[j])
    if is_log(prob.names[j]):
        return (float(math.exp(za)), float(math.exp(zb)))
    return (float(za), float(zb))


def lag1(r: np.ndarray, sizes: list[int]) -> float:
    """Pooled lag-1 autocorrelation of the residual series of each channel (`sizes`: their lengths, in order)."""
    num = den = 0.0
    k = 0
    for n in sizes:
        x = r[k : k + n] - r[k : k + n].mean()
        k += n
        if n > 2:
            num += float(x[1:] @ x[:-1])
            den += float(x @ x)
    return num / den if den > 0 else 0.0
