"""Intervals that include the model's error: what the fitted values would be had another part of the record
been fitted, for a calibration whose misfit says the model cannot explain the data.

Why: the noise-based interval (Gauss-Newton, inflated for the residuals' correlation) answers "how far would
the optimum move with another draw of the noise". When the model is wrong that is not the question: the best
value then depends on which motion is fitted. On a real 3-story test a linear frame's stiffness scale came out
1.030 on the small-amplitude part and 0.975 on the strong motion, while its noise-based 95 % interval over the
whole record was 0.2 % wide.

Method: a window split of the record (non-overlapping subseries: Carlstein 1986, "The use of subseries values
for estimating the variance of a general statistic from a stationary sequence", Ann. Statist. 14:1171). The
scored window is cut into WINDOWS contiguous windows of equal duration; on each the model is refitted alone
(least squares from the whole record's optimum, every parameter free, the noise floors of the whole record,
the simulation from t = 0 to the window's end). A window whose measured data are not above their noise (their RMS
at most [calibrate] misfit_factor times the noise floor: the table at rest before or after the shaking) says
nothing: by the rule that calls a residual within that factor noise, the structure at rest would explain it as
well as any fitted model. In the others, per parameter, the windows whose own optimum lies inside the bounds
(fitstats.on_bound) and whose noise-based 95 % interval spans at most IDENTIFIED of the bounds' range identify
it (a window without impacts does not identify the contact); from their K values (fit coordinates, log for
stiffnesses) with standard deviation s:

    half-width h = t_(K-1)(0.975) s sqrt(1 + 1/K)

the normal prediction interval for the value a further window would give (its value and the K known ones
independent, normal with a common spread). The model-error interval is the whole record's estimate +/- h,
widened where needed to hold every identifying window's value and the noise-based interval, clipped to the
bounds. A window whose optimum is on a bound is a censored value (its data want a value beyond the bound, and
the normal approximation behind its half-width is void there): it takes no part in s, and the interval reaches
that bound. For
K <= 8 it holds the window values anyway (Samuelson's inequality: no value of a sample lies more than
s (K - 1) / sqrt(K) from its mean), so a fit of any union of these windows, which is close to a weighted mean
of theirs, lies inside it too. With fewer than 2 identifying windows the interval is the bounds: the data
cannot bound that parameter's model error, and the report says so.

Which to quote: the model-error interval whenever the misfit warning fires (the residual more than
misfit_factor times the noise floor), the noise-based one otherwise (the window split costs WINDOWS local fits
and, without model error, is about sqrt(WINDOWS + 1) times wider than it need be).
"""

from __future__ import annotations

import math

import numpy as np

from pounding_sweep.scene.parameters import is_log
from pounding_sweep.sweep.fitstats import gauss_newton, interval, local_fit, misfit_of, on_bound

WINDOWS = 4  # windows of the split (the prediction interval's t quantile grows fast below 4)
IDENTIFIED = 0.25  # a window identifies a parameter when its 95 % half-width is at most this share of the range


def identifies(half_width, z, lo, hi, moving: bool) -> np.ndarray:
    """Per fit coordinate, whether a window's fit identifies the parameter (the rule in one place): its data
    move (RMS above misfit_factor times their noise: `moving`), its optimum z is inside the bounds (lo, hi),
    and its 95 % half-width (fit coordinates) is at most IDENTIFIED of the bounds' range."""
    z, lo, hi = np.asarray(z, float), np.asarray(lo, float), np.asarray(hi, float)
    return (np.asarray(half_width) <= IDENTIFIED * (hi - lo)) & (on_bound(z, lo, hi) == 0) & bool(moving)


def fit_window(prob, z0: np.ndarray, window: tuple[float, float], max_nfev: int) -> dict:
    """The model refitted on the samples of `window` (simulation time [s]) alone, from z0 (least squares, every
    parameter free, the whole record's noise floors): per parameter its value, noise-based standard error and
    whether the window identifies it (data above their noise, its optimum inside the bounds, its 95 % half-width
    at most IDENTIFIED of the range: module docstring); the data's RMS over the noise floor, the misfit, the
    residual sum of squares and the optimum's fit coordinates ('z')."""
    lo, hi = prob.z_bounds
    sub = prob.restricted((float(window[0]), float(window[1])))
    T = sub.target
    signal = misfit_of(np.concatenate([v / s for v, s in zip(T.values, T.sigma)]), sub.sizes())
    res = local_fit(sub, z0, max_nfev)
    gn = gauss_newton(res.jac, res.fun, sub.sizes(), len(prob.names))
    moving = signal > prob.scene.calibrate.misfit_factor
    side = on_bound(res.z, lo, hi) if moving else np.zeros(len(prob.names), int)
    ok = identifies(gn.tq * gn.se_z, res.z, lo, hi, moving)
    theta = prob.to_theta(res.z)
    prob.evaluations += sub.evaluations
    se = [float(t * s) if is_log(n) else float(s) for n, t, s in zip(prob.names, theta, gn.se_z)]
    return {
        "start_s": float(window[0]),
        "end_s": float(window[1]),
        "signal_over_noise": signal,
        "misfit_over_noise": misfit_of(res.fun, sub.sizes()),
        "rss": float(res.fun @ res.fun),
        **{n: float(theta[j]) for j, n in enumerate(prob.names)},
        **{f"std_error_{n}": se[j] for j, n in enumerate(prob.names)},
        **{f"identified_{n}": bool(ok[j]) for j, n in enumerate(prob.names)},
        **{f"on_bound_{n}": int(side[j]) for j, n in enumerate(prob.names)},  # -1 lower, +1 upper (data moving)
        "z": res.z,
    }


def model_error_intervals(fit, prob, max_nfev: int, windows: int = WINDOWS) -> None:
    """Fill fit.windows (each window's fit) and fit.ci95_model, and set fit.quote = 'model_error'."""
    from scipy.stats import t as student_t

    a, b = prob.window
    edges = np.linspace(a, b, windows + 1)
    z_all, ok_all = [], []
    fit.windows = []
    for w0, w1 in zip(edges[:-1], edges[1:]):
        w = fit_window(prob, fit.z_opt, (w0, w1), max_nfev)
        z_all.append(w.pop("z"))
        ok_all.append([w[f"identified_{n}"] for n in prob.names])
        fit.windows.append(w)
    Z, OK = np.array(z_all), np.array(ok_all)
    lo, hi = prob.z_bounds
    for j, n in enumerate(prob.names):
        zk = Z[OK[:, j], j]
        if zk.size < 2:
            fit.ci95_model[n] = fit.bounds[n]
            continue
        k = zk.size
        h = float(student_t.ppf(0.975, k - 1)) * float(np.std(zk, ddof=1)) * math.sqrt(1.0 + 1.0 / k)
        noise = [math.log(v) if is_log(n) else v for v in fit.ci95[n]]
        za = min(fit.z_opt[j] - h, float(zk.min()), noise[0])
        zb = max(fit.z_opt[j] + h, float(zk.max()), noise[1])
        censored = {w[f"on_bound_{n}"] for w in fit.windows}  # windows whose data want a value beyond a bound
        za = lo[j] if -1 in censored else za
        zb = hi[j] if 1 in censored else zb
        fit.ci95_model[n] = interval(prob, j, za, zb)
    fit.quote = "model_error"


def better_window_fit(w, whole, window) -> dict:
    """What a fit of `window` (simulation time [s]) gives, for checking the model-error interval of the whole
    record's fit `whole` (calibrate.Fit): the window's own calibration `w`, or where it ends lower the refit from
    the whole record's optimum (fit_window): a window's calibration may stop in a local minimum of a parameter
    it hardly sees. {'estimate', 'std_error', 'misfit', 'refit'}."""
    r = fit_window(whole.problem, whole.z_opt, window, whole.problem.scene.calibrate.max_evals)
    if r["rss"] < w.rss:
        names = whole.names
        return {
            "estimate": {n: r[n] for n in names},
            "std_error": {n: r[f"std_error_{n}"] for n in names},
            "misfit": r["misfit_over_noise"],
            "refit": True,
        }
    return {"estimate": w.estimate, "std_error": w.std_error, "misfit": w.misfit_ratio, "refit": False}
