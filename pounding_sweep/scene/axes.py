"""Sweep axes: which scene parameters a [sweep] may vary (a view of scene/parameters.py), and the one rule for the contact stiffness
(given as k_s / k_ref or as k_s in N/m, never both: setting one form makes the other derived)."""

from __future__ import annotations

import math

from pounding_sweep.errors import ConfigError
from pounding_sweep.scene.parameters import PARAMETERS, STRUCTURE, SWEEP, names

#: name -> (section, key) of every parameter a [sweep] may vary (scene/parameters.py holds them all)
SWEEPABLE = {p.name: (p.section, p.key) for p in PARAMETERS if p.has(SWEEP)}

#: the axes that change the structure's matrices or the experiment's sampling: a grid over them runs each
#: distinct combination as its own group of runs (sweep/prepare.py Prepared.run)
STRUCTURE_AXES = names(STRUCTURE)

#: the two forms of the contact stiffness
KS_FORMS = ("ks_ratio", "ks_N_per_m")


def ks_counterpart(name: str) -> str:
    """The other form of the contact stiffness: ks_ratio <-> ks_N_per_m."""
    return KS_FORMS[1] if name == KS_FORMS[0] else KS_FORMS[0]


def setting_ks(name: str, value) -> dict:
    """The contact keys to set when one form of k_s is given: that form, and the other cleared."""
    return {name: value, ks_counterpart(name): None}


def contact_stiffness(ks_ratio, ks_N_per_m, k_ref):
    """k_s [N/m]: ks_N_per_m where it is given, else ks_ratio k_ref (scalars with None, or NumPy arrays
    with NaN, for 'not given')."""
    if hasattr(ks_N_per_m, "shape") or hasattr(ks_ratio, "shape"):
        import numpy as np

        return np.where(np.isnan(ks_N_per_m), ks_ratio * k_ref, ks_N_per_m)
    return float(ks_N_per_m) if ks_N_per_m is not None else float(ks_ratio) * k_ref


def check_ks(contact, axes: dict) -> None:
    """One form of k_s at the base point or on a sweep axis; finite once resolved."""
    if "ks_ratio" in axes and "ks_N_per_m" in axes:
        raise ConfigError("[sweep]: sweep ks_ratio or ks_N_per_m, not both")
    if contact.ks_ratio is not None and contact.ks_N_per_m is not None:
        raise ConfigError("[contact]: give ks_ratio or ks_N_per_m, not both")
    if contact.ks_ratio is None and contact.ks_N_per_m is None and not axes.keys() & set(KS_FORMS):
        if not _all_hertz_with_kh(contact, axes):
            raise ConfigError("[contact]: missing key 'ks_ratio' (or 'ks_N_per_m'): the contact stiffness")
    # the resolved contact stiffness enters ke = k_s + 2 c / dt and the contact matrix: it must stay finite
    k_ref = contact.k_ref_N_per_m
    for key, ratio in [("[contact] ks_ratio", contact.ks_ratio)] + [
        ("[sweep] ks_ratio", v) for v in axes.get("ks_ratio", ())
    ]:
        if ratio is not None and not math.isfinite(4.0 * ratio * k_ref):
            raise ConfigError(
                f"{key} = {ratio!r} with [contact] k_ref_N_per_m = {k_ref!r}: k_s = ratio k_ref "
                "overflows (is k_ref in N/m?)"
            )
    for key, ks in [("[contact] ks_N_per_m", contact.ks_N_per_m)] + [
        ("[sweep] ks_N_per_m", v) for v in axes.get("ks_N_per_m", ())
    ]:
        if ks is not None and not math.isfinite(4.0 * ks):
            raise ConfigError(f"{key} = {ks!r}: too large (the contact terms overflow)")


def _all_hertz_with_kh(contact, axes: dict) -> bool:
    """Every law of the scene is a Hertz-type one and k_h is given: no k_s is needed."""
    from pounding_sweep.codes import CONTACT_LAWS, is_nonlinear

    laws = axes.get("law", (contact.law,))
    has_kh = contact.kh_N_per_m1_5 is not None or "kh_N_per_m1_5" in axes
    return has_kh and all(is_nonlinear(CONTACT_LAWS.get(x, 0)) for x in laws)
