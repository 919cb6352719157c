"""Scenes of the risk tests: the shipped stochastic study's full-scale models, made small."""

from __future__ import annotations

import dataclasses

from conftest import SWEEPS

from pounding_sweep.scene import Axis, load_scene


def stochastic_scene(
    seeds: int = 40,
    levels=(0.2, 0.4, 0.8),
    duration_s: float = 8.0,
    filter: str = "clough_penzien",
    envelope: bool = True,
    damping=None,
    risk=None,
    folder=None,
    chunk_runs: int = 64,
):
    """sweeps/risk_stochastic.toml with fewer motions, levels and seconds (and a Kanai-Tajimi or stationary
    variant on request); the study folder in `folder`."""
    s = load_scene(SWEEPS / "risk_stochastic.toml")
    st = s.stochastic
    if filter == "kanai_tajimi":
        st = dataclasses.replace(st, filter=filter, highpass_frequency_Hz=None, highpass_damping=None)
    if not envelope:
        st = dataclasses.replace(st, envelope="none", rise_s=None, strong_end_s=None, decay_per_s=None)
    b1, b2 = s.building1, s.building2
    if damping is not None:
        b1, b2 = dataclasses.replace(b1, damping_ratio=damping), dataclasses.replace(b2, damping_ratio=damping)
    r = s.risk
    if folder is not None:
        r = dataclasses.replace(r, path=str(folder))
    if risk is not None:
        r = dataclasses.replace(r, **risk)
    return dataclasses.replace(
        s,
        building1=b1,
        building2=b2,
        stochastic=st,
        excitation=dataclasses.replace(s.excitation, duration_s=duration_s),
        sweep=(Axis("seed", tuple(float(i) for i in range(seeds))), Axis("scale", tuple(levels))),
        risk=r,
        execution=dataclasses.replace(s.execution, chunk_runs=chunk_runs),
    )
