"""Modal identification of a displacement table (a tracked video, a test record): its columns grouped
by building, each building identified (identify/modes.py), and the model update that matches each
building's first frequency (identify/update.py). Every problem with the table is one ExperimentError
naming the file, what is wrong and the value."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pounding_sweep.errors import ExperimentError
from pounding_sweep.identify.modes import ModalResult, identify
from pounding_sweep.identify.update import StiffnessUpdate, update_scene
from pounding_sweep.scene.video import floor_code

#: columns a tracked table carries besides the floors' displacements
NOT_DISPLACEMENT = {"frame", "table_in_camera_mm"}


@dataclass(frozen=True)
class TableIdentification:
    """Per building (1, 2; 0 for columns that name no floor) the identified modes of its columns."""

    source: str
    fs: float  # samples per second
    results: dict[int, ModalResult]


def _bad(src, what, value=None) -> ExperimentError:
    return ExperimentError(f"{src}: {what}" + ("" if value is None else f" ({value})"))


def building_groups(columns) -> dict[int, list[str]]:
    """Columns by building ('b1f3' or 'model1_floor3_mm' -> building 1), floor 1 first; 0: no floor name."""
    g: dict = {}
    for c in columns:
        code = floor_code(c)
        b, f = (int(code[1:].split("f")[0]), int(code.split("f")[1])) if code else (0, 0)
        g.setdefault(b, []).append((f, c))
    return {b: [c for _, c in sorted(v)] for b, v in g.items()}


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
) -> TableIdentification:
    """Check the table (a uniformly sampled time column, finite numeric columns) and identify each
    building's modes from its floors' columns (default: every numeric column but the tracker's extras)."""
    if n_modes < 1:
        raise _bad(src, "--modes must be >= 1", n_modes)
    if time_column not in df.columns:
        raise _bad(src, f"no time column '{time_column}'", ", ".join(map(str, df.columns)))
    t = df[time_column].to_numpy(dtype=float)
    if t.size < 16 or not np.all(np.isfinite(t)) or np.any(np.diff(t) <= 0):
        raise _bad(src, f"column '{time_column}' must hold at least 16 increasing finite times", f"{t.size} rows")
    dt = np.diff(t)
    if np.max(np.abs(dt / np.median(dt) - 1)) > 0.01:
        raise _bad(
            src,
            f"column '{time_column}' is not uniformly sampled (within 1 %)",
            f"steps {dt.min():.6g} .. {dt.max():.6g} s",
        )
    fs = 1.0 / float(np.median(dt))
    if columns:
        for c in columns:
            if c not in df.columns:
                raise _bad(src, f"no column '{c}'", ", ".join(map(str, df.columns)))
        cols = list(columns)
    else:
        cols = [
            c
            for c in df.columns
            if c != time_column
            and c not in NOT_DISPLACEMENT
            and not str(c).endswith(("_quality", "_px"))
            and np.issubdtype(df[c].dtype, np.number)
        ]
    if not cols:
        raise _bad(src, "no displacement columns to analyse", ", ".join(map(str, df.columns)))
    for c in cols:
        x = df[c].to_numpy(dtype=float)
        if not np.all(np.isfinite(x)):
            raise _bad(src, f"column '{c}' holds non-finite values", f"row {int(np.argmax(~np.isfinite(x))) + 1}")
    results = {}
    for b, cs in sorted(building_groups(cols).items()):
        X = np.column_stack([df[c].to_numpy(dtype=float) for c in cs])
        try:
            results[b] = identify(
                X, fs, cs, n_modes=n_modes, fmin=fmin, fmax=fmax, free_vibration=free_vibration, start_s=start_s
            )
        except ValueError as e:
            raise _bad(src, f"cannot identify {', '.join(cs)}", e) from None
    return TableIdentification(src, fs, results)


def model_updates(ident: TableIdentification, scene, update_damping: bool = False) -> list[StiffnessUpdate]:
    """The stiffness updates (and, asked for, damping) that give each building of `scene` its identified
    first frequency (paper sec. 3)."""
    targets = {b: r.modes[0].frequency_Hz for b, r in ident.results.items() if b in (1, 2) and r.modes}
    if not targets:
        cols = [c for r in ident.results.values() for c in r.channels]
        raise _bad(
            ident.source,
            "no building's floors among the columns (name them b1f3 or model1_floor3_mm) to update",
            ", ".join(cols),
        )
    damp = None
    if update_damping:
        damp = {}
        for b in targets:
            m = ident.results[b].modes[0]
            z = m.damping_log_decrement if m.damping_log_decrement is not None else m.damping_half_power
            if z is not None and np.isfinite(z):
                damp[b] = z
    return update_scene(scene, targets, damp)
