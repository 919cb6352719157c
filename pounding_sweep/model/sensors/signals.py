"""What two sensors' records say about each other, in a band where a building moves with its table: the
first resonance (from their spectra alone, so before any alignment), the band below it, and the lag and sign
of one record against another there (band-limited cross-correlation). Shared by the import (alignment, sign)
and the checks (a channel reversed or lagging).

Why the band below half the first resonance: there a shear frame's floors follow the table almost rigidly and
in phase. Its transmissibility is H(r) = (1 + 2 i zeta r) / (1 - r^2 + 2 i zeta r) for one mode at r = f / f1
(Chopra, Dynamics of Structures, eq. 3.6.4 for the absolute acceleration), real and positive up to a phase of
atan(2 zeta r^3 / (1 - r^2 + 4 zeta^2 r^2)), at r = 1/2 and zeta = 0.05 0.017 rad: a delay of 0.017 / (2 pi
f1 / 2) = 1.1 ms at f1 = 5 Hz (PHYSICAL_DELAY_BOUND). A sign or a lag found there is the sensor's, not the
structure's.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.signal  # noqa: F401 - welch

#: the band used for sign and lag: [LOW_CYCLES / record length, BAND_FRACTION x the first resonance]
BAND_FRACTION = 0.5
LOW_CYCLES = 10.0
#: the largest damping ratio assumed when bounding the structure's own delay in that band
ZETA_MAX = 0.05


#: a correlation in the rigid band weaker than this decides nothing: no sign, no alignment (model/sensors/assemble.py
#: and checks.py)
MIN_CORRELATION = 0.5


def welch(x: np.ndarray, fs: float, seconds: float = 8.0) -> tuple[np.ndarray, np.ndarray]:
    """Welch PSD (Hann segments of `seconds`, at most a quarter of the record; Welch 1967), linear trend removed."""
    n = int(min(max(16, seconds * fs), max(16, x.size // 4)))
    return scipy.signal.welch(x, fs=fs, nperseg=n, detrend="linear")


#: a transmissibility peak counts as a resonance when it is at least this share of the highest one, above
#: MIN_AMPLIFICATION (an amplification, not the table's own motion), and stands out by half that threshold
PEAK_SHARE = 0.25
MIN_AMPLIFICATION = 2.0


def first_resonance(
    ground: np.ndarray, fs_ground: float, floor: np.ndarray, fs_floor: float, fmin: float = 1.0
) -> float:
    """The lowest resonance above `fmin` of sqrt(PSD_floor / PSD_ground) (Welch, each record at its own rate over
    the span both cover, the floor's spectrum read on the table's frequencies; no alignment needed): the lowest
    peak at least PEAK_SHARE of the highest, above MIN_AMPLIFICATION and prominent by half that threshold (else
    the highest). A floor's highest peak can be a higher mode: on the stiff 3-story frame of ../shared
    (imu_shake_table) floor 1 peaks at 25 Hz (29 times the table) over 14 times at its 7.75 Hz first mode, whose
    peak is at least 0.48 of the highest on every floor of the five tests; bumps of the noise below it stay under
    3. Up to 0.4 times the slower rate (the anti-alias roll-off)."""
    from scipy.ndimage import uniform_filter1d
    from scipy.signal import find_peaks

    span = min(ground.size / fs_ground, floor.size / fs_floor)
    f, pg = welch(ground[: int(span * fs_ground)], fs_ground)
    ff, pt = welch(floor[: int(span * fs_floor)], fs_floor)
    band = (f >= fmin) & (f <= 0.4 * min(fs_ground, fs_floor))
    tiny = np.finfo(float).tiny
    ratio = np.sqrt(np.interp(f[band], ff, pt) / np.maximum(pg[band], tiny))
    # smoothed over 3 bins (a single bin where the table's spectrum dips is no resonance), the ends by their own
    # values: zero padding would pull the first bin down and make a false peak beside it
    ratio = uniform_filter1d(ratio, 3, mode="nearest")
    thr = max(PEAK_SHARE * float(np.max(ratio)), MIN_AMPLIFICATION)
    peaks, _ = find_peaks(ratio, height=thr, prominence=0.5 * thr)
    return float(f[band][peaks[0] if peaks.size else int(np.argmax(ratio))])


def rigid_band(f1: float, duration_s: float, fs: float) -> tuple[float, float]:
    """[LOW_CYCLES / duration, BAND_FRACTION f1], within 0.4 fs (module docstring)."""
    lo = LOW_CYCLES / duration_s
    hi = min(BAND_FRACTION * f1, 0.4 * fs)
    return (lo, hi) if hi > 2 * lo else (hi / 4, hi)


def physical_delay_bound(f1: float, zeta: float = ZETA_MAX) -> float:
    """The largest delay [s] of a floor on its table in the rigid band (module docstring), at r = BAND_FRACTION."""
    r = BAND_FRACTION
    phase = np.arctan2(2 * zeta * r**3, 1 - r * r + 4 * zeta * zeta * r * r)
    return float(phase / (2 * np.pi * r * f1))


@dataclass(frozen=True)
class Relation:
    """How record y relates to record x in a band: y(t) ~ sign * x(t - lag_s), with the correlation there."""

    lag_s: float  # > 0: y is late
    sign: int  # +1 or -1
    correlation: float  # at the lag, signed
    runner_up: float  # the largest |correlation| at another lobe (an ambiguous, periodic match comes close)


#: the cross-correlation is evaluated on a grid this many times finer than the samples (band-limited interpolation)
UPSAMPLE = 16


def relation(x: np.ndarray, y: np.ndarray, fs: float, band: tuple[float, float], max_lag_s: float) -> Relation:
    """Lag and sign of y against x (same length, same rate) from their cross-correlation in `band`: both
    transformed (zero-padded to avoid wrap-around), every frequency outside the band set to zero (an ideal,
    zero-phase band-pass: a resonance just above the band, amplified 50 times, leaks nothing into it), the
    cross-spectrum transformed back on a grid UPSAMPLE times finer than the samples (the band-limited
    interpolation of the correlation: Oppenheim & Schafer, Discrete-Time Signal Processing, sec. 4.6), normalised
    by the band-passed records' norms; its largest |value| within +/- max_lag_s, refined by a parabola through
    the three grid values around it."""
    n = min(x.size, y.size)
    a, b = x[:n] - np.mean(x[:n]), y[:n] - np.mean(y[:n])
    nfft = 1 << int(np.ceil(np.log2(2 * n)))
    f = np.fft.rfftfreq(nfft, 1.0 / fs)
    keep = (f >= band[0]) & (f <= band[1])
    A, B = np.fft.rfft(a, nfft) * keep, np.fft.rfft(b, nfft) * keep
    na = np.linalg.norm(np.fft.irfft(A, nfft))
    nb = np.linalg.norm(np.fft.irfft(B, nfft))
    m = nfft * UPSAMPLE
    c = np.fft.irfft(np.conj(A) * B, m) * UPSAMPLE / max(na * nb, 1e-300)
    lags = np.arange(m, dtype=float)
    lags[lags > m / 2] -= m
    lags /= UPSAMPLE  # in samples
    inside = np.abs(lags) <= max_lag_s * fs
    order = np.argsort(lags[inside])
    c, lags = c[inside][order], lags[inside][order]
    i = int(np.argmax(np.abs(c)))
    p = 0.0
    if 0 < i < c.size - 1:
        u, v, w = np.abs(c[i - 1 : i + 2])
        den = u - 2 * v + w
        p = 0.5 * (u - w) / den if den < 0 else 0.0
    # the runner-up: the largest |c| outside the main lobe (half a period of the band's upper edge each side)
    lobe = 0.5 * fs / band[1]
    away = np.abs(lags - lags[i]) > lobe
    runner = float(np.max(np.abs(c[away]))) if away.any() else 0.0
    return Relation(float((lags[i] + p / UPSAMPLE) / fs), 1 if c[i] >= 0 else -1, float(c[i]), runner)


#: two floors' records nearly proportional in a band: |correlation| at the best lag at least this
PROPORTIONAL = 0.9


def proportional_band(x: np.ndarray, y: np.ndarray, fs: float) -> tuple[tuple[float, float], Relation] | None:
    """The widest band [lo, hi] from the lowest frequency upward, hi doubling from 4 lo (the narrow ones skipped
    while they hold no common motion, e.g. below a harmonic test's forcing), in which y is nearly
    proportional to x (|correlation| >= PROPORTIONAL at the best lag within half a period of 4 lo, at most 1 s), and the
    relation there; None when even the lowest band is not. Two floors of a building move together there: below
    the first resonance rigidly, and at a resonance the first mode's shape puts every floor in phase; the
    correlation drops where modes mix. No resonance needs to be known (the ratio of two floors' spectra peaks
    at the lower floor's zeros, not at the building's modes)."""
    n = min(x.size, y.size)
    lo = LOW_CYCLES * fs / n
    best = None
    hi = 4 * lo
    while hi < 0.4 * fs:
        rel = relation(x[:n], y[:n], fs, (lo, hi), min(0.5 / (4 * lo), 1.0))
        if abs(rel.correlation) >= PROPORTIONAL and (best is None or rel.sign == best[1].sign):
            best = ((lo, hi), rel)
        elif best is not None:
            break
        hi *= 2
    return best
