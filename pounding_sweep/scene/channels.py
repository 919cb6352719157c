"""Names of time-history channels (`disp_b1f3`, `force_f3`, ...) and their kernel codes."""

from __future__ import annotations

import re

from pounding_sweep import codes
from pounding_sweep.errors import ConfigError

_PATTERNS = {
    "disp": (codes.H_DISP, "m"),
    "vel": (codes.H_VEL, "m_s"),
    "abs_acc": (codes.H_ABS_ACC, "m_s2"),
}


#: a model floor, b<building>f<floor>, behind an optional channel prefix (abs_acc_b1f3, disp_b2f1): the one parse
#: of a floor's name (floor_dof checks it against a scene as well)
_FLOOR = re.compile(r"(abs_acc_|disp_|vel_)?b(\d+)f(\d+)")


def building_floor(code: str, bare: bool = False) -> tuple[int, int] | None:
    """'b1f3', 'abs_acc_b1f3' or 'disp_b2f1' -> (building, floor), numbered from 1; None where it names no floor
    (bare: only 'b1f3' itself, as a floor sensor is named at import)."""
    m = _FLOOR.fullmatch(code)
    return (int(m[2]), int(m[3])) if m and not (bare and m[1]) else None


def floor_dof(code: str, floors: tuple[int, int], key: str, value: str | None = None) -> int:
    """'b1f3' (building 1, floor 3) -> its DOF index in the coupled model (`value`: what the scene wrote,
    for the message, when code is a part of it)."""
    said = repr(code if value is None else value)
    m = re.fullmatch(r"b(0|[1-9]\d*)f(0|[1-9]\d*)", code)
    if not m:
        raise ConfigError(f"{key} = {said}: a model floor is written b<building>f<floor>, e.g. 'b1f3'")
    b, f = int(m.group(1)), int(m.group(2))
    if b not in (1, 2):
        raise ConfigError(f"{key} = {said}: there is no building {b} (the model has buildings 1 and 2)")
    if not floors[b - 1]:
        raise ConfigError(f"{key} = {said}: there is no building {b} (a single-building scene: no [building2])")
    if not 1 <= f <= floors[b - 1]:
        raise ConfigError(f"{key} = {said}: building {b} has floors 1..{floors[b - 1]}, so it maps to no floor")
    return (f - 1) if b == 1 else floors[0] + f - 1


#: an experiment channel mapped to a floor's absolute acceleration: 'abs_acc_b1f3' (as the history channel)
ACC_PREFIX = "abs_acc_"


def is_acceleration(code: str) -> bool:
    """Whether an experiment channel's model side ('b1f3', 'abs_acc_b1f3') is a floor's absolute acceleration."""
    return code.startswith(ACC_PREFIX)


def experiment_channel(code: str, floors: tuple[int, int], key: str) -> tuple[int, int]:
    """An [experiment] channel's model side -> (codes.H_DISP or codes.H_ABS_ACC, its DOF): 'b1f3' is the
    floor's displacement relative to the table, 'abs_acc_b1f3' its absolute acceleration."""
    if not re.fullmatch(r"(abs_acc_)?b\d+f\d+", code):
        raise ConfigError(
            f"{key} = {code!r}: an experiment channel is a floor's displacement relative to the table, "
            "b<building>f<floor> (e.g. 'b1f3'), or its absolute acceleration, abs_acc_b<building>f<floor>"
        )
    if is_acceleration(code):
        return codes.H_ABS_ACC, floor_dof(code[len(ACC_PREFIX) :], floors, key, code)
    return codes.H_DISP, floor_dof(code, floors, key)


def parse_channel(name: str, floors: tuple[int, int]) -> tuple[int, int, str]:
    """Channel name -> (kind, index, column name with unit). Index is a DOF or a pair."""
    m = re.fullmatch(r"(disp|vel|abs_acc)_(b\d+f\d+)", name)
    if m:
        kind, unit = _PATTERNS[m.group(1)]
        return kind, floor_dof(m.group(2), floors, f"[output] histories: channel '{name}'"), f"{name}_{unit}"
    m = re.fullmatch(r"force_f(\d+)", name)
    if m:
        j = int(m.group(1))
        if not min(floors):
            raise ConfigError(f"[output] histories: channel '{name}': a single-building scene has no contact force")
        if not 1 <= j <= min(floors):
            raise ConfigError(f"[output] histories: channel '{name}': facing floor pairs are 1..{min(floors)}")
        return codes.H_FORCE, j - 1, f"{name}_N"
    if name == "ground_acc":
        return codes.H_GROUND_ACC, 0, "ground_acc_m_s2"
    raise ConfigError(
        f"[output] histories: unknown channel '{name}' (use disp_b1f3, vel_b2f1, abs_acc_b1f2, force_f3, ground_acc)"
    )


def channel_unit(code: str) -> tuple[str, str]:
    """An experiment channel's SI unit and its name in keys: ('m', 'm') for a displacement 'b1f3', ('m/s^2',
    'm_s2') for an absolute acceleration 'abs_acc_b1f3'."""
    return ("m/s^2", "m_s2") if is_acceleration(code) else ("m", "m")


def shown_value(code: str, value_si: float) -> str:
    """A channel's value in its own quantity, for a message: displacements in mm, accelerations in m/s^2."""
    if is_acceleration(code):
        return f"{value_si:.4g} m/s^2"
    return f"{value_si * 1e3:.4g} mm"
