"""Recorded ground acceleration: PEER AT2 / two-column CSV readers, similitude scaling, resampling.

Everything inside is SI: accelerations in m/s^2, times in s.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from pounding_sweep.codes import ACCEPTED_UNITS, UNIT_ALIASES
from pounding_sweep.errors import RecordError
from pounding_sweep.scene.files import MAX_RECORD_BYTES, read_regular, text_problem

G_STANDARD = 9.80665  # m/s^2
#: the largest |acceleration| a measurement may hold [m/s^2] (100,000 g): beyond it the units are wrong
MAX_ACC_M_S2 = 1e6

__all__ = [
    "G_STANDARD",
    "MAX_ACC_M_S2",
    "VERTICAL_COMPONENTS",
    "vertical_component",
    "RecordError",
    "GroundRecord",
    "read_at2",
    "read_csv_record",
    "read_record",
    "similitude_scale",
    "resample",
    "implausible_timing",
]


# RecordError lives in pounding_sweep.errors (raised here, imported by every reader's caller)


# --------------------------------------------------------------------------- record


@dataclass(frozen=True, eq=False)  # eq=False: identity equality/hash (arrays make == ambiguous)
class GroundRecord:
    """A uniformly sampled ground-acceleration history in m/s^2, starting at t = 0."""

    name: str
    source: str
    dt_s: float
    acc_m_s2: np.ndarray
    description: str = ""

    def __post_init__(self) -> None:
        """Validate dt and store a private, read-only float64 copy so the record cannot change."""
        dt = float(self.dt_s)
        if not (math.isfinite(dt) and dt > 0.0):
            raise RecordError(f"{self.source}: sample interval must be finite and > 0, got {self.dt_s!r}")
        acc = np.array(self.acc_m_s2, dtype=np.float64, copy=True)
        if acc.ndim != 1 or acc.size == 0:
            raise RecordError(f"{self.source}: acceleration must be a non-empty 1-D array, got shape {acc.shape}")
        if not np.all(np.isfinite(acc)):
            raise RecordError(f"{self.source}: acceleration contains NaN or inf")
        acc.flags.writeable = False
        object.__setattr__(self, "dt_s", dt)
        object.__setattr__(self, "acc_m_s2", acc)

    @property
    def duration_s(self) -> float:
        """Time of the last sample, (n - 1) * dt."""
        return (self.acc_m_s2.size - 1) * self.dt_s

    @property
    def time_s(self) -> np.ndarray:
        """Sample times n * dt, n = 0..len-1."""
        return np.arange(self.acc_m_s2.size, dtype=np.float64) * self.dt_s

    @property
    def pga_m_s2(self) -> float:
        """Peak ground acceleration, max |a|."""
        return float(np.max(np.abs(self.acc_m_s2)))


# --------------------------------------------------------------------------- helpers

_UNIT_FACTORS = {"g": G_STANDARD, "m/s2": 1.0, "cm/s2": 0.01}
_UNIT_ALIASES = UNIT_ALIASES  # the accepted spellings: pounding_sweep.codes (one home)
_ACCEPTED_UNITS = ACCEPTED_UNITS

# How an AT2 header's line 3 names units. NGA-West2 and the older PEER format write "... IN UNITS OF G";
# files from elsewhere write the same thing many ways ("IN CM/SEC/SEC", "(cm/s^2)", "UNITS: GAL",
# "cm.s-2", "cm/s²"). Every mention on the line is found, wherever it stands: a length over time squared,
# "gal", or g as a word after "units of", "in", "unit(s):" or in brackets. Lengths other than m and cm
# are recognised so that they are refused, not read as g.
_LENGTHS = {"M": "m", "CM": "cm", "MM": "mm", "IN": "in", "INCH": "in", "INCHES": "in", "FT": "ft", "FEET": "ft"}
_TIME = r"(?:S|SEC|SECS|SECOND|SECONDS)"
_SQUARED = rf"(?:/\s*{_TIME}|\^?\s*2|\*\*\s*2|²)"
_HEADER_COMPOUND = re.compile(
    rf"(?<![A-Z0-9])(M|CM|MM|IN|INCH|INCHES|FT|FEET)\s*"
    rf"(?:/\s*{_TIME}\s*{_SQUARED}|[*.·]?\s*{_TIME}\s*(?:\^|\*\*)?\s*(?:-\s*2|⁻²))(?![A-Z0-9])"
)
_HEADER_GAL = re.compile(r"(?<![A-Z0-9])GALS?(?![A-Z0-9])")
_HEADER_G = re.compile(r"(?:UNITS?\s*(?:OF|:|=|IS|ARE)?\s*|\bIN\s+|[(\[]\s*)G(?:'?S)?(?:\s*[)\]]|(?![A-Z0-9/]))")
_HEADER_UNITS_WORD = re.compile(r"UNITS?\s+OF\s+(\S+(?:\s*/\s*\S+)*)")
_SUPPORTED = {"g": "g", "m": "m/s2", "cm": "cm/s2"}

# Plain decimal / Fortran E (or D) number: "-.6403182E-02", "5", "1.5d-3". No underscores, no hex.
_NUMBER = re.compile(r"[+-]?(?:\d+\.?\d*|\.\d+)(?:[eEdD][+-]?\d+)?")
_NPTS = re.compile(r"\bNPTS\s*[=:]?\s*([^\s,;]+)", re.IGNORECASE)
_DT = re.compile(r"\bDT\s*[=:]?\s*([^\s,;]+)", re.IGNORECASE)
# Very old PEER line 4: "  4000   .01000   NPTS, DT"
_NPTS_DT_TRAILING = re.compile(r"^\s*([^\s,]+)[\s,]+([^\s,]+)[\s,]+NPTS\s*,\s*DT\b", re.IGNORECASE)


def _unit_factor(units: object, path: str) -> tuple[str, float]:
    """Canonical unit name and its factor to m/s^2, or RecordError listing the accepted spellings."""
    key = units.strip().lower().replace(" ", "") if isinstance(units, str) else None
    if key not in _UNIT_ALIASES:
        raise RecordError(f"{path}: unknown units {units!r}; accepted: {_ACCEPTED_UNITS}")
    canon = _UNIT_ALIASES[key]
    return canon, _UNIT_FACTORS[canon]


def _read_lines(path: Path) -> list[str]:
    """Whole file as lines (any line ending); UTF-8 with a Latin-1 fallback for accented station names.
    A FIFO, a device or a file over MAX_RECORD_BYTES is refused unread; UTF-16 and binary files are
    refused by what they are (never echoed as Latin-1 characters)."""
    raw = read_regular(path, "record file", MAX_RECORD_BYTES, RecordError)
    if (why := text_problem(path, "record file", raw)) is not None:
        raise RecordError(why)
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError:
        text = raw.decode("latin-1")
    return text.splitlines()


def _number(token: str) -> float | None:
    """float of a plain/Fortran number token, or None if it is not one (NaN/inf spellings included)."""
    if _NUMBER.fullmatch(token) is None:
        return None
    return float(token.replace("d", "e").replace("D", "E"))


def _resolution(token: str) -> float:
    """Half a unit in the last place a number was written with ('0.003333' -> 5e-7, '1.5e-3' -> 5e-5,
    '5' -> 0.5): how far the value may lie from the number it was rounded from."""
    m = re.fullmatch(r"[+-]?(\d*)(?:\.(\d*))?(?:[eEdD]([+-]?\d+))?", token)
    if m is None:
        return 0.0
    decimals = len(m.group(2) or "")
    exponent = int(m.group(3) or 0)
    return 0.5 * 10.0 ** (exponent - decimals)


def _is_nonfinite_spelling(token: str) -> bool:
    """True for tokens Python reads as NaN or inf ('nan', '-Infinity', ...), to give them their own message."""
    try:
        return not math.isfinite(float(token))
    except ValueError:
        return False


# --------------------------------------------------------------------------- AT2


def _at2_header_units(line3: str, path: str) -> tuple[str | None, str]:
    """(canonical units, as written) named on AT2 line 3 ('... IN UNITS OF G'), or (None, '') when the
    line names none. A line naming two different units, units this reader does not convert (mm, in, ft
    over s^2), or 'UNITS OF' something unknown is a RecordError: such a record is refused, never read as g."""
    upper = line3.upper()
    if ("VELOCITY" in upper or "DISPLACEMENT" in upper) and "ACCELERATION" not in upper:
        raise RecordError(f"{path}, line 3: not an acceleration record: {line3.strip()!r}")
    found: dict[str, str] = {}  # canonical or unsupported length -> as written
    for m in _HEADER_COMPOUND.finditer(upper):
        length = _LENGTHS[m.group(1)]
        found.setdefault(_SUPPORTED.get(length, f"{length}/s2"), m.group(0).strip())
    for m in _HEADER_GAL.finditer(upper):
        found.setdefault("cm/s2", m.group(0))
    for m in _HEADER_G.finditer(upper):
        found.setdefault("g", m.group(0).strip())
    unsupported = [w for u, w in found.items() if u not in _UNIT_FACTORS]
    if unsupported:
        raise RecordError(
            f"{path}, line 3: units {unsupported[0]!r} in header {line3.strip()!r} are not supported: "
            "convert the record to g, m/s2 or cm/s2"
        )
    if len(found) > 1:
        named = " and ".join(repr(w) for w in found.values())
        raise RecordError(
            f"{path}, line 3: header {line3.strip()!r} names two units ({named}): keep the one the values are in"
        )
    if found:
        ((canon, written),) = found.items()
        return canon, written
    m = _HEADER_UNITS_WORD.search(upper)
    if m is not None:  # 'UNITS OF <something unknown>': refuse rather than guess g
        word = re.sub(r"\s+", "", m.group(1)).rstrip(".,;:")
        return None, word
    return None, ""


def _at2_npts_dt(line4: str, path: str) -> tuple[int, float]:
    """NPTS and DT from AT2 line 4, tolerant of spacing, commas and '.0050'-style values."""
    m_n, m_d = _NPTS.search(line4), _DT.search(line4)
    if m_n and m_d:
        npts_tok, dt_tok = m_n.group(1), m_d.group(1)
    elif (m_old := _NPTS_DT_TRAILING.match(line4)) is not None:
        npts_tok, dt_tok = m_old.group(1), m_old.group(2)
    else:
        missing = " and ".join(k for k, m in (("NPTS", m_n), ("DT", m_d)) if m is None)
        raise RecordError(f"{path}, line 4: no {missing} found in {line4.strip()!r}")
    npts_f = _number(npts_tok)
    if npts_f is None or not math.isfinite(npts_f) or npts_f != int(npts_f) or npts_f <= 0:
        raise RecordError(f"{path}, line 4: NPTS must be a positive integer, got {npts_tok!r}")
    dt = _number(dt_tok)
    if dt is None or not math.isfinite(dt) or dt <= 0.0:
        raise RecordError(f"{path}, line 4: DT must be a finite number > 0, got {dt_tok!r}")
    return int(npts_f), dt


def read_at2(path, units=None) -> GroundRecord:
    """Read a PEER AT2 file (NGA-West2 or older PEER header) into m/s^2.

    Units: those header line 3 names (NGA-West2: "UNITS OF G"; other spellings of g, m/s2 and cm/s2
    are recognised too), else `units`, else g (the PEER convention). `units` given and the header
    naming others is a RecordError naming both (a record is never read in units its header contradicts),
    and so is a header naming units this reader cannot convert, or unknown ones without `units`.
    """
    p = Path(path)
    src = str(path)
    explicit = None if units is None else _unit_factor(units, src)[0]  # bad units: refused before the file
    lines = _read_lines(p)
    if len(lines) < 4:
        raise RecordError(f"{src}: only {len(lines)} line(s); a PEER AT2 file needs 4 header lines")
    npts, dt = _at2_npts_dt(lines[3], src)
    header, written = _at2_header_units(lines[2], src)
    if header is not None and explicit is not None and header != explicit:
        raise RecordError(
            f"{src}, line 3: units = {units!r} ({explicit}) contradicts the header, which says {written!r} "
            f"({header}): {lines[2].strip()!r}; leave units out to read the record as its header says"
        )
    if header is None and written and explicit is None:
        raise RecordError(
            f"{src}, line 3: unrecognised units {written!r} in header {lines[2].strip()!r}; "
            "give units explicitly if the values are in g, m/s2 or cm/s2"
        )
    canon = header or explicit or "g"
    factor = _UNIT_FACTORS[canon]

    values: list[float] = []
    for lineno, line in enumerate(lines[4:], start=5):
        for tok in line.split():
            x = _number(tok)
            if x is None:
                if _is_nonfinite_spelling(tok):
                    raise RecordError(f"{src}, line {lineno}: non-finite value {tok!r}")
                raise RecordError(f"{src}, line {lineno}: not a number: {tok!r}")
            if not math.isfinite(x):
                raise RecordError(f"{src}, line {lineno}: value overflows to inf: {tok!r}")
            if len(values) == npts:
                raise RecordError(f"{src}, line {lineno}: more values than NPTS={npts} (first extra value {tok!r})")
            values.append(x)
    if len(values) < npts:
        raise RecordError(f"{src}: found {len(values)} values but NPTS={npts} (file truncated?)")

    return GroundRecord(
        name=p.stem,
        source=src,
        dt_s=dt,
        acc_m_s2=np.asarray(values, dtype=np.float64) * factor,
        description=lines[1].strip(),
    )


# --------------------------------------------------------------------------- CSV

_CSV_SPLIT = re.compile(r"\s*[,;]\s*|\s+")


def read_csv_record(path, units="m/s2") -> GroundRecord:
    """Read a two-column (time s, acceleration) text file into m/s^2; the time must be uniform.

    Optional single header row; comma, semicolon or whitespace delimited; blank and '#' lines are
    skipped. A nonzero start time t0 is dropped: the record is shifted so its first sample is t = 0.
    """
    p = Path(path)
    src = str(path)
    _, factor = _unit_factor(units, src)
    lines = _read_lines(p)

    rows: list[tuple[int, float, float]] = []  # (1-based line, t, a)
    seen_first = False
    for lineno, line in enumerate(lines, start=1):
        s = line.strip()
        if not s or s.startswith("#"):
            continue
        fields = _CSV_SPLIT.split(s)
        while fields and fields[-1] == "":  # tolerate a trailing delimiter
            fields.pop()
        parsed = [_number(f) for f in fields]
        if not seen_first:
            seen_first = True
            if all(x is None and not _is_nonfinite_spelling(f) for x, f in zip(parsed, fields)):
                continue  # header row: nothing on it is a number
        if len(fields) != 2:
            raise RecordError(
                f"{src}, line {lineno}: expected 2 columns (time, acceleration), got {len(fields)}: {s!r}"
            )
        for f, x in zip(fields, parsed):
            if x is None:
                kind = "non-finite value" if _is_nonfinite_spelling(f) else "not a number"
                raise RecordError(f"{src}, line {lineno}: {kind}: {f!r}")
            if not math.isfinite(x):
                raise RecordError(f"{src}, line {lineno}: value overflows to inf: {f!r}")
        rows.append((lineno, parsed[0], parsed[1], _resolution(fields[0])))

    if len(rows) < 2:
        raise RecordError(f"{src}: need at least 2 data rows, found {len(rows)}")
    lineno_arr = np.array([r[0] for r in rows])
    t = np.array([r[1] for r in rows], dtype=np.float64)
    a = np.array([r[2] for r in rows], dtype=np.float64)

    d = np.diff(t)
    bad = np.flatnonzero(d <= 0.0)
    if bad.size:
        i = bad[0] + 1
        raise RecordError(
            f"{src}, line {lineno_arr[i]}: time must be strictly increasing, "
            f"got {float(t[i])!r} after {float(t[i - 1])!r}"
        )
    # the step from the first and last stamps: exact where the stamps are k dt correctly rounded (the median
    # of the differences carries their rounding, up to n u relative). Each step and each stamp may then
    # depart from it by the stamps' own rounding: one unit in the last place written (the finest seen:
    # trailing zeros may be dropped; 6 decimals at 300 Hz are 1e-6 s), at most 1e-3 dt
    dt = float((t[-1] - t[0]) / (t.size - 1))
    unit = 2.0 * min(r[3] for r in rows)
    allowed = min(unit, 1e-3 * dt) + 16.0 * np.finfo(float).eps * float(np.abs(t).max())
    typical = float(np.median(d))
    jumps = np.flatnonzero(np.abs(d - typical) > allowed)
    off = np.abs(t - (t[0] + np.arange(t.size) * dt))
    if jumps.size or off.max() > allowed:
        i = int(jumps[0]) + 1 if jumps.size else int(np.argmax(off))
        raise RecordError(
            f"{src}, line {lineno_arr[i]}: non-uniform time step: {float(d[i - 1])!r} s before t = {float(t[i])!r} s "
            f"against {typical!r} s (stamps written to {unit:.3g} s); resample the record to a uniform step first"
        )
    return GroundRecord(name=p.stem, source=src, dt_s=dt, acc_m_s2=a * factor, description="")


# --------------------------------------------------------------------------- dispatch


def read_record(path, format="auto", units=None) -> GroundRecord:
    """Read a record as AT2 or CSV; format "auto" goes by suffix (.at2 -> AT2, .csv/.txt -> CSV).

    units=None uses the format's default (AT2: its header's units, else g; CSV: m/s2).
    """
    src = str(path)
    fmt = format.strip().lower() if isinstance(format, str) else format
    if fmt == "auto":
        suffix = Path(path).suffix.lower()
        fmt = {".at2": "at2", ".csv": "csv", ".txt": "csv"}.get(suffix)
        if fmt is None:
            raise RecordError(f"{src}: cannot tell the format from suffix {suffix!r}; pass format='at2' or 'csv'")
    if fmt == "at2":
        return read_at2(path, units=units)
    if fmt == "csv":
        return read_csv_record(path) if units is None else read_csv_record(path, units=units)
    raise RecordError(f"{src}: unknown format {format!r}; accepted: 'auto', 'at2', 'csv'")


# --------------------------------------------------------------------------- plausibility

#: a ground-motion record's sample step and length beyond which its time is probably not in seconds
#: (strong-motion records are sampled every 0.001-0.02 s and last seconds to a few minutes)
PLAUSIBLE_STEP_S = 0.05
PLAUSIBLE_LENGTH_S = 600.0


#: plausible sample steps of a measured record or table [s]: 10 kHz down to 20 Hz
PLAUSIBLE_STEPS_S = (1e-4, PLAUSIBLE_STEP_S)
#: time units a column may have been written in by mistake, and their factor to s
TIME_UNITS = {"ms": 1e-3, "us": 1e-6, "ns": 1e-9}


def time_unit_guess(step_s: float) -> str | None:
    """The unit ('ms', 'us' or 'ns') that turns an implausible sample step read as seconds into a plausible one
    (PLAUSIBLE_STEPS_S), or None."""
    lo, hi = PLAUSIBLE_STEPS_S
    if lo <= step_s <= hi:
        return None
    for unit, f in TIME_UNITS.items():
        if lo <= step_s * f <= hi:
            return unit
    return None


def implausible_timing(rec: GroundRecord) -> str | None:
    """What is odd about a record's time axis as read (before similitude scaling), or None."""
    odd, limits = [], []
    if rec.dt_s > PLAUSIBLE_STEP_S:
        odd.append(f"a sample step of {rec.dt_s:.6g} s")
        limits.append(f"steps above {PLAUSIBLE_STEP_S:g} s")
    if rec.duration_s > PLAUSIBLE_LENGTH_S:
        odd.append(f"a length of {rec.duration_s:,.6g} s")
        limits.append(f"lengths above {PLAUSIBLE_LENGTH_S:g} s")
    if not odd:
        return None
    unit = time_unit_guess(rec.dt_s) or "ms"
    return (
        f"{rec.source}: {' and '.join(odd)} {'are' if len(odd) > 1 else 'is'} implausible for a ground-motion "
        f"record ({', '.join(limits)}): "
        f"is its time in {unit} rather than s?"
        + (
            f" (in {unit} the step is {rec.dt_s * TIME_UNITS[unit]:.6g} s: divide the time column by "
            f"{1 / TIME_UNITS[unit]:g})"
            if unit != "ms"
            else ""
        )
    )


# --------------------------------------------------------------------------- scaling, resampling


#: the component names a vertical record's header gives (PEER: 'Bolu, UP', 'Lamont 362, V'; others UD, DWN, Z)
VERTICAL_COMPONENTS = frozenset({"UP", "UD", "V", "VER", "VERT", "VERTICAL", "DWN", "DOWN", "Z"})


def vertical_component(rec: GroundRecord) -> str | None:
    """The component name where a record's header says it is vertical (the last comma-separated field of its
    description line, e.g. 'Duzce Turkey, 11/12/1999, Bolu, UP'), else None."""
    last = rec.description.split("[similitude")[0].rsplit(",", 1)[-1].strip().upper()
    return last if "," in rec.description and last in VERTICAL_COMPONENTS else None


def similitude_scale(rec: GroundRecord, length_scale: float) -> GroundRecord:
    """Record for a 1/length_scale model (Sekerci & Damci eqs. 17-19): lambda_T = sqrt(lambda_L), lambda_A = 1.

    Accelerations are unchanged; time is compressed, so dt becomes dt / sqrt(length_scale).
    """
    try:
        lam = float(length_scale)
    except (TypeError, ValueError):
        lam = math.nan
    if isinstance(length_scale, bool) or not (math.isfinite(lam) and lam > 0.0):
        raise RecordError(f"{rec.source}: length_scale must be finite and > 0, got {length_scale!r}")
    tag = f"[similitude 1/{lam:g}: time / sqrt({lam:g})]"
    return GroundRecord(
        name=rec.name,
        source=rec.source,
        dt_s=rec.dt_s / math.sqrt(lam),
        acc_m_s2=rec.acc_m_s2,
        description=f"{rec.description} {tag}" if rec.description else tag,
    )


_MAX_SAMPLES = 100_000_000  # guards against dt given in the wrong units (e.g. ms)


def resample(rec: GroundRecord, dt_s: float, duration_s: float | None = None) -> np.ndarray:
    """Acceleration at t = n*dt_s, n = 0..N-1, N = floor(duration/dt_s + 1e-9) + 1, linear between samples.

    Past the record's end the acceleration is 0 (free-vibration tail). No anti-alias filtering.
    """
    dt = float(dt_s)
    if not (math.isfinite(dt) and dt > 0.0):
        raise RecordError(f"{rec.source}: resample dt_s must be finite and > 0, got {dt_s!r}")
    dur = rec.duration_s if duration_s is None else float(duration_s)
    if not (math.isfinite(dur) and dur >= 0.0):
        raise RecordError(f"{rec.source}: resample duration_s must be finite and >= 0, got {duration_s!r}")
    n = math.floor(dur / dt + 1e-9) + 1
    if n > _MAX_SAMPLES:
        odd = implausible_timing(rec)
        raise RecordError(
            f"{rec.source}: resampling to dt={dt!r} s over {dur!r} s needs {n} samples; "
            + (odd.removeprefix(f"{rec.source}: ") if odd else "dt too small?")
        )

    t = np.arange(n, dtype=np.float64) * dt
    t_end = rec.duration_s
    inside = t <= t_end + 1e-9 * rec.dt_s  # round-off at the last sample must not drop it to 0
    out = np.interp(np.minimum(t, t_end), rec.time_s, rec.acc_m_s2)
    out[~inside] = 0.0
    return np.ascontiguousarray(out, dtype=np.float64)
