"""Scene files: TOML -> frozen, validated dataclasses, with did-you-mean for unknown keys.

A scene names two buildings, the contact element, the excitation, the integration, an
optional sweep (axes over scalar parameters) and the outputs. Every field has a docstring in
its metadata; `describe()` prints them. The canonical JSON of the resolved scene and its
SHA-256 identify a sweep (stored in the Parquet metadata).
"""

from __future__ import annotations

import dataclasses
import difflib
import hashlib
import json
import math
import tomllib
import types
import typing
from dataclasses import dataclass, field
from pathlib import Path


class ConfigError(ValueError):
    """A scene that cannot be run: the message names the file, the key and the value."""


def _f(doc: str, default=dataclasses.MISSING, **kw):
    if default is dataclasses.MISSING:
        return field(metadata={"doc": doc}, **kw)
    return field(default=default, metadata={"doc": doc}, **kw)


EXECUTORS = ("local", "dask")
MAX_AXIS_VALUES = 10_000_000  # a range longer than this is a typo, not a sweep
MAX_STEPS = 100_000_000  # steps of one harmonic run (records: the same limit on resampling, records._MAX_SAMPLES)

from pounding_sweep.scene.video import VideoSpec  # noqa: E402  (plain data; OpenCV stays unimported)

# ----------------------------------------------------------------------------- sections


@dataclass(frozen=True)
class BuildingConfig:
    """One shear frame. Floor 1 is the lowest. Give story stiffnesses, or column EI + count + height."""

    masses_kg: tuple[float, ...] = _f("floor masses [kg], floor 1 first")
    name: str = _f("label used in outputs", "")
    story_stiffness_N_per_m: tuple[float, ...] | None = _f(
        "lateral stiffness of each story [N/m] (one value: the same for every story)", None
    )
    column_EI_Nm2: tuple[float, ...] | None = _f("column flexural stiffness EI [N m^2] (k = n_columns 12 EI / h^3)", None)
    n_columns: int | None = _f("columns per story (with column_EI_Nm2)", None)
    story_height_m: tuple[float, ...] | None = _f("story height h [m] (with column_EI_Nm2)", None)
    damping_ratio: float | None = _f("Rayleigh damping ratio matched at damping_modes (0.0105 = 1.05 %)", None)
    damping_modes: tuple[int, ...] = _f("the two modes (1-based) at which damping_ratio holds", (1, 2))
    rayleigh_a0_per_s: float | None = _f("explicit Rayleigh mass coefficient a0 [1/s] (instead of damping_ratio)", None)
    rayleigh_a1_s: float | None = _f("explicit Rayleigh stiffness coefficient a1 [s] (instead of damping_ratio)", None)


@dataclass(frozen=True)
class ContactConfig:
    """Kelvin-Voigt element at each facing floor pair (eqs. 8-10)."""

    r: float = _f("coefficient of restitution r in [0, 1] (eq. 10)")
    gap_m: float = _f("seismic gap d [m] between facing floors at rest", 0.0)
    ks_ratio: float | None = _f("contact stiffness as a ratio k_s / k_ref", None)
    ks_N_per_m: float | None = _f("contact stiffness k_s [N/m] (instead of ks_ratio)", None)
    k_ref_N_per_m: float = _f("reference story stiffness k for ks_ratio [N/m] (paper: 6830)", 6830.0)
    law: str = _f("'classic' (eq. 8, may pull briefly before separation) or 'no_tension' (force >= 0)", "classic")


@dataclass(frozen=True)
class ExcitationConfig:
    """Table motion: harmonic displacement, or a recorded ground acceleration."""

    type: str = _f("'harmonic' or 'record'")
    name: str = _f("label used in outputs", "")
    amplitude_m: float | None = _f("harmonic: table displacement amplitude [m]", None)
    frequency_Hz: float | None = _f("harmonic: table frequency [Hz]", None)
    duration_s: float | None = _f("length of the run [s] (record: default its own length; longer pads zeros)", None)
    record: str | None = _f("record: path of a PEER .AT2 or a two-column CSV (time [s], acceleration)", None)
    format: str = _f("record format: 'auto' (by suffix), 'at2' or 'csv'", "auto")
    units: str | None = _f("record acceleration units: 'g', 'm/s2' or 'cm/s2' (default: the format's)", None)
    scale: float = _f("factor on the record's acceleration", 1.0)
    length_scale: float = _f("similitude length scale lambda_L (eqs. 17-19): time / sqrt(lambda_L), acceleration kept", 1.0)


@dataclass(frozen=True)
class IntegrationConfig:
    """Time integration: Newmark average acceleration (gamma = 1/2, beta = 1/4)."""

    dt_s: float | str = _f("time step [s], or 'auto': per run, halved from dt_max_s until the run's result changes "
                           "by less than dt_tolerance (step doubling with a Richardson estimate)", 1e-4)
    dt_tolerance: float = _f("dt_s = 'auto': relative error allowed in the scored errors (fractions of the "
                             "experiment's RMS) and peaks, or without an experiment in the peak displacements and forces",
                             1e-3)
    dt_max_s: float = _f("dt_s = 'auto': the coarsest step tried [s]", 2e-3)
    dt_min_s: float = _f("dt_s = 'auto': the finest step tried [s]; runs above the tolerance there are flagged", 1e-6)
    scheme: str = _f("'implicit' (contact in the step, active set), 'event' (steps split at contact switches: second order) "
                     "or 'paper' (trial force as load, sec. 2)", "event")
    max_contact_iterations: int = _f("active-set iterations per step before a step counts as unsettled", 16)
    min_steps_per_contact_period: float = _f("flag runs with fewer steps per contact period 2 pi sqrt(m_eff/k_s)", 20.0)

    @property
    def auto(self) -> bool:
        return self.dt_s == "auto"

    @property
    def first_dt_s(self) -> float:
        """The fixed dt, or with 'auto' the coarsest one tried."""
        return self.dt_max_s if self.auto else self.dt_s


@dataclass(frozen=True)
class OutputConfig:
    """Where results go and which time histories to keep."""

    path: str = _f("Parquet file of one row per run (relative to the scene file)", "")
    histories: tuple[str, ...] = _f(
        "history channels: disp_b1f3, vel_b2f1, abs_acc_b1f3, force_f3, ground_acc (none: metrics only)", ()
    )
    history_decimate: int = _f("keep every n-th step of the histories", 1)


@dataclass(frozen=True)
class ExecutionConfig:
    """How the grid is run on this machine."""

    threads: int = _f("worker threads of the local executor (0: all cores)", 0)
    batch_runs: int = _f("runs handed to a thread at a time (0: automatic)", 0)
    executor: str = _f("'local' (threads in this process) or 'dask' (Dask distributed: a LocalCluster, or the "
                       "scheduler at dask_address)", "local")
    dask_address: str = _f("scheduler address, e.g. 'tcp://10.0.0.5:8786' (empty: start a LocalCluster here)", "")
    dask_workers: int = _f("worker processes of the LocalCluster, one thread each (0: all cores)", 0)
    chunk_runs: int = _f("runs per result part (Parquet file) and per task", 4096)
    max_runs: int = _f("largest grid run without confirmation (the command line's --yes lifts it)", 2_000_000)


@dataclass(frozen=True)
class ExperimentConfig:
    """Tracked displacement to score every run against (CSV or Parquet; see the README's format)."""

    table: str | None = _f("path of the tracked-displacement table (.csv or .parquet); or an [experiment.video] "
                           "section to track a video instead", None)
    channels: dict | None = _f("table column -> model floor, e.g. {model1_floor3 = 'b1f3'} (with a video: default "
                               "every marker named by a floor)", None)
    time_column: str = _f("name of the time column [s]", "t_s")
    units: str = _f("units of the displacement columns: 'mm' or 'm'", "mm")
    window_s: tuple[float, ...] | None = _f("[start, end] of the compared window in simulation time [s] (default: all overlap)", None)
    time_offset_s: float = _f("experiment time minus simulation time [s] (the table's t = offset is the simulation's t = 0)", 0.0)
    max_lag_s: float = _f("largest lag searched for the best correlation [s]", 0.1)
    combine: str = _f("how channels combine into one error: 'mean', 'max' or 'rms' of their eq. 20 errors", "mean")
    refine: bool = _f("after the grid, minimise the combined error over continuous k_s/k and r (scipy.optimize)", False)
    refine_max_evals: int = _f("simulations the refinement may spend", 80)
    video: VideoSpec | None = _f("[experiment.video]: a shake-table video whose LED markers are tracked into the "
                                 "table (see python -m pounding_sweep track --help for its keys)", None)


@dataclass(frozen=True)
class Axis:
    """One sweep axis: a scene parameter and its values."""

    name: str
    values: tuple


@dataclass(frozen=True)
class Scene:
    """A whole scene, resolved and validated. Paths are absolute."""

    name: str
    description: str
    building1: BuildingConfig
    building2: BuildingConfig
    contact: ContactConfig
    excitation: ExcitationConfig
    integration: IntegrationConfig
    output: OutputConfig
    execution: ExecutionConfig
    sweep: tuple[Axis, ...]
    source: str  # the scene file
    toml_text: str  # the scene file as written
    experiment: ExperimentConfig | None = None

    def canonical(self) -> dict:
        """Resolved scene as plain data (what the hash covers), with record file digests. How and
        where it runs ([execution], the output path) is left out: it does not change a result, so a
        sweep can be resumed on another executor or after its folder moved."""
        d = dataclasses.asdict(self)
        d.pop("source")
        d.pop("toml_text")
        d.pop("execution")
        d["output"].pop("path")
        d["sweep"] = [{"name": a.name, "values": list(a.values)} for a in self.sweep]
        files = sorted(({self.excitation.record} | set(_axis_values(self, "record"))) - {None})
        if self.experiment is not None:
            files.append(self.experiment.video.path if self.experiment.video is not None else self.experiment.table)
        d["record_sha256"] = {Path(p).name: _file_digest(p) for p in files}
        return d

    def config_hash(self) -> str:
        blob = json.dumps(self.canonical(), sort_keys=True, default=str).encode()
        return hashlib.sha256(blob).hexdigest()


def _axis_values(scene: Scene, name: str) -> tuple:
    for a in scene.sweep:
        if a.name == name:
            return a.values
    return ()


def _file_digest(path: str) -> str:
    """SHA-256 of a file, read in 1 MiB blocks (a video may be larger than memory wants)."""
    h = hashlib.sha256()
    try:
        with open(path, "rb") as f:
            for block in iter(lambda: f.read(1 << 20), b""):
                h.update(block)
    except OSError:
        return "unreadable"
    return h.hexdigest()


# ----------------------------------------------------------------------------- sweep axes

#: axis name -> (section, field): the scalar parameters a sweep may vary
SWEEPABLE = {
    "ks_ratio": ("contact", "ks_ratio"),
    "ks_N_per_m": ("contact", "ks_N_per_m"),
    "r": ("contact", "r"),
    "gap_m": ("contact", "gap_m"),
    "amplitude_m": ("excitation", "amplitude_m"),
    "frequency_Hz": ("excitation", "frequency_Hz"),
    "scale": ("excitation", "scale"),
    "record": ("excitation", "record"),
}

SECTIONS = {
    "building1": BuildingConfig,
    "building2": BuildingConfig,
    "contact": ContactConfig,
    "excitation": ExcitationConfig,
    "integration": IntegrationConfig,
    "output": OutputConfig,
    "execution": ExecutionConfig,
}
TOP_KEYS = {"name", "description", "sweep", "experiment", *SECTIONS}
MAX_GRID = 50_000_000


# ----------------------------------------------------------------------------- loading


def load_scene(path: str | Path) -> Scene:
    """Read, resolve and validate a scene file; raise ConfigError naming file, key and value."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as e:
        raise ConfigError(f"{path}: cannot read scene file ({e.strerror or e})") from None
    except UnicodeDecodeError as e:
        raise ConfigError(f"{path}: not UTF-8 text ({e.reason} at byte {e.start})") from None
    try:
        raw = tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise ConfigError(f"{path}: TOML syntax error: {e}{_toml_line(text, str(e))}") from None
    try:
        return scene_from_dict(raw, base_dir=path.resolve().parent, source=str(path), toml_text=text)
    except ConfigError as e:
        raise ConfigError(f"{path}: {e}") from None


def _toml_line(text: str, message: str) -> str:
    """The line a TOML error points at, as written (tomllib names only its number); at column 1
    also the statement before it, which is usually the one left unfinished (an unclosed array)."""
    import re

    lines = text.splitlines()

    def show(i: int) -> str:
        line = lines[i].strip()
        return repr(line[:80] + " ..." if len(line) > 80 else line)

    def before(i: int) -> int:
        return max((k for k in range(i) if lines[k].strip() and not lines[k].lstrip().startswith("#")), default=-1)

    m = re.search(r"at line (\d+), column (\d+)", message)
    if m and 1 <= int(m.group(1)) <= len(lines):
        i = int(m.group(1)) - 1
        prev = before(i) if m.group(2) == "1" else -1
        return f": {show(i)}" + (f" (after line {prev + 1}: {show(prev)})" if prev >= 0 else "")
    i = before(len(lines))  # "at end of document": the last statement
    return f": {show(i)} (line {i + 1})" if i >= 0 else ""


def scene_from_dict(raw: dict, base_dir: Path, source: str = "<dict>", toml_text: str = "") -> Scene:
    """Build a Scene from parsed TOML (keys checked, types coerced, values validated)."""
    _check_keys(raw, TOP_KEYS, "top level")
    for req in ("building1", "building2", "contact", "excitation"):
        if req not in raw:
            raise ConfigError(f"missing section [{req}]")
    sections = {}
    for name, cls in SECTIONS.items():
        table = raw.get(name, {})
        if not isinstance(table, dict):
            raise ConfigError(f"'{name}' must be a table [{name}], got {type(table).__name__} {table!r}")
        sections[name] = _build(cls, table, name)
    name = _typed(raw.get("name", Path(source).stem), str, "name")
    if not name or any(c in name for c in '/\\\x00') or name in (".", ".."):
        raise ConfigError(f"name = {name!r}: a scene name is also the default output file name; "
                          "use letters, digits, '-', '_' or '.', no path separators")
    desc = _typed(raw.get("description", ""), str, "description")
    exc = sections["excitation"]
    if exc.record is not None:
        sections["excitation"] = dataclasses.replace(exc, record=str((base_dir / exc.record).resolve()))
    out = sections["output"]
    out_path = out.path or f"results/{name}.parquet"
    sections["output"] = dataclasses.replace(out, path=str((base_dir / out_path).resolve()))
    sweep = _parse_sweep(raw.get("sweep", {}), base_dir)
    experiment = None
    if "experiment" in raw:
        if not isinstance(raw["experiment"], dict):
            raise ConfigError(f"'experiment' must be a table [experiment], got {raw['experiment']!r}")
        xraw = dict(raw["experiment"])
        video = xraw.pop("video", None)
        experiment = _build(ExperimentConfig, xraw, "experiment")
        if video is not None:
            from pounding_sweep.scene.video import parse_video_section  # no OpenCV import: tracking imports it lazily

            spec = parse_video_section(video, base_dir)
            experiment = dataclasses.replace(experiment, video=spec,
                                             channels=experiment.channels or spec.default_channels())
        if experiment.table is not None:
            experiment = dataclasses.replace(experiment, table=str((base_dir / experiment.table).resolve()))
    scene = Scene(name=name, description=desc, sweep=sweep, source=source, toml_text=toml_text,
                  experiment=experiment, **sections)
    validate(scene)
    return scene


def _check_keys(table: dict, allowed, where: str) -> None:
    for key in table:
        if key not in allowed:
            close = difflib.get_close_matches(key, list(allowed), n=1, cutoff=0.6)
            hint = f"; did you mean '{close[0]}'?" if close else f"; allowed: {', '.join(sorted(allowed))}"
            raise ConfigError(f"unknown key '{key}' in {where}{hint}")


def _build(cls, table: dict, section: str):
    fields = {f.name: f for f in dataclasses.fields(cls)}
    _check_keys(table, fields, f"[{section}]")
    hints = typing.get_type_hints(cls)
    kwargs = {}
    for name, f in fields.items():
        key = f"[{section}] {name}"
        if name in table:
            kwargs[name] = _coerce(table[name], hints[name], key)
        elif f.default is dataclasses.MISSING:
            raise ConfigError(f"missing key '{name}' in [{section}] ({f.metadata['doc']})")
    return cls(**kwargs)


def _coerce(value, hint, key: str):
    """Check a TOML value against a field type; ints are accepted for floats, scalars for tuples."""
    origin = typing.get_origin(hint)
    if origin in (typing.Union, types.UnionType):
        args = [a for a in typing.get_args(hint) if a is not type(None)]
        if isinstance(value, str) and str in args:  # float | str: a word goes to str, the rest to the number
            return _coerce(value, str, key)
        return _coerce(value, args[0], key)
    if origin is tuple:
        item = typing.get_args(hint)[0]
        seq = value if isinstance(value, list) else [value]
        if not seq:
            raise ConfigError(f"{key} = []: needs at least one value")
        return tuple(_typed(v, item, key) for v in seq)
    return _typed(value, hint, key)


def _typed(value, typ, key: str):
    if typ is bool:
        if not isinstance(value, bool):
            raise ConfigError(f"{key} = {value!r}: expected true or false")
        return value
    if typ is dict:
        if not isinstance(value, dict) or not value:
            raise ConfigError(f"{key} = {value!r}: expected a non-empty table of name = value")
        return {str(k): _typed(v, str, f"{key}.{k}") for k, v in value.items()}
    if typ is float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ConfigError(f"{key} = {value!r}: expected a number")
        value = float(value)
        if not math.isfinite(value):
            raise ConfigError(f"{key} = {value!r}: must be finite")
        return value
    if typ is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise ConfigError(f"{key} = {value!r}: expected an integer")
        return value
    if typ is str:
        if not isinstance(value, str):
            raise ConfigError(f"{key} = {value!r}: expected a string")
        if "\x00" in value:
            raise ConfigError(f"{key} = {value!r}: contains a NUL character")
        return value
    raise TypeError(typ)  # pragma: no cover - a field type the loader does not know


def _parse_sweep(table, base_dir: Path) -> tuple[Axis, ...]:
    if not isinstance(table, dict):
        raise ConfigError(f"'sweep' must be a table [sweep], got {table!r}")
    _check_keys(table, SWEEPABLE, "[sweep]")
    axes = []
    for name, spec in table.items():
        key = f"[sweep] {name}"
        if name == "record":
            vals = spec if isinstance(spec, list) else [spec]
            if not vals:
                raise ConfigError(f"{key} = []: an axis needs at least one value")
            vals = tuple(str((base_dir / _typed(v, str, key)).resolve()) for v in vals)
        elif isinstance(spec, dict):
            vals = _range_values(spec, key)
        else:
            vals = _coerce(spec, tuple[float, ...], key)
        if len(set(vals)) != len(vals):
            raise ConfigError(f"{key} = {list(vals)!r}: repeated values")
        axes.append(Axis(name, vals))
    return tuple(axes)


def _range_values(spec: dict, key: str) -> tuple[float, ...]:
    import numpy as np

    _check_keys(spec, {"start", "stop", "num", "spacing"}, key)
    for req in ("start", "stop", "num"):
        if req not in spec:
            raise ConfigError(f"{key}: a range needs 'start', 'stop' and 'num' (missing '{req}')")
    start = _typed(spec["start"], float, f"{key}.start")
    stop = _typed(spec["stop"], float, f"{key}.stop")
    num = _typed(spec["num"], int, f"{key}.num")
    spacing = _typed(spec.get("spacing", "linear"), str, f"{key}.spacing")
    if num < 1:
        raise ConfigError(f"{key}.num = {num}: must be at least 1")
    if num > MAX_AXIS_VALUES:
        raise ConfigError(f"{key}.num = {num:,}: more than {MAX_AXIS_VALUES:,} values on one axis")
    if spacing == "linear":
        return tuple(float(x) for x in np.linspace(start, stop, num))
    if spacing == "log":
        if start <= 0 or stop <= 0:
            raise ConfigError(f"{key}: log spacing needs start and stop > 0 (got {start}, {stop})")
        return tuple(float(x) for x in np.geomspace(start, stop, num))
    raise ConfigError(f"{key}.spacing = {spacing!r}: expected 'linear' or 'log'")


# ----------------------------------------------------------------------------- validation


def _positive(value, key):
    if value is not None and not value > 0:
        raise ConfigError(f"{key} = {value!r}: must be > 0")


def validate(s: Scene) -> None:
    """Physical and logical checks that the type coercion cannot make."""
    for bname in ("building1", "building2"):
        b: BuildingConfig = getattr(s, bname)
        n = len(b.masses_kg)
        for v in b.masses_kg:
            _positive(v, f"[{bname}] masses_kg")
        has_k = b.story_stiffness_N_per_m is not None
        has_ei = b.column_EI_Nm2 is not None
        if has_k == has_ei:
            raise ConfigError(f"[{bname}]: give either story_stiffness_N_per_m or column_EI_Nm2 (+ n_columns, story_height_m), not {'both' if has_k else 'neither'}")
        lists = {"story_stiffness_N_per_m": b.story_stiffness_N_per_m, "column_EI_Nm2": b.column_EI_Nm2, "story_height_m": b.story_height_m}
        for k, vals in lists.items():
            if vals is None:
                continue
            if len(vals) not in (1, n):
                raise ConfigError(f"[{bname}] {k} has {len(vals)} values for {n} floors (give 1 or {n})")
            for v in vals:
                _positive(v, f"[{bname}] {k}")
        if has_ei and (b.n_columns is None or b.story_height_m is None):
            raise ConfigError(f"[{bname}]: column_EI_Nm2 needs n_columns and story_height_m")
        if b.n_columns is not None:
            _positive(b.n_columns, f"[{bname}] n_columns")
        _check_story_stiffness(b, bname, n)
        explicit = b.rayleigh_a0_per_s is not None or b.rayleigh_a1_s is not None
        if explicit and b.damping_ratio is not None:
            raise ConfigError(f"[{bname}]: give damping_ratio or rayleigh_a0_per_s/rayleigh_a1_s, not both")
        for k in ("rayleigh_a0_per_s", "rayleigh_a1_s"):
            v = getattr(b, k)
            if v is not None and v < 0:
                raise ConfigError(f"[{bname}] {k} = {v!r}: must be >= 0")
        if b.damping_ratio is not None and not 0 <= b.damping_ratio < 1:
            raise ConfigError(f"[{bname}] damping_ratio = {b.damping_ratio!r}: must lie in [0, 1)")
        if len(b.damping_modes) != 2 or len(set(b.damping_modes)) != 2 or not all(1 <= m <= n for m in b.damping_modes):
            if n > 1:
                raise ConfigError(f"[{bname}] damping_modes = {list(b.damping_modes)}: two different modes between 1 and {n}")
    c = s.contact
    axes = {a.name: a.values for a in s.sweep}
    _check_r(c.r, "[contact] r")
    for v in axes.get("r", ()):
        _check_r(v, "[sweep] r")
    if "ks_ratio" in axes and "ks_N_per_m" in axes:
        raise ConfigError("[sweep]: sweep ks_ratio or ks_N_per_m, not both")
    if c.ks_ratio is not None and c.ks_N_per_m is not None:
        raise ConfigError("[contact]: give ks_ratio or ks_N_per_m, not both")
    if c.ks_ratio is None and c.ks_N_per_m is None and not axes.keys() & {"ks_ratio", "ks_N_per_m"}:
        raise ConfigError("[contact]: missing key 'ks_ratio' (or 'ks_N_per_m'): the contact stiffness")
    _positive(c.ks_ratio, "[contact] ks_ratio")
    _positive(c.ks_N_per_m, "[contact] ks_N_per_m")
    _positive(c.k_ref_N_per_m, "[contact] k_ref_N_per_m")
    # the resolved contact stiffness enters ke = k_s + 2 c / dt and the contact matrix: it must stay finite
    for key, ratio in [("[contact] ks_ratio", c.ks_ratio)] + [("[sweep] ks_ratio", v) for v in axes.get("ks_ratio", ())]:
        if ratio is not None and not math.isfinite(4.0 * ratio * c.k_ref_N_per_m):
            raise ConfigError(f"{key} = {ratio!r} with [contact] k_ref_N_per_m = {c.k_ref_N_per_m!r}: k_s = ratio k_ref "
                              "overflows (is k_ref in N/m?)")
    for key, ks in [("[contact] ks_N_per_m", c.ks_N_per_m)] + [("[sweep] ks_N_per_m", v) for v in axes.get("ks_N_per_m", ())]:
        if ks is not None and not math.isfinite(4.0 * ks):
            raise ConfigError(f"{key} = {ks!r}: too large (the contact terms overflow)")
    for k in ("ks_ratio", "ks_N_per_m", "amplitude_m", "frequency_Hz", "scale"):
        for v in axes.get(k, ()):
            _positive(v, f"[sweep] {k}")
    if c.gap_m < 0:
        raise ConfigError(f"[contact] gap_m = {c.gap_m!r}: must be >= 0")
    for v in axes.get("gap_m", ()):
        if v < 0:
            raise ConfigError(f"[sweep] gap_m = {v!r}: must be >= 0")
    from pounding_sweep.model.contact import CONTACT_LAWS
    from pounding_sweep.engine.scalar import SCHEMES

    if c.law not in CONTACT_LAWS:
        raise ConfigError(f"[contact] law = {c.law!r}: expected one of {sorted(CONTACT_LAWS)}")
    e = s.excitation
    if e.type not in ("harmonic", "record"):
        raise ConfigError(f"[excitation] type = {e.type!r}: expected 'harmonic' or 'record'")
    if e.type == "harmonic":
        for k in ("amplitude_m", "frequency_Hz", "duration_s"):
            if getattr(e, k) is None and k not in axes:
                raise ConfigError(f"[excitation] missing key '{k}' for a harmonic excitation")
            _positive(getattr(e, k), f"[excitation] {k}")
        if "record" in axes or e.record is not None:
            raise ConfigError("[excitation] record: only for a record excitation (type = 'record')")
    else:
        if e.record is None and "record" not in axes:
            raise ConfigError("[excitation] missing key 'record' (path of the .AT2 or .csv file)")
        for k in ("amplitude_m", "frequency_Hz"):
            if getattr(e, k) is not None or k in axes:
                raise ConfigError(f"[excitation] {k}: only for a harmonic excitation")
        _positive(e.duration_s, "[excitation] duration_s")
    _positive(e.scale, "[excitation] scale")
    _positive(e.length_scale, "[excitation] length_scale")
    if e.format not in ("auto", "at2", "csv"):
        raise ConfigError(f"[excitation] format = {e.format!r}: expected 'auto', 'at2' or 'csv'")
    if e.units is not None:
        from pounding_sweep.model.records import _ACCEPTED_UNITS, _UNIT_ALIASES

        if e.units.strip().lower().replace(" ", "") not in _UNIT_ALIASES:
            raise ConfigError(f"[excitation] units = {e.units!r}: expected one of {_ACCEPTED_UNITS}")
    i = s.integration
    if isinstance(i.dt_s, str):
        if i.dt_s != "auto":
            raise ConfigError(f"[integration] dt_s = {i.dt_s!r}: expected a time step in seconds or 'auto'")
        _positive(i.dt_tolerance, "[integration] dt_tolerance")
        _positive(i.dt_min_s, "[integration] dt_min_s")
        if not i.dt_max_s > i.dt_min_s:
            raise ConfigError(f"[integration] dt_max_s = {i.dt_max_s!r}: must be larger than dt_min_s = {i.dt_min_s!r}")
        if s.output.histories:
            raise ConfigError("[output] histories need one time step for all runs: give [integration] dt_s a number "
                              "(not 'auto'), e.g. the dt_s an 'auto' sweep chose")
    else:
        _positive(i.dt_s, "[integration] dt_s")
    if i.scheme not in SCHEMES:
        raise ConfigError(f"[integration] scheme = {i.scheme!r}: expected one of {sorted(SCHEMES)}")
    _positive(i.max_contact_iterations, "[integration] max_contact_iterations")
    if i.min_steps_per_contact_period < 0:
        raise ConfigError(f"[integration] min_steps_per_contact_period = {i.min_steps_per_contact_period!r}: must be >= 0")
    if e.type == "harmonic" and e.duration_s is not None and i.first_dt_s >= e.duration_s:
        raise ConfigError(f"[integration] dt_s = {i.first_dt_s!r}: must be shorter than [excitation] duration_s = {e.duration_s!r}")
    if e.type == "harmonic" and e.duration_s is not None and e.duration_s / i.first_dt_s > MAX_STEPS:
        raise ConfigError(f"[integration] {'dt_max_s' if i.auto else 'dt_s'} = {i.first_dt_s!r}: {e.duration_s / i.first_dt_s:.3g} "
                          f"steps over [excitation] duration_s = {e.duration_s!r}, more than {MAX_STEPS:,} (dt in the wrong units?)")
    _positive(s.output.history_decimate, "[output] history_decimate")
    from pounding_sweep.scene.channels import parse_channel

    for ch in s.output.histories:
        parse_channel(ch, (len(s.building1.masses_kg), len(s.building2.masses_kg)))
    if s.execution.threads < 0:
        raise ConfigError(f"[execution] threads = {s.execution.threads}: must be >= 0")
    if s.execution.batch_runs < 0:
        raise ConfigError(f"[execution] batch_runs = {s.execution.batch_runs}: must be >= 0")
    if s.execution.executor not in EXECUTORS:
        raise ConfigError(f"[execution] executor = {s.execution.executor!r}: expected one of {list(EXECUTORS)}")
    if s.execution.dask_workers < 0:
        raise ConfigError(f"[execution] dask_workers = {s.execution.dask_workers}: must be >= 0")
    if s.execution.max_runs < 1:
        raise ConfigError(f"[execution] max_runs = {s.execution.max_runs}: must be >= 1")
    if s.execution.chunk_runs < 1:
        raise ConfigError(f"[execution] chunk_runs = {s.execution.chunk_runs}: must be >= 1")
    if s.experiment is not None:
        _validate_experiment(s)
    n = 1
    for a in s.sweep:
        n *= len(a.values)
    if n > MAX_GRID:
        raise ConfigError(f"[sweep]: {n} grid points exceed the limit of {MAX_GRID}")


def _check_story_stiffness(b: BuildingConfig, bname: str, n: int) -> None:
    """Each story's stiffness, as the model forms it (k = n_columns 12 EI / h^3 from columns), must be a
    positive number whose stiffness matrix (2 k on the diagonal) stays finite: 1e308 N/m, or an EI and
    h that overflow, would otherwise end in the model's arithmetic."""
    if b.story_stiffness_N_per_m is not None:
        for k in b.story_stiffness_N_per_m:
            if not math.isfinite(2.0 * k):
                raise ConfigError(f"[{bname}] story_stiffness_N_per_m = {k!r}: too large (the stiffness matrix overflows)")
        return
    ei, h = (v if len(v) == n else v * n for v in (b.column_EI_Nm2, b.story_height_m))
    for e, hh in zip(ei, h):
        try:
            k = b.n_columns * 12.0 * e / hh**3
        except OverflowError:  # h^3 beyond the largest float
            k = 0.0
        except ZeroDivisionError:  # h^3 below the smallest
            k = math.inf
        if not (k > 0 and math.isfinite(2.0 * k)):
            raise ConfigError(f"[{bname}] column_EI_Nm2 = {e!r}, n_columns = {b.n_columns}, story_height_m = {hh!r}: "
                              f"k = n_columns 12 EI / h^3 = {k!r} N/m, not a usable story stiffness")


def _validate_experiment(s: Scene) -> None:
    x = s.experiment
    if (x.table is None) == (x.video is None):
        raise ConfigError("[experiment]: give either table = '...' (a tracked-displacement table) or an "
                          "[experiment.video] section (a video to track), not " + ("both" if x.table else "neither"))
    if x.video is not None and x.units != "mm":
        raise ConfigError(f"[experiment] units = {x.units!r}: a tracked video gives millimetres; use 'mm'")
    if not x.channels:
        raise ConfigError("[experiment] channels: map at least one table column to a floor, e.g. "
                          "channels = { model1_floor3_mm = 'b1f3' }")
    if x.units not in ("mm", "m"):
        raise ConfigError(f"[experiment] units = {x.units!r}: expected 'mm' or 'm'")
    if x.combine not in ("mean", "max", "rms"):
        raise ConfigError(f"[experiment] combine = {x.combine!r}: expected 'mean', 'max' or 'rms'")
    if x.window_s is not None and (len(x.window_s) != 2 or not x.window_s[0] < x.window_s[1]):
        raise ConfigError(f"[experiment] window_s = {list(x.window_s)}: expected [start, end] with start < end")
    if x.max_lag_s < 0:
        raise ConfigError(f"[experiment] max_lag_s = {x.max_lag_s!r}: must be >= 0")
    _positive(x.refine_max_evals, "[experiment] refine_max_evals")
    from pounding_sweep.scene.channels import floor_dof

    floors = (len(s.building1.masses_kg), len(s.building2.masses_kg))
    seen = {}
    for col, target in x.channels.items():
        floor_dof(target, floors, f"[experiment] channels.{col}")
        if target in seen:
            raise ConfigError(f"[experiment] channels: '{seen[target]}' and '{col}' both map to floor '{target}'")
        seen[target] = col


def _check_r(r, key):
    if not 0.0 <= r <= 1.0:
        raise ConfigError(f"{key} = {r!r}: the coefficient of restitution must lie in [0, 1]")


def describe() -> str:
    """Every section and key with its meaning: the reference for writing scenes."""
    lines = []
    for name, cls in {**SECTIONS, "experiment": ExperimentConfig}.items():
        lines.append(f"[{name}]  {cls.__doc__}")
        for f in dataclasses.fields(cls):
            default = "" if f.default is dataclasses.MISSING else f" (default {f.default!r})"
            lines.append(f"  {f.name}: {f.metadata['doc']}{default}")
    lines.append("[sweep]  axes: " + ", ".join(SWEEPABLE) + "; a list of values or {start, stop, num, spacing = 'linear'|'log'}")
    return "\n".join(lines)
