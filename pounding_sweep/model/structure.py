"""Lumped-mass shear frames: mass, stiffness and damping matrices (Rayleigh, or one ratio per mode), modes.

Matrices follow the paper's eqs. (3)-(4) (Sekerci & Damci), generalised to any number
of stories; Rayleigh damping as in Chopra, *Dynamics of Structures*, sec. 11.4; the damping matrix
from modal damping ratios as in its sec. 11.5 (superposition of modal damping matrices).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


def column_story_stiffness(EI_Nm2: float, n_columns: int, height_m: float) -> float:
    """Lateral stiffness of one story of fixed-fixed columns: k = n_cols * 12 EI / L^3 (paper, sec. 3)."""
    return n_columns * 12.0 * EI_Nm2 / height_m**3


def shear_frame_stiffness(k: np.ndarray) -> np.ndarray:
    """Tridiagonal stiffness of a shear frame with story stiffnesses k[0] (ground story) .. k[n-1], eq. (3)."""
    k = np.asarray(k, dtype=float)
    n = k.size
    K = np.zeros((n, n))
    for i in range(n):
        K[i, i] = k[i] + (k[i + 1] if i + 1 < n else 0.0)
        if i + 1 < n:
            K[i, i + 1] = K[i + 1, i] = -k[i + 1]
    return K


def rayleigh_from_ratio(omega_i: float, omega_j: float, zeta_i: float, zeta_j: float) -> tuple[float, float]:
    """Rayleigh coefficients (a0, a1) giving damping ratios zeta_i, zeta_j at two circular frequencies.

    zeta(w) = a0 / (2 w) + a1 w / 2 (Chopra eq. 11.4.9); solved exactly for the two modes.
    """
    A = np.array([[1.0 / (2.0 * omega_i), omega_i / 2.0], [1.0 / (2.0 * omega_j), omega_j / 2.0]])
    a0, a1 = np.linalg.solve(A, np.array([zeta_i, zeta_j]))
    return float(a0), float(a1)


def modal_damping_matrix(M: np.ndarray, K: np.ndarray, zeta) -> np.ndarray:
    """The damping matrix with damping ratio zeta[n] in mode n and no coupling between modes:
    C = M (sum_n 2 zeta_n omega_n / M_n phi_n phi_n^T) M (Chopra, Dynamics of Structures, sec. 11.5), here with
    mass-normalised shapes (M_n = phi_n^T M phi_n = 1): C = (M Phi) diag(2 zeta omega) (M Phi)^T, so that
    Phi^T C Phi = diag(2 zeta_n omega_n). One ratio per mode (every mode damped as stated)."""
    w2, phi = mass_normalised_modes(M, K)
    omega = np.sqrt(np.clip(w2, 0.0, None))
    mp = M @ phi
    C = (mp * (2.0 * np.asarray(zeta, dtype=float) * omega)) @ mp.T
    return 0.5 * (C + C.T)


@dataclass(frozen=True)
class ShearFrame:
    """One building: floor masses [kg] and story stiffnesses [N/m], floor 1 first, with Rayleigh damping, or
    with one damping ratio per mode (modal_damping_ratios: then the Rayleigh coefficients are 0)."""

    name: str
    masses_kg: tuple[float, ...]
    story_stiffness_N_per_m: tuple[float, ...]
    rayleigh_a0_per_s: float
    rayleigh_a1_s: float
    modal_damping_ratios: tuple[float, ...] | None = None

    @property
    def n_floors(self) -> int:
        return len(self.masses_kg)

    @property
    def M(self) -> np.ndarray:
        return np.diag(np.asarray(self.masses_kg, dtype=float))

    @property
    def K(self) -> np.ndarray:
        return shear_frame_stiffness(np.asarray(self.story_stiffness_N_per_m))

    @property
    def C(self) -> np.ndarray:
        """C = a0 M + a1 K, eqs. (3)-(4); with modal damping ratios, modal_damping_matrix."""
        if self.modal_damping_ratios is not None:
            return modal_damping_matrix(self.M, self.K, self.modal_damping_ratios)
        return self.rayleigh_a0_per_s * self.M + self.rayleigh_a1_s * self.K

    def modes(self) -> Modes:
        return modal_analysis(self.M, self.K, self.C)


@dataclass(frozen=True)
class Modes:
    """Undamped modes of (K, M): circular frequencies, mass-normalised shapes, damping ratios of C."""

    omega_rad_s: np.ndarray
    shapes: np.ndarray  # columns are modes, mass-normalised (phi^T M phi = 1)
    damping_ratio: np.ndarray  # phi^T C phi / (2 omega): exact for classical (e.g. Rayleigh) damping

    @property
    def frequency_Hz(self) -> np.ndarray:
        return self.omega_rad_s / (2.0 * np.pi)

    @property
    def period_s(self) -> np.ndarray:
        return 1.0 / self.frequency_Hz


def mass_normalised_modes(M: np.ndarray, K: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(w^2, Phi) of K phi = w^2 M phi (generalised symmetric eigenproblem), ascending,
    phi^T M phi = 1, each mode's top floor positive."""
    import scipy.linalg  # 0.2-0.3 s to import: only when modes are asked for (Numba's BLAS probe imports it too)

    w2, phi = scipy.linalg.eigh(K, M)
    return w2, phi * np.where(phi[-1, :] < 0, -1.0, 1.0)


def modal_analysis(M: np.ndarray, K: np.ndarray, C: np.ndarray | None = None) -> Modes:
    """Solve K phi = w^2 M phi (generalised symmetric eigenproblem), frequencies ascending."""
    w2, phi = mass_normalised_modes(M, K)
    omega = np.sqrt(np.clip(w2, 0.0, None))
    if C is None:
        zeta = np.zeros_like(omega)
    else:
        zeta = np.einsum("im,ij,jm->m", phi, C, phi) / (2.0 * omega)
    return Modes(omega, phi, zeta)


def build_shear_frame(
    name: str,
    masses_kg,
    story_stiffness_N_per_m,
    *,
    damping_ratio: float | None = None,
    damping_modes: tuple[int, int] = (1, 2),
    rayleigh_a0_per_s: float | None = None,
    rayleigh_a1_s: float | None = None,
    modal_damping_ratios=None,
) -> ShearFrame:
    """Make a ShearFrame, with Rayleigh damping from a ratio matched at two modes or explicit a0, a1, or with
    one damping ratio per mode (modal_damping_ratios, mode 1 first).

    With one story only mode 1 exists: the ratio is then met by stiffness-proportional damping alone.
    """
    m = tuple(float(x) for x in masses_kg)
    k = tuple(float(x) for x in story_stiffness_N_per_m)
    if modal_damping_ratios is not None:
        return ShearFrame(name, m, k, 0.0, 0.0, tuple(float(z) for z in modal_damping_ratios))
    if rayleigh_a0_per_s is not None or rayleigh_a1_s is not None:
        return ShearFrame(name, m, k, float(rayleigh_a0_per_s or 0.0), float(rayleigh_a1_s or 0.0))
    zeta = 0.0 if damping_ratio is None else float(damping_ratio)
    modes = modal_analysis(np.diag(m), shear_frame_stiffness(np.asarray(k)))
    i, j = damping_modes
    if len(m) == 1:
        return ShearFrame(name, m, k, 0.0, 2.0 * zeta / modes.omega_rad_s[0])
    a0, a1 = rayleigh_from_ratio(modes.omega_rad_s[i - 1], modes.omega_rad_s[j - 1], zeta, zeta)
    return ShearFrame(name, m, k, a0, a1)
