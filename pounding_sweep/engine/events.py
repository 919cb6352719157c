"""The event scheme's pieces that do not depend on coordinates, shared by the scalar kernel (floors)
and the lane kernel (modes): the ground motion inside a step, the contact indicator on a step's cubic
Hermite interpolant, the switch tolerance, the Illinois false-position bracket, the force extremes,
and the scheme's limits. One home: both kernels compile these same functions.

Event scheme (Wriggers, Computational Contact Mechanics, 2006, sec. 9.5 on event-driven integration):
a step is taken with the contact set of its start; where its end contradicts the set, the switch
instant is located on the real sub-step map (false position started at the interpolant's estimate),
the step split there and continued with the new set.
"""

from __future__ import annotations

import numpy as np

from pounding_sweep.codes import EXC_HARMONIC
from pounding_sweep.engine import layout as L
from pounding_sweep.engine.jit import njit_kernel

MAX_EVENTS = 16  # contact switches located inside one step before the step is taken as it is (flagged)
EVENT_MIN_FRACTION = 1e-9  # a sub-step shorter than this fraction of dt is not integrated (rounding)


@njit_kernel
def ground_acceleration(kind, amp, omega, rec_flat, rec_off, rec_len, step, dt):
    """Ground (table) acceleration [m/s^2] at t = step * dt."""
    if kind == EXC_HARMONIC:
        return -amp * omega * omega * np.sin(omega * step * dt)
    if step < rec_len:
        return amp * rec_flat[rec_off + step]
    return 0.0


@njit_kernel
def ground_acceleration_at(amp, omega, t):
    """Harmonic ground acceleration [m/s^2] at any time t (event sub-steps)."""
    return -amp * omega * omega * np.sin(omega * t)


@njit_kernel
def _ag_inside(hs, h, ag_s, ag_e, harmonic, amp, om, t_s):
    """Ground acceleration hs into the rest (length h) of a step: exact for harmonic motion, linear
    between the record's samples otherwise."""
    if harmonic:
        return ground_acceleration_at(amp, om, t_s + hs)
    return ag_s + (ag_e - ag_s) * (hs / h)


@njit_kernel
def _want_contact(p0, p1, m0, m1, tau, h, law, k_s, c):
    """Contact indicator at fraction tau of the step (> 0: the pair should be in contact), from the
    cubic Hermite interpolant of the penetration (p0, p1; end slopes m0, m1 = v_rel h)."""
    t2 = tau * tau
    t3 = t2 * tau
    p = (2 * t3 - 3 * t2 + 1) * p0 + (t3 - 2 * t2 + tau) * m0 + (-2 * t3 + 3 * t2) * p1 + (t3 - t2) * m1
    if law == 0:
        return p
    dp = (6 * t2 - 6 * tau) * p0 + (3 * t2 - 4 * tau + 1) * m0 + (-6 * t2 + 6 * tau) * p1 + (3 * t2 - 2 * tau) * m1
    f = p + (c / k_s) * dp / h  # no tension: in contact while penetrating and pushing (F / k_s, metres)
    return min(p, f)


@njit_kernel
def _switch_tolerance(up, uq):
    """Penetration [m] below which a contact switch is rounding, not motion: a femtometre, or 1e-12 of
    the floors' displacement. Without it a pair resting exactly at zero penetration (gap 0 at rest)
    would switch back and forth on rounding noise."""
    return 1e-15 + 1e-12 * (abs(up) + abs(uq))


@njit_kernel
def _secant_point(lo, hi, f_lo, f_hi):
    """The false-position point of the bracket (lo, hi), or its midpoint when that falls outside."""
    x = hi - f_hi * (hi - lo) / (f_hi - f_lo)
    return x if lo < x < hi else 0.5 * (lo + hi)


@njit_kernel
def _illinois(lo, hi, f_lo, f_hi, side, x, fx):
    """One update of an Illinois false-position bracket (lo, hi) with f(lo) < 0 <= f(hi): x, where
    f is fx, replaces the end of its sign; when the same end moves twice running, the other end's
    value is halved (the modified regula falsi: Dowell & Jarratt, BIT 11, 1971). Returns (lo, hi,
    f_lo, f_hi, side), side = 1 after the high end moved, -1 after the low end."""
    if fx >= 0.0:
        if side == 1:
            f_lo *= 0.5
        return lo, x, f_lo, fx, 1
    if side == -1:
        f_hi *= 0.5
    return x, hi, fx, f_hi, -1


@njit_kernel
def _force_extremes(out, base, f, t):
    if f > out[base + L.PAIR_PEAK_FORCE]:
        out[base + L.PAIR_PEAK_FORCE] = f
        out[base + L.PAIR_PEAK_FORCE_TIME] = t
    if f < out[base + L.PAIR_MIN_FORCE]:
        out[base + L.PAIR_MIN_FORCE] = f
