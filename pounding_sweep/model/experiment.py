"""Tracked experimental displacement and measured acceleration: read and check the table (the sweep layer
turns it into the samples the kernel scores each run against, filtered and weighted: sweep/scoring.py), and
each channel's noise floor.

Table format (CSV or Parquet, written by the video tracker too): a time column in seconds
(default `t_s`), strictly increasing, and one column per channel: the displacement of one floor
relative to the shaking table, in the units the scene states ('mm' or 'm'), or the absolute
acceleration of a floor (an accelerometer on it), in `acc_units` ('m/s2' or 'g').
Extra columns (quality flags, other floors) are ignored unless the scene maps them.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:  # pandas costs 0.3 s to import: only where a table is built
    import pandas as pd

from pounding_sweep import codes
from pounding_sweep.errors import ExperimentError
from pounding_sweep.model.records import G_STANDARD
from pounding_sweep.scene import ExperimentConfig
from pounding_sweep.scene.channels import building_floor, experiment_channel
from pounding_sweep.scene.files import MAX_TABLE_BYTES, open_regular, text_problem
from pounding_sweep.scene.schema import ACC_UNITS
from pounding_sweep.warn import warn


@dataclass(frozen=True)
class Experiment:
    """The experiment's channels on its own time axis, in SI units: displacement [m] relative to the table
    ('b1f3') and absolute acceleration [m/s^2] ('abs_acc_b1f3')."""

    path: str
    time_s: np.ndarray  # experiment clock
    channels: dict[str, np.ndarray]  # channel code ('b1f3', 'abs_acc_b1f3') -> displacement [m] or acceleration [m/s^2]
    columns: dict[str, str]  # channel code -> table column
    metadata: dict
    kinds: dict[str, int] = field(default_factory=dict)  # channel code -> codes.H_DISP or codes.H_ABS_ACC
    noise: dict[str, float] = field(default_factory=dict)  # channel code -> noise standard deviation, SI, where known
    noise_source: dict[str, str] = field(default_factory=dict)  # channel code -> how it was known
    dofs: dict[str, int] = field(default_factory=dict)  # channel code -> the model's degree of freedom it measures

    @property
    def dt_sample(self) -> float:
        return float(np.median(np.diff(self.time_s))) if self.time_s.size > 1 else 1.0

    @property
    def sensor_import(self) -> dict:
        """How the table was imported from raw sensor files ('sensor_import' metadata, cli/import_.py: 'settings'
        and 'sensors'), {} for a table that was not (or whose record cannot be read)."""
        import json

        try:
            record = json.loads(self.metadata.get("sensor_import", "{}"))
        except (TypeError, ValueError, AttributeError):
            return {}
        return record if isinstance(record, dict) else {}

    @property
    def displacements(self) -> dict[str, np.ndarray]:
        """The displacement channels only ('b1f3' -> [m])."""
        return {c: x for c, x in self.channels.items() if self.kinds.get(c, codes.H_DISP) == codes.H_DISP}


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
    if (problem := time_order_problem(t, cfg.time_column)) is not None:
        raise ExperimentError(f"{where}: {problem}")
    d = np.diff(t)
    _time_unit(t, where, cfg.time_column)
    dev = np.abs(d / np.median(d) - 1.0)
    if np.any(dev > 0.01):
        k = int(np.argmax(dev)) + 1
        raise ExperimentError(
            f"{where}: column '{cfg.time_column}' is not uniformly sampled: step {float(d[k - 1]):.6g} s at row {k + 1} "
            f"against the median {float(np.median(d)):.6g} s (resample the table to a uniform step first)"
        )
    chans, cols, kinds, dofs = {}, {}, {}, {}
    for col, code in cfg.channels.items():
        if col not in df.columns:
            raise ExperimentError(
                f"{where}: no column '{col}' (mapped to floor {code}); columns: {', '.join(map(str, df.columns))}"
            )
        kinds[code], dofs[code] = experiment_channel(code, floors, f"[experiment] channels.{col}")
    recorded = _recorded_units(md)
    for col, code in cfg.channels.items():
        x = _numeric(df[col], where, col)
        acc = kinds[code] == codes.H_ABS_ACC
        units = cfg.acc_units if acc else cfg.units
        if col in recorded:
            _check_recorded_unit(where, col, code, recorded[col], acc, units)
        if np.all(x == x[0]):
            what = "zero throughout" if x[0] == 0 else f"constant ({float(x[0])!r} {units} throughout)"
            why = (
                "an accelerometer that reads no motion gives nothing to score against (not recording, or the "
                "wrong column?)"
                if acc
                else "a floor that never moves relative to the table gives nothing to score against (a marker not "
                "tracked, or the wrong column?)"
            )
            raise ExperimentError(f"{where}: column '{col}' (floor {code}) is {what}: {why}")
        chans[code] = x * UNIT_FACTORS[units]
        cols[code] = col
    noise, how = channel_noise(t, chans, cols, kinds, cfg, where)
    exp = Experiment(str(where), t, chans, cols, md, kinds, noise, how, dofs)
    for kind, msg in experiment_problems(exp):
        warn(kind, msg)
    return exp


def time_order_problem(t: np.ndarray, column: str) -> str | None:
    """What is wrong with the order of a time column (its first row not after the one before: duplicate or
    unsorted), None where it strictly increases; the row counted from 1, as a spreadsheet shows it."""
    d = np.diff(t)
    if not np.any(d <= 0):
        return None
    k = int(np.argmax(d <= 0)) + 1
    kind = "duplicate" if d[k - 1] == 0 else "unsorted"
    return f"column '{column}' must be strictly increasing: {kind} time {float(t[k])!r} at row {k + 1} (after {float(t[k - 1])!r})"


def experiment_problems(exp) -> list[tuple[str, str]]:
    """(kind, message) for each problem the table's channels show (model/experiment.py Experiment): offsets in
    its acceleration channels, and each channel's sign and lag against the other floors of its building with a
    channel of the same kind (checks.consensus_problems)."""
    from pounding_sweep.model.sensors.checks import consensus_problems, offset_problem

    out = []
    fs = 1.0 / exp.dt_sample
    floors: dict[tuple[int, int], list[tuple[int, str]]] = {}
    for code, x in exp.channels.items():
        kind = exp.kinds.get(code, codes.H_DISP)
        name = f"{exp.path}: column '{exp.columns[code]}' ({code})"
        if kind == codes.H_ABS_ACC:
            if (w := offset_problem(name, x, exp.dt_sample, exp.noise.get(code, 0.0))) is not None:
                out.append(("channel_offset", w))
        b, f = building_floor(code)
        floors.setdefault((kind, b), []).append((f, code))
    for group in floors.values():
        group.sort()
        names = [f"{exp.path}: column '{exp.columns[c]}' ({c})" for _, c in group]
        out += consensus_problems(names, [exp.channels[c] for _, c in group], fs)
    return out


#: a table's sample step beyond which nothing sensible can follow (no structure's mode is resolved) [s]
MAX_TABLE_STEP_S = 1.0


def _time_unit(t: np.ndarray, where: str, col: str) -> None:
    """An error when the time column's step is implausible as seconds by far (over MAX_TABLE_STEP_S, or under
    1 us): named with the unit that makes it plausible; a warning for steps above records.PLAUSIBLE_STEP_S."""
    from pounding_sweep.model.records import PLAUSIBLE_STEP_S, TIME_UNITS, time_unit_guess

    step = float(np.median(np.diff(t)))
    unit = time_unit_guess(step)
    hint = (
        f": is it in {unit}? In {unit} the step is {step * TIME_UNITS[unit]:.6g} s ({1 / (step * TIME_UNITS[unit]):.6g} "
        f"samples/s): divide the column by {1 / TIME_UNITS[unit]:g}"
        if unit
        else ""
    )
    if step > MAX_TABLE_STEP_S or step < 1e-6:
        raise ExperimentError(
            f"{where}: column '{col}' steps by {step:.6g} s (median): implausible for a time in seconds{hint}"
        )
    if step > PLAUSIBLE_STEP_S:
        warn(
            "table_timing",
            f"{where}: column '{col}' steps by {step:.6g} s ({1 / step:.3g} samples/s): too coarse for a structure's "
            f"modes; is it in ms rather than s?{hint.removeprefix(':') if unit else ''}",
        )


def channel_noise(t, chans, cols, kinds, cfg: ExperimentConfig, where) -> tuple[dict, dict]:
    """Each channel's noise standard deviation [SI] where the scene gives it (`noise`, in the column's own
    units) or a quiet window to measure it in (`noise_window_s`, experiment time: the sample standard deviation
    there); channels without either are left out (the noise floor is then estimated from the data)."""
    given = getattr(cfg, "noise", None) or {}
    window = getattr(cfg, "noise_window_s", None)
    noise, how = {}, {}
    for code, col in cols.items():
        units = cfg.acc_units if kinds[code] == codes.H_ABS_ACC else cfg.units
        if col in given:
            noise[code] = float(given[col]) * UNIT_FACTORS[units]
            how[code] = f"[experiment] noise.{col} = {given[col]!r} {units}"
        elif window is not None:
            inside = (t >= window[0]) & (t <= window[1])
            if inside.sum() < NOISE_MIN_DIFFERENCES:
                raise ExperimentError(
                    f"[experiment] noise_window_s = {list(window)}: holds {int(inside.sum())} sample(s) of {where} "
                    f"(at least {NOISE_MIN_DIFFERENCES}; its time runs {t[0]:.6g} .. {t[-1]:.6g} s)"
                )
            noise[code] = float(np.std(chans[code][inside], ddof=1))
            how[code] = f"standard deviation in noise_window_s = [{window[0]:g}, {window[1]:g}] s"
            if not noise[code] > 0:
                raise ExperimentError(
                    f"[experiment] noise_window_s = {list(window)}: column '{col}' is constant there: no noise to measure"
                )
    return noise, how


#: SI factor of each unit a table's columns may be in (scene/schema.py ExperimentConfig units, acc_units)
UNIT_FACTORS = {"mm": 1e-3, "m": 1.0, "m/s2": 1.0, "g": G_STANDARD}
#: the units of a length a table may record for a column ('column_units' metadata), as the scene's `units` reads them
LENGTH_UNITS = ("mm", "m")


def _recorded_units(md: dict) -> dict:
    """The table's own record of its columns' units ('column_units' metadata: a JSON object, column -> unit, as
    `python -m pounding_sweep import` writes it); {} where it has none or it cannot be read."""
    try:
        units = json.loads(md.get("column_units", "{}"))
    except (TypeError, ValueError):
        return {}
    return {str(k): str(v) for k, v in units.items()} if isinstance(units, dict) else {}


def _check_recorded_unit(where, col: str, code: str, recorded: str, acc: bool, units: str) -> None:
    """ExperimentError where the scene reads a column otherwise than the table records it: an acceleration
    mapped to a displacement channel (or the reverse), another unit than the recorded one, or a recorded unit the
    scene cannot read (acc_units: m/s2 or g; units: mm or m). A unit neither of length nor of acceleration: the
    scene's word stands."""
    word = recorded.strip().lower()
    length = word if word in LENGTH_UNITS else None
    accel = codes.canonical_unit(recorded)  # m/s^2, M/S2, gal, cm/s^2 ...: codes.UNIT_ALIASES
    if length is None and accel is None:
        return
    is_acc = accel is not None
    if is_acc != acc:
        what = "an acceleration" if is_acc else "a displacement"
        fix = f"'abs_acc_{code}'" if is_acc else f"'{code.removeprefix('abs_acc_')}'"
        raise ExperimentError(
            f"{where}: column '{col}' is {what} in {recorded} (the table's column_units) but [experiment] "
            f"channels.{col} = '{code}' reads it as {'a displacement' if is_acc else 'an acceleration'}: map it "
            f"to {fix}"
        )
    spelled = accel if is_acc else length
    if spelled != units:
        key = "acc_units" if acc else "units"
        readable = ACC_UNITS if acc else LENGTH_UNITS
        fix = f"write {key} = '{spelled}'" if spelled in readable else (
            f"the scene reads {' or '.join(readable)}: convert the column"
        )  # fmt: skip
        raise ExperimentError(
            f"{where}: column '{col}' is in {recorded} (the table's column_units) but [experiment] {key} = "
            f"'{units}': {fix}"
        )


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


#: the difference orders noise_floor tries
NOISE_ORDERS = range(1, 9)
#: differences an order needs to be tried (a median of fewer says little)
NOISE_MIN_DIFFERENCES = 10


def noise_floor(x: np.ndarray) -> tuple[float, int]:
    """Standard deviation of the white measurement noise in a sampled signal, estimated from its
    differences, and the difference order that gave it; (nan, 0) when the signal is too short.

    A smooth signal's k-th differences shrink as the sample rate grows (as (2 sin(pi f dt))^k for a
    sinusoid of frequency f) while white noise's do not: their variance is C(2k, k) sigma^2 (the sum of the
    squared binomial coefficients). Order 1 is the mean square successive difference of von Neumann,
    Kent, Bellinson & Hart (Ann. Math. Statist. 12, 1941) that Rice (Ann. Statist. 12, 1984) uses for noise
    in nonparametric regression, order 2 the pseudo-residuals of Gasser, Sroka & Jennen-Steinmetz
    (Biometrika 73, 1986). The scale of the differences is taken robustly, as their median absolute value
    over Phi^-1(3/4) = 0.6745 (Hampel's MAD, J. Amer. Statist. Assoc. 69, 1974; so Donoho & Johnstone,
    Biometrika 81, 1994, estimate noise from the finest wavelet coefficients), so that the minority of
    differences spanning an impact (a displacement's kink, an acceleration's spike) does not count; and
    at the order 1..8 that gives the smallest estimate, since the signal adds to every order and the
    noise is the same in all.

    Measured (benchmarks/bench_noise_floor.py: the paper's 6 Hz and Duzce runs through simulate() plus known
    Gaussian noise): displacement at 100 samples/s 1.1-1.25 times the noise (6 Hz Model-2, which pounds
    every cycle: 1.8); absolute acceleration at 500-1000 samples/s 1.0-1.3 times; pure noise 0.96 (500
    samples; the smallest of 8 estimates, spread 0.07). Acceleration at 100 samples/s comes out 2-20 times
    too large: impacts lasting 6-23 ms (k_s/k = 10 to 1: median_compression_phase) are not resolved at that
    rate, and its signal cannot be told from noise. An estimate too large only lowers that channel's weight
    (sweep/scoring.py)."""
    from math import comb

    best, order = np.inf, 0
    for k in NOISE_ORDERS:
        if x.size - k < NOISE_MIN_DIFFERENCES:
            break
        s = float(np.median(np.abs(np.diff(x, k)))) / (MAD_GAUSSIAN * np.sqrt(comb(2 * k, k)))
        if s < best:
            best, order = s, k
    return (best, order) if order else (float("nan"), 0)


#: Phi^-1(3/4): the median of |N(0, 1)| (a Gaussian's MAD is 0.6745 sigma)
MAD_GAUSSIAN = 0.6744897501960817
