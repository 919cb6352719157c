"""Raw sensor exports and the registry of their formats: each format turns one file into a SensorFile
(time on the sensor's own clock in s, named channels in SI units, what was dropped on the way).

Adding a format: write `read(path, head) -> SensorFile` and `sniff(head) -> bool` (head: the file's first
4 kB as text), and `register(SensorFormat("name", "what it is", sniff, read))`; `read_sensor` then finds it
by its sniff (or by name, `--format name`). Every problem is a SensorError naming the file, the line or
column and the value. Times are converted here, once: a device clock in its own unit (Xsens SampleTimeFine:
microseconds, 32-bit, wrapping) becomes seconds, unwrapped.
"""

from __future__ import annotations

import io
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from pounding_sweep.errors import SensorError
from pounding_sweep.model.records import G_STANDARD, MAX_ACC_M_S2
from pounding_sweep.scene.files import MAX_TABLE_BYTES, read_regular, text_problem


@dataclass(frozen=True, eq=False)
class SensorFile:
    """One sensor's export as read: its clock (s, unwrapped, as the device counts: two sensors on a shared
    clock read the same value at the same instant), channels in SI units, and what the reader did."""

    path: str
    format: str
    device: str  # the device's tag or id, as the file names it ('' when none)
    time_s: np.ndarray  # the device clock [s], strictly increasing
    clock: str  # what the time is: 'SampleTimeFine (device clock, us, 32-bit)', or a file column
    clock_period_s: float  # where the clock wraps (inf: it does not)
    channels: dict[str, np.ndarray]  # 'Acc_X' -> values in `units`
    units: dict[str, str]  # 'Acc_X' -> 'm/s^2'
    kinds: dict[str, str]  # 'Acc_X' -> 'acceleration' (what a table column holding it measures)
    notes: tuple[str, ...] = field(default_factory=tuple)  # rows dropped, clock wraps, ...
    warnings: tuple[str, ...] = field(default_factory=tuple)  # what the reader corrected that the user must hear of

    @property
    def rate_Hz(self) -> float:
        return 1.0 / float(np.median(np.diff(self.time_s)))


@dataclass(frozen=True)
class SensorFormat:
    name: str
    description: str
    sniff: Callable[[str], bool]
    read: Callable[[Path, str], SensorFile]


FORMATS: dict[str, SensorFormat] = {}


def register(fmt: SensorFormat) -> None:
    """Make a format known to read_sensor (by its sniff, and by name)."""
    FORMATS[fmt.name] = fmt


def read_sensor(path, format: str = "auto") -> SensorFile:
    """Read one sensor's export; format 'auto' tries each registered format's sniff on the file's head."""
    p = Path(path)
    raw = read_regular(p, "sensor export", MAX_TABLE_BYTES, SensorError)
    if (why := text_problem(p, "sensor export", raw[:4096])) is not None:
        raise SensorError(why)
    text = raw.decode("utf-8-sig", errors="replace")
    head = text[:4096]
    if format == "auto":
        found = [f for f in FORMATS.values() if f.sniff(head)]
        if not found:
            raise SensorError(
                f"{p}: not a sensor export this reader knows (formats: {', '.join(FORMATS)}; first line "
                f"{head.splitlines()[0][:60] if head.strip() else '(empty)'!r}); docs/how-to/import-real-sensor-data.md says how to add one"
            )
        fmt = found[0]
    elif format in FORMATS:
        fmt = FORMATS[format]
    else:
        raise SensorError(f"{p}: unknown sensor format {format!r} (known: {', '.join(FORMATS)})")
    return fmt.read(p, text)


# ----------------------------------------------------------------------------- Xsens DOT (Movella)

#: SampleTimeFine: microseconds on a 32-bit counter (Movella DOT user manual: "SampleTimeFine ... in us")
XSENS_TICK_S = 1e-6
XSENS_WRAP = 2**32
#: the export's columns and what they hold (Movella DOT export: Euler in deg, Acc in m/s^2 with gravity, Gyr deg/s)
XSENS_COLUMNS = {
    "Acc_X": ("m/s^2", "acceleration", 1.0),
    "Acc_Y": ("m/s^2", "acceleration", 1.0),
    "Acc_Z": ("m/s^2", "acceleration", 1.0),
    "Gyr_X": ("rad/s", "angular_velocity", math.pi / 180),
    "Gyr_Y": ("rad/s", "angular_velocity", math.pi / 180),
    "Gyr_Z": ("rad/s", "angular_velocity", math.pi / 180),
    "Euler_X": ("rad", "angle", math.pi / 180),
    "Euler_Y": ("rad", "angle", math.pi / 180),
    "Euler_Z": ("rad", "angle", math.pi / 180),
}


def clock_gaps(t: np.ndarray) -> np.ndarray:
    """Indices i where samples are missing between t[i] and t[i + 1]: a step above 1.5 times the median step."""
    d = np.diff(t)
    return np.flatnonzero(d > 1.5 * np.median(d))


#: a sensor at rest reads gravity within this share of g: its mean acceleration vector's length tells the units
GRAVITY_SHARE = 0.2


def _gravity_units(p: Path, chans: dict[str, np.ndarray]) -> list[str]:
    """The acceleration units of an export whose Acc_X/Y/Z hold gravity, from the length of their mean vector
    (the shaking's mean is about zero, so it is gravity's, g, whichever way the sensor is tilted): m/s^2 as the
    format says (about 9.81), or g (about 1: converted here, with a warning); anything else is an error, since
    no factor can then be trusted. Exports without all three axes are taken as the format says."""
    if any(f"Acc_{a}" not in chans for a in "XYZ"):
        return []
    read = float(np.linalg.norm([np.mean(chans[f"Acc_{a}"]) for a in "XYZ"]))
    if abs(read - G_STANDARD) <= GRAVITY_SHARE * G_STANDARD:
        return []
    if abs(read - 1.0) <= GRAVITY_SHARE:
        for a in "XYZ":
            chans[f"Acc_{a}"] = chans[f"Acc_{a}"] * G_STANDARD
        return [
            f"{p}: its accelerations read gravity as {read:.4g}: they are in g, not in the export's m/s^2; "
            f"converted (x {G_STANDARD})"
        ]
    raise SensorError(
        f"{p}: its accelerations read gravity as {read:.4g} (the length of Acc_X/Y/Z's mean), where m/s^2 read "
        f"{G_STANDARD} and g read 1: their units are neither, and no factor can be trusted (mm/s^2 would read "
        f"{1e3 * G_STANDARD:.0f}); export them in m/s^2"
    )


def _xsens_sniff(head: str) -> bool:
    lines = head.splitlines()
    return any(ln.startswith("DeviceTag:") for ln in lines[:8]) and any(
        ln.startswith("PacketCounter,SampleTimeFine") for ln in lines[:20]
    )


def _xsens_read(p: Path, text: str) -> SensorFile:
    """An Xsens/Movella DOT CSV export: `key:,value` header lines to a blank line, then a header row
    `PacketCounter,SampleTimeFine,...`. Leading rows whose accelerations and angular velocities are all exactly
    zero (the device writes one before its first measurement) are dropped; the clock is unwrapped modulo 2^32 us."""
    import pandas as pd

    lines = text.splitlines()
    try:
        k = next(i for i, ln in enumerate(lines[:50]) if ln.startswith("PacketCounter,"))
    except StopIteration:
        raise SensorError(f"{p}: no 'PacketCounter,SampleTimeFine,...' header row in its first 50 lines") from None
    meta = {}
    for ln in lines[:k]:
        if ":" in ln:
            key, _, val = ln.partition(":")
            meta[key.strip()] = val.lstrip(",").strip()
    try:
        df = pd.read_csv(io.StringIO("\n".join(lines[k:])), dtype=float)
    except Exception as e:  # noqa: BLE001 - pandas raises many types
        raise SensorError(f"{p}: cannot read the rows after line {k + 1} ({type(e).__name__}: {e})") from None
    if "SampleTimeFine" not in df.columns:
        raise SensorError(f"{p}, line {k + 1}: no column SampleTimeFine (columns: {', '.join(df.columns)})")
    measured = [c for c in df.columns if c in XSENS_COLUMNS]
    if not any(c.startswith("Acc_") for c in measured):
        raise SensorError(f"{p}, line {k + 1}: no acceleration column Acc_X/Y/Z (columns: {', '.join(df.columns)})")
    for c in ["SampleTimeFine", *measured]:
        bad = ~np.isfinite(df[c].to_numpy())
        if bad.any():
            i = int(np.argmax(bad))
            row = lines[k + 1 + i] if k + 1 + i < len(lines) else ""
            fields, want = len(row.split(",")), len(df.columns)
            if fields < want:
                raise SensorError(
                    f"{p}, line {k + 2 + i}: {fields} of the header's {want} fields (column {c} missing): a line cut "
                    "short (an export that did not finish?)"
                )
            raise SensorError(f"{p}, line {k + 2 + i}: column {c} is not a finite number")
    notes = []
    inertial = [c for c in measured if XSENS_COLUMNS[c][1] in ("acceleration", "angular_velocity")]
    vals = df[inertial].to_numpy()
    lead = 0
    while lead < len(df) and np.all(vals[lead] == 0.0):
        lead += 1
    if lead:
        notes.append(
            f"dropped {lead} leading row(s) whose accelerations and angular velocities are all exactly zero (the device's first row: no measurement yet)"
        )
    df = df.iloc[lead:]
    if len(df) < 16:
        raise SensorError(f"{p}: {len(df)} sample row(s) after the header: at least 16 needed")
    raw = df["SampleTimeFine"].to_numpy(dtype=np.int64)
    if raw.min() < 0 or raw.max() >= XSENS_WRAP:
        i = int(np.argmax((raw < 0) | (raw >= XSENS_WRAP)))
        raise SensorError(f"{p}, line {k + 2 + lead + i}: SampleTimeFine {raw[i]} is not a 32-bit microsecond count")
    step = np.diff(raw) % XSENS_WRAP  # a wrap of the 32-bit counter reads as a step back
    wraps = int(np.sum(np.diff(raw) < 0))
    if wraps:
        notes.append(f"SampleTimeFine wrapped {wraps} time(s) (32-bit us counter, every {XSENS_WRAP * 1e-6:.1f} s)")
    if np.any(step == 0):
        i = int(np.argmax(step == 0)) + 1
        raise SensorError(f"{p}, line {k + 2 + lead + i}: SampleTimeFine {raw[i]} repeats the row before")
    med = float(np.median(step))
    if np.any(step > XSENS_WRAP // 2):
        i = int(np.argmax(step > XSENS_WRAP // 2)) + 1
        raise SensorError(f"{p}, line {k + 2 + lead + i}: SampleTimeFine steps back ({raw[i - 1]} -> {raw[i]})")
    t = (raw[0] + np.concatenate([[0], np.cumsum(step)])) * XSENS_TICK_S
    gaps = clock_gaps(t)
    if gaps.size:
        notes.append(
            f"{gaps.size} gap(s) in the clock (largest {step.max() * XSENS_TICK_S:.4g} s against the step "
            f"{med * XSENS_TICK_S:.4g} s): samples missing there"
        )
    chans, units, kinds = {}, {}, {}
    for c in measured:
        unit, kind, factor = XSENS_COLUMNS[c]
        chans[c] = df[c].to_numpy(dtype=float) * factor
        units[c], kinds[c] = unit, kind
    for c in (c for c in chans if kinds[c] == "acceleration"):
        big = np.abs(chans[c]) > MAX_ACC_M_S2
        if big.any():
            i = int(np.argmax(big))
            raise SensorError(
                f"{p}, line {k + 2 + lead + i}: {c} = {chans[c][i]:.4g} m/s^2, beyond {MAX_ACC_M_S2:.0e} m/s^2 "
                f"({MAX_ACC_M_S2 / G_STANDARD:,.0f} g): no measurement (a corrupted sample, or the wrong units)"
            )
    warnings = _gravity_units(p, chans)
    return SensorFile(
        str(p),
        "xsens_dot",
        meta.get("DeviceTag", ""),
        t,
        "SampleTimeFine (device clock, us, 32-bit)",
        XSENS_WRAP * XSENS_TICK_S,
        chans,
        units,
        kinds,
        tuple(notes),
        tuple(warnings),
    )


register(
    SensorFormat(
        "xsens_dot",
        "Movella/Xsens DOT CSV export (header lines, PacketCounter, SampleTimeFine in us, Euler, Acc m/s^2, Gyr deg/s)",
        _xsens_sniff,
        _xsens_read,
    )
)
