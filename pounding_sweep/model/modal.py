"""Modal coordinates of the two uncoupled shear frames, and Newmark's step in them, for the lane kernel.

Each building's damping is classical (Rayleigh, C = a0 M + a1 K: paper eqs. 3-4), so its
mass-normalised modes (K phi = w^2 M phi, phi^T M phi = I) decouple M, C and K: with u = Phi q,

    q_k'' + d_k q_k' + w_k^2 q_k = -Gamma_k ag - (Psi F)_k,   d_k = phi_k^T C phi_k = a0 + a1 w_k^2,

Gamma = Phi^T M 1 (participation), Psi = Phi^T G (G: column j is e(b1, j) - e(b2, j), kernel.py),
and the penetration of pair j is delta_j = (Psi^T q)_j - gap. Newmark average acceleration is
linear, so applied to the modes it is the same scheme as applied to the floors (Chopra, Dynamics of
Structures, sec. 16.2.5 for the modal form), with each mode's step a scalar recurrence. With the
scaled velocity r = (h/2) q' and the acceleration from equilibrium, one step of length h is

    dq = cf (fsum) + cq q + cr r,   q+ = q + dq,   r+ = dq - r,
    cf = 1/keff, cq = -2 w^2 / keff, cr = 8 / (h^2 keff), keff = w^2 + 2 d / h + 4 / h^2,

fsum = f(t) + f(t + h) (Chopra Table 5.4.2 with a_n eliminated). Contact forces at the step end
solve (I + diag(kappa) W)_SS F_S = (k_s delta + c delta')_S of the free step, W = Psi^T diag(cf) Psi,
kappa = k_s + 2 c / h: the same system as kernel.py's S = G^T Keff^-1 G.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pounding_sweep.model.coupled import SystemArrays
from pounding_sweep.model.structure import mass_normalised_modes

#: largest relative off-diagonal of Phi^T C Phi accepted as classical damping (rounding of eigh)
CLASSICAL_TOL = 1e-10


@dataclass(frozen=True)
class ModalArrays:
    """Modal data of the coupled model at one dt (float64, C-contiguous); modes of building 1 first."""

    dt: float
    phi: np.ndarray  # (N, N) floor i, mode k; block-diagonal (a mode moves one building)
    psi: np.ndarray  # (N, P) Phi^T G
    om2: np.ndarray  # w_k^2 [1/s^2]
    dmp: np.ndarray  # d_k = 2 zeta_k w_k [1/s]
    gam: np.ndarray  # Gamma_k = phi_k^T M 1 [kg^0.5]
    cf: np.ndarray  # 1 / keff at dt
    cq: np.ndarray  # -2 w^2 / keff
    cr: np.ndarray  # 8 / (dt^2 keff)
    W: np.ndarray  # (P, P) Psi^T diag(cf) Psi


def modal_arrays(sys: SystemArrays, n1: int) -> ModalArrays:
    """Modal data of the system's two blocks (floors [0, n1) and [n1, N)); ValueError when a block's
    damping is not classical (then the lane kernel cannot be used)."""
    n = sys.m.size
    p = sys.i1.size
    dt = sys.dt
    phi = np.zeros((n, n))
    om2 = np.zeros(n)
    dmp = np.zeros(n)
    for lo, hi in ((0, n1), (n1, n)):
        M = np.diag(sys.m[lo:hi])
        K = sys.K[lo:hi, lo:hi]
        C = sys.C[lo:hi, lo:hi]
        w2, ph = mass_normalised_modes(M, K)
        D = ph.T @ C @ ph
        off = D - np.diag(np.diag(D))
        scale = np.sqrt(np.abs(np.outer(np.diag(D), np.diag(D)))) + 1e-300
        if np.any(np.abs(off) > CLASSICAL_TOL * scale + 1e-14 * np.abs(D).max()):
            raise ValueError("damping is not classical (Phi^T C Phi is not diagonal)")
        phi[lo:hi, lo:hi] = ph
        om2[lo:hi] = np.clip(w2, 0.0, None)
        dmp[lo:hi] = np.diag(D)
    G = np.zeros((n, p))
    G[sys.i1, np.arange(p)] = 1.0
    G[sys.i2, np.arange(p)] = -1.0
    psi = phi.T @ G
    gam = phi.T @ sys.m
    keff = om2 + 2.0 * dmp / dt + 4.0 / (dt * dt)
    cf = 1.0 / keff
    W = psi.T @ (cf[:, None] * psi)
    c = np.ascontiguousarray
    return ModalArrays(
        dt,
        c(phi),
        c(psi),
        c(om2),
        c(dmp),
        c(gam),
        c(cf),
        c(-2.0 * om2 * cf),
        c(8.0 / (dt * dt) * cf),
        c(0.5 * (W + W.T)),
    )


def height_order_fault(values, slack: float = 1.0) -> int | None:
    """Where a shear frame's first-mode values, floor by floor from the ground, stop growing with height (Chopra,
    Dynamics of Structures, sec. 10.2: every floor on one side, each further out than the one below): the index of
    the first floor not above 0 or moving more than `slack` times the floor above it; None where they grow. The one
    rule for identify's shapes (signed, slack 1) and a scene's measured channels (amplitudes, with slack)."""
    values = list(values)
    for k, v in enumerate(values):
        if not v > 0 or (k + 1 < len(values) and v > slack * values[k + 1]):
            return k
    return None
