"""The pounding laws' parameters from a scene's stiffness and coefficient of restitution r, and the
restitution each law actually returns in a single free impact.

Laws (force F > 0 in compression at penetration delta > 0, rate delta_dot; e = r; m_eff = m1 m2 / (m1 + m2)):

- classic, no_tension: Kelvin-Voigt, F = k_s delta + c delta_dot (paper eq. 8; no_tension clipped at 0),
  c = 2 xi sqrt(k_s m_eff) (eq. 9). Authors' relation: eq. 10, xi = -ln e / sqrt(pi^2 + ln^2 e)
  (Anagnostopoulos 1988, EESD 16:443), exact for the classic law; under no_tension the clip strands spring
  energy and a single impact returns more than e (0.2 -> 0.325).
- hertz: F = k_h delta^1.5 (Hertz 1882; Davis 1992, EESD 21:253). Elastic: e = 1, r is not used.
- hertzdamp: F = k_h delta^1.5 (1 + a delta_dot / v0), v0 the approach speed at the impact's start
  (Muthukumar & DesRoches 2006, EESD 35:811). Authors' relation (default): Ye, Li & Zhu 2009 (EESD
  38:1135), a = 8 (1 - e) / (5 e). Also "muthukumar2006": the original relation taken from Lankarani &
  Nikravesh 1990, a = 3 (1 - e^2) / 4, derived for e near 1: it cannot return e below about 0.66 (e = 0.2
  gives 0.67), which is why Ye et al. corrected it and why it is not the default.
- jankowski: F = k_h delta^1.5 + c delta_dot while approaching, k_h delta^1.5 while separating,
  c = 2 xi sqrt(k_h sqrt(delta) m_eff) (Jankowski 2005, EESD 34:595). Authors' relation: Jankowski 2006
  (EESD 35:517), xi = 9 sqrt(5) (1 - e^2) / (2 e (e (9 pi - 16) + 16)).

Relation "exact" (any law): the parameter for which a single free impact of two bodies returns exactly e
(the numerical inverse of single_impact_restitution below), so that r means the same for every law.

The stiffness. A linear law's k_s [N/m] and a Hertz law's k_h [N/m^1.5] are matched at a stated reference
penetration delta_ref: k_h = k_s / sqrt(delta_ref), i.e. both give the same force k_s delta_ref there, so
a k_s/k axis means the same stiffness for every law at that penetration (the scene's
reference_penetration_m, default 1 mm: the paper's model pounds with penetrations of 0.5-15 mm at
k_s/k = 0.1-10). k_h may also be given directly (kh_N_per_m1_5).
"""

from __future__ import annotations

import functools
import math

import numpy as np

from pounding_sweep.codes import LAW_CLASSIC, LAW_HERTZ, LAW_HERTZDAMP, LAW_JANKOWSKI, LAW_NO_TENSION
from pounding_sweep.codes import RESTITUTION_RELATIONS as RELATIONS
from pounding_sweep.model.contact import damping_ratio_from_restitution, effective_mass


def hertz_stiffness(ks_N_per_m, reference_penetration_m):
    """k_h = k_s / sqrt(delta_ref) [N/m^1.5]: the Hertz law's force at delta_ref equals k_s delta_ref."""
    return ks_N_per_m / math.sqrt(reference_penetration_m)


# ----------------------------------------------------------------------------- authors' relations


def ye2009_a(e):
    """Hertz-damp's normalised damping a = 8 (1 - e) / (5 e) (Ye, Li & Zhu 2009); e in (0, 1]."""
    return 8.0 * (1.0 - e) / (5.0 * e)


def lankarani_a(e):
    """Hertz-damp's a = 3 (1 - e^2) / 4 (Lankarani & Nikravesh 1990, as Muthukumar & DesRoches 2006 use it)."""
    return 0.75 * (1.0 - e * e)


def jankowski2006_xi(e):
    """Jankowski's impact damping ratio xi = 9 sqrt(5) (1 - e^2) / (2 e (e (9 pi - 16) + 16)) (2006); e in (0, 1]."""
    return 9.0 * math.sqrt(5.0) * (1.0 - e * e) / (2.0 * e * (e * (9.0 * math.pi - 16.0) + 16.0))


# ----------------------------------------------------------------------------- single free impact


def _kv_clipped_restitution(xi: float) -> float:
    """e of the no-tension Kelvin-Voigt law: unit mass and stiffness, x(0) = 0, x'(0) = 1; the contact ends
    where x + 2 xi x' = 0 (force zero), after which the bodies fly apart at -x'."""
    if xi <= 0.0:
        return 1.0
    if xi < 1.0:
        w = math.sqrt(1.0 - xi * xi)

        def x(t):
            return math.exp(-xi * t) * math.sin(w * t) / w

        def xd(t):
            return math.exp(-xi * t) * (math.cos(w * t) - xi * math.sin(w * t) / w)

        t_hi = math.pi / w
    else:
        s = math.sqrt(xi * xi - 1.0)
        r1, r2 = -xi + s, -xi - s
        if s == 0.0:

            def x(t):
                return t * math.exp(-t)

            def xd(t):
                return (1.0 - t) * math.exp(-t)

        else:

            def x(t):
                return (math.exp(r1 * t) - math.exp(r2 * t)) / (r1 - r2)

            def xd(t):
                return (r1 * math.exp(r1 * t) - r2 * math.exp(r2 * t)) / (r1 - r2)

        t_hi = 50.0 / max(-r1, 1e-3)
    from scipy.optimize import brentq

    def force(t):
        return x(t) + 2.0 * xi * xd(t)

    # the force starts at 2 xi > 0 and turns negative before the penetration returns to 0
    t_lo = 1e-12
    t_root = brentq(force, t_lo, t_hi, xtol=1e-15, rtol=4 * np.finfo(float).eps, maxiter=500)
    return max(0.0, -xd(t_root))


def _hertzdamp_restitution(a: float) -> float:
    """e of Hertz-damp with normalised damping a: the phase-plane first integral of m v dv/dx = -k x^n (1 + a v / v0)
    gives -a e - ln(1 - a e) = a - ln(1 + a), independent of k, m, n and v0; solved with y = -ln(1 - a e)."""
    if a <= 0.0:
        return 1.0
    rhs = a - math.log1p(a)
    from scipy.optimize import brentq

    y = brentq(lambda y: y - 1.0 + math.exp(-y) - rhs, 0.0, rhs + 2.0 + 50.0, xtol=1e-15, rtol=4 * np.finfo(float).eps)
    return -math.expm1(-y) / a


def _jankowski_restitution(xi: float) -> float:
    """e of Jankowski's law with damping ratio xi: the approach x'' = -x^1.5 - 2 xi x^0.25 x' (unit k_h, m_eff
    and v0; the produced e depends on xi only) integrated in the penetration as w = x'^2,
    dw/dx = -2 x^1.5 - 4 xi x^0.25 sqrt(w), until w = 0 at x_max; the elastic restitution returns
    x'^2 = 0.8 x_max^2.5."""
    if xi <= 0.0:
        return 1.0
    from scipy.integrate import solve_ivp

    def rhs(x, w):
        return [-2.0 * x**1.5 - 4.0 * xi * x**0.25 * math.sqrt(max(w[0], 0.0))]

    def stop(x, w):
        return w[0]

    stop.terminal, stop.direction = True, -1.0
    x_free = 1.25**0.4  # the undamped maximum penetration bounds the damped one
    sol = solve_ivp(rhs, (0.0, 2.0 * x_free), [1.0], events=stop, rtol=1e-12, atol=1e-14, method="DOP853")
    x_max = sol.t_events[0][0]
    return math.sqrt(0.8 * x_max**2.5)


def single_impact_restitution(law: str, parameter: float) -> float:
    """The coefficient of restitution a single free impact of two bodies returns under `law` with its damping
    parameter (classic, no_tension, jankowski: xi; hertzdamp: a; hertz: none), independent of the masses,
    stiffness and approach speed (each law is scale invariant with its damping normalised as here)."""
    if law == "classic":
        xi = parameter
        return math.exp(-xi * math.pi / math.sqrt(1.0 - xi * xi)) if xi < 1.0 else 0.0
    if law == "no_tension":
        return _kv_clipped_restitution(parameter)
    if law == "hertz":
        return 1.0
    if law == "hertzdamp":
        return _hertzdamp_restitution(parameter)
    if law == "jankowski":
        return _jankowski_restitution(parameter)
    raise ValueError(f"unknown contact law {law!r}")


# ----------------------------------------------------------------------------- r -> the law's parameter


def _inverse(law: str, e: float, hi: float) -> float:
    """The parameter p in (0, hi) with single_impact_restitution(law, p) = e (decreasing in p)."""
    from scipy.optimize import brentq

    return brentq(lambda p: single_impact_restitution(law, p) - e, 1e-12, hi, xtol=1e-13, rtol=1e-12)


@functools.lru_cache(maxsize=4096)
def damping_parameter(law: str, r: float, relation: str = "authors") -> float:
    """The law's damping parameter for restitution r (module docstring): xi for classic, no_tension and
    jankowski, a for hertzdamp, 0 for hertz. r = 0 is refused where the parameter is infinite."""
    if not 0.0 <= r <= 1.0:
        raise ValueError(f"coefficient of restitution r must lie in [0, 1], got {r!r}")
    if relation not in RELATIONS:
        raise ValueError(f"restitution relation {relation!r}: expected one of {RELATIONS}")
    if law == "hertz":
        return 0.0
    if law in ("classic", "no_tension"):
        if relation != "exact" or law == "classic" or r in (0.0, 1.0):
            return float(damping_ratio_from_restitution(r))
        return _inverse("no_tension", r, 50.0)
    if r == 0.0:
        raise ValueError(f"r = 0 has no finite damping under the {law} law (a perfectly plastic impact)")
    if r == 1.0:
        return 0.0
    if law == "hertzdamp":
        if relation == "muthukumar2006":
            return lankarani_a(r)
        if relation == "exact":
            return _inverse("hertzdamp", r, 10.0 / r)
        return ye2009_a(r)
    if law == "jankowski":
        if relation == "exact":
            return _inverse("jankowski", r, 4.0 * jankowski2006_xi(r) + 1.0)
        return jankowski2006_xi(r)
    raise ValueError(f"unknown contact law {law!r}")


def law_arrays(law_codes, k, r, relation, m1, m2, names):
    """Per run (rows) and pair (columns): the kernels' coefficient array for each run's law.

    k: per run k_s [N/m] for the linear laws, k_h [N/m^1.5] for the Hertz ones. Returns (coef (runs,
    pairs), damping parameter per run, produced single-impact restitution per run): coef is the
    Kelvin-Voigt dashpot c_j (eq. 9) for classic and no_tension, a for hertzdamp, c0_j = 2 xi
    sqrt(k_h m_eff_j) for jankowski (so c = c0 delta^0.25), 0 for hertz. `names`: law code -> name.
    The parameters are computed once per distinct (law, r)."""
    law_codes = np.asarray(law_codes, np.int64)
    r = np.asarray(r, float)
    k = np.asarray(k, float)
    meff = effective_mass(np.asarray(m1, float), np.asarray(m2, float))
    param = np.zeros(r.size)
    produced = np.zeros(r.size)
    for code in np.unique(law_codes):
        sel = law_codes == code
        values, inv = np.unique(r[sel], return_inverse=True)
        name = names[int(code)]
        ps = np.array([damping_parameter(name, float(x), relation) for x in values])
        param[sel] = ps[inv]
        produced[sel] = np.array([_produced(name, float(p)) for p in ps])[inv]
    coef = np.zeros((r.size, meff.size))
    kv = np.isin(law_codes, (LAW_CLASSIC, LAW_NO_TENSION, LAW_JANKOWSKI))
    coef[kv] = 2.0 * param[kv, None] * np.sqrt(k[kv, None] * meff[None, :])
    hd = law_codes == LAW_HERTZDAMP
    coef[hd] = param[hd, None]
    unknown = ~np.isin(law_codes, (LAW_CLASSIC, LAW_NO_TENSION, LAW_HERTZ, LAW_HERTZDAMP, LAW_JANKOWSKI))
    if unknown.any():
        raise ValueError(f"unknown contact law code {law_codes[unknown][0]!r}")
    return coef, param, produced


@functools.lru_cache(maxsize=4096)
def _produced(law: str, p: float) -> float:
    return single_impact_restitution(law, p)
