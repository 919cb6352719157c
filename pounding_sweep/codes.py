"""Names and the integer codes the kernels take for them, in one place: integration schemes, contact
laws, excitation kinds, history channel kinds and record units. Every layer may import this module (it
imports nothing), so choosing a scheme by name never loads the kernels."""

from __future__ import annotations

#: integration schemes (engine/scalar.py, engine/nonlinear.py and engine/lanes implement them)
SCHEME_IMPLICIT = 0
SCHEME_PAPER = 1
SCHEME_EVENT = 2
SCHEMES = {"implicit": SCHEME_IMPLICIT, "paper": SCHEME_PAPER, "event": SCHEME_EVENT}

#: contact laws (model/contact.py and model/laws.py hold their parameters): the linear Kelvin-Voigt laws
#: (engine/scalar.py, engine/lanes) and the Hertz-type nonlinear ones (engine/nonlinear.py); engine/registry.py
#: says which kernel integrates which
LAW_CLASSIC = 0
LAW_NO_TENSION = 1
LAW_HERTZ = 2
LAW_HERTZDAMP = 3
LAW_JANKOWSKI = 4
CONTACT_LAWS = {
    "classic": LAW_CLASSIC,
    "no_tension": LAW_NO_TENSION,
    "hertz": LAW_HERTZ,
    "hertzdamp": LAW_HERTZDAMP,
    "jankowski": LAW_JANKOWSKI,
}

#: how r sets a law's damping (model/laws.py): the law's authors' relation, the exact single-impact inverse, or
#: for hertzdamp the original relation of Muthukumar & DesRoches 2006
RESTITUTION_RELATIONS = ("authors", "exact", "muthukumar2006")


#: the linear Kelvin-Voigt laws and the Hertz-type ones (force ~ penetration^1.5)
KELVIN_VOIGT_LAWS = (LAW_CLASSIC, LAW_NO_TENSION)
HERTZ_LAWS = (LAW_HERTZ, LAW_HERTZDAMP, LAW_JANKOWSKI)


def is_nonlinear(law: int) -> bool:
    """A Hertz-type law (force ~ penetration^1.5), integrated by engine/nonlinear.py."""
    return law in HERTZ_LAWS


#: excitation kinds: table displacement amp sin(omega t) (ground acceleration -amp omega^2 sin(omega t)),
#: or a ground acceleration record resampled to dt
EXC_HARMONIC = 0
EXC_RECORD = 1

#: history channel kinds (scene/channels.py names them: disp_b1f3, vel_..., abs_acc_..., force_f3, ground_acc)
H_DISP, H_VEL, H_ABS_ACC, H_FORCE, H_GROUND_ACC = range(5)

#: record acceleration units as a scene may spell them -> canonical name (model/records.py has the factors)
UNIT_ALIASES = {"g": "g", "m/s2": "m/s2", "m/s^2": "m/s2", "cm/s2": "cm/s2", "cm/s^2": "cm/s2", "gal": "cm/s2"}
ACCEPTED_UNITS = ", ".join(repr(u) for u in UNIT_ALIASES)


def canonical_unit(units: str) -> str | None:
    """'CM/S^2' -> 'cm/s2'; None when the spelling is not accepted."""
    return UNIT_ALIASES.get(units.strip().lower().replace(" ", "")) if isinstance(units, str) else None
