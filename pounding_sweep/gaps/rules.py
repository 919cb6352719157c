"""Required separation of two adjacent buildings from their peak displacements: the combination rules
of codes and of the pounding literature, and a code's minimum gap.

u1, u2 are peak displacement magnitudes of the two buildings at the same level, from analyses of each
building alone (separated). Building 1 stands left of building 2 (+x moves it toward building 2).

- ABS, the absolute sum u1 + u2: an upper bound on the exact one-sided requirement (both peaks toward
  each other at once); older codes' rule, and what each building standing back its own peak from a
  common property line amounts to.
- SRSS, sqrt(u1^2 + u2^2): the rule of EN 1998-1 4.4.2.7 and ASCE 7-10 12.12.3 (with their own
  displacement amplification), and the DDC with rho = 0. Not a bound.
- DDC, the double difference combination, sqrt(u1^2 + u2^2 - 2 rho u1 u2) (Jeng, Kasai & Maison,
  "A spectral difference method to estimate building separations to avoid pounding", Earthquake
  Spectra 8(2), 1992), rho the correlation of the two buildings' displacement responses to the same
  ground motion, from their first-mode frequencies and damping by the CQC coefficient of Der Kiureghian
  (1981, Earthquake Eng. Struct. Dyn. 9:419-435). It estimates the peak of |u1 - u2|. Not a bound.
- TBEC 2018 minimum (Turkish Building Earthquake Code 2018, as the paper's introduction states it): at
  least 30 mm up to 6 m height, and 10 mm more for each further 3 m (taken per started 3 m), at full
  scale.
"""

from __future__ import annotations

import numpy as np

RULES = ("ABS", "SRSS", "DDC")


def cqc_correlation(w1, w2, z1, z2):
    """Der Kiureghian's (1981) correlation of two oscillators' responses to the same white-noise base
    motion: rho = 8 sqrt(z1 z2) (z1 + r z2) r^1.5 / ((1 - r^2)^2 + 4 z1 z2 r (1 + r^2) + 4 (z1^2 + z2^2) r^2),
    r = w2 / w1 (paired with z1 + r z2: symmetric under swapping both frequencies and damping ratios).
    1 for identical oscillators, 0 without damping (unless r = 1)."""
    w1, w2, z1, z2 = (np.asarray(x, dtype=float) for x in (w1, w2, z1, z2))
    r = w2 / w1
    num = 8.0 * np.sqrt(z1 * z2) * (z1 + r * z2) * r**1.5
    den = (1.0 - r * r) ** 2 + 4.0 * z1 * z2 * r * (1.0 + r * r) + 4.0 * (z1 * z1 + z2 * z2) * r * r
    with np.errstate(invalid="ignore", divide="ignore"):
        rho = np.where(den > 0, num / np.where(den > 0, den, 1.0), 1.0)
    return float(rho) if rho.ndim == 0 else rho


def combined_gap(u1, u2, rule: str, rho=0.0):
    """The separation a rule asks for from the two peak magnitudes u1, u2 (any length unit)."""
    u1, u2 = np.asarray(u1, dtype=float), np.asarray(u2, dtype=float)
    if rule == "ABS":
        out = u1 + u2
    elif rule == "SRSS":
        out = np.sqrt(u1 * u1 + u2 * u2)
    elif rule == "DDC":
        out = np.sqrt(np.maximum(u1 * u1 + u2 * u2 - 2.0 * np.asarray(rho) * u1 * u2, 0.0))  # 0 for identical frames
    else:
        raise ValueError(f"rule {rule!r}: expected one of {RULES}")
    return float(out) if out.ndim == 0 else out


#: TBEC 2018's least gap in words (tbec2018_minimum_gap_m), as the tables' column notes give it
TBEC2018_RULE = "30 mm up to 6 m, 10 mm per further started 3 m"


def tbec2018_minimum_gap_m(height_m):
    """TBEC 2018's least gap at a level `height_m` above the ground [m], full scale: 30 mm up to 6 m,
    plus 10 mm for each further started 3 m."""
    h = np.asarray(height_m, dtype=float)
    extra = np.maximum(np.ceil(np.round((h - 6.0) / 3.0, 9)), 0.0)
    out = 0.030 + 0.010 * extra
    return float(out) if out.ndim == 0 else out


def first_mode(masses_kg, story_stiffness_N_per_m, rayleigh_a0, rayleigh_a1) -> tuple[float, float]:
    """(circular frequency [rad/s], damping ratio) of a shear frame's first mode (Rayleigh damping:
    zeta = a0 / (2 w) + a1 w / 2)."""
    from pounding_sweep.model.structure import modal_analysis, shear_frame_stiffness

    M = np.diag(np.asarray(masses_kg, float))
    K = shear_frame_stiffness(np.asarray(story_stiffness_N_per_m, float))
    w = float(modal_analysis(M, K).omega_rad_s[0])
    return w, rayleigh_a0 / (2.0 * w) + rayleigh_a1 * w / 2.0


def frame_first_mode(frame) -> tuple[float, float]:
    """first_mode of a model.structure.ShearFrame: from its Rayleigh coefficients, or with modal damping its
    mode 1's ratio as given."""
    if frame.modal_damping_ratios is not None:
        return float(frame.modes().omega_rad_s[0]), float(frame.modal_damping_ratios[0])
    return first_mode(frame.masses_kg, frame.story_stiffness_N_per_m, frame.rayleigh_a0_per_s, frame.rayleigh_a1_s)


def floor_heights_m(story_heights) -> np.ndarray:
    """Heights of the floors above the ground [m] from the story heights, floor 1 first."""
    return np.cumsum(np.asarray(story_heights, dtype=float))


__all__ = ["RULES", "cqc_correlation", "combined_gap", "tbec2018_minimum_gap_m", "first_mode", "floor_heights_m"]
