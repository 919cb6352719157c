"""Scores of a numerical history against an experimental one (Numba, callable from Python too).

The kernel samples each run at the experiment's time stamps while it integrates and calls
`score_channel` at the end of the run, so no run's history outlives the run.
"""

from __future__ import annotations

import numpy as np

from pounding_sweep.engine.jit import njit_kernel

# slots of the per-channel score vector
S_REL_RMS_PCT, S_PEAK_NUM, S_PEAK_NUM_TIME, S_PEAK_DIFF_PCT, S_CORR, S_CORR_MAX, S_LAG = range(7)
N_SCORES = 7
SCORE_NAMES = (
    ("rel_rms_{c}_pct", "relative RMS error, eq. 20 [%]"),
    ("peak_num_{c}_m", "largest |numerical displacement| in the window [m]"),
    ("peak_num_time_{c}_s", "time of that peak [s]"),
    ("peak_diff_{c}_pct", "(experimental peak - numerical peak) / experimental peak, Table 4 [%]"),
    ("corr_{c}", "Pearson correlation at zero lag [-]"),
    ("corr_max_{c}", "largest correlation over lags within +/- max_lag_s [-]"),
    ("corr_lag_{c}_s", "the lag of that maximum; > 0: numerical history late [s]"),
)


@njit_kernel
def relative_rms_error_pct(xd, xe):
    """eps_rel = sqrt(mean((xd - xe)^2)) / sqrt(mean(xe^2)) * 100, the paper's eq. (20)."""
    num = 0.0
    den = 0.0
    for k in range(xe.size):
        e = xd[k] - xe[k]
        num += e * e
        den += xe[k] * xe[k]
    if den == 0.0:
        return np.inf if num > 0.0 else 0.0
    return np.sqrt(num / den) * 100.0


@njit_kernel
def peak_abs(x, t):
    """Largest |x| and the time it occurs (first occurrence)."""
    best = 0.0
    tb = t[0] if t.size > 0 else 0.0
    for k in range(x.size):
        if abs(x[k]) > best:
            best = abs(x[k])
            tb = t[k]
    return best, tb


@njit_kernel
def lagged_correlation(xd, xe, lag):
    """Pearson correlation of xd[k + lag] with xe[k] over the samples both have."""
    n = xe.size
    k0 = max(0, -lag)
    k1 = min(n, n - lag)
    m = k1 - k0
    if m < 2:
        return np.nan
    sd = 0.0
    se = 0.0
    for k in range(k0, k1):
        sd += xd[k + lag]
        se += xe[k]
    md = sd / m
    me = se / m
    cde = 0.0
    cdd = 0.0
    cee = 0.0
    for k in range(k0, k1):
        a = xd[k + lag] - md
        b = xe[k] - me
        cde += a * b
        cdd += a * a
        cee += b * b
    if cdd == 0.0 or cee == 0.0:
        return np.nan
    return cde / np.sqrt(cdd * cee)


@njit_kernel
def score_channel(xd, xe, t, max_lag, dt_sample, out):
    """Fill out[0:N_SCORES] for one channel: eq. 20, Table 4 peak difference, correlation and lag."""
    out[S_REL_RMS_PCT] = relative_rms_error_pct(xd, xe)
    pn, tn = peak_abs(xd, t)
    pe, _ = peak_abs(xe, t)
    out[S_PEAK_NUM] = pn
    out[S_PEAK_NUM_TIME] = tn
    out[S_PEAK_DIFF_PCT] = (pe - pn) / pe * 100.0 if pe > 0.0 else np.nan
    out[S_CORR] = lagged_correlation(xd, xe, 0)
    best = -np.inf
    best_lag = 0
    for lag in range(-max_lag, max_lag + 1):
        c = lagged_correlation(xd, xe, lag)
        if c > best:  # NaN never wins
            best = c
            best_lag = lag
    out[S_CORR_MAX] = best if best > -np.inf else np.nan
    out[S_LAG] = best_lag * dt_sample
