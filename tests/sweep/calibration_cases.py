"""Scored scenes the calibration tests share: the paper's 6 Hz test, cut short, against an experiment the engine
made with the scene's own structure and discretisation (no model error)."""

from __future__ import annotations

import dataclasses

from conftest import SWEEPS

from pounding_sweep.scene import load_scene
from pounding_sweep.scene.schema import CalibrateConfig, ExperimentConfig
from pounding_sweep.synthetic import make_experiment, write_experiment

TOP_FLOORS = {"model1_floor3_mm": "b1f3", "model2_floor3_mm": "b2f3"}


def exact_6hz(tmp_path, seed: int, duration_s: float = 1.5, hidden=None, **cal):
    """The 6 Hz scene (`duration_s`) scored against its own run at the hidden values (default k_s/k 3, r 0.5) plus
    0.05 mm of white noise (`seed`) on the top floors; with `cal`, a [calibrate] of those keywords."""
    s = load_scene(SWEEPS / "paper_6hz.toml")
    s = dataclasses.replace(s, sweep=(), excitation=dataclasses.replace(s.excitation, duration_s=duration_s))
    hidden = hidden or {"ks_ratio": 3.0, "r": 0.5}
    df, prov = make_experiment(s, hidden, stiffness_factor=(1.0, 1.0), damping_factor=(1.0, 1.0), dt_s=1e-4, seed=seed)
    path = tmp_path / f"exact{seed}.parquet"
    write_experiment(df, prov, path)
    exp = ExperimentConfig(table=str(path), channels=TOP_FLOORS)
    return dataclasses.replace(s, experiment=exp, calibrate=CalibrateConfig(**cal) if cal else None)
