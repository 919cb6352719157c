"""The parameter registry: every scene parameter a [sweep] may vary or [calibrate] may fit, once.

Per parameter: where it lives in the scene (section, key), its unit, the meaning of its result column, its plot
labels, the range its values must lie in, whether a fit works on its logarithm, and its roles. The tables the
layers above read (the sweep axes, the structure axes, the fittable and profiled names, the best-run columns,
the column docs, the plot labels, the range checks) are views of this one list, so adding a parameter is one
entry here plus its physics (where the model reads the key). Order: the order of [sweep] axes in --describe and
of the grid's fixed values; the views keep it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

#: the roles a parameter may have
SWEEP = "sweep"  # a [sweep] axis
STRUCTURE = "structure"  # changes the structure's matrices or the experiment's sampling: runs grouped by it
CONTACT = "contact"  # sweeping it says the scene studies pounding (sweep/checks.py)
STIFFNESS = "stiffness"  # sets a run's contact stiffness, so its contact period (sweep/checks.py)
FITTABLE = "fittable"  # [calibrate] may fit it
PROFILED = "profiled"  # profiled by default when fitted (sweep/calibrate.py)
BEST = "best"  # a column of the best-runs table (sweep/ranking.py)
ROLES = (SWEEP, STRUCTURE, CONTACT, STIFFNESS, FITTABLE, PROFILED, BEST)


@dataclass(frozen=True)
class Range:
    """The values a parameter may take: [low, high] with each end closed or open; `must` completes a message on
    one value ('r = 2: must ...'), `bounds` one on a pair of [calibrate] bounds ('r = [0, 2]: ...')."""

    low: float
    high: float
    low_closed: bool
    high_closed: bool
    must: str
    bounds: str

    def holds(self, v: float) -> bool:
        """v inside the range (NaN never is)."""
        above = v >= self.low if self.low_closed else v > self.low
        below = v <= self.high if self.high_closed else v < self.high
        return bool(above and below)


POSITIVE = Range(0.0, math.inf, False, True, "must be > 0", "must be > 0")
NON_NEGATIVE = Range(0.0, math.inf, True, True, "must be >= 0", "a gap is >= 0")
RESTITUTION = Range(
    0.0,
    1.0,
    True,
    True,
    "the coefficient of restitution must lie in [0, 1]",
    "a coefficient of restitution lies in [0, 1]",
)
DAMPING_RATIO = Range(0.0, 1.0, True, False, "must lie in [0, 1)", "a damping ratio lies in [0, 1)")


@dataclass(frozen=True)
class Parameter:
    """One scene parameter (module docstring). `label` and `short` name it on a figure's axis and in a text line,
    its values shown times `factor` (None: a name, shown as it is); `range`: None where any value is allowed
    (or, for a name, where the scene checks it otherwise); `log`: a fit and a profile work on log(value)."""

    name: str
    section: str
    key: str
    unit: str
    doc: str
    roles: frozenset
    range: Range | None = None
    log: bool = False
    label: str | None = None
    short: str | None = None
    factor: float | None = 1.0
    per: str = ""  # a family (FAMILIES): 's' one value per story, 'm' one per mode; 'c' per channel (CHANNEL_OFFSET)
    neutral: float | None = None  # a family member's value where the scene gives no list (None: it must give one)

    def has(self, role: str) -> bool:
        return role in self.roles


def _roles(*names: str) -> frozenset:
    unknown = set(names) - set(ROLES)
    if unknown:
        raise ValueError(f"unknown parameter roles {sorted(unknown)}")
    return frozenset((SWEEP, *names))


def _structure(b: int) -> list[Parameter]:
    """Building b's model-error parameters: a factor on every story stiffness, on every floor mass, and its
    Rayleigh damping ratio at its damping_modes (model/coupled.py reads them)."""
    sec = f"building{b}"
    return [
        Parameter(
            f"stiffness_scale_b{b}",
            sec,
            "stiffness_scale",
            "-",
            f"factor on every story stiffness of building {b} (swept) [-]",
            _roles(STRUCTURE, FITTABLE, BEST),
            POSITIVE,
        ),
        Parameter(
            f"mass_scale_b{b}",
            sec,
            "mass_scale",
            "-",
            f"factor on every floor mass of building {b} (swept) [-]",
            _roles(STRUCTURE, FITTABLE, BEST),
            POSITIVE,
        ),
        Parameter(
            f"damping_ratio_b{b}",
            sec,
            "damping_ratio",
            "-",
            f"Rayleigh damping ratio of building {b} at its damping_modes (swept) [-]",
            _roles(STRUCTURE, FITTABLE, BEST),
            DAMPING_RATIO,
        ),
    ]


def _ordered_structure() -> list[Parameter]:
    """Both buildings' structure parameters, kind by kind (stiffness, mass, damping), building 1 first."""
    b1, b2 = _structure(1), _structure(2)
    return [p for pair in zip(b1, b2) for p in pair]


PARAMETERS: tuple[Parameter, ...] = (
    Parameter(
        "ks_ratio",
        "contact",
        "ks_ratio",
        "-",
        "contact stiffness k_s / k_ref [-]",
        _roles(CONTACT, STIFFNESS, FITTABLE, PROFILED, BEST),
        POSITIVE,
        log=True,
        label="contact stiffness ratio $k_s/k$ [-]",
        short="k_s/k",
    ),
    Parameter(
        "ks_N_per_m",
        "contact",
        "ks_N_per_m",
        "N/m",
        "contact stiffness k_s [N/m]",
        _roles(CONTACT, STIFFNESS, FITTABLE, PROFILED, BEST),
        POSITIVE,
        log=True,
        label="contact stiffness $k_s$ [N/m]",
        short="k_s [N/m]",
    ),
    Parameter(
        "r",
        "contact",
        "r",
        "-",
        "coefficient of restitution [-]",
        _roles(CONTACT, FITTABLE, PROFILED, BEST),
        RESTITUTION,
        label="coefficient of restitution r [-]",
        short="r",
    ),
    Parameter(
        "law",
        "contact",
        "law",
        "",
        "the run's pounding law (its column: contact_law)",
        _roles(STIFFNESS),
        factor=None,
    ),
    Parameter(
        "kh_N_per_m1_5",
        "contact",
        "kh_N_per_m1_5",
        "N/m^1.5",
        "Hertz-type laws: k_h [N/m^1.5] (given, or k_s / sqrt(reference_penetration_m))",
        _roles(STIFFNESS, FITTABLE, PROFILED),
        POSITIVE,
        log=True,
    ),
    Parameter(
        "gap_m",
        "contact",
        "gap_m",
        "m",
        "gap d between facing floors at rest [m]",
        _roles(CONTACT, FITTABLE, BEST),
        NON_NEGATIVE,
        label="gap d [mm]",
        short="gap [mm]",
        factor=1e3,
    ),
    Parameter(
        "amplitude_m",
        "excitation",
        "amplitude_m",
        "m",
        "harmonic table motion: its displacement amplitude [m]",
        _roles(FITTABLE, BEST),
        POSITIVE,
        label="table amplitude [mm]",
        short="amplitude [mm]",
        factor=1e3,
    ),
    Parameter(
        "frequency_Hz",
        "excitation",
        "frequency_Hz",
        "Hz",
        "harmonic table motion: its frequency [Hz]",
        _roles(BEST),
        POSITIVE,
        label="table frequency [Hz]",
        short="f [Hz]",
    ),
    Parameter(
        "scale",
        "excitation",
        "scale",
        "-",
        "factor on the motion's acceleration; with [excitation] scaling = 'intensity': its intensity [g]",
        _roles(FITTABLE, BEST),
        POSITIVE,
        label="record scale [-]",
        short="scale",
    ),
    Parameter(
        "record",
        "excitation",
        "record",
        "",
        "record excitation: the run's ground-motion record (its file's name)",
        _roles(BEST),
        label="record",
        short="record",
        factor=None,
    ),
    Parameter(
        "seed",  # a stochastic motion's realisation (scene/stochastic.py checks its values)
        "stochastic",
        "seed",
        "-",
        "stochastic excitation: the seed of the run's ground-motion realisation [-]",
        _roles(),
    ),
    # the structure and the experiment's clock: model error, swept or fitted (sweep/calibrate.py)
    *_ordered_structure(),
    Parameter(
        "time_offset_s",
        "experiment",
        "time_offset_s",
        "s",
        "experiment time minus simulation time (swept) [s]",
        _roles(STRUCTURE, FITTABLE, BEST),
    ),
)

BY_NAME: dict[str, Parameter] = {p.name: p for p in PARAMETERS}


def _families(b: int) -> list[Parameter]:
    """Building b's per-story stiffness factors (model/coupled.py) and per-mode damping ratios
    (model/structure.py modal_damping_matrix): one fittable value per story or mode."""
    return [
        Parameter(
            f"story_stiffness_scale_b{b}",
            f"building{b}",
            "story_stiffness_scales",
            "-",
            f"factor on one story's stiffness of building {b}, on top of stiffness_scale (fitted) [-]",
            frozenset((STRUCTURE, FITTABLE)),
            POSITIVE,
            per="s",
            neutral=1.0,
        ),
        Parameter(
            f"modal_damping_ratio_b{b}",
            f"building{b}",
            "modal_damping_ratios",
            "-",
            f"damping ratio of one mode of building {b} (fitted) [-]",
            frozenset((STRUCTURE, FITTABLE)),
            DAMPING_RATIO,
            per="m",
        ),
    ]


#: parameters with one value per story or per mode (a [buildingN] list key): fitted one member at a time, each
#: named <family>_<per><index> (story_stiffness_scale_b1_s2: building 1's second story; modal_damping_ratio_b2_m1:
#: building 2's first mode); not [sweep] axes
FAMILIES: tuple[Parameter, ...] = (*_families(1), *_families(2))


#: a channel's own clock, on top of the table's: experiment time minus simulation time of one [experiment] channel
#: is time_offset_s + time_offset_s_<code> (<code> the channel's model code as [experiment] channels gives it:
#: time_offset_s_abs_acc_b1f3, time_offset_s_b2f1), for sensors whose clocks are not synchronised. Fitted only
#: (sweep/calibrate.py shifts that channel's samples); neutral 0; not a structure parameter (no run changes).
CHANNEL_OFFSET = Parameter(
    "time_offset_s",
    "experiment",
    "time_offset_s",
    "s",
    "one channel's clock offset on top of the table's time_offset_s (fitted) [s]",
    frozenset((FITTABLE,)),
    per="c",
    neutral=0.0,
)
CHANNEL_OFFSET_PREFIX = f"{CHANNEL_OFFSET.name}_"


def channel_offset(name: str) -> str | None:
    """The channel code of a per-channel clock offset ('time_offset_s_abs_acc_b1f3' -> 'abs_acc_b1f3'), else None.
    Whether the scene has that channel is the scene's check (scene/validate.py)."""
    code = name.removeprefix(CHANNEL_OFFSET_PREFIX)
    return code if code != name and code else None


def member(name: str) -> tuple[Parameter, int] | None:
    """(family, index) of a per-story or per-mode name ('story_stiffness_scale_b1_s2' -> (its family, 2)), else
    None."""
    for fam in FAMILIES:
        head, sep, index = name.rpartition(f"_{fam.per}")
        if sep and head == fam.name and index.isdigit() and int(index) >= 1:
            return fam, int(index)
    return None


def parameter(name: str) -> Parameter | None:
    """The registry entry of a name: a parameter's own, or the family of a per-story name; None if unknown."""
    if name in BY_NAME:
        return BY_NAME[name]
    if channel_offset(name) is not None:
        return CHANNEL_OFFSET
    found = member(name)
    return found[0] if found else None


def names(role: str) -> tuple[str, ...]:
    """The names of the parameters with `role`, in registry order."""
    if role not in ROLES:
        raise ValueError(f"unknown parameter role {role!r}")
    return tuple(p.name for p in PARAMETERS if p.has(role))


def is_log(name: str) -> bool:
    """A fit, a profile and a figure work on log(value) of this parameter."""
    p = parameter(name)
    return p is not None and p.log


def out_of_range(name: str, value, where: str) -> str | None:
    """The message for `value` of parameter `name` outside its range ('[sweep] r = 2.0: the coefficient ...'),
    None when it is inside (or the parameter has no range)."""
    rng = parameter(name).range
    if rng is None or value is None or rng.holds(value):
        return None
    return f"{where} = {value!r}: {rng.must}"


def bounds_out_of_range(name: str, lo: float, hi: float, where: str) -> str | None:
    """The message for [calibrate] bounds [lo, hi] of `name` reaching outside its range, None when inside."""
    rng = parameter(name).range
    if rng is None or (rng.holds(lo) and rng.holds(hi)):
        return None
    return f"{where} = [{lo}, {hi}]: {rng.bounds}"


#: the forms of the contact stiffness a fit may take (one at a time): k_s / k_ref, k_s, k_h
STIFFNESS_FORMS = tuple(p.name for p in PARAMETERS if p.has(STIFFNESS) and p.has(FITTABLE))


def default_profiled(fitted) -> list[str]:
    """The fitted parameters profiled when [calibrate] profile names none: the profiled ones among `fitted`,
    the contact stiffness's form first."""
    chosen = [n for n in names(PROFILED) if n in fitted]
    return sorted(chosen, key=lambda n: n not in STIFFNESS_FORMS)
