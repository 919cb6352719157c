"""Scenes of the risk tests: the shipped stochastic study's full-scale models, made small (risk.study.resized)."""

from __future__ import annotations

import dataclasses

from conftest import SWEEPS

from pounding_sweep.risk.study import resized
from pounding_sweep.scene import load_scene


def stochastic_scene(
    seeds: int = 40,
    levels=(0.2, 0.4, 0.8),
    duration_s: float = 8.0,
    filter: str | None = None,
    envelope: bool = True,
    risk=None,
    folder=None,
    chunk_runs: int = 64,
):
    """sweeps/risk_stochastic.toml with fewer motions, levels and seconds (and a Kanai-Tajimi or stationary
    variant on request); the study folder in `folder`."""
    r = dict(risk or {})
    if folder is not None:
        r["path"] = str(folder)
    s = resized(load_scene(SWEEPS / "risk_stochastic.toml"), seeds, levels, duration_s, filter, not envelope, **r)
    return dataclasses.replace(s, execution=dataclasses.replace(s.execution, chunk_runs=chunk_runs))
