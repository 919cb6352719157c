"""TOML -> a Scene: keys checked (did-you-mean for unknown ones), values coerced to the field types,
relative paths resolved against the scene file, then validated (scene/validate.py). Every error is one
ConfigError naming the file, the key and the value."""

from __future__ import annotations

import dataclasses
import math
import tomllib
import types
import typing
from pathlib import Path

from pounding_sweep import codes
from pounding_sweep.errors import ConfigError, shown
from pounding_sweep.scene.axes import SWEEPABLE
from pounding_sweep.scene.files import MAX_SCENE_BYTES, read_regular, resolve, text_problem
from pounding_sweep.scene.keys import check_keys
from pounding_sweep.scene.risk import RiskConfig
from pounding_sweep.scene.schema import (
    ACC_UNITS,
    MAX_AXIS_VALUES,
    SECTIONS,
    TOP_KEYS,
    Axis,
    BuildingConfig,
    CalibrateConfig,
    ExperimentConfig,
    Scene,
)
from pounding_sweep.scene.stochastic import StochasticConfig
from pounding_sweep.scene.validate import one_storey_damping_modes, validate


def load_scene(path: str | Path) -> Scene:
    """Read, resolve and validate a scene file; raise ConfigError naming file, key and value."""
    path = Path(path)
    data = read_regular(path, "scene file", MAX_SCENE_BYTES, ConfigError)
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as e:
        why = text_problem(path, "scene file", data)
        raise ConfigError(why or f"{path}: not UTF-8 text ({e.reason} at byte {e.start})") from None
    if (why := text_problem(path, "scene file", data)) is not None:
        raise ConfigError(why)
    try:
        raw = tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise ConfigError(f"{path}: TOML syntax error: {e}{_toml_line(text, str(e))}") from None
    except RecursionError:  # tomllib recurses once per level of nested arrays and inline tables
        raise ConfigError(f"{path}: TOML nested too deeply (arrays or inline tables inside each other)") from None
    if _depth(raw) > MAX_NESTING:
        raise ConfigError(
            f"{path}: TOML nested more than {MAX_NESTING} levels deep (arrays or tables inside each other)"
        )
    try:
        return scene_from_dict(raw, base_dir=resolve(path).parent, source=str(path), toml_text=text)
    except ConfigError as e:
        raise ConfigError(f"{path}: {e}") from None


MAX_NESTING = 8  # the deepest a scene goes is 5: the file, [experiment], [experiment.video], marker positions, [x, y]


def _depth(value, level: int = 0) -> int:
    """How deeply tables and arrays nest (the top table is level 1), without recursion."""
    deepest, todo = level, [(value, 1)]
    while todo:
        v, d = todo.pop()
        if isinstance(v, dict | list):
            deepest = max(deepest, d)
            if d <= MAX_NESTING:  # deeper is refused anyway: no need to walk it all
                todo.extend((x, d + 1) for x in (v.values() if isinstance(v, dict) else v))
    return deepest


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


def _single_building(raw: dict) -> bool:
    """A scene of one building: neither [building2] nor [contact]. Either without the other is refused: a
    [contact] has nothing to touch without a second building, and two buildings need their contact."""
    has2, hasc = "building2" in raw, "contact" in raw
    if has2 and not hasc:
        raise ConfigError("missing section [contact]: two buildings need their contact (or leave out [building2])")
    if hasc and not has2:
        raise ConfigError(
            "[contact] without [building2]: one building has nothing to touch; add [building2], or leave out "
            "[contact] for a single-building scene"
        )
    return not has2


def scene_from_dict(raw: dict, base_dir: Path, source: str = "<dict>", toml_text: str = "") -> Scene:
    """Build a Scene from parsed TOML (keys checked, types coerced, values validated)."""
    check_keys(raw, TOP_KEYS, "top level")
    for req in ("building1", "excitation"):
        if req not in raw:
            raise ConfigError(f"missing section [{req}]")
    single = _single_building(raw)
    sections = {}
    for name, cls in SECTIONS.items():
        if single and name in ("building2", "contact"):
            sections[name] = None
            continue
        table = raw.get(name, {})
        if not isinstance(table, dict):
            raise ConfigError(f"'{name}' must be a table [{name}], got {type(table).__name__} {shown(table)}")
        sections[name] = _build(cls, table, name)
        if cls is BuildingConfig and len(sections[name].masses_kg) == 1 and "damping_modes" in table:
            raise ConfigError(one_storey_damping_modes(name, sections[name].damping_modes))  # given, even as [1, 2]
    name = _typed(raw.get("name", Path(source).stem), str, "name")
    if not name or any(c in name for c in "/\\\x00") or name in (".", ".."):
        raise ConfigError(
            f"name = {shown(name)}: a scene name is also the default output file name; "
            "use letters, digits, '-', '_' or '.', no path separators"
        )
    desc = _typed(raw.get("description", ""), str, "description")
    exc = sections["excitation"]
    if exc.record is not None:
        sections["excitation"] = dataclasses.replace(exc, record=str(resolve(base_dir / exc.record)))
    out = sections["output"]
    out_path = out.path or f"results/{name}.parquet"
    sections["output"] = dataclasses.replace(out, path=str(resolve(base_dir / out_path)))
    sweep = _parse_sweep(raw.get("sweep", {}), base_dir)
    experiment = None
    if "experiment" in raw:
        if not isinstance(raw["experiment"], dict):
            raise ConfigError(f"'experiment' must be a table [experiment], got {shown(raw['experiment'])}")
        xraw = dict(raw["experiment"])
        video = xraw.pop("video", None)
        experiment = _build(ExperimentConfig, xraw, "experiment")
        if video is not None:
            from pounding_sweep.scene.video import parse_video_section  # no OpenCV import: tracking imports it lazily

            spec = parse_video_section(video, base_dir)
            experiment = dataclasses.replace(
                experiment, video=spec, channels=experiment.channels or spec.default_channels()
            )
        if experiment.table is not None:
            experiment = dataclasses.replace(experiment, table=str(resolve(base_dir / experiment.table)))
        acc_units = codes.canonical_unit(experiment.acc_units)
        if acc_units in ACC_UNITS:  # one spelling inside ('m/s^2' as the import prints it is 'm/s2')
            experiment = dataclasses.replace(experiment, acc_units=acc_units)
    calibrate = None
    if "calibrate" in raw:
        if not isinstance(raw["calibrate"], dict):
            raise ConfigError(f"'calibrate' must be a table [calibrate], got {shown(raw['calibrate'])}")
        calibrate = _build(CalibrateConfig, raw["calibrate"], "calibrate")
        if calibrate.start_from is not None:  # identify's modes file, beside the scene
            calibrate = dataclasses.replace(calibrate, start_from=str(resolve(base_dir / calibrate.start_from)))
    stochastic = _section(raw, "stochastic", StochasticConfig)
    risk = _section(raw, "risk", RiskConfig)
    if risk is not None:
        out_risk = risk.path or f"results/{name}.risk"
        hazard = str(resolve(base_dir / risk.hazard)) if risk.hazard is not None else None
        risk = dataclasses.replace(risk, path=str(resolve(base_dir / out_risk)), hazard=hazard)
    scene = Scene(
        name=name,
        description=desc,
        sweep=sweep,
        source=source,
        toml_text=toml_text,
        experiment=experiment,
        calibrate=calibrate,
        stochastic=stochastic,
        risk=risk,
        **sections,
    )
    validate(scene)
    return scene


def _section(raw: dict, name: str, cls):
    """An optional section [name] built as cls, or None."""
    if name not in raw:
        return None
    if not isinstance(raw[name], dict):
        raise ConfigError(f"'{name}' must be a table [{name}], got {shown(raw[name])}")
    return _build(cls, raw[name], name)


def _build(cls, table: dict, section: str):
    fields = {f.name: f for f in dataclasses.fields(cls)}
    check_keys(table, fields, f"[{section}]")
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
    if origin is dict:  # a table of name = value of the value type (the names are the caller's to check)
        if not isinstance(value, dict) or not value:
            raise ConfigError(f"{key} = {shown(value)}: expected a non-empty table of name = value")
        vtype = typing.get_args(hint)[1]
        return {str(k): _coerce(v, vtype, f"{key}.{k}") for k, v in value.items()}
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
            raise ConfigError(f"{key} = {shown(value)}: expected true or false")
        return value
    if typ is dict:
        if not isinstance(value, dict) or not value:
            raise ConfigError(f"{key} = {shown(value)}: expected a non-empty table of name = value")
        return {str(k): _typed(v, str, f"{key}.{k}") for k, v in value.items()}
    if typ is float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ConfigError(f"{key} = {shown(value)}: expected a number")
        value = float(value)
        if not math.isfinite(value):
            raise ConfigError(f"{key} = {shown(value)}: must be finite")
        return value
    if typ is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise ConfigError(f"{key} = {shown(value)}: expected an integer")
        return value
    if typ is str:
        if not isinstance(value, str):
            raise ConfigError(f"{key} = {shown(value)}: expected a string")
        if "\x00" in value:
            raise ConfigError(f"{key} = {shown(value)}: contains a NUL character")
        return value
    raise TypeError(typ)  # pragma: no cover - a field type the loader does not know


def _parse_sweep(table, base_dir: Path) -> tuple[Axis, ...]:
    if not isinstance(table, dict):
        raise ConfigError(f"'sweep' must be a table [sweep], got {shown(table)}")
    check_keys(table, SWEEPABLE, "[sweep]")
    axes = []
    for name, spec in table.items():
        key = f"[sweep] {name}"
        if name == "record":
            vals = spec if isinstance(spec, list) else [spec]
            if not vals:
                raise ConfigError(f"{key} = []: an axis needs at least one value")
            vals = tuple(str(resolve(base_dir / _typed(v, str, key))) for v in vals)
        elif name == "law":
            vals = spec if isinstance(spec, list) else [spec]
            if not vals:
                raise ConfigError(f"{key} = []: an axis needs at least one value")
            vals = tuple(_typed(v, str, key) for v in vals)
        elif isinstance(spec, dict):
            vals = _range_values(spec, key)
        else:
            vals = _coerce(spec, tuple[float, ...], key)
        if len(set(vals)) != len(vals):
            raise ConfigError(f"{key} = {shown(list(vals))}: repeated values")
        axes.append(Axis(name, vals))
    return tuple(axes)


def _range_values(spec: dict, key: str) -> tuple[float, ...]:
    import numpy as np

    check_keys(spec, {"start", "stop", "num", "spacing"}, key)
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
    raise ConfigError(f"{key}.spacing = {shown(spacing)}: expected 'linear' or 'log'")
