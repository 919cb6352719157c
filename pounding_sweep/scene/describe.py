"""`python -m pounding_sweep --describe`: every section and key of a scene with its meaning, its default,
and whether it is required."""

from __future__ import annotations

import dataclasses

from pounding_sweep.scene.axes import SWEEPABLE
from pounding_sweep.scene.schema import SECTIONS, ExperimentConfig

#: sections a scene must have (scene_from_dict refuses it without them)
REQUIRED_SECTIONS = ("building1", "building2", "contact", "excitation")
TOP = (
    ("name", "the scene's name: the default output results/<name>.parquet and a label in outputs", "the file's name"),
    ("description", "free text about the scene, kept in the result metadata", "''"),
)


def _default(f: dataclasses.Field) -> str:
    """'(required)', '(default 0.4)', or what leaving a None-default key out means."""
    if f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING:
        return " (required)"
    when = f.metadata.get("when")
    if f.default is None:
        return f" ({when or 'optional'})"
    if when and when.startswith("default:"):
        return f" ({when})"
    value = f.default if f.default is not dataclasses.MISSING else f.default_factory()
    return f" (default {value!r}" + (f"; {when})" if when else ")")


def describe() -> str:
    """Every section and key with its meaning: the reference for writing scenes."""
    lines = ["(top level)  keys outside any section"]
    lines += [f"  {k}: {doc} (default {d})" for k, doc, d in TOP]
    for name, cls in {**SECTIONS, "experiment": ExperimentConfig}.items():
        need = " (required section)" if name in REQUIRED_SECTIONS else " (optional section)"
        lines.append(f"[{name}]{need}  {cls.__doc__}")
        for f in dataclasses.fields(cls):
            lines.append(f"  {f.name}: {f.metadata['doc']}{_default(f)}")
    lines.append(
        "[sweep] (optional section)  axes: "
        + ", ".join(SWEEPABLE)
        + "; a list of values or {start, stop, num, spacing = 'linear'|'log'}"
    )
    return "\n".join(lines)
