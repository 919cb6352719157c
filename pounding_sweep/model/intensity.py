"""Intensity measures of ground motions: peak ground acceleration and the 5 %-damped spectral acceleration
at a period, computed exactly for the piecewise-linear acceleration the engine integrates.

Spectral response (Nigam & Jennings 1969, "Calculation of response spectra from strong-motion earthquake
records", Bull. Seismol. Soc. Am. 59(2):909-922): an oscillator u'' + 2 zeta w u' + w^2 u = -a(t), at rest at
t = 0, driven by an acceleration that is linear between samples, has the exact step recursion

    x[n+1] = Phi x[n] + F1 a[n] + F2 (a[n+1] - a[n]),   x = (u, u'),   Phi = exp(A dt),
    F1 = int_0^dt exp(A s) b ds,   F2 = int_0^dt exp(A (dt - s)) b s / dt ds,

(their closed-form coefficients). The matrices come here from one exponential of an augmented matrix (Van
Loan 1978, "Computing integrals involving the matrix exponential", IEEE Trans. Autom. Control 23:395-404),
which is the same algebra without the long closed forms. The peak is taken over the samples, as Nigam and
Jennings do: it may miss the peak between two samples by at most (w dt)^2 / 8 of it. Sa is the pseudo-
spectral acceleration w^2 max|u| (the usual "spectral acceleration" of hazard curves and ground-motion
models). Everything is SI: accelerations in m/s^2, periods in s.
"""

from __future__ import annotations

import math

import numpy as np

#: damping ratio of the spectral acceleration that hazard curves and ground-motion models quote
SPECTRAL_DAMPING = 0.05
#: the intensity measures a scene may name ([excitation] intensity)
MEASURES = ("pga", "sa")


def oscillator_step(period_s: float, damping: float, dt: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(Phi, F1, F2) of the exact step of the oscillator under piecewise-linear base acceleration (module
    docstring): 2x2, 2 and 2 arrays."""
    from scipy.linalg import expm

    w = 2.0 * math.pi / period_s
    m = np.zeros((4, 4))
    m[:2, :2] = [[0.0, 1.0], [-w * w, -2.0 * damping * w]]
    m[1, 2] = -1.0  # b = (0, -1): the base acceleration enters with a minus sign
    m[2, 3] = 1.0 / dt  # the input's slope: a(s) = a[n] + (a[n+1] - a[n]) s / dt
    e = expm(m * dt)
    return e[:2, :2].copy(), e[:2, 2].copy(), e[:2, 3].copy()


def oscillator_displacement(acc, dt: float, period_s: float, damping: float = SPECTRAL_DAMPING) -> np.ndarray:
    """The oscillator's displacement relative to the base at every sample [m], from rest at t = 0, exact for
    acceleration linear between the samples (Nigam & Jennings 1969). `acc`: (..., samples) [m/s^2].

    The recursion runs as a second-order IIR filter (scipy.signal.lfilter, along the last axis) whose
    coefficients follow from (Phi, F1, F2): with G0 = F1 - F2 and G1 = F2, x[n+1] = Phi x[n] + G0 a[n] +
    G1 a[n+1], so U(z) = e1' adj(zI - Phi) (G0 + z G1) A(z) / det(zI - Phi). The filter starts from zero
    history, which puts x[0] = G1 a[0]; the structure is at rest at t = 0, so that start's free response,
    a[0] e1' Phi^n G1, is subtracted (linearity)."""
    from scipy.signal import lfilter

    a = np.asarray(acc, dtype=float)
    phi, f1, f2 = oscillator_step(period_s, damping, dt)
    g0, g1 = f1 - f2, f2
    den = np.array([1.0, -(phi[0, 0] + phi[1, 1]), phi[0, 0] * phi[1, 1] - phi[0, 1] * phi[1, 0]])
    # e1' adj(zI - Phi) = (z - Phi22, Phi12)
    num = np.array([g1[0], g0[0] - phi[1, 1] * g1[0] + phi[0, 1] * g1[1], -phi[1, 1] * g0[0] + phi[0, 1] * g0[1]])
    u = lfilter(num, den, a, axis=-1)
    # the free response from x[0] = G1 (per unit a[0]): e1' Phi^n G1 = impulse response of z (e1' adj G1) / det
    impulse = np.zeros(a.shape[-1])
    impulse[0] = 1.0
    free = lfilter([g1[0], phi[0, 1] * g1[1] - phi[1, 1] * g1[0]], den, impulse)
    return u - a[..., :1] * free


def spectral_displacement(acc, dt: float, period_s: float, damping: float = SPECTRAL_DAMPING) -> np.ndarray:
    """Sd(T, zeta): the largest |u| over the samples [m] (Nigam & Jennings 1969)."""
    return np.max(np.abs(oscillator_displacement(acc, dt, period_s, damping)), axis=-1)


def spectral_acceleration(acc, dt: float, period_s: float, damping: float = SPECTRAL_DAMPING) -> np.ndarray:
    """Sa(T, zeta) = (2 pi / T)^2 Sd [m/s^2]: the pseudo-spectral acceleration."""
    w = 2.0 * math.pi / period_s
    return w * w * spectral_displacement(acc, dt, period_s, damping)


def peak_ground_acceleration(acc) -> np.ndarray:
    """PGA = max |a| over the samples [m/s^2] (exact for acceleration linear between them)."""
    return np.max(np.abs(np.asarray(acc, dtype=float)), axis=-1)


def intensity(acc, dt: float, measure: str, period_s: float | None = None, damping: float = SPECTRAL_DAMPING):
    """The intensity measure `measure` ('pga' or 'sa' at period_s) of each motion [m/s^2]."""
    if measure == "pga":
        return peak_ground_acceleration(acc)
    if measure == "sa":
        if period_s is None:
            raise ValueError("intensity 'sa' needs period_s")
        return spectral_acceleration(acc, dt, period_s, damping)
    raise ValueError(f"intensity measure {measure!r}: expected one of {MEASURES}")


def response_spectrum(acc, dt: float, periods_s, damping: float = SPECTRAL_DAMPING) -> np.ndarray:
    """Sa at each period [m/s^2]: (..., periods)."""
    return np.stack([spectral_acceleration(acc, dt, float(t), damping) for t in np.atleast_1d(periods_s)], axis=-1)


def geometric_mean_period(periods_s) -> float:
    """(T1 T2 ...)^(1/n): the period at which an Sa for two buildings is commonly taken [s]."""
    t = np.asarray(periods_s, dtype=float)
    return float(np.exp(np.mean(np.log(t))))


__all__ = [
    "SPECTRAL_DAMPING",
    "MEASURES",
    "oscillator_step",
    "oscillator_displacement",
    "spectral_displacement",
    "spectral_acceleration",
    "peak_ground_acceleration",
    "intensity",
    "response_spectrum",
    "geometric_mean_period",
]
