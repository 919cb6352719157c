"""Modal identification from displacement records (tracked floors, or any): spectra, peak
frequencies, damping by half-power bandwidth and by logarithmic decrement, mode-shape ratios.

The paper (Sekerci & Damci, sec. 3) found the models' frequencies and mode shapes from the
tracked pixel histories by FFT, and checked f1 by FFT before each test. Methods and references:

- Amplitude spectrum: FFT of the mean-removed record, Hann window by default (for free vibration:
  flat, then a cosine taper over the last half, which keeps the start where the response lives and
  removes the cut at the end), zero-padded so that peaks can be read between bins; power spectral density: Welch's averaged periodograms (Welch,
  IEEE Trans. Audio Electroacoust. 15 (1967) 70; scipy.signal.welch).
- Peak frequency: the largest bin refined by a parabola through the log-magnitudes of it and its
  two neighbours (quadratic interpolation of spectral peaks; J. O. Smith, Spectral Audio Signal
  Processing, W3K 2011, "Quadratic Interpolation of Spectral Peaks").
- Half-power bandwidth: zeta = (f_b - f_a) / (2 f_n), f_a and f_b where the amplitude falls to
  peak / sqrt(2) (Chopra, Dynamics of Structures, sec. 3.2.5, eq. 3.2.20). On a free-vibration
  record it needs the record to have decayed (the transform of a decaying sinusoid is the
  frequency response's shape) and a rectangular window (a Hann window widens the peak); below
  about 2 % damping its error grows quickly.
- Logarithmic decrement: delta = (1/j) ln(u_i / u_{i+j}) over successive positive peaks of free
  vibration, zeta = delta / sqrt(4 pi^2 + delta^2) (Chopra sec. 2.2.4, eqs. 2.2.3-2.2.4); here the
  slope of a least-squares line through ln(peak) against peak number, after an optional
  zero-phase band-pass around the mode (scipy.signal.sosfiltfilt) so that higher modes do not
  disturb the peaks.
- Mode-shape ratios: at an identified frequency f, the ratio of each channel's Fourier
  coefficient (the windowed record's DTFT evaluated at exactly f) to the reference channel's,
  signed by their phase (peak picking, the basic frequency-domain method; Bendat & Piersol,
  Engineering Applications of Correlation and Spectral Analysis, 2nd ed., Wiley 1993). Compared
  with a model's modes through the MAC (Allemang & Brown, Proc. 1st IMAC, 1982).
- With the table's motion (the input): the transmissibility floor / table, estimated as H1 =
  cross-spectrum / input auto-spectrum (Bendat & Piersol), so that the peaks are the structure's and
  not the input's. Welch's segment averaging needs segments longer than the response's decay (a
  resolution well below the half-power band); a shake-table record of a few seconds of lightly damped
  models has no such segments (on the 6.68 s Duzce record, 1.67 s segments put Model-2's 7.12 Hz at
  6.75 Hz). The whole record is used instead, under an exponential window w = exp(-sigma t), as in
  impact testing (Ewins, Modal Testing, 2nd ed., Research Studies Press 2000): for a structure at
  rest at the start, y w = (h w) * (x w) exactly (w(t) = w(t - s) w(s)), so the ratio of the windowed
  transforms is the transfer function of the same modes with sigma added to each decay rate
  (frequencies kept, damping ratio + sigma / omega, removed again from the half-power damping); sigma
  makes the window 1 % at the record's end, so the cut-off response leaks next to nothing.
  Cross- and auto-spectra are averaged over 3 adjacent bins (frequency smoothing): the peaks are found
  on that estimate (resolution 3 / record length) and placed on the unsmoothed ratio nearby (bins of
  1 / record length). A peak counts only where the floors' response stands above its noise floor
  (where the table's motion is tracking noise, the ratio of two noises has peaks of its own).
- Single-frequency input: the share of the input's power, as acceleration (what drives the
  relative-coordinate equations; a displacement's spectrum is weighted by f^4) and above its noise
  floor (4 x the median of its Welch spectrum), in the main lobe (+/- 2 bins) of its largest peak.

NumPy and SciPy only (no OpenCV).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np
import scipy.signal


@dataclass(frozen=True)
class Spectrum:
    frequency_Hz: np.ndarray
    values: np.ndarray  # amplitude (same units as the record) or PSD (units^2 / Hz)
    kind: str  # 'amplitude' or 'psd'
    resolution_Hz: float  # 1 / record length (fft) or fs / nperseg (welch): what the data resolve


def _as_record(x, fs) -> np.ndarray:
    x = np.asarray(x, dtype=float)
    if x.ndim != 1 or x.size < 8:
        raise ValueError(f"a record needs at least 8 samples in one dimension, got shape {x.shape}")
    if not np.all(np.isfinite(x)):
        raise ValueError("the record holds non-finite values")
    if not (np.isfinite(fs) and fs > 0):
        raise ValueError(f"sampling rate must be > 0, got {fs!r}")
    return x - x.mean()


def _window(name, n: int) -> np.ndarray:
    """'hann', 'boxcar' (none), 'decay' (flat, then a cosine taper over the last half: for free
    vibration, which starts at full amplitude and should not be cut off at the end), or any
    scipy.signal.get_window name."""
    if name in ("boxcar", "rect", None):
        return np.ones(n)
    if name == "decay":
        w = np.ones(n)
        m = n // 2
        w[n - m :] = 0.5 * (1 + np.cos(np.pi * np.arange(1, m + 1) / m))
        return w
    return scipy.signal.get_window(name, n, fftbins=False)


def amplitude_spectrum(x, fs: float, window: str = "hann", pad: int = 8) -> Spectrum:
    """One-sided amplitude spectrum of a record (a sinusoid of amplitude A reads about A at its
    frequency for any window), zero-padded to `pad` times the next power of two."""
    x = _as_record(x, fs)
    n = x.size
    w = _window(window, n)
    nfft = int(2 ** np.ceil(np.log2(n))) * max(int(pad), 1)
    x = x - (w * x).sum() / w.sum()  # no window-weighted mean: no peak at 0 Hz leaking into the lowest bins
    X = np.fft.rfft(x * w, nfft)
    amp = 2.0 * np.abs(X) / w.sum()
    return Spectrum(np.fft.rfftfreq(nfft, 1.0 / fs), amp, "amplitude", fs / n)


def welch_psd(x, fs: float, nperseg: int | None = None) -> Spectrum:
    """Power spectral density by Welch's method (Hann segments, 50 % overlap)."""
    x = _as_record(x, fs)
    nper = min(nperseg or max(x.size // 4, 8), x.size)
    f, p = scipy.signal.welch(x, fs=fs, nperseg=nper)
    return Spectrum(f, p, "psd", fs / nper)


#: what a table channel measures -> power of f that turns its spectrum into its acceleration's
TO_ACCELERATION = {"displacement": 4, "velocity": 2, "acceleration": 0}


@dataclass(frozen=True)
class InputLine:
    """The largest line of a table motion's spectrum and the share of the motion's power in it."""

    frequency_Hz: float
    fraction: float  # of the acceleration power above the noise floor, in the line's main lobe
    kind: str  # 'displacement', 'velocity' or 'acceleration'
    resolution_Hz: float
    #: the line's power over the table's noise power in the whole band (the median PSD level times the band's
    #: width, in the motion's own quantity): a driven table's line stands far above its noise, a quiet one's not
    over_noise: float = float("inf")


def input_line(x, fs: float, kind: str = "displacement") -> InputLine:
    """How concentrated at one frequency a table motion is: the share of its power (as acceleration,
    which is what drives the structure: a displacement's PSD times f^4) in the main lobe (+/- 2 bins) of
    its largest peak, counting only bins above the noise floor (4 x the median of the PSD as measured:
    white tracking noise, weighted by f^4, would otherwise outweigh a 2 mm sine). Welch PSD, segments of a
    quarter of the record (7 averages at 50 % overlap: noise bins stay well below 4 x the median), linear
    trend removed. A sine reads 1.0; the shipped Duzce record, as table displacement or acceleration,
    0.15-0.35 (0.42 with 0.5 mm of tracking noise)."""
    if kind not in TO_ACCELERATION:
        raise ValueError(f"table motion kind must be one of {', '.join(TO_ACCELERATION)}, got {kind!r}")
    x = _as_record(x, fs)
    nper = max(x.size // 4, 8)
    f, p = scipy.signal.welch(x, fs=fs, nperseg=nper, detrend="linear")
    res = fs / nper
    band = f >= 2.0 * res
    keep = band & (p > 4.0 * float(np.median(p[band])))
    q = np.where(keep, p * f ** TO_ACCELERATION[kind], 0.0)
    if q.sum() <= 0:
        return InputLine(float("nan"), 0.0, kind, res, 0.0)
    i = int(np.argmax(q))
    lobe = np.abs(f - f[i]) <= 2.0 * res
    noise_power = float(np.median(p[band])) * (f[band][-1] - f[band][0])
    over = float(np.sum(p[lobe]) * (f[1] - f[0]) / noise_power) if noise_power > 0 else float("inf")
    # the line's frequency, read between bins on the whole record's spectrum
    a = amplitude_spectrum(scipy.signal.detrend(x), fs)
    near = np.nonzero(np.abs(a.frequency_Hz - f[i]) <= 2.0 * res)[0]
    j = int(near[np.argmax(a.values[near])])
    return InputLine(refine_peak(a.frequency_Hz, a.values, j)[0], float(q[lobe].sum() / q.sum()), kind, res, over)


@dataclass(frozen=True)
class Transmissibility:
    """Floor / table transfer functions of a record (H1, exponentially windowed, frequency-smoothed)."""

    frequency_Hz: np.ndarray
    H: np.ndarray  # (frequencies, channels) complex: smoothed cross-spectrum / smoothed input auto-spectrum
    raw: np.ndarray  # (frequencies, channels) complex: ratio of the windowed transforms, no smoothing
    response: np.ndarray  # (frequencies, channels): amplitude of each floor's smoothed spectrum
    resolution_Hz: float  # smoothing width: smooth_bins / record length
    decay_per_s: float  # sigma of the exponential window, added to every mode's decay rate


def transmissibility(x, Y, fs: float, smooth_bins: int = 3, end_weight: float = 0.01, pad: int = 8) -> Transmissibility:
    """H1 = S_xy / S_xx of every column of Y (floors) on x (the table), from the whole record under the
    window exp(-sigma t) with exp(-sigma T) = end_weight, spectra averaged over `smooth_bins` adjacent
    bins of 1 / T. Records are taken relative to their first sample (the structure at rest)."""
    x = _as_record(x, fs)
    Y = np.asarray(Y, dtype=float)
    if Y.ndim == 1:
        Y = Y[:, None]
    if Y.shape[0] != x.size:
        raise ValueError(f"the table record has {x.size} samples, the floors {Y.shape[0]}")
    n = x.size
    sigma = np.log(1.0 / end_weight) * fs / n
    w = np.exp(-sigma * np.arange(n) / fs)
    nfft = int(2 ** np.ceil(np.log2(n))) * max(int(pad), 1)
    f = np.fft.rfftfreq(nfft, 1.0 / fs)
    X = np.fft.rfft((x - x[0]) * w, nfft)
    Yf = np.fft.rfft((Y - Y[:1]) * w[:, None], nfft, axis=0)
    m = max(1, int(round(smooth_bins * nfft / n))) | 1  # odd: centred

    def smooth(v):
        k = np.ones(m) / m
        if v.ndim == 1:
            return np.convolve(v, k, "same")
        return np.column_stack([np.convolve(v[:, j], k, "same") for j in range(v.shape[1])])

    sxx = smooth(np.abs(X) ** 2)
    sxy = smooth(np.conj(X)[:, None] * Yf)
    syy = smooth(np.abs(Yf) ** 2)
    tiny = np.finfo(float).tiny
    H = sxy / np.maximum(sxx, tiny)[:, None]
    raw = Yf / np.where(np.abs(X) > 0, X, tiny)[:, None]
    return Transmissibility(f, H, raw, np.sqrt(syy), smooth_bins * fs / n, float(sigma))


def spectrum(x, fs: float, method: str = "fft", **kw) -> Spectrum:
    if method == "fft":
        return amplitude_spectrum(x, fs, **kw)
    if method == "welch":
        return welch_psd(x, fs, **kw)
    raise ValueError(f"spectrum method must be 'fft' or 'welch', got {method!r}")


def refine_peak(f: np.ndarray, v: np.ndarray, i: int) -> tuple[float, float]:
    """Frequency and height of the peak at bin i, by a parabola through log(v) at i-1, i, i+1."""
    if i <= 0 or i >= v.size - 1 or min(v[i - 1], v[i], v[i + 1]) <= 0:
        return float(f[i]), float(v[i])
    a, b, c = np.log(v[i - 1]), np.log(v[i]), np.log(v[i + 1])
    den = a - 2 * b + c
    p = 0.5 * (a - c) / den if den < 0 else 0.0
    p = float(np.clip(p, -0.5, 0.5))
    df = f[1] - f[0]
    return float(f[i] + p * df), float(np.exp(b - 0.25 * (a - c) * p))


@dataclass(frozen=True)
class Peak:
    frequency_Hz: float
    height: float
    bin: int
    prominence: float = float("nan")  # scipy.signal.find_peaks' prominence on the spectrum searched


def _band(s: Spectrum, fmin: float, fmax: float | None) -> tuple[float, float, np.ndarray]:
    """(low, high, bins) of the band [fmin, fmax]; below twice the resolution nothing is a peak (a
    record cannot resolve a period longer than half its length)."""
    f = s.frequency_Hz
    lo = max(fmin, 2.0 * s.resolution_Hz)
    hi = f[-1] if fmax is None else min(fmax, f[-1])
    return lo, hi, np.nonzero((f >= lo) & (f <= hi))[0]


def find_peaks(
    s: Spectrum,
    n: int = 3,
    fmin: float = 0.0,
    fmax: float | None = None,
    min_relative_height: float = 0.002,
    min_snr: float = 4.0,
    valid=None,
    sidelobes=None,
) -> list[Peak]:
    """The `n` most prominent spectral peaks in [fmin, fmax], in ascending frequency, each refined
    between bins; peaks lower than `min_relative_height` times the highest are ignored, and so are
    peaks closer than 4 resolutions (the Hann main lobe and its first side lobes) to a higher one; below twice the resolution nothing
    is a peak (a record cannot resolve a period longer than half its length). Peaks that rise less
    than `min_snr` times the spectrum's median in the band (its noise floor: peaks of a noise
    spectrum rarely reach 3 times it) above their surroundings (scipy's prominence) are noise or
    bumps on a stronger mode's flank, not modes. A peak is a bin higher than both neighbours in the
    whole spectrum, and the 4-resolution rule looks outside the band too: where the band's edge is its
    largest value, the spectrum still rises outside the band (the flank of a peak there), and that is
    no mode (band_edge_maximum says so). `sidelobes(d)`, when given, is the window's side-lobe envelope
    (relative height d resolutions from a line, e.g. `hann_sidelobes`): a peak no higher than twice it
    under a higher peak of the whole spectrum is that peak's side lobe. `valid(peak)`, when given, is a
    further test each peak must pass before the `n` are chosen."""
    f, v = s.frequency_Hz, s.values
    _, _, idx = _band(s, fmin, fmax)
    if idx.size < 3:
        return []
    top = v[idx].max()
    if top <= 0:
        return []
    df = f[1] - f[0]
    floor = min_snr * float(np.median(v[idx]))
    # peaks of the whole spectrum above twice the resolution, kept if inside the band: a bump next to a
    # stronger peak outside the band (its side lobe) and the band's edge on that peak's flank are none
    _, _, every = _band(s, 0.0, None)
    found, props = scipy.signal.find_peaks(
        v[every[0] :],
        height=min_relative_height * top,
        prominence=floor,
        distance=max(1, int(round(4 * s.resolution_Hz / df))),
    )
    found = found + every[0]
    inside = (found >= idx[0]) & (found <= idx[-1])
    if sidelobes is not None:
        for k in np.nonzero(inside)[0]:
            d = np.abs(f[found] - f[found[k]]) / s.resolution_Hz
            higher = (v[found] > v[found[k]]) & (d > 1.0)
            if np.any(v[found[k]] <= 2.0 * sidelobes(d[higher]) * v[found[higher]]):
                inside[k] = False
    prom = props["prominences"][inside]
    order = np.argsort(-prom)
    peaks = [Peak(*refine_peak(f, v, int(i)), int(i), float(p)) for i, p in zip(found[inside][order], prom[order])]
    if valid is not None:
        peaks = [p for p in peaks if valid(p)]
    return sorted(peaks[:n], key=lambda p: p.frequency_Hz)


def hann_sidelobes(d):
    """Envelope of the Hann window's side lobes d bins from a line, relative to the line's height:
    |sinc(d) / (1 - d^2)| <= 1 / (pi d |d^2 - 1|) (the lobes' peaks come within 10 % of it; d > 1)."""
    d = np.asarray(d, dtype=float)
    return 1.0 / (np.pi * d * np.abs(d * d - 1.0))


def band_edge_maximum(s: Spectrum, fmin: float = 0.0, fmax: float | None = None) -> float | None:
    """The edge frequency of [fmin, fmax] when the spectrum is largest there (the flank of a peak
    outside the band, not a mode); None when the band's largest value lies inside it."""
    _, _, idx = _band(s, fmin, fmax)
    if idx.size == 0:
        return None
    j = idx[int(np.argmax(s.values[idx]))]
    return float(s.frequency_Hz[j]) if j in (idx[0], idx[-1]) else None


def half_power_damping(s: Spectrum, f_peak: float) -> float:
    """Damping ratio from the half-power bandwidth around the peak nearest f_peak (Chopra eq. 3.2.20).

    Amplitude spectra are cut at peak / sqrt(2), PSDs at peak / 2; the crossings are interpolated
    linearly between bins. NaN if the band is not closed on both sides."""
    f, v = s.frequency_Hz, s.values
    i = int(np.argmin(np.abs(f - f_peak)))
    lo, hi = max(i - 3, 1), min(i + 4, v.size - 1)
    i = lo + int(np.argmax(v[lo:hi]))
    fp, vp = refine_peak(f, v, i)
    level = vp / (np.sqrt(2.0) if s.kind == "amplitude" else 2.0)
    a = i
    while a > 0 and v[a] > level:
        a -= 1
    b = i
    while b < v.size - 1 and v[b] > level:
        b += 1
    if v[a] > level or v[b] > level or a == i or b == i:
        return float("nan")
    fa = f[a] + (level - v[a]) * (f[a + 1] - f[a]) / (v[a + 1] - v[a])
    fb = f[b - 1] + (level - v[b - 1]) * (f[b] - f[b - 1]) / (v[b] - v[b - 1])
    return float((fb - fa) / (2.0 * fp))


@dataclass(frozen=True)
class LogDecrement:
    damping_ratio: float
    delta: float  # logarithmic decrement per cycle
    frequency_Hz: float  # damped frequency from the mean peak spacing
    peak_times_s: np.ndarray
    peak_values: np.ndarray
    cycles: int
    damping_std_error: float = float("nan")  # from the line's slope (least squares), nan with 3 peaks


def log_decrement(
    x,
    fs: float,
    band_Hz: tuple[float, float] | None = None,
    start_s: float = 0.0,
    min_relative_peak: float = 0.05,
    skip_cycles: int = 1,
) -> LogDecrement:
    """Damping of a free-vibration record from the decay of its positive peaks (Chopra sec. 2.2.4).

    band_Hz: zero-phase Butterworth band-pass first (isolate one mode); start_s: where free vibration
    begins; peaks below `min_relative_peak` of the first one used (noise) and the first and last
    `skip_cycles` (filter transients) are left out. The equilibrium is the mean of the record's last
    quarter (not of the whole record: the mean of a decaying oscillation is not its centre)."""
    x = _as_record(x, fs)
    x = x - x[-max(x.size // 4, 1) :].mean()
    if band_Hz is not None:
        lo, hi = band_Hz
        if not 0 < lo < hi < fs / 2:
            raise ValueError(f"band_Hz must satisfy 0 < low < high < fs/2 = {fs / 2}, got {band_Hz}")
        sos = scipy.signal.butter(4, [lo, hi], btype="bandpass", fs=fs, output="sos")
        x = scipy.signal.sosfiltfilt(sos, x)
    t = np.arange(x.size) / fs
    xs = x[t >= start_s]
    ts = t[t >= start_s]
    # the dominant period from the zero-crossing spacing bounds the peak search
    up = np.nonzero((xs[:-1] <= 0) & (xs[1:] > 0))[0]
    if up.size < 3:
        raise ValueError("fewer than 3 cycles of free vibration in the record")
    period = np.median(np.diff(up)) / fs
    idx, _ = scipy.signal.find_peaks(xs, distance=max(1, int(0.6 * period * fs)), height=0.0)
    idx = idx[skip_cycles : len(idx) - skip_cycles] if len(idx) > 2 * skip_cycles + 2 else idx
    tp, vp = [], []
    for i in idx:
        if 0 < i < xs.size - 1:
            a, b, c = xs[i - 1], xs[i], xs[i + 1]
            den = a - 2 * b + c
            p = 0.5 * (a - c) / den if den < 0 else 0.0
            tp.append(ts[i] + p / fs)
            vp.append(b - 0.25 * (a - c) * p)
    tp, vp = np.asarray(tp), np.asarray(vp)
    if vp.size:
        keep = vp > min_relative_peak * vp[0]
        cut = int(np.argmin(keep)) if not keep.all() else vp.size
        tp, vp = tp[:cut], vp[:cut]
    if vp.size < 3:
        raise ValueError(f"need at least 3 decaying peaks above the noise, found {vp.size}")
    k = np.arange(vp.size)
    (slope, icpt) = np.polyfit(k, np.log(vp), 1)
    delta = -float(slope)
    fd = (vp.size - 1) / (tp[-1] - tp[0])
    # the slope's standard error (ordinary least squares), through d zeta / d delta = 4 pi^2 / (4 pi^2 + delta^2)^1.5
    resid = np.log(vp) - (slope * k + icpt)
    se_slope = (
        float(np.sqrt(resid @ resid / (vp.size - 2) / np.sum((k - k.mean()) ** 2))) if vp.size > 3 else float("nan")
    )
    se = se_slope * 4 * np.pi**2 / (4 * np.pi**2 + delta**2) ** 1.5
    return LogDecrement(
        float(delta / np.sqrt(4 * np.pi**2 + delta**2)), delta, float(fd), tp, vp, int(vp.size - 1), float(se)
    )


def fourier_coefficients(X, fs: float, f: float, window: str = "hann") -> np.ndarray:
    """DTFT of each column of X (samples x channels, mean removed, windowed) at frequency f."""
    X = np.asarray(X, dtype=float)
    if X.ndim == 1:
        X = X[:, None]
    X = X - X.mean(axis=0)
    n = X.shape[0]
    w = _window(window, n)
    X = X - (w @ X) / w.sum()
    e = np.exp(-2j * np.pi * f * np.arange(n) / fs)
    return (w * e) @ X


def mode_shape_ratios(
    X, fs: float, f: float, reference: int = -1, window: str = "hann"
) -> tuple[np.ndarray, np.ndarray]:
    """(signed real ratios, complex ratios) of every channel to `reference` at frequency f: the
    operational deflection shape at a resonance peak, i.e. the mode shape when modes are well
    separated and lightly damped. A ratio's sign is + when in phase with the reference."""
    c = fourier_coefficients(X, fs, f, window)
    ref = c[reference]
    if abs(ref) == 0:
        raise ValueError(f"the reference channel has no response at {f:.4g} Hz")
    r = c / ref
    return np.abs(r) * np.sign(np.cos(np.angle(r))), r


def mac(phi_a, phi_b) -> float:
    """Modal Assurance Criterion |a^H b|^2 / ((a^H a)(b^H b)), 1 for proportional shapes."""
    a, b = np.asarray(phi_a), np.asarray(phi_b)
    return float(np.abs(np.vdot(a, b)) ** 2 / (np.vdot(a, a).real * np.vdot(b, b).real))


@dataclass(frozen=True)
class Mode:
    frequency_Hz: float
    damping_half_power: float  # NaN when the band is not resolved
    damping_log_decrement: float | None  # free vibration only
    shape: dict  # channel -> signed ratio to the reference channel
    #: the half-power damping's interval: each half-power frequency known to half a resolution, so the band to
    #: one resolution: zeta +/- resolution / (2 f) (the lower end clipped at 0)
    damping_half_power_interval: tuple[float, float] = (float("nan"), float("nan"))
    damping_log_decrement_se: float | None = None  # its standard error (the log line's slope)
    merged_Hz: tuple[float, ...] = ()  # other peaks of the same shape merged into this mode (MAC >= MAC_SAME)
    prominence: float = float("nan")
    #: transmissibility only: one mode fitted to the complex ratio near the peak (fit_peak), the window's decay
    #: removed; its 95 % interval from the fit's standard error inflated for the window's bin correlation
    damping_fit: float = float("nan")
    damping_fit_ci95: tuple[float, float] = (float("nan"), float("nan"))
    frequency_fit_Hz: float = float("nan")


#: two peaks whose shapes have a MAC at least this are one mode (a split peak): Allemang, "The modal assurance
#: criterion - twenty years of use and abuse", Sound and Vibration 37 (2003): above 0.9, consistent shapes
MAC_SAME = 0.9
#: ... and lie within this share of each other's frequency: a split peak (a frequency that drifts with the
#: amplitude during a record, beating) is a few percent wide; a forced response's peaks (output-only: the
#: input's spectrum) have the first mode's shape too, and lie further off
MERGE_SPAN = 0.05


@dataclass(frozen=True)
class ModalResult:
    channels: tuple[str, ...]
    fs: float
    reference: str
    modes: tuple[Mode, ...]
    spectrum: Spectrum  # what the peaks were picked on: sum of the channels' |H| or amplitude spectra, each normalised
    notes: tuple[str, ...] = field(default_factory=tuple)
    method: str = "output-only"  # or 'transmissibility'
    decay_per_s: float = 0.0  # the exponential window's sigma (transmissibility), removed from the damping
    band_Hz: tuple[float, float] = (0.0, 0.0)  # where peaks were looked for


def identify(
    X,
    fs: float,
    channels,
    n_modes: int = 3,
    fmin: float = 0.0,
    fmax: float | None = None,
    free_vibration: bool = False,
    reference: int = -1,
    start_s: float = 0.0,
    table=None,
    min_snr: float = 4.0,
) -> ModalResult:
    """Frequencies, damping and shape ratios of up to `n_modes` modes of one structure from its
    floors' records (columns of X; the reference channel is usually the top floor).

    With `table` (the table's motion, sampled with X): peaks of the transmissibility floor / table
    (`transmissibility`), summed over the channels, each normalised; a peak counts where the floors'
    response stands `min_snr` times above its median; half-power damping on the reference channel's
    unsmoothed ratio, less the window's sigma / omega; shapes from the ratios of H at the peak.
    Without: peaks of the sum of the channels' normalised spectra (a mode strong at any floor counts;
    Hann window, or for a free vibration one that only tapers its end); half-power damping on the
    reference channel's rectangular-window spectrum. A forced record's spectrum peaks at the forcing as
    much as at the modes: this cannot tell them apart. With free_vibration, also the logarithmic
    decrement of each mode after a band-pass of +/- 25 % around it."""
    X = np.asarray(X, dtype=float)
    if X.ndim == 1:
        X = X[:, None]
    channels = tuple(channels)
    if X.shape[1] != len(channels):
        raise ValueError(f"{X.shape[1]} columns but {len(channels)} channel names")
    t = np.arange(X.shape[0]) / fs
    Xs = X[t >= start_s]
    notes = []
    # a free vibration lives at the record's start: a Hann window would weight it almost to zero and
    # bias a fast-decaying mode's peak; no window leaves the side lobes of a slow mode cut off at the
    # end (spurious peaks): keep the start, taper the end
    win = "decay" if free_vibration else "hann"
    sigma = 0.0
    if table is None:
        specs = [amplitude_spectrum(Xs[:, j], fs, window=win) for j in range(Xs.shape[1])]
        tot = sum(s.values / max(s.values[1:].max(), 1e-300) for s in specs)
        sumspec = Spectrum(specs[0].frequency_Hz, tot, "amplitude", specs[0].resolution_Hz)
        lobes = hann_sidelobes if win == "hann" else None
        peaks = find_peaks(sumspec, 2 * n_modes, fmin, fmax, min_snr=min_snr, sidelobes=lobes)
        rect = amplitude_spectrum(Xs[:, reference], fs, window="boxcar")
        method = "output-only"
    else:
        tr = transmissibility(np.asarray(table, dtype=float)[t >= start_s], Xs, fs)
        sigma = tr.decay_per_s
        f = tr.frequency_Hz
        _, _, idx = _band(Spectrum(f, f, "amplitude", tr.resolution_Hz), fmin, fmax)
        mag = np.abs(tr.H)
        inband = idx if idx.size else np.arange(f.size)
        tot = (mag / np.maximum(mag[inband].max(axis=0), 1e-300)).sum(axis=1)
        sumspec = Spectrum(f, tot, "amplitude", tr.resolution_Hz)
        resp = (tr.response / np.maximum(tr.response[inband].max(axis=0), 1e-300)).sum(axis=1)
        floor = min_snr * float(np.median(resp[inband]))
        dropped = []

        def above_noise(p: Peak) -> bool:
            if resp[p.bin] >= floor:
                return True
            dropped.append(p)
            return False

        peaks = find_peaks(sumspec, 2 * n_modes, fmin, fmax, min_snr=min_snr, valid=above_noise)
        for p in sorted(dropped[:n_modes], key=lambda p: p.frequency_Hz):
            notes.append(
                f"{p.frequency_Hz:.3f} Hz: a peak of the transmissibility where the floors' response is at its "
                f"noise floor ({resp[p.bin] / floor * min_snr:.1f} x its median, under {min_snr:g}): not a mode"
            )
        # the smoothed estimate finds the peaks; the unsmoothed ratio places them: smoothing averages H over
        # +/- half its width with the input's power as weights, which pulls a peak toward the stronger input
        rawmag = np.abs(tr.raw)
        rawsum = (rawmag / np.maximum(rawmag[inband].max(axis=0), 1e-300)).sum(axis=1)
        half = max(1, int(round(0.5 * tr.resolution_Hz / (f[1] - f[0]))))
        placed = []
        for p in peaks:
            a, b = max(p.bin - half, 1), min(p.bin + half, f.size - 2)
            i = a + int(np.argmax(rawsum[a : b + 1]))
            placed.append(Peak(*refine_peak(f, rawsum, i), i, p.prominence) if a < i < b else p)
        peaks = placed
        # damping: the unsmoothed ratio keeps the peak's width (the exponential window's sigma is removed below)
        rect = Spectrum(f, np.abs(tr.raw[:, reference]), "amplitude", fs / Xs.shape[0])
        method = "transmissibility"
    lo, hi, _ = _band(sumspec, fmin, fmax)
    edge = band_edge_maximum(sumspec, fmin, fmax)
    if edge is not None:
        notes.append(
            f"the spectrum is largest at the band's {'lower' if abs(edge - lo) <= abs(edge - hi) else 'upper'} "
            f"edge {edge:.4g} Hz: the flank of a peak outside {lo:.4g}-{hi:.4g} Hz, not a mode"
        )
    if not peaks and edge is None:
        notes.append(f"no peak in {lo:.4g}-{hi:.4g} Hz rises above the noise floor ({min_snr:g} x the median)")
    modes = []
    for p in peaks:
        zhp = half_power_damping(rect, p.frequency_Hz)
        interval = (float("nan"), float("nan"))
        if np.isfinite(zhp):
            # the band as measured; under the exponential window it is widened by sigma / pi, removed here
            band = 2 * zhp * p.frequency_Hz
            zhp -= sigma / (2 * np.pi * p.frequency_Hz)
            half = rect.resolution_Hz / (2 * p.frequency_Hz)
            interval = (max(zhp - half, 0.0), max(zhp + half, 0.0))
            if zhp <= 0:
                notes.append(
                    f"{p.frequency_Hz:.3f} Hz: half-power damping {100 * zhp:.2f} % after the window's decay "
                    f"{sigma:.3g} 1/s is removed, not above 0: the peak is no wider than the window makes it (record "
                    "too short, or not a resonance): damping unreliable"
                )
                zhp = float("nan")
            elif band < 2 * rect.resolution_Hz:
                notes.append(
                    f"{p.frequency_Hz:.3f} Hz: half-power band {band:.3g} Hz is not wider than twice the resolution "
                    f"{rect.resolution_Hz:.3g} Hz (record too short): damping unreliable"
                )
        zld, zse = None, None
        if free_vibration:
            hi_bp = min(1.25 * p.frequency_Hz, 0.49 * fs)
            try:
                ld = log_decrement(Xs[:, reference], fs, band_Hz=(0.75 * p.frequency_Hz, hi_bp))
                zld, zse = ld.damping_ratio, ld.damping_std_error
                if zld <= 0:
                    notes.append(
                        f"{p.frequency_Hz:.3f} Hz: logarithmic decrement {100 * zld:.2f} %: the peaks do not decay "
                        "(forced, or beating of two close modes): damping unreliable"
                    )
            except ValueError as e:
                notes.append(f"{p.frequency_Hz:.3f} Hz: no logarithmic decrement ({e})")
        zfit, zci, ffit = float("nan"), (float("nan"), float("nan")), float("nan")
        if table is not None:
            zfit, zci, ffit = _fitted_damping(tr, reference, p.frequency_Hz, zhp, Xs.shape[0], fs, notes)
            hp_trusted = not any(n.startswith(f"{p.frequency_Hz:.3f} Hz: half-power") for n in notes)
            if hp_trusted:  # a half-power estimate already noted unreliable has no interval to compare
                notes.extend(_disagreeing_damping(p.frequency_Hz, zhp, interval, zfit, zci))
        if table is None:
            ratios, _ = mode_shape_ratios(Xs, fs, p.frequency_Hz, reference, window=win)
        else:
            h = tr.H[p.bin]
            r = h / h[reference] if abs(h[reference]) > 0 else np.full(h.shape, np.nan)
            ratios = np.abs(r) * np.sign(np.cos(np.angle(r)))
        modes.append(
            Mode(
                p.frequency_Hz,
                zhp,
                zld,
                dict(zip(channels, ratios.tolist())),
                interval,
                zse,
                (),
                p.prominence,
                zfit,
                zci,
                ffit,
            )
        )
    found = {f"{m.frequency_Hz:.3f}" for m in modes}
    modes = merge_same_shapes(modes, notes)
    # the n most prominent of the peaks looked for (twice as many, so that a merged split peak leaves room)
    if len(modes) > n_modes:
        order = sorted(range(len(modes)), key=lambda k: -modes[k].prominence if np.isfinite(modes[k].prominence) else 0)
        modes = sorted((modes[k] for k in order[:n_modes]), key=lambda m: m.frequency_Hz)
    # the notes on a peak merged into another or left out are not about a mode reported
    gone = found - {f"{m.frequency_Hz:.3f}" for m in modes}
    notes = [n for n in notes if n.split(" Hz: ")[0] not in gone] + single_channel_pairs(modes)
    return ModalResult(
        channels, float(fs), channels[reference], tuple(modes), sumspec, tuple(notes), method, sigma, (lo, hi)
    )


def _fitted_damping(tr: Transmissibility, reference: int, f_peak: float, zhp: float, n: int, fs: float, notes: list):
    """(damping, its 95 % interval, frequency) of the mode at f_peak fitted to the unsmoothed ratio (fit_peak)
    over +/- 3 half-power bandwidths of the windowed response (at least 6 bins of 1 / T), the window's decay
    sigma / omega removed. The bins are 1 / T apart (every pad-th of the zero-padded transform); the window
    correlates neighbours over about 1 + sigma T / pi of them (its transform's width), so the standard error is
    inflated by the square root of that (the effective number of independent bins)."""
    T = n / fs
    df = tr.frequency_Hz[1] - tr.frequency_Hz[0]
    step = max(1, int(round(1.0 / (T * df))))
    z_window = tr.decay_per_s / (2 * np.pi * f_peak)
    z_est = (zhp if np.isfinite(zhp) else 0.0) + z_window
    half = max(3 * 2 * z_est * f_peak, 6.0 / T)
    fit = fit_peak(tr.frequency_Hz, tr.raw[:, reference], f_peak, half, step)
    nan = float("nan")
    if fit is None:
        notes.append(f"{f_peak:.3f} Hz: no damping fit (too few bins near the peak)")
        return nan, (nan, nan), nan
    z = fit.damping_ratio - tr.decay_per_s / (2 * np.pi * fit.frequency_Hz)
    from scipy.stats import t as student_t

    inflate = np.sqrt(1.0 + tr.decay_per_s * T / np.pi)
    q = float(student_t.ppf(0.975, max(2 * fit.points - 6, 1)))
    ci = (z - q * inflate * fit.damping_se, z + q * inflate * fit.damping_se)
    if z <= 0:
        notes.append(
            f"{f_peak:.3f} Hz: fitted damping {100 * z:.2f} % (95 % {100 * ci[0]:.2f} to {100 * ci[1]:.2f} %) is not "
            "above 0 once the window's decay is removed: damping unreliable (the record too short for it)"
        )
    elif ci[0] <= 0:
        notes.append(
            f"{f_peak:.3f} Hz: fitted damping {100 * z:.2f} %, but its 95 % interval ({100 * ci[0]:.2f} to "
            f"{100 * ci[1]:.2f} %) reaches 0: not told from no damping by this record"
        )
    if fit.rms_misfit > 0.5:
        notes.append(
            f"{f_peak:.3f} Hz: one mode fits the response near the peak only to {100 * fit.rms_misfit:.0f} % "
            "RMS: close modes or noise; the fitted damping unreliable"
        )
    return z, ci, fit.frequency_Hz


def _disagreeing_damping(f_Hz: float, zhp: float, hp_interval, zfit: float, fit_ci) -> list[str]:
    """A note where the half-power and fitted damping of one peak are both finite and their intervals do not overlap
    (a helper's real Sine 1.5: 0.38-0.56 % against 1.12-1.69 %, shown without a word). Which is off it cannot say:
    the half-power interval is +/- a resolution, not a sampling interval, and the bandwidth reads low on a smoothed
    or short record (a known frame's 1 %: 0.65-0.82 %, tests/identify/test_real_spectra.py), while a peak that is
    not one linear mode's (damping that changes with amplitude, a split peak) moves both. So the note says so and
    marks neither unreliable; the modes file keeps the fitted one, as before."""
    bounds = (*hp_interval, *fit_ci)
    if not (np.isfinite(zhp) and np.isfinite(zfit) and all(np.isfinite(b) for b in bounds)):
        return []
    if hp_interval[1] >= fit_ci[0] and fit_ci[1] >= hp_interval[0]:
        return []
    return [
        f"{f_Hz:.3f} Hz: half-power damping {100 * zhp:.2f} % ({100 * hp_interval[0]:.2f} to "
        f"{100 * hp_interval[1]:.2f} %) and fitted damping {100 * zfit:.2f} % (95 % {100 * fit_ci[0]:.2f} to "
        f"{100 * fit_ci[1]:.2f} %) disagree: the half-power bandwidth reads low on a short or smoothed record, and a "
        "peak that is not one linear mode's (damping that changes with amplitude, a split peak) moves both; take "
        "the damping as known to no better than their spread"
    ]


def single_channel_pairs(modes) -> list[str]:
    """Notes naming each pair of reported modes within MERGE_SPAN of each other where there is one channel: their
    shapes cannot be compared, so one split peak and two modes look alike (merge_same_shapes cannot decide)."""
    if not modes or len(modes[0].shape) >= 2:
        return []
    return [
        f"{a.frequency_Hz:.3f} and {b.frequency_Hz:.3f} Hz lie within {100 * MERGE_SPAN:g} % of each other: with one "
        "channel their shapes cannot be compared, so one mode split in two or two modes, this record cannot tell "
        "(identify with every floor's channel)"
        for a, b in zip(modes, modes[1:])
        if b.frequency_Hz - a.frequency_Hz <= MERGE_SPAN * b.frequency_Hz
    ]


def merge_same_shapes(modes: list[Mode], notes: list[str]) -> list[Mode]:
    """Neighbouring peaks (in frequency, within MERGE_SPAN) whose shapes have a MAC of MAC_SAME or more are one mode: the more
    prominent peak is kept, the other listed in its merged_Hz, and a note says so. With one channel every shape
    is the same: nothing is merged (a single channel cannot tell a split peak from two modes: single_channel_pairs)."""
    if not modes or len(modes[0].shape) < 2:
        return modes
    out = [modes[0]]
    for m in modes[1:]:
        prev = out[-1]
        a, b = np.array(list(prev.shape.values())), np.array(list(m.shape.values()))
        near = m.frequency_Hz - prev.frequency_Hz <= MERGE_SPAN * m.frequency_Hz
        if near and np.all(np.isfinite(a)) and np.all(np.isfinite(b)) and mac(a, b) >= MAC_SAME:
            keep, drop = (prev, m) if not (m.prominence > prev.prominence) else (m, prev)
            notes.append(
                f"{drop.frequency_Hz:.3f} and {keep.frequency_Hz:.3f} Hz have the same shape (MAC {mac(a, b):.3f} >= "
                f"{MAC_SAME:g}): one mode, a split peak; kept {keep.frequency_Hz:.3f} Hz, the more prominent"
            )
            out[-1] = dataclasses.replace(keep, merged_Hz=(*keep.merged_Hz, drop.frequency_Hz, *drop.merged_Hz))
        else:
            out.append(m)
    return out


@dataclass(frozen=True)
class PeakFit:
    """One mode fitted to a complex frequency response near its peak (fit_peak)."""

    frequency_Hz: float
    damping_ratio: float  # as in the response fitted (the exponential window's share not yet removed)
    frequency_se_Hz: float
    damping_se: float
    points: int  # independent bins used
    rms_misfit: float  # RMS residual over RMS |H| in the fitted band


def fit_peak(f: np.ndarray, H: np.ndarray, f_peak: float, half_band_Hz: float, step: int = 1) -> PeakFit | None:
    """Fit H(f) ~ A f0^2 / (f0^2 - f^2 + 2 i zeta f0 f) + C (one mode and a constant for the others: the
    single-degree-of-freedom form of a modal model, as rational-fraction fitting does, Richardson & Formenti,
    Proc. 1st IMAC 1982) to the complex response in f_peak +/- half_band_Hz, every `step`-th bin (independent
    bins: 1 / record length apart). Variable projection: A and C by linear least squares for each (f0, zeta),
    those two by scipy.optimize.least_squares; standard errors from the Gauss-Newton covariance
    s^2 (J^T J)^-1 of the residuals. None when fewer than 6 bins or the fit fails."""
    from scipy.optimize import least_squares

    sel = np.nonzero(np.abs(f - f_peak) <= half_band_Hz)[0][::step]
    if sel.size < 6:
        return None
    ff, hh = f[sel], H[sel]

    def basis(p):
        f0, z = p
        return np.column_stack([f0 * f0 / (f0 * f0 - ff * ff + 2j * z * f0 * ff), np.ones(ff.size)])

    def resid(p):
        B = basis(p)
        coef, *_ = np.linalg.lstsq(B, hh, rcond=None)
        r = B @ coef - hh
        return np.concatenate([r.real, r.imag])

    z0 = max(half_band_Hz / (4 * f_peak), 1e-4)
    try:
        res = least_squares(resid, [f_peak, z0], bounds=([ff[0], 1e-6], [ff[-1], 0.5]), x_scale=[half_band_Hz, z0])
    except (ValueError, np.linalg.LinAlgError):
        return None
    J = res.jac
    dof = 2 * sel.size - 2 - 4  # real residuals less (f0, zeta) and the complex A, C
    if dof <= 0:
        return None
    s2 = float(res.fun @ res.fun) / dof
    try:
        cov = np.linalg.inv(J.T @ J) * s2
    except np.linalg.LinAlgError:
        return None
    se = np.sqrt(np.clip(np.diag(cov), 0, None))
    misfit = float(np.sqrt(np.mean(res.fun**2) * 2) / np.sqrt(np.mean(np.abs(hh) ** 2)))
    return PeakFit(float(res.x[0]), float(res.x[1]), float(se[0]), float(se[1]), int(sel.size), misfit)
