"""The modes `identify --modes-out` writes, read back as a calibration's start values ([calibrate] start_from).

The file is TOML: one table per building, `[building1]`, holding lists mode by mode (mode 1 first):
`frequencies_Hz`, `damping_ratios` (the estimate identify trusts most: the logarithmic decrement of free
vibration, else the ratio fitted to the transmissibility, else the half-power bandwidth; NaN where there is
none), `damping_ci95` ([low, high] pairs, NaN where unknown), `damping_methods` (which estimate each is) and
`damping_reliable` (false where identify does not trust the estimate: not above 0, its interval reaching 0, a band
not resolved, a poor fit; a calibration still starts there, clipped into its bounds, and warns).
Written by the identify layer (identify/startfile.py), read here so that a scene is checked when it is loaded;
the values become start values in sweep/calibrate.py.
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass

from pounding_sweep.errors import ConfigError, shown
from pounding_sweep.scene.files import read_regular

MAX_MODES_FILE_BYTES = 1 << 20  # a few hundred bytes a building; a megabyte is not identify's
#: the keys of a building's table, in the order written
KEYS = ("channels", "frequencies_Hz", "damping_ratios", "damping_ci95", "damping_methods", "damping_reliable")


@dataclass(frozen=True)
class IdentifiedModes:
    """One building's identified modes (module docstring)."""

    frequencies_Hz: tuple[float, ...]
    damping_ratios: tuple[float, ...]
    damping_methods: tuple[str, ...] = ()
    damping_reliable: tuple[bool, ...] = ()  # empty: not said (a file written before the key)


class _Unreadable(Exception):
    pass


def read_modes(path: str, key: str = "[calibrate] start_from") -> dict[int, IdentifiedModes]:
    """{building: its modes} of an identify modes file; ConfigError naming `key` and the path when it cannot be
    read, is not TOML, or holds no building's modes in the form above."""
    where = f"{key} = {path!r}"
    try:
        text = read_regular(path, "identify's modes", MAX_MODES_FILE_BYTES, _Unreadable).decode("utf-8")
        raw = tomllib.loads(text)
    except _Unreadable as e:
        raise ConfigError(f"{where}: {str(e).removeprefix(f'{path}: ')}") from None
    except UnicodeDecodeError:
        raise ConfigError(f"{where}: not UTF-8 text (identify --modes-out writes TOML)") from None
    except tomllib.TOMLDecodeError as e:
        raise ConfigError(f"{where}: not a modes file identify wrote (TOML: {e})") from None
    out = {}
    for name, table in raw.items():
        b = name.removeprefix("building")
        if not (name.startswith("building") and b.isdigit() and isinstance(table, dict)):
            raise ConfigError(f"{where}: {name!r} is not a [buildingN] table of identified modes")
        out[int(b)] = _modes(table, f"{where}: [{name}]")
    if not out:
        raise ConfigError(
            f"{where}: holds no building's modes (python -m pounding_sweep identify TABLE --modes-out FILE)"
        )
    return out


def _modes(table: dict, where: str) -> IdentifiedModes:
    unknown = sorted(set(table) - set(KEYS))
    if unknown:
        raise ConfigError(f"{where}: unknown key {unknown[0]!r} (expected {', '.join(KEYS)})")
    freq = _numbers(table.get("frequencies_Hz"), f"{where} frequencies_Hz")
    if not freq or not all(f > 0 for f in freq):
        raise ConfigError(f"{where} frequencies_Hz = {shown(table.get('frequencies_Hz'))}: one frequency > 0 per mode")
    zeta = _numbers(table.get("damping_ratios", [math.nan] * len(freq)), f"{where} damping_ratios")
    if len(zeta) != len(freq):
        raise ConfigError(f"{where} damping_ratios = {shown(list(zeta))}: one per mode ({len(freq)} frequencies)")
    methods = table.get("damping_methods", [])
    reliable = table.get("damping_reliable", [])
    if (
        not isinstance(reliable, list)
        or not all(isinstance(x, bool) for x in reliable)
        or len(reliable) not in (0, len(freq))
    ):
        raise ConfigError(
            f"{where} damping_reliable = {shown(reliable)}: true or false per mode ({len(freq)} frequencies)"
        )
    return IdentifiedModes(tuple(freq), tuple(zeta), tuple(str(m) for m in methods), tuple(reliable))


def _numbers(v, where: str) -> list[float]:
    if not isinstance(v, list) or not all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in v):
        raise ConfigError(f"{where} = {shown(v)}: a list of numbers, mode 1 first")
    return [float(x) for x in v]
