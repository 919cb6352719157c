"""Scores of a numerical history against an experimental one (Numba, callable from Python too).

The kernel samples each run at the experiment's time stamps while it integrates and calls
`_score_channel` at the end of the run, so no run's history outlives the run. The functions the kernel calls
have no Python entry (engine/jit.py njit_piece); the public names at the end of the module are their entries
from Python.
"""

from __future__ import annotations

import numpy as np

from pounding_sweep.engine.jit import njit_kernel, njit_piece

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
#: the same for an absolute-acceleration channel (c = 'abs_acc_b1f3'), whose signals are compared after
#: the experiment's low-pass filter, when it has one
ACC_SCORE_NAMES = (
    ("rel_rms_{c}_pct", "relative RMS error, eq. 20, of the (filtered) absolute acceleration [%]"),
    ("peak_num_{c}_m_s2", "largest |numerical absolute acceleration| in the window, filtered [m/s^2]"),
    ("peak_num_time_{c}_s", "time of that peak [s]"),
    ("peak_diff_{c}_pct", "(experimental peak - numerical peak) / experimental peak, filtered [%]"),
    ("corr_{c}", "Pearson correlation at zero lag [-]"),
    ("corr_max_{c}", "largest correlation over lags within +/- max_lag_s [-]"),
    ("corr_lag_{c}_s", "the lag of that maximum; > 0: numerical history late [s]"),
)


@njit_piece
def _relative_rms_error_pct(xd, xe):
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


@njit_piece
def _peak_abs(x, t):
    """Largest |x| and the time it occurs (first occurrence)."""
    best = 0.0
    tb = t[0] if t.size > 0 else 0.0
    for k in range(x.size):
        if abs(x[k]) > best:
            best = abs(x[k])
            tb = t[k]
    return best, tb


@njit_piece
def _lagged_correlation(xd, xe, lag):
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


#: from this many lags on (2 max_lag + 1), the lag search goes through the FFT (below it the direct
#: search is cheaper: it costs about 4 n flops per lag, the FFT path about 150 n in all)
FFT_MIN_LAGS = 128
_U = 1.1102230246251565e-16  # unit roundoff of float64, 2^-53


@njit_piece
def _best_lag_direct(xd, xe, max_lag):
    """The largest lagged_correlation over lags -max_lag..max_lag and its lag (the first, in ascending
    order, on a tie; NaN never wins; (NaN, 0) when every lag is NaN). Costs n (2 max_lag + 1)."""
    best = -np.inf
    best_lag = 0
    for lag in range(-max_lag, max_lag + 1):
        c = _lagged_correlation(xd, xe, lag)
        if c > best:  # NaN never wins
            best = c
            best_lag = lag
    return (best if best > -np.inf else np.nan), best_lag


@njit_piece
def _best_lag(xd, xe, max_lag, fft_min_lags=FFT_MIN_LAGS):
    """What best_lag_direct returns, bit for bit, at the cost of an FFT cross-correlation.

    Every lag's correlation is first estimated from FFT cross-correlation sums (overlap-save blocks, so
    memory follows max_lag, not the record) with the same normalisation as lagged_correlation (means
    and variances over each lag's own overlap), together with a bound on how far that estimate and
    lagged_correlation's own rounding can lie apart (see lag_estimates). Only the lags whose estimate
    could reach the best one within the bounds (and any lag the estimate cannot vouch for) are then
    computed by lagged_correlation itself, in ascending order with the direct search's rule: a lag
    left out is provably below the best, so the result is the direct search's, exactly."""
    n = xe.size
    if 2 * max_lag + 1 < fft_min_lags or n < 2:
        return _best_lag_direct(xd, xe, max_lag)
    for k in range(n):
        if not (np.isfinite(xd[k]) and np.isfinite(xe[k])):
            return _best_lag_direct(xd, xe, max_lag)
    est, bound, trusted = _lag_estimates(xd, xe, max_lag)
    lower = -np.inf
    for i in range(est.size):
        if trusted[i] and est[i] - bound[i] > lower:
            lower = est[i] - bound[i]
    best = -np.inf
    best_lag = 0
    for i in range(est.size):
        if trusted[i] and est[i] + bound[i] < lower:
            continue  # provably below the best: the direct search would not pick it
        c = _lagged_correlation(xd, xe, i - max_lag)
        if c > best:
            best = c
            best_lag = i - max_lag
    return (best if best > -np.inf else np.nan), best_lag


@njit_piece
def _lag_estimates(xd, xe, max_lag):
    """For every lag -max_lag..max_lag (index lag + max_lag): the Pearson correlation of xd[k + lag] with
    xe[k] over their overlap estimated through the FFT, a bound on |estimate - lagged_correlation|, and
    whether the estimate can be trusted at all (its overlap variances clear of zero).

    The data are centred on their whole means first (Pearson's r does not change); the cross sums come
    from overlap-save FFT blocks, the overlap's own sums from the whole sums less at most max_lag end
    values. The bound adds worst-case (Higham, ch. 3-4 and 24) errors of both computations, relative
    to the overlap's sqrt(var_d var_e): lagged_correlation's two-pass sums, (m + 3) u (1 + rho_d + rho_e)
    with rho = max|x| / std (its means' rounding); this one's FFT, 20 log2(N) u per block and nb u over
    nb blocks, on ||a|| ||b|| / sqrt(var_d var_e); its whole-array sums, n u (R_d + R_e + rho_d + rho_e)
    with R = whole / overlap variance; times 8 for safety."""
    n = xe.size
    L = max_lag
    nl = 2 * L + 1
    md = 0.0
    me = 0.0
    amax_d = 0.0
    amax_e = 0.0
    for k in range(n):
        md += xd[k]
        me += xe[k]
        amax_d = max(amax_d, abs(xd[k]))
        amax_e = max(amax_e, abs(xe[k]))
    md /= n
    me /= n
    a = np.empty(n)
    b = np.empty(n)
    ta = 0.0
    tb = 0.0
    ta2 = 0.0
    tb2 = 0.0
    for k in range(n):
        a[k] = xd[k] - md
        b[k] = xe[k] - me
        ta += a[k]
        tb += b[k]
        ta2 += a[k] * a[k]
        tb2 += b[k] * b[k]
    # overlap-save: blocks of B values of b against N values of a (N = B + 2 L, a power of two)
    N = 256
    while N < 4 * nl:
        N *= 2
    B = N - 2 * L
    nb = (n + B - 1) // B
    logn = np.log2(N)
    tw = np.empty(N // 2, dtype=np.complex128)
    for k in range(N // 2):
        ang = -2.0 * np.pi * k / N
        tw[k] = complex(np.cos(ang), np.sin(ang))
    rev = _bit_reverse(N)
    z = np.empty(N, dtype=np.complex128)
    p = np.empty(N, dtype=np.complex128)
    sab = np.zeros(nl)
    for blk in range(nb):
        b0 = blk * B
        for i in range(N):
            e = b[b0 + i] if (i < B and b0 + i < n) else 0.0
            j = b0 - L + i
            y = a[j] if 0 <= j < n else 0.0
            z[i] = complex(e, y)
        _fft(z, tw, rev)
        for k in range(N):
            zk = z[k]
            zc = z[(N - k) % N].conjugate()
            ek = 0.5 * (zk + zc)
            yk = -0.5j * (zk - zc)
            p[k] = (ek.conjugate() * yk).conjugate()  # the inverse through the forward: conj(fft(conj P))
        _fft(p, tw, rev)
        for s in range(nl):
            sab[s] += p[s].real / N
    est = np.empty(nl)
    bound = np.empty(nl)
    trusted = np.zeros(nl, dtype=np.bool_)
    # the overlap's sums: whole sums less the ends the lag leaves out (at most L values each)
    head_a = np.zeros(L + 1)  # sums of a[0:j], a^2 likewise
    head_a2 = np.zeros(L + 1)
    tail_a = np.zeros(L + 1)  # sums of a[n-j:n]
    tail_a2 = np.zeros(L + 1)
    head_b = np.zeros(L + 1)
    head_b2 = np.zeros(L + 1)
    tail_b = np.zeros(L + 1)
    tail_b2 = np.zeros(L + 1)
    for j in range(1, L + 1):
        head_a[j] = head_a[j - 1] + a[j - 1]
        head_a2[j] = head_a2[j - 1] + a[j - 1] * a[j - 1]
        tail_a[j] = tail_a[j - 1] + a[n - j]
        tail_a2[j] = tail_a2[j - 1] + a[n - j] * a[n - j]
        head_b[j] = head_b[j - 1] + b[j - 1]
        head_b2[j] = head_b2[j - 1] + b[j - 1] * b[j - 1]
        tail_b[j] = tail_b[j - 1] + b[n - j]
        tail_b2[j] = tail_b2[j - 1] + b[n - j] * b[n - j]
    for s in range(nl):
        lag = s - L
        m = n - abs(lag)
        if lag >= 0:  # xd[lag:n] against xe[0:n-lag]
            a1 = ta - head_a[lag]
            a2 = ta2 - head_a2[lag]
            b1 = tb - tail_b[lag]
            b2 = tb2 - tail_b2[lag]
        else:  # xd[0:n+lag] against xe[-lag:n]
            a1 = ta - tail_a[-lag]
            a2 = ta2 - tail_a2[-lag]
            b1 = tb - head_b[-lag]
            b2 = tb2 - head_b2[-lag]
        vd = a2 - a1 * a1 / m
        ve = b2 - b1 * b1 / m
        cov = sab[s] - a1 * b1 / m
        if not (vd > 0.0 and ve > 0.0 and m >= 2):
            est[s] = np.nan
            bound[s] = np.inf
            continue
        sd = np.sqrt(vd / m)
        se = np.sqrt(ve / m)
        rho = amax_d / sd + amax_e / se
        rd = ta2 / vd
        re = tb2 / ve
        err = (m + 3.0) * (1.0 + rho) + (20.0 * logn + nb) * np.sqrt(2.0 * rd * re) + n * (rd + re + rho)
        bound[s] = 8.0 * _U * err
        est[s] = cov / np.sqrt(vd * ve)
        trusted[s] = bound[s] < 0.5 and np.isfinite(est[s])
    return est, bound, trusted


@njit_piece
def _bit_reverse(N):
    rev = np.zeros(N, dtype=np.int64)
    bits = 0
    while (1 << bits) < N:
        bits += 1
    for i in range(N):
        r = 0
        x = i
        for _ in range(bits):
            r = (r << 1) | (x & 1)
            x >>= 1
        rev[i] = r
    return rev


@njit_piece
def _fft(z, tw, rev):
    """In-place radix-2 FFT of z (length N, a power of two), twiddles tw[k] = exp(-2 pi i k / N) computed
    each from its own cos and sin (no recurrence: an error of a few u log2 N relative to ||z||)."""
    N = z.size
    for i in range(N):
        j = rev[i]
        if j > i:
            t = z[i]
            z[i] = z[j]
            z[j] = t
    half = 1
    while half < N:
        step = N // (2 * half)
        for start in range(0, N, 2 * half):
            for k in range(half):
                w = tw[k * step]
                u = z[start + k]
                v = z[start + k + half] * w
                z[start + k] = u + v
                z[start + k + half] = u - v
        half *= 2


@njit_piece
def _sos_filter(sos, x):
    """Filter x in place through the cascade of second-order sections `sos` (rows [b0, b1, b2, 1, a1, a2]),
    causally and from rest (zero initial state). Each section in the transposed direct form II,
    y[n] = b0 x[n] + z1, z1 = b1 x[n] - a1 y[n] + z2, z2 = b2 x[n] - a2 y[n] (Oppenheim & Schafer,
    Discrete-Time Signal Processing, 3rd ed. 2010, sec. 6.4, transposed forms): the structure of
    scipy.signal.sosfilt, which the sweep layer applies to the experiment's samples (sweep/scoring.py)."""
    ns = sos.shape[0]
    z = np.zeros((ns, 2))
    for n in range(x.size):
        xc = x[n]
        for s in range(ns):
            y = sos[s, 0] * xc + z[s, 0]
            z[s, 0] = sos[s, 1] * xc - sos[s, 4] * y + z[s, 1]
            z[s, 1] = sos[s, 2] * xc - sos[s, 5] * y
            xc = y
        x[n] = xc


@njit_piece
def _score_channel(xd, xe, t, max_lag, dt_sample, out):
    """Fill out[0:N_SCORES] for one channel: eq. 20, Table 4 peak difference, correlation and lag."""
    out[S_REL_RMS_PCT] = _relative_rms_error_pct(xd, xe)
    pn, tn = _peak_abs(xd, t)
    pe, _ = _peak_abs(xe, t)
    out[S_PEAK_NUM] = pn
    out[S_PEAK_NUM_TIME] = tn
    out[S_PEAK_DIFF_PCT] = (pe - pn) / pe * 100.0 if pe > 0.0 else np.nan
    out[S_CORR] = _lagged_correlation(xd, xe, 0)
    best, best_lag_ = _best_lag(xd, xe, max_lag, FFT_MIN_LAGS)  # = the direct search over every lag, exactly
    out[S_CORR_MAX] = best
    out[S_LAG] = best_lag_ * dt_sample


# Python entries: the functions above have none (engine/jit.py njit_piece: the kernels' scoring links their code
# and optimises it once, in its own module); these call them, for the sweep layer, the plots and the tests


@njit_kernel
def relative_rms_error_pct(xd, xe):
    """_relative_rms_error_pct from Python: the paper's eq. (20) [%]."""
    return _relative_rms_error_pct(xd, xe)


@njit_kernel
def peak_abs(x, t):
    """_peak_abs from Python: the largest |x| and its time."""
    return _peak_abs(x, t)


@njit_kernel
def lagged_correlation(xd, xe, lag):
    """_lagged_correlation from Python: Pearson's r of xd[k + lag] with xe[k] over their overlap."""
    return _lagged_correlation(xd, xe, lag)


@njit_kernel
def best_lag_direct(xd, xe, max_lag):
    """_best_lag_direct from Python: the best lagged correlation and its lag, every lag computed."""
    return _best_lag_direct(xd, xe, max_lag)


@njit_kernel
def best_lag(xd, xe, max_lag, fft_min_lags=FFT_MIN_LAGS):
    """_best_lag from Python: what best_lag_direct returns, bit for bit, through the FFT's estimates."""
    return _best_lag(xd, xe, max_lag, fft_min_lags)


@njit_kernel
def lag_estimates(xd, xe, max_lag):
    """_lag_estimates from Python: every lag's correlation estimated through the FFT, its bound, its trust."""
    return _lag_estimates(xd, xe, max_lag)


@njit_kernel
def score_channel(xd, xe, t, max_lag, dt_sample, out):
    """_score_channel from Python: one channel's scores into out[0:N_SCORES]."""
    _score_channel(xd, xe, t, max_lag, dt_sample, out)
