"""Modal identification against records whose frequencies, damping and shapes are known exactly:
analytic damped sinusoids, and the shear-frame model's own free vibration (no video here)."""

from __future__ import annotations

import numpy as np
import pytest

from pounding_sweep.identify.modes import (
    amplitude_spectrum,
    band_edge_maximum,
    find_peaks,
    fourier_coefficients,
    half_power_damping,
    hann_sidelobes,
    identify,
    input_line,
    log_decrement,
    mac,
    mode_shape_ratios,
    refine_peak,
    transmissibility,
    welch_psd,
)
from pounding_sweep.model.structure import build_shear_frame

FS = 100.0


def damped(t, f, zeta, amp=1.0):
    wn = 2 * np.pi * f
    return amp * np.exp(-zeta * wn * t) * np.sin(wn * np.sqrt(1 - zeta**2) * t)


def test_amplitude_spectrum_reads_a_sinusoid_amplitude_and_frequency_between_bins():
    t = np.arange(0, 3.0, 1 / FS)
    x = 2.5 * np.sin(2 * np.pi * 4.37 * t + 0.4) + 0.7
    s = amplitude_spectrum(x, FS)
    assert s.resolution_Hz == pytest.approx(1 / 3.0)
    (p,) = find_peaks(s, n=1)
    assert p.frequency_Hz == pytest.approx(4.37, rel=2e-4)  # a bin is 0.33 Hz: 8 % of f
    assert p.height == pytest.approx(2.5, rel=0.01)


def test_refine_peak_is_exact_for_a_sampled_gaussian():
    f = np.arange(0, 10, 0.5)
    v = np.exp(-((f - 3.3) ** 2) / 2.0)
    i = int(np.argmax(v))
    fp, h = refine_peak(f, v, i)
    assert fp == pytest.approx(3.3, abs=1e-12) and h == pytest.approx(1.0, abs=1e-12)


@pytest.mark.parametrize("zeta", [0.01, 0.02, 0.05])
def test_half_power_and_log_decrement_recover_damping(zeta):
    t = np.arange(0, 60.0, 1 / FS)  # decays fully: the transform is the frequency response's shape
    x = damped(t, 4.25, zeta) + 0.3 * damped(t, 11.8, zeta)
    rect = amplitude_spectrum(x, FS, window="boxcar")
    assert half_power_damping(rect, 4.25) == pytest.approx(zeta, rel=0.03)
    assert half_power_damping(rect, 11.8) == pytest.approx(zeta, rel=0.03)
    ld = log_decrement(x, FS, band_Hz=(3.0, 6.0))
    assert ld.damping_ratio == pytest.approx(zeta, rel=0.01)
    assert ld.frequency_Hz == pytest.approx(4.25 * np.sqrt(1 - zeta**2), rel=1e-3)
    # without the band-pass the second mode disturbs the peaks, and the estimate is worse
    raw = log_decrement(x, FS).damping_ratio
    assert abs(raw - zeta) > abs(ld.damping_ratio - zeta)


def test_log_decrement_by_hand():
    """Peaks halving every cycle: delta = ln 2, zeta = ln 2 / sqrt(4 pi^2 + ln^2 2) (Chopra eq. 2.2.4)."""
    f = 2.0
    t = np.arange(0, 6.0, 1 / 1000.0)
    x = 0.5 ** (f * t) * np.cos(2 * np.pi * f * t)
    ld = log_decrement(x, 1000.0, skip_cycles=0, min_relative_peak=0.02)
    assert ld.delta == pytest.approx(np.log(2.0), rel=1e-3)
    assert ld.damping_ratio == pytest.approx(np.log(2) / np.sqrt(4 * np.pi**2 + np.log(2) ** 2), rel=1e-3)


def test_half_power_on_a_psd_and_welch_peak():
    t = np.arange(0, 60.0, 1 / FS)
    x = damped(t, 6.0, 0.03)
    rect = amplitude_spectrum(x, FS, window="boxcar")
    psd = type(rect)(rect.frequency_Hz, rect.values**2, "psd", rect.resolution_Hz)
    assert half_power_damping(psd, 6.0) == pytest.approx(0.03, rel=0.03)
    w = welch_psd(np.sin(2 * np.pi * 7.0 * t), FS, nperseg=1024)
    (p,) = find_peaks(w, n=1)
    assert p.frequency_Hz == pytest.approx(7.0, abs=0.05)


def test_half_power_is_nan_when_the_band_is_not_closed():
    from pounding_sweep.identify.modes import Spectrum

    f = np.linspace(0, 10, 101)
    rising = Spectrum(f, 1.0 + f, "amplitude", 0.1)  # never falls to 1/sqrt(2) after its peak at the end
    assert np.isnan(half_power_damping(rising, 9.9))


def test_mode_shapes_of_the_shear_frame_free_vibration():
    """Free vibration of Model-1 from an initial displacement in all three modes (superposed modal
    solutions): identify finds the model's three frequencies, shapes (MAC > 0.999) and damping."""
    frame = build_shear_frame("Model-1", [1.7, 1.7, 1.6], [5920.0] * 3, damping_ratio=0.0105)
    modes = frame.modes()
    t = np.arange(0, 30.0, 1 / FS)
    X = np.zeros((t.size, 3))
    for k, amp in enumerate((1.0, 0.2, 0.1)):
        X += amp * np.outer(
            damped(t, modes.frequency_Hz[k], modes.damping_ratio[k]), modes.shapes[:, k] / modes.shapes[-1, k]
        )
    X += np.random.default_rng(0).normal(0, 1e-4, X.shape)
    r = identify(X, FS, ["b1f1", "b1f2", "b1f3"], n_modes=3, free_vibration=True)
    assert len(r.modes) == 3 and r.reference == "b1f3"
    for k, m in enumerate(r.modes):
        assert m.frequency_Hz == pytest.approx(
            modes.frequency_Hz[k] * np.sqrt(1 - modes.damping_ratio[k] ** 2), rel=1e-3
        )
        phi = np.array(list(m.shape.values()))
        assert mac(phi, modes.shapes[:, k]) > 0.999
        assert m.damping_log_decrement == pytest.approx(modes.damping_ratio[k], rel=0.05)
        assert m.damping_half_power == pytest.approx(modes.damping_ratio[k], rel=0.1)
    assert r.modes[1].shape["b1f1"] < 0  # mode 2 changes sign along the height


def test_mode_shape_ratio_sign_and_complex_coefficient():
    t = np.arange(0, 5.0, 1 / FS)
    x = np.sin(2 * np.pi * 5.0 * t)
    X = np.column_stack([-0.5 * x, 0.8 * x, x])
    real, cplx = mode_shape_ratios(X, FS, 5.0)
    assert real == pytest.approx([-0.5, 0.8, 1.0], abs=1e-9)
    assert cplx[2] == pytest.approx(1.0)
    c = fourier_coefficients(x, FS, 5.0, window="boxcar")
    assert abs(c[0]) == pytest.approx(t.size / 2, rel=1e-9)  # a unit sine at an exact bin: N / 2


def test_bad_records_raise():
    with pytest.raises(ValueError, match="at least 8 samples"):
        amplitude_spectrum([1.0, 2.0], FS)
    with pytest.raises(ValueError, match="non-finite"):
        amplitude_spectrum([1.0] * 9 + [np.nan], FS)
    with pytest.raises(ValueError, match="fewer than 3 cycles"):
        log_decrement(np.linspace(0, 1, 100), FS)
    with pytest.raises(ValueError, match="band_Hz"):
        log_decrement(np.sin(np.arange(100)), FS, band_Hz=(5.0, 80.0))
    with pytest.raises(ValueError, match="columns but"):
        identify(np.zeros((100, 2)), FS, ["a"])


# ------------------------------------------------------------------ band edges


def test_a_band_whose_edge_is_the_maximum_holds_no_mode():
    """A 6 Hz sine seen through 6.5-8.5 Hz: the band is the flank of the 6 Hz peak (and its side lobes),
    largest at 6.5 Hz. No mode, and a note that says why (it used to report 6.5063 Hz)."""
    t = np.arange(0, 5.0, 1 / FS)
    x = np.sin(2 * np.pi * 6.0 * t) + np.random.default_rng(1).normal(0, 1e-3, t.size)
    s = amplitude_spectrum(x, FS)
    # the 6 Hz line's fourth Hann side lobe (6.9 Hz, 0.37 % of the line) stands above this record's noise:
    # a peak, but under the window's side-lobe envelope of the line, so not a mode
    (lobe,) = find_peaks(s, n=3, fmin=6.5, fmax=8.5)
    assert lobe.height < 2 * hann_sidelobes((lobe.frequency_Hz - 6.0) / s.resolution_Hz)
    assert find_peaks(s, n=3, fmin=6.5, fmax=8.5, sidelobes=hann_sidelobes) == []
    # the first bin at or above 6.5 Hz: bins are 1 / (8 x 512 samples) x 100 Hz = 0.024 Hz apart
    assert band_edge_maximum(s, 6.5, 8.5) == pytest.approx(6.5, abs=100 / 4096)
    r = identify(np.column_stack([0.5 * x, x]), FS, ["b1f1", "b1f2"], fmin=6.5, fmax=8.5)
    assert r.modes == () and r.band_Hz == (6.5, 8.5)
    assert any("largest at the band's lower edge 6.5" in n and "not a mode" in n for n in r.notes)
    # the same band with the peak inside it finds the peak, and says nothing about an edge
    r = identify(np.column_stack([0.5 * x, x]), FS, ["b1f1", "b1f2"], fmin=5.0, fmax=8.5)
    assert [round(m.frequency_Hz, 2) for m in r.modes] == [6.0]
    assert not any("edge" in n for n in r.notes)


# ------------------------------------------------------------------ the table's motion as the input


def test_input_line_tells_a_sine_from_a_broadband_motion():
    """A sine holds its power in one line whatever it measures (displacement weighted by f^4 to
    acceleration, or acceleration as it is); white noise, as acceleration, spreads it."""
    t = np.arange(0, 5.0, 1 / FS)
    rng = np.random.default_rng(2)
    sine = 2.0 * np.sin(2 * np.pi * 6.0 * t) + rng.normal(0, 0.05, t.size)  # 2 mm at 6 Hz, 0.05 mm tracking noise
    for kind in ("displacement", "acceleration"):
        line = input_line(sine, FS, kind)
        # the Hann main lobe (+/- 2 bins) holds 99.9 % of a sine's power; the noise bins that pass 4 x the
        # median of a 7-segment Welch PSD are rare and small: 0.95 leaves room for them
        assert line.fraction > 0.95 and line.kind == kind
        # read between bins on the whole record's spectrum: a tenth of its 0.2 Hz resolution
        assert line.frequency_Hz == pytest.approx(6.0, abs=0.02)
    white = input_line(rng.normal(size=t.size), FS, "acceleration")
    # flat: no bin passes 4 x the median, so no line holds anything
    assert white.fraction < 0.5
    with pytest.raises(ValueError, match="table motion kind"):
        input_line(sine, FS, "jerk")


def sdof_response(x, fs, f0, zeta):
    """Relative displacement of an SDOF oscillator at rest at t = 0, driven by -x (the table's acceleration),
    by discrete convolution with its impulse response (exact for the sampled input)."""
    t = np.arange(x.size) / fs
    wn = 2 * np.pi * f0
    wd = wn * np.sqrt(1 - zeta**2)
    h = np.exp(-zeta * wn * t) * np.sin(wd * t) / wd
    return np.convolve(x, h)[: x.size] / fs


@pytest.mark.parametrize("n, f0, zeta", [(700, 5.0, 0.02), (700, 4.3, 0.01), (500, 7.1, 0.01)])
def test_transmissibility_of_an_oscillator_gives_its_frequency_and_damping(n, f0, zeta):
    """The exponential window adds sigma to the decay rate and nothing else: |H| peaks where an oscillator
    with damping zeta + sigma / omega peaks (f0 sqrt(1 - 2 zeta'^2)), and the half-power damping less
    sigma / omega is zeta."""
    t = np.arange(n) / FS
    knock = np.where(t < 0.05, np.sin(np.pi * t / 0.05), 0.0)  # a half-sine pulse: a smooth spectrum
    y = sdof_response(knock, FS, f0, zeta)
    tr = transmissibility(knock, y, FS)
    T = n / FS
    assert tr.decay_per_s == pytest.approx(np.log(100) / T, rel=1e-12)  # the window is 1 % at the end
    assert tr.resolution_Hz == pytest.approx(3 / T, rel=1e-12)
    r = identify(np.column_stack([0.5 * y, y]), FS, ["b1f1", "b1f2"], n_modes=1, table=knock)
    (m,) = r.modes
    assert r.method == "transmissibility" and r.decay_per_s == tr.decay_per_s
    zeta_w = zeta + tr.decay_per_s / (2 * np.pi * f0)
    # read by a parabola through bins of the 8x zero-padded ratio, 1 / (8 T) apart: within one such bin
    assert m.frequency_Hz == pytest.approx(f0 * np.sqrt(1 - 2 * zeta_w**2), abs=1 / (8 * T))
    # the half-power band (2 zeta' f, 0.3-0.4 Hz here) is read between those bins by linear interpolation,
    # a tenth of a bin at each edge at most: +/- 1 % of the band, +/- 2.5 % of zeta once sigma / omega (exact)
    # is removed (zeta' / zeta <= 2.5 here)
    assert m.damping_half_power == pytest.approx(zeta, rel=0.025)
    # shapes: the ratio of the two channels' H at the peak
    assert m.shape == pytest.approx({"b1f1": 0.5, "b1f2": 1.0}, rel=1e-9)


def test_transmissibility_peaks_where_the_table_is_noise_are_not_modes():
    """Where the table's motion is tracking noise, the ratio of two noises has peaks of its own; the
    floors' response is at its noise floor there, and such a peak is dropped with a note."""
    rng = np.random.default_rng(4)
    n = 700
    t = np.arange(n) / FS
    knock = np.where(t < 0.05, np.sin(np.pi * t / 0.05), 0.0)
    y = sdof_response(knock, FS, 4.3, 0.01)
    noisy_table = knock + rng.normal(0, 1e-3, n)
    noisy_y = y + rng.normal(0, 1e-3 * np.abs(y).max(), n)
    r = identify(noisy_y[:, None], FS, ["b1f1"], n_modes=3, table=noisy_table)
    # the oscillator's one mode, at 4.3 Hz within one bin of 1 / T (noise moves it, not by a bin)
    assert [m.frequency_Hz for m in r.modes] == [pytest.approx(4.3, abs=FS / n)]
