"""Closed-form answers without contact: modal superposition of classically damped frames, harmonic
response from rest (Chopra sec. 3.2 per mode) and free vibration (Chopra eq. 2.2.4 per mode)."""

from __future__ import annotations

import math

import numpy as np


def classical_modes(M, C, K):
    """Undamped modes of (K, M), mass-normalised (phi^T M phi = I), and their damping ratios.

    Solved through the Cholesky factor M = L L^T (a symmetric eigenproblem of L^-1 K L^-T).
    Raises if C is not diagonal in these modes (modal superposition would then not decouple).
    """
    Linv = np.linalg.inv(np.linalg.cholesky(M))
    w2, psi = np.linalg.eigh(Linv @ K @ Linv.T)
    phi = Linv.T @ psi
    Cm = phi.T @ C @ phi
    off = Cm - np.diag(np.diag(Cm))
    if np.max(np.abs(off)) > 1e-9 * np.max(np.abs(Cm)):
        raise ValueError("damping is not classical: the modal equations would be coupled")
    wn = np.sqrt(w2)
    return wn, phi, np.diag(Cm) / (2.0 * wn)


def modal_harmonic_response(M, C, K, amp, omega, t) -> np.ndarray:
    """Exact u(t) (len(t), n) of M u'' + C u' + K u = -M 1 ag, ag = -amp omega^2 sin(omega t), from rest.

    Classically damped (Rayleigh) systems decouple in the undamped modes phi_m:
    q_m'' + 2 z_m w_m q_m' + w_m^2 q_m = -Gamma_m ag(t), Gamma_m = phi_m^T M 1 (Chopra sec. 13.1),
    i.e. a harmonic load p0 sin(omega t) with p0 = Gamma_m amp omega^2 per unit modal mass. Each
    mode is Chopra's harmonic solution (sec. 3.2): steady state C1 sin + D1 cos with
    C1 = p0/w^2 (1 - b^2)/((1 - b^2)^2 + (2 z b)^2), D1 = p0/w^2 (-2 z b)/(...), b = omega / w,
    plus the damped transient e^{-z w t}(A cos wD t + B sin wD t) fixed by q(0) = q'(0) = 0.
    """
    wn, phi, zeta = classical_modes(M, C, K)
    gamma = phi.T @ M @ np.ones(M.shape[0])
    t = np.asarray(t, dtype=float)
    u = np.zeros((t.size, M.shape[0]))
    for m in range(wn.size):
        w, z = wn[m], zeta[m]
        p0 = gamma[m] * amp * omega**2
        b = omega / w
        den = (1.0 - b**2) ** 2 + (2.0 * z * b) ** 2
        c1 = p0 / w**2 * (1.0 - b**2) / den
        d1 = p0 / w**2 * (-2.0 * z * b) / den
        wd = w * math.sqrt(1.0 - z**2)
        a_ = -d1  # q(0) = a_ + d1 = 0
        b_ = (z * w * a_ - c1 * omega) / wd  # q'(0) = -z w a_ + wd b_ + c1 omega = 0
        q = (
            np.exp(-z * w * t) * (a_ * np.cos(wd * t) + b_ * np.sin(wd * t))
            + c1 * np.sin(omega * t)
            + d1 * np.cos(omega * t)
        )
        u += np.outer(q, phi[:, m])
    return u


def modal_free_vibration(M, C, K, u0, v0, t) -> np.ndarray:
    """Exact u(t) (len(t), n) of M u'' + C u' + K u = 0 from u(0) = u0, u'(0) = v0 (classical damping).

    Modal initial conditions q0 = phi^T M u0, q0' = phi^T M v0 (mass-normalised phi), then per
    mode Chopra eq. (2.2.4): q(t) = e^{-z w t} (q0 cos wD t + (q0' + z w q0) / wD sin wD t).
    """
    wn, phi, zeta = classical_modes(M, C, K)
    q0, qd0 = phi.T @ M @ u0, phi.T @ M @ v0
    t = np.asarray(t, dtype=float)
    u = np.zeros((t.size, M.shape[0]))
    for m in range(wn.size):
        w, z = wn[m], zeta[m]
        wd = w * math.sqrt(1.0 - z**2)
        q = np.exp(-z * w * t) * (q0[m] * np.cos(wd * t) + (qd0[m] + z * w * q0[m]) / wd * np.sin(wd * t))
        u += np.outer(q, phi[:, m])
    return u
