"""`python -m pounding_sweep --describe`: every section and key of a scene with its meaning, its default,
and whether it is required."""

from __future__ import annotations

import dataclasses

from pounding_sweep.scene.axes import SWEEPABLE
from pounding_sweep.scene.files import MAX_RECORD_BYTES, MAX_SCENE_BYTES, MAX_TABLE_BYTES, MiB
from pounding_sweep.scene.parse import MAX_NESTING
from pounding_sweep.scene.risk import RiskConfig
from pounding_sweep.scene.schema import (
    MAX_AXIS_VALUES,
    MAX_CALIBRATE_COUNTS,
    MAX_FLOORS,
    MAX_GRID,
    MAX_STEPS,
    MAX_THREADS,
    NOISE_M_RANGE,
    SECTIONS,
    CalibrateConfig,
    ExperimentConfig,
)
from pounding_sweep.scene.stochastic import StochasticConfig

MAX_EVENTS = 16  # engine.events.MAX_EVENTS: the scene layer loads no Numba (tests/scene checks they agree)

#: sections a scene must have (scene_from_dict refuses it without them)
REQUIRED_SECTIONS = ("building1", "excitation")
#: sections required together: a second building and the contact between the two (without both: one building)
PAIRED_SECTIONS = ("building2", "contact")
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
    optional = {"experiment": ExperimentConfig, "calibrate": CalibrateConfig, "stochastic": StochasticConfig}
    for name, cls in {**SECTIONS, **optional, "risk": RiskConfig}.items():
        need = (
            " (required section)"
            if name in REQUIRED_SECTIONS
            else " (required with the other of building2 and contact; without both: one building on its own)"
            if name in PAIRED_SECTIONS
            else " (optional section)"
        )
        lines.append(f"[{name}]{need}  {cls.__doc__}")
        for f in dataclasses.fields(cls):
            lines.append(f"  {f.name}: {f.metadata['doc']}{_default(f)}")
    lines.append(
        "[sweep] (optional section)  axes: "
        + ", ".join(SWEEPABLE)
        + "; a list of values or {start, stop, num, spacing = 'linear'|'log'}"
    )
    lines.append(LIMITS)
    return "\n".join(lines)


#: what the engine supports, and the sizes a scene may have (--describe prints it; the README lists it too)
LIMITS = f"""\
Limits  what the engine supports
  floors: at most {MAX_FLOORS:,} per building. The lane kernel (4 or 8 runs side by side; metrics only, event or
    implicit scheme) takes a model with 6 (N1 + N2) + min(N1, N2) <= 160, i.e. up to 12 + 12 floors; larger
    models, and every chunk with histories, scoring or the paper scheme, run on the scalar kernel, whose cost
    per step grows about as N^3.5 (about 2 minutes per 1 s run at 200 + 200 floors).
  contact switches: at most {MAX_EVENTS} are located within one step, for the whole model (all floor pairs
    together); a step with more keeps its last trial and the run is flagged contact_unsettled. Many pairs
    switching at once (tall buildings at gap 0: every 50-200-storey pair) reach it; a smaller dt_s lowers the
    switches per step. Flagged runs are not resolved: read them as such.
  grid: at most {MAX_GRID:,} runs ([execution] max_runs, default 2,000,000, without --yes), {MAX_AXIS_VALUES:,}
    values per axis; a run at most {MAX_STEPS:,} steps.
  files: each a regular file (not a FIFO or a device); a scene at most {MAX_SCENE_BYTES // MiB} MiB, its tables and
    arrays nested at most {MAX_NESTING} deep; a record at most {MAX_RECORD_BYTES // MiB} MiB and an experiment table
    {MAX_TABLE_BYTES // MiB // 1024} GiB, as UTF-8 or ASCII text where they are text (AT2, CSV).
  threads, Dask LocalCluster workers: at most {MAX_THREADS:,}.
  [calibrate]: {", ".join(f"{k} at most {v:,}" for k, v in MAX_CALIBRATE_COUNTS.items())};
    noise_m in [{NOISE_M_RANGE[0]:g}, {NOISE_M_RANGE[1]:g}] m."""
