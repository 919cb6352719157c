"""`python -m pounding_sweep --describe`: every section and key of a scene with its meaning."""

from __future__ import annotations

import dataclasses

from pounding_sweep.scene.axes import SWEEPABLE
from pounding_sweep.scene.schema import SECTIONS, ExperimentConfig


def describe() -> str:
    """Every section and key with its meaning: the reference for writing scenes."""
    lines = []
    for name, cls in {**SECTIONS, "experiment": ExperimentConfig}.items():
        lines.append(f"[{name}]  {cls.__doc__}")
        for f in dataclasses.fields(cls):
            default = "" if f.default is dataclasses.MISSING else f" (default {f.default!r})"
            lines.append(f"  {f.name}: {f.metadata['doc']}{default}")
    lines.append(
        "[sweep]  axes: " + ", ".join(SWEEPABLE) + "; a list of values or {start, stop, num, spacing = 'linear'|'log'}"
    )
    return "\n".join(lines)
