"""Tracked experimental displacement: read and check the table (the sweep layer turns it into the
samples the kernel scores each run against: sweep/scoring.py).

Table format (CSV or Parquet, written by the video tracker too): a time column in seconds
(default `t_s`), strictly increasing, and one column per tracked channel: the displacement of
one floor relative to the shaking table, in the units the scene states ('mm' or 'm').
Extra columns (quality flags, other floors) are ignored unless the scene maps them.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:  # pandas costs 0.3 s to import: only where a table is built
    import pandas as pd

from pounding_sweep.errors import ExperimentError
from pounding_sweep.scene import ExperimentConfig
from pounding_sweep.scene.channels import floor_dof
from pounding_sweep.scene.files import MAX_TABLE_BYTES, open_regular, text_problem


@dataclass(frozen=True)
class Experiment:
    """Tracked displacement channels on the experiment's own time axis, in metres."""

    path: str
    time_s: np.ndarray  # experiment clock
    channels: dict[str, np.ndarray]  # model floor code ('b1f3') -> displacement [m]
    columns: dict[str, str]  # model floor code -> table column
    metadata: dict

    @property
    def dt_sample(self) -> float:
        return float(np.median(np.diff(self.time_s))) if self.time_s.size > 1 else 1.0


TABLE_SUFFIXES = (".csv", ".parquet")  # read as text or by pyarrow; nothing else (no pickles, no Excel)


def read_table(path: str | Path) -> tuple[pd.DataFrame, dict]:
    """Read a CSV or Parquet table (and Parquet key-value metadata, decoded); the suffix decides."""
    path = Path(path)
    if path.is_dir():
        raise ExperimentError(f"{path}: a folder, not an experiment table (.csv or .parquet)")
    if not path.exists() and not path.is_symlink():
        raise ExperimentError(f"{path}: experiment table not found")
    if path.suffix.lower() not in TABLE_SUFFIXES:
        raise ExperimentError(
            f"{path}: an experiment table is .csv or .parquet, not {path.suffix or 'a file without suffix'!r}"
        )
    # a FIFO, a device or a file over MAX_TABLE_BYTES is refused before it is read
    with open_regular(path, "experiment table", MAX_TABLE_BYTES, ExperimentError) as fh:
        try:
            if path.suffix.lower() == ".parquet":
                import pyarrow.parquet as pq

                try:
                    names = pq.read_schema(path).names
                except Exception:  # noqa: BLE001 - unreadable: read_table below says why, as it always has
                    names = []
                if len(set(names)) < len(names):  # pyarrow cannot read such a table: say why
                    raise ExperimentError(f"{path}: {_repeated(sorted({n for n in names if names.count(n) > 1})[0])}")
                t = pq.read_table(path)  # by name, so its errors name the file (checked just above)
                md = {
                    k.decode(errors="replace"): v.decode(errors="replace") for k, v in (t.schema.metadata or {}).items()
                }
                names = t.schema.names
                df = t.to_pandas()
            else:
                import csv
                import io

                head = fh.read(4096)
                if (why := text_problem(path, "experiment table", head)) is not None:
                    raise ExperimentError(why)
                fh.seek(0)
                import pandas as pd

                raw = fh.read()
                df, md = pd.read_csv(io.BytesIO(raw)), {}
                text = raw.decode("utf-8", errors="replace")
                names = next(csv.reader(io.StringIO(text)), [])  # as written: pandas renames a repeated 'x' to 'x.1'
            df.attrs["repeated_columns"] = sorted({str(n) for n in names if names.count(n) > 1})
            return df, md
        except ExperimentError:
            raise
        except Exception as e:  # pandas/pyarrow raise many types for unreadable files
            raise ExperimentError(f"{path}: cannot read the experiment table ({type(e).__name__}: {e})") from None


def load_experiment(cfg: ExperimentConfig, floors: tuple[int, int]) -> Experiment:
    """The experiment of an [experiment] section whose `table` names a file (a video is tracked by the
    sweep layer: sweep/scoring.py), read and checked (experiment_from_table)."""
    if cfg.video is not None:
        raise ValueError("an [experiment.video] section is tracked by pounding_sweep.sweep.scoring.load_experiment")
    df, md = read_table(cfg.table)
    return experiment_from_table(df, md, cfg.table, cfg, floors)


def experiment_from_table(
    df: pd.DataFrame, md: dict, where: str, cfg: ExperimentConfig, floors: tuple[int, int]
) -> Experiment:
    """Read the table and check it: time column present, numeric, finite, strictly increasing;
    every mapped column present, named once, numeric, finite and not constant; every channel a model floor."""
    repeated = set(df.attrs.get("repeated_columns", ()))
    for col in [cfg.time_column, *cfg.channels]:
        if col in repeated:
            raise ExperimentError(f"{where}: {_repeated(col)}")
    if cfg.time_column not in df.columns:
        raise ExperimentError(
            f"{where}: no time column '{cfg.time_column}' (columns: {', '.join(map(str, df.columns))})"
        )
    t = _numeric(df[cfg.time_column], where, cfg.time_column)
    if t.size < 2:
        raise ExperimentError(f"{where}: column '{cfg.time_column}' needs at least 2 samples, has {t.size}")
    d = np.diff(t)
    if np.any(d <= 0):
        k = int(np.argmax(d <= 0)) + 1
        kind = "duplicate" if d[k - 1] == 0 else "unsorted"
        raise ExperimentError(
            f"{where}: column '{cfg.time_column}' must be strictly increasing: {kind} time {float(t[k])!r} at row {k + 1} "
            f"(after {float(t[k - 1])!r})"
        )
    dev = np.abs(d / np.median(d) - 1.0)
    if np.any(dev > 0.01):
        k = int(np.argmax(dev)) + 1
        raise ExperimentError(
            f"{where}: column '{cfg.time_column}' is not uniformly sampled: step {float(d[k - 1]):.6g} s at row {k + 1} "
            f"against the median {float(np.median(d)):.6g} s (resample the table to a uniform step first)"
        )
    factor = 1e-3 if cfg.units == "mm" else 1.0
    chans, cols = {}, {}
    for col, code in cfg.channels.items():
        if col not in df.columns:
            raise ExperimentError(
                f"{where}: no column '{col}' (mapped to floor {code}); columns: {', '.join(map(str, df.columns))}"
            )
        floor_dof(code, floors, f"[experiment] channels.{col}")
    for col, code in cfg.channels.items():
        x = _numeric(df[col], where, col)
        if np.all(x == x[0]):
            what = "zero throughout" if x[0] == 0 else f"constant ({float(x[0])!r} {cfg.units} throughout)"
            raise ExperimentError(
                f"{where}: column '{col}' (floor {code}) is {what}: a floor that never moves relative to the "
                "table gives nothing to score against (a marker not tracked, or the wrong column?)"
            )
        chans[code] = x * factor
        cols[code] = col
    return Experiment(str(where), t, chans, cols, md)


def _repeated(col: str) -> str:
    return (
        f"column name '{col}' appears more than once in the table's header: which one is meant cannot be told; "
        "give each column its own name"
    )


def _numeric(series: pd.Series, where: str, col: str) -> np.ndarray:
    import pandas as pd

    x = pd.to_numeric(series, errors="coerce").to_numpy(dtype=float)
    bad = ~np.isfinite(x)
    if bad.any():
        k = int(np.argmax(bad))
        v = series.iloc[k]
        v = v.item() if hasattr(v, "item") else v
        raise ExperimentError(f"{where}: column '{col}' row {k + 1}: value {v!r} is not a finite number")
    return x
