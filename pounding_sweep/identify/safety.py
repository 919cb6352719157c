"""What keeps a forced or pounding record from passing for a modal test (issue 19): a single-frequency
table motion is refused, a peak at a forcing frequency is called the forcing, and a model update that
lands on a forcing frequency or changes a stiffness by more than 30 % is not written unless forced.

Where the forcing frequencies come from:
- the table channel's largest line, when it holds half of the table's acceleration power or more and stands
  HARMONIC_OVER_NOISE times above the table's noise (a line holding 80 % or more is a harmonic test, refused
  before any peak is picked; a quiet table's line, in free vibration, is no forcing); a broadband table shows
  no forcing, and then no harmonic series is looked for among the peaks;
- without a table channel, the scene's harmonic excitation (the record is taken to be its response)
  and the fundamental of any harmonic series among a building's peaks (f, 2f, 3f ...: a periodic,
  i.e. forced, response; pounding under harmonic forcing makes exactly such series). A shear frame's
  modes are not in integer ratios (3 equal stories: 1 : 2.80 : 4.05).

"Near" is within 3 % or one resolution of the estimate, whichever is wider: a peak closer than a
resolution to the forcing cannot be told apart from it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

#: a table motion with this share of its acceleration power in one line is a harmonic test (refused)
HARMONIC_INPUT_FRACTION = 0.8
#: ... and its line's power is at least this many times the table's noise power over the whole band
HARMONIC_OVER_NOISE = 10.0
#: a table line with this share is a forcing frequency (peaks near it are suspect)
FORCING_LINE_FRACTION = 0.5
#: a peak this close (relative) to a forcing frequency or its harmonic is taken for the forcing
FORCING_TOLERANCE = 0.03
#: peaks this close (relative) to k f0 make a harmonic series f0, 2 f0, ... (or within k half resolutions):
#: a forcing's harmonics are exact lines, read to a small part of a resolution; two modes near an integer
#: ratio are off by more on a record long enough to resolve them
HARMONIC_TOLERANCE = 0.002
#: harmonics k f of a forcing frequency checked, k = 1 .. HARMONICS
HARMONICS = 3
#: a model update that scales a stiffness by more than this (relative) is not written unless forced
MAX_STIFFNESS_CHANGE = 0.30


@dataclass(frozen=True)
class Forcing:
    frequency_Hz: float
    source: str  # where it was seen, for the messages


#: what a table column may measure (identify --input-kind)
INPUT_KINDS = ("displacement", "velocity", "acceleration")


def input_kind(column: str, given: str | None = None, metadata: dict | None = None) -> tuple[str, str]:
    """(what the table column measures, where that was learnt): `given` (--input-kind), else the table's
    metadata (`column_kinds`, which `python -m pounding_sweep import` writes), else displacement (the
    tracked-displacement table's format). Never guessed from the column's name."""
    import json

    if given is not None:
        return given, "--input-kind"
    try:
        kinds = json.loads((metadata or {}).get("column_kinds", "{}"))
    except (TypeError, ValueError):
        kinds = {}
    if isinstance(kinds, dict) and kinds.get(str(column)) in INPUT_KINDS:
        return kinds[str(column)], "the table's metadata"
    return "displacement", "default: a tracked-displacement table; --input-kind acceleration if it is not"


def is_harmonic(line) -> bool:
    """A table motion is harmonic when one line holds HARMONIC_INPUT_FRACTION of its power above the noise and
    stands HARMONIC_OVER_NOISE times above the table's whole noise power: a quiet table (free vibration) has a
    line of its own noise or of the structure's reaction, not a forcing."""
    return line.fraction >= HARMONIC_INPUT_FRACTION and line.over_noise >= HARMONIC_OVER_NOISE


def close(f: float, g: float, resolution_Hz: float) -> bool:
    """f within FORCING_TOLERANCE of g, or within one resolution."""
    return abs(f - g) <= max(FORCING_TOLERANCE * g, resolution_Hz)


def harmonic_fundamentals(freqs, resolution_Hz: float) -> list[float]:
    """Frequencies f0 among `freqs` with another of them at k f0 (k = 2 .. HARMONICS), within
    HARMONIC_TOLERANCE or k half resolutions (a harmonic made by the forcing or by impacts is exact, to
    the peaks' precision: k f0 carries k times f0's error)."""
    fs = sorted(freqs)
    out = []
    for i, f0 in enumerate(fs):
        if f0 <= 0:
            continue
        if any(
            abs(g - k * f0) <= max(HARMONIC_TOLERANCE * k * f0, k * resolution_Hz / 2)
            for g in fs[i + 1 :]
            for k in range(2, HARMONICS + 1)
        ):
            out.append(f0)
    return out


def forcing_frequencies(ident, scene=None) -> list[Forcing]:
    """The forcing frequencies a TableIdentification and (optionally) the scene reveal (module docstring)."""
    out = []
    line = ident.input_line if ident.input_line is not None else getattr(ident, "table_line", None)
    col = ident.input_column or getattr(ident, "table_column", None)
    if line is not None:
        # the table's own motion says whether there is a forcing: a broadband table has none, and peaks near an
        # integer ratio are then modes, not a forcing's harmonics
        if line.fraction >= FORCING_LINE_FRACTION and line.over_noise >= HARMONIC_OVER_NOISE:
            out.append(Forcing(line.frequency_Hz, f"table column '{col}', {100 * line.fraction:.0f} % of its power"))
        return out
    if scene is not None and scene.excitation.type == "harmonic":
        freqs = {scene.excitation.frequency_Hz}
        for a in scene.sweep:
            if a.name == "frequency_Hz":
                freqs |= set(a.values)
        out += [Forcing(float(f), "the scene's harmonic excitation") for f in sorted(freqs) if f]
    for b, r in sorted(ident.results.items()):
        for f0 in harmonic_fundamentals([m.frequency_Hz for m in r.modes], r.spectrum.resolution_Hz):
            if not any(close(f0, g.frequency_Hz, r.spectrum.resolution_Hz) for g in out):
                where = f"building {b}" if b else "the other columns"
                out.append(Forcing(f0, f"with its harmonics among {where}'s peaks: a periodic response"))
    return out


def near_forcing(f: float, forcing, resolution_Hz: float) -> tuple[Forcing, int] | None:
    """(forcing, k) when f is near k times a forcing frequency, k = 1 .. HARMONICS."""
    for g in forcing:
        for k in range(1, HARMONICS + 1):
            if close(f, k * g.frequency_Hz, resolution_Hz):
                return g, k
    return None


def _at(g: Forcing, k: int) -> str:
    what = "the forcing frequency" if k == 1 else f"{k} x the forcing frequency"
    return f"{what} {k * g.frequency_Hz:.4f} Hz ({g.source})"


def forcing_notes(result, forcing) -> list[str]:
    """A note for each identified peak of one building that sits at a forcing frequency or its harmonic."""
    out = []
    for m in result.modes:
        hit = near_forcing(m.frequency_Hz, forcing, result.spectrum.resolution_Hz)
        if hit is not None:
            out.append(f"{m.frequency_Hz:.3f} Hz is at {_at(*hit)}: probably the forcing, not a mode")
    return out


def modes_problems(ident, forcing) -> list[str]:
    """Why a modes file (--modes-out, a calibration's start) should not be written: a building's mode 1 at a
    forcing frequency or its harmonic (a calibration would start its stiffness there: a 2 Hz sine's forcing read
    as the 8 Hz frame's mode 1 starts it at a sixteenth); [] when none."""
    out = []
    for b, r in sorted(ident.results.items()):
        if b == 0 or not r.modes:
            continue
        hit = near_forcing(r.modes[0].frequency_Hz, forcing, r.spectrum.resolution_Hz)
        if hit is not None:
            out.append(f"building{b}: mode 1 {r.modes[0].frequency_Hz:.4f} Hz is at {_at(*hit)}")
    return out


def update_problems(updates, ident, forcing, damping: bool = False) -> list[str]:
    """Why each model update should not be written: a first frequency at a forcing frequency, a
    stiffness scaled by more than MAX_STIFFNESS_CHANGE, or (`damping`: --update-damping) a damping estimate identify
    does not trust (identify/startfile.py damping_reliable, as a modes file marks it); [] when none."""
    from pounding_sweep.identify.startfile import damping_estimate, damping_reliable

    out = []
    for u in updates:
        r = ident.results[int(u.section[-1])]
        if damping and r.modes:
            m = r.modes[0]
            z, ci, method = damping_estimate(m)
            if math.isfinite(z) and not damping_reliable(m, z, ci, method, r.notes):  # NaN: none written
                out.append(
                    f"{u.section}: its first mode's damping {100 * z:.3g} % ({method}) is one identify does not "
                    "trust (its notes above say why)"
                )
        hit = near_forcing(u.f1_target_Hz, forcing, r.spectrum.resolution_Hz)
        if hit is not None:
            g, k = hit
            pct = 100 * abs(u.f1_target_Hz / (k * g.frequency_Hz) - 1)
            why = (
                ""
                if pct <= 100 * FORCING_TOLERANCE
                else f", closer than the resolution {r.spectrum.resolution_Hz:.3g} Hz"
            )
            out.append(f"{u.section}: f1 {u.f1_target_Hz:.4f} Hz is within {pct:.2f} % of {_at(g, k)}{why}")
        if abs(u.factor - 1) > MAX_STIFFNESS_CHANGE:
            out.append(
                f"{u.section}: stiffness x {u.factor:.4f} ({100 * (u.factor - 1):+.0f} %, f1 {u.f1_model_Hz:.4f} -> "
                f"{u.f1_target_Hz:.4f} Hz) changes it by more than {100 * MAX_STIFFNESS_CHANGE:.0f} %"
            )
    return out


def method_warnings(ident, scene=None) -> list[str]:
    """Loud words on a method that cannot be trusted for a model update: output-only peaks of a record
    the scene drives with a ground-motion record."""
    if ident.input_column is None and scene is not None and scene.excitation.type == "record":
        return [
            "no table channel, and the scene drives the models with a ground-motion record: the floors' "
            "spectra are the record's spectrum times the structure's, and their peaks are not the modes "
            "(a separated synthetic Duzce test reads 3.37 and 6.18 Hz for modes at 4.28 and 7.12 Hz); "
            "give the table's motion as a column (--input) to identify against it"
        ]
    return []
