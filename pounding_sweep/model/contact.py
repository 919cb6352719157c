"""Kelvin-Voigt pounding element parameters (paper eqs. 8-10).

F_j = k_s (u1j - u2j - d) + c_j (v1j - v2j) while u1j - u2j - d > 0, else 0 (eq. 8);
-F_j acts on building 1's floor j and +F_j on building 2's (eqs. 1-2). Force is positive
in compression. The classic law pulls briefly before separation (the dashpot term turns
negative while the spring is still compressed); `no_tension` clips that to zero.
"""

from __future__ import annotations

import math

import numpy as np

from pounding_sweep.codes import CONTACT_LAWS, LAW_CLASSIC, LAW_NO_TENSION  # noqa: F401  (the laws' names and codes)


def damping_ratio_from_restitution(r):
    """xi_s = -ln r / sqrt(pi^2 + (ln r)^2), eq. (10); exact limits xi_s(1) = 0 and xi_s(0) = 1.

    Written as 1 / sqrt(1 + (pi / ln r)^2) so that r = 0 needs no log(0). Scalars or arrays.
    """
    ra = np.asarray(r, dtype=float)
    if np.any(~((ra >= 0.0) & (ra <= 1.0))):
        bad = ra[~((ra >= 0.0) & (ra <= 1.0))].ravel()[0]
        raise ValueError(f"coefficient of restitution r must lie in [0, 1], got {bad!r}")
    inner = (ra > 0.0) & (ra < 1.0)
    lnr = np.log(np.where(inner, ra, 0.5))
    xi = np.where(inner, 1.0 / np.sqrt(1.0 + (math.pi / lnr) ** 2), np.where(ra == 0.0, 1.0, 0.0))
    return float(xi) if xi.ndim == 0 else xi


def effective_mass(m1: np.ndarray | float, m2: np.ndarray | float):
    """Two-body reduced mass m1 m2 / (m1 + m2), the mass the contact spring sees (eq. 9)."""
    return m1 * m2 / (m1 + m2)


def dashpot_coefficient(ks, r, m1, m2):
    """c_j = 2 xi_s sqrt(k_s m1j m2j / (m1j + m2j)), eq. (9) [N s/m]; broadcasts like NumPy."""
    return 2.0 * damping_ratio_from_restitution(r) * np.sqrt(ks * effective_mass(m1, m2))


def contact_period(ks, m1, m2):
    """Natural period 2 pi sqrt(m_eff / k_s) of two floors joined by the contact spring [s].

    Newmark average acceleration needs several steps per period to resolve an impact: its
    period error is about (w dt)^2 / 12 (Chopra, sec. 5.5).
    """
    return 2.0 * np.pi * np.sqrt(effective_mass(m1, m2) / ks)
