"""Modal identification of a displacement table (a tracked video, a test record): its columns grouped
by building, each building identified (identify/modes.py) against the table's motion when the table has
a column for it (transmissibility) or from the floors alone (output-only), and the model update that
matches each building's first frequency (identify/update.py). Every problem with the table is one
ExperimentError naming the file, what is wrong and the value; so is a single-frequency table motion
(identify/safety.py)."""

from __future__ import annotations

import dataclasses
import re
from dataclasses import dataclass

import numpy as np

from pounding_sweep.errors import ExperimentError
from pounding_sweep.identify.modes import InputLine, ModalResult, identify, input_line
from pounding_sweep.identify.safety import HARMONIC_INPUT_FRACTION, HARMONIC_OVER_NOISE, input_kind, is_harmonic
from pounding_sweep.identify.startfile import damping_estimate
from pounding_sweep.identify.update import StiffnessUpdate, update_scene
from pounding_sweep.model.experiment import MAX_TABLE_STEP_S, time_order_problem
from pounding_sweep.model.modal import height_order_fault
from pounding_sweep.model.records import TIME_UNITS, time_unit_guess
from pounding_sweep.scene.channels import building_floor
from pounding_sweep.scene.video import floor_code

#: a column name's unit suffix ('b1f3_acc_m_s2', 'b1f3_mm'), dropped before its floor is read from it
UNIT_SUFFIX = re.compile(r"(_acc)?_(m_s2|mm_s2|m|mm|g)$")
#: columns a tracked table carries besides the floors' displacements
NOT_DISPLACEMENT = {"frame", "table_in_camera_mm"}
#: a column whose name starts so holds the table's motion (track writes table_in_camera_mm)
TABLE_PREFIXES = ("table", "ground")


@dataclass(frozen=True)
class TableIdentification:
    """Per building (1, 2; 0 for columns that name no floor) the identified modes of its columns."""

    source: str
    fs: float  # samples per second
    results: dict[int, ModalResult]
    input_column: str | None = None  # the table's motion, when used (transmissibility)
    input_line: InputLine | None = None  # its largest spectral line and that line's share of its power
    table_column: str | None = None  # the table's motion found in the table, used as the input or not
    table_line: InputLine | None = None  # its line, also when it is not the input (--input none, free vibration)
    input_kind_source: str = ""  # where the table column's kind was learnt (--input-kind, metadata, default)
    free_vibration: bool = False

    @property
    def method(self) -> str:
        """One line: how the modes were found."""
        if self.input_column is None and self.free_vibration:
            return (
                "output-only, free vibration: peaks of the floors' spectra (window flat, then tapered over the "
                "record's second half), logarithmic decrement of each mode"
                + (f"; the table's column '{self.table_column}' is not the input" if self.table_column else "")
            )
        if self.input_column is None:
            return (
                "output-only: peaks of the floors' spectra (no table channel; a forced record's peaks are "
                "the forcing's as much as the structure's)"
            )
        r = next(iter(self.results.values()), None)
        extra = "" if r is None else f", window decay {r.decay_per_s:.3g} 1/s removed from the damping"
        return (
            f"transmissibility floor / table, H1 = cross-spectrum / auto-spectrum of '{self.input_column}' "
            f"({self.input_line.kind}, from {self.input_kind_source}; exponential window{extra}, 3-bin smoothing)"
        )

    @property
    def empty(self) -> bool:
        return not any(r.modes for r in self.results.values())


def _bad(src, what, value=None) -> ExperimentError:
    return ExperimentError(f"{src}: {what}" + ("" if value is None else f" ({value})"))


def building_groups(columns) -> dict[int, list[str]]:
    """Columns by building ('b1f3' or 'model1_floor3_mm' -> building 1), floor 1 first; 0: no floor name."""
    g: dict = {}
    for c in columns:
        code = floor_code(UNIT_SUFFIX.sub("", str(c)))
        b, f = building_floor(code) if code else (0, 0)
        g.setdefault(b, []).append((f, c))
    return {b: [c for _, c in sorted(v)] for b, v in g.items()}


def table_motion_column(df, src, time_column: str = "t_s", choice: str | None = "auto") -> str | None:
    """The column holding the table's motion: `choice` if a name, None for 'none', else the one numeric
    column whose name starts with 'table' or 'ground' (none: None; several: an error)."""
    if choice is None or str(choice).lower() == "none":
        return None
    if choice != "auto":
        if choice not in df.columns:
            raise _bad(src, f"no column '{choice}' for the table's motion (--input)", ", ".join(map(str, df.columns)))
        if not np.issubdtype(df[choice].dtype, np.number):
            raise _bad(src, f"column '{choice}' (--input) is not numeric", df[choice].dtype)
        return choice
    found = [
        c
        for c in df.columns
        if c != time_column
        and str(c).lower().startswith(TABLE_PREFIXES)
        and not str(c).endswith(("_quality", "_px"))
        and np.issubdtype(df[c].dtype, np.number)
    ]
    if len(found) > 1:
        raise _bad(src, "several columns hold the table's motion: choose one with --input", ", ".join(found))
    return found[0] if found else None


def identify_table(
    df,
    src: str,
    time_column: str = "t_s",
    columns=None,
    n_modes: int = 3,
    fmin: float = 0.0,
    fmax: float | None = None,
    start_s: float = 0.0,
    free_vibration: bool = False,
    table_column: str | None = "auto",
    input_kind_given: str | None = None,
    metadata: dict | None = None,
) -> TableIdentification:
    """Check the table (a uniformly sampled time column, finite numeric columns) and identify each
    building's modes from its floors' columns (default: every numeric column but the tracker's extras
    and the table's motion), against the table's motion when there is a column for it
    (`table_motion_column`); a harmonic table motion is refused (safety.is_harmonic). With free_vibration the
    table's column (unless named by table_column) is not the input: a quiet table's motion is its noise, and a
    ratio of two noises has peaks of its own; its line is still read (table_line) for what it says of a forcing.
    The column's kind (displacement, velocity, acceleration) is `input_kind_given`, else the metadata's, else
    displacement (safety.input_kind)."""
    if n_modes < 1:
        raise _bad(src, "--modes must be >= 1", n_modes)
    if time_column not in df.columns:
        raise _bad(src, f"no time column '{time_column}'", ", ".join(map(str, df.columns)))
    t = df[time_column].to_numpy(dtype=float)
    if t.size < 16:
        raise _bad(src, f"column '{time_column}' must hold at least 16 times", f"{t.size} rows")
    if not np.all(np.isfinite(t)):
        k = int(np.argmin(np.isfinite(t)))
        raise _bad(src, f"column '{time_column}' must hold finite times", f"{t[k]!r} at row {k + 1}")
    if (problem := time_order_problem(t, time_column)) is not None:  # the row, as the sweep's reader names it
        raise _bad(src, problem)
    dt = np.diff(t)
    if np.max(np.abs(dt / np.median(dt) - 1)) > 0.01:
        raise _bad(
            src,
            f"column '{time_column}' is not uniformly sampled (within 1 %)",
            f"steps {dt.min():.6g} .. {dt.max():.6g} s",
        )
    step = float(np.median(dt))
    unit = time_unit_guess(step)
    if step > MAX_TABLE_STEP_S or step < 1e-6:
        raise _bad(
            src,
            f"column '{time_column}' steps by {step:.6g} s: implausible for a time in seconds"
            + (
                f" (in {unit} it is {step * TIME_UNITS[unit]:.6g} s: divide it by {1 / TIME_UNITS[unit]:g})"
                if unit
                else ""
            ),
            f"{1 / step:.6g} samples/s",
        )
    fs = 1.0 / step
    top = fmax if fmax is not None else fs / 2
    if not (np.isfinite(fmin) and np.isfinite(top) and 0 <= fmin < top <= fs / 2):
        raise _bad(
            src,
            f"--fmin and --fmax must satisfy 0 <= fmin < fmax <= {fs / 2:g} Hz (half the sampling rate)",
            f"fmin {fmin:g}, fmax {top:g}",
        )
    # identify() takes the samples at its times n / fs >= start_s (modes.identify): at least 16 must be left
    after = np.arange(t.size) / fs >= start_s
    kept = int(after.sum())
    if not (np.isfinite(start_s) and start_s >= 0 and kept >= 16):
        raise _bad(
            src,
            f"--start {start_s:g} s leaves {max(kept, 0)} samples of the table ({t.size} samples, "
            f"{(t.size - 1) / fs:.4g} s): at least 16 needed",
            f"--start {start_s:g}",
        )
    found_col = table_motion_column(df, src, time_column, table_column)
    explicit = table_column not in (None, "auto") and str(table_column).lower() != "none"
    table_col = None if (free_vibration and not explicit) else found_col
    if columns:
        for c in columns:
            if c not in df.columns:
                raise _bad(src, f"no column '{c}'", ", ".join(map(str, df.columns)))
            if c == found_col:
                raise _bad(src, f"column '{c}' is the table's motion, not a floor (--input none to analyse it)")
        cols = list(columns)
    else:
        cols = [
            c
            for c in df.columns
            if c != time_column
            and c not in NOT_DISPLACEMENT
            and c != found_col
            and not str(c).endswith(("_quality", "_px"))
            and np.issubdtype(df[c].dtype, np.number)
        ]
    if not cols:
        raise _bad(src, "no displacement columns to analyse", ", ".join(map(str, df.columns)))
    for c in cols:
        x = df[c].to_numpy(dtype=float)
        if not np.all(np.isfinite(x)):
            raise _bad(src, f"column '{c}' holds non-finite values", f"row {int(np.argmax(~np.isfinite(x))) + 1}")
    table, line, tline, kind_source = None, None, None, ""
    if found_col is not None:
        motion = df[found_col].to_numpy(dtype=float)
        if not np.all(np.isfinite(motion)):
            raise _bad(
                src, f"column '{found_col}' holds non-finite values", f"row {int(np.argmax(~np.isfinite(motion))) + 1}"
            )
        kind, kind_source = input_kind(found_col, input_kind_given, metadata)
        try:
            tline = input_line(motion[after], fs, kind)  # the samples identify takes
        except ValueError as e:
            raise _bad(src, f"cannot analyse the table's motion '{found_col}'", e) from None
        if table_col is not None:
            table, line = motion, tline
            if is_harmonic(line):
                raise _bad(
                    src,
                    f"column '{table_col}' is a single-frequency (harmonic) table motion: "
                    f"{100 * line.fraction:.1f} % of its power at {line.frequency_Hz:.3f} Hz, {line.over_noise:.3g} "
                    "times its noise; the floors of a harmonic test move at the forcing frequency, not at their "
                    "modes: identify from free vibration (--free-vibration) or a broadband record",
                    f"{HARMONIC_INPUT_FRACTION:.0%} or more in one line, {HARMONIC_OVER_NOISE:g} times the noise, "
                    "is refused",
                )
    results = {}
    for b, cs in sorted(building_groups(cols).items()):
        X = np.column_stack([df[c].to_numpy(dtype=float) for c in cs])
        try:
            results[b] = identify(
                X,
                fs,
                cs,
                n_modes=n_modes,
                fmin=fmin,
                fmax=fmax,
                free_vibration=free_vibration,
                start_s=start_s,
                table=table,
            )
        except ValueError as e:
            raise _bad(src, f"cannot identify {', '.join(cs)}", e) from None
    for b, r in results.items():
        if b and fmin <= 0 and (note := floor_order_note(r)) is not None:  # above fmin the lowest is not mode 1
            results[b] = dataclasses.replace(r, notes=(*r.notes, note))
    return TableIdentification(src, fs, results, table_col, line, found_col, tline, kind_source, free_vibration)


def floor_order_note(r: ModalResult) -> str | None:
    """A note when the first mode's shape does not grow with height: a shear frame's first mode has every floor
    on the same side, each further out than the one below (Chopra, Dynamics of Structures, sec. 10.2), so a
    shape that does not is two floors' files swapped, or a floor reversed."""
    if not r.modes or len(r.channels) < 2:
        return None
    floors = [building_floor(floor_code(UNIT_SUFFIX.sub("", c)))[1] for c in r.channels]
    shape = np.array([r.modes[0].shape[c] for c in r.channels])[np.argsort(floors)]
    names = [r.channels[k] for k in np.argsort(floors)]
    if height_order_fault(shape) is None:
        return None
    return (
        f"mode 1 ({r.modes[0].frequency_Hz:.3f} Hz) shape {', '.join(f'{c} {v:+.3f}' for c, v in zip(names, shape))} "
        "does not grow with height as a shear frame's first mode does: are two floors' files swapped, or one "
        "reversed?"
    )


def empty_reason(ident: TableIdentification) -> str:
    """Why no building has a mode: each building's band and notes, in one line."""
    parts = []
    for b, r in sorted(ident.results.items()):
        head = f"building {b}" if b else "other columns"
        lo, hi = r.band_Hz
        why = "; ".join(n for n in r.notes if "damping" not in n) or "no peak above the noise"
        parts.append(f"{head}, {lo:.4g}-{hi:.4g} Hz: {why}")
    return "no mode found (" + "; ".join(parts) + ")"


def model_updates(ident: TableIdentification, scene, update_damping: bool = False) -> list[StiffnessUpdate]:
    """The stiffness updates (and, asked for, damping) that give each building of `scene` its identified
    first frequency (paper sec. 3)."""
    targets = {b: r.modes[0].frequency_Hz for b, r in ident.results.items() if b in (1, 2) and r.modes}
    if not targets:
        if any(b in (1, 2) for b in ident.results):
            raise _bad(ident.source, "no mode identified for building 1 or 2: nothing to update", empty_reason(ident))
        cols = [c for r in ident.results.values() for c in r.channels]
        raise _bad(
            ident.source,
            "no building's floors among the columns (name them b1f3 or model1_floor3_mm) to update",
            ", ".join(cols),
        )
    damp = None
    if update_damping:
        damp = {}
        for b in targets:  # the estimate a modes file keeps (identify/startfile.py), one rule for both
            z, _, _ = damping_estimate(ident.results[b].modes[0])
            if np.isfinite(z):
                damp[b] = z
    return update_scene(scene, targets, damp)
