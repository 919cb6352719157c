"""Modal identification against records whose frequencies, damping and shapes are known exactly:
analytic damped sinusoids, and the shear-frame model's own free vibration (no video here)."""

from __future__ import annotations

import numpy as np
import pytest

from pounding_sweep.identify.modes import (
    amplitude_spectrum,
    find_peaks,
    fourier_coefficients,
    half_power_damping,
    identify,
    log_decrement,
    mac,
    mode_shape_ratios,
    refine_peak,
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
