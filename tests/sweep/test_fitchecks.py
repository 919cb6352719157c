"""A channel reversed against the model is named at the fit (sweep/fitchecks.py; issue 27 item 2), and a
right-signed channel with model error (a scaled or lagged response) is not."""

from __future__ import annotations

import dataclasses
import re
import warnings

import numpy as np
import pandas as pd
import pytest
from calibration_cases import exact_6hz

from pounding_sweep.scene.schema import ExperimentConfig
from pounding_sweep.sweep.calibrate import calibrate
from pounding_sweep.sweep.fitchecks import correlation

T = np.linspace(0.0, 2.0, 2001)
MODEL = np.sin(2 * np.pi * 6.0 * T) + 0.3 * np.sin(2 * np.pi * 17.0 * T)


def test_correlation_of_constant_and_negated_series():
    assert correlation(MODEL, np.zeros_like(T)) == 0.0  # a dead channel has no sign to doubt
    assert correlation(MODEL, -2.0 * MODEL) == pytest.approx(-1.0, abs=1e-12)  # rounding of a 2001-term sum


def _names_reversed(fit, code):
    return [w for w in fit.warnings if "looks reversed" in w and f"channel {code} " in w]


def test_the_calibration_names_the_reversed_channel(tmp_path):
    """The 6 Hz test scored against its own run (no model error), once as made and once with building 2's top
    floor negated: only the negated channel is named (building 1's, right-signed beside it, misfits as much: negated
    it fits worse), and negated back the fit finds the hidden values."""
    bounds = {"ks_ratio": [0.1, 20.0], "r": [0.05, 1.0]}
    scene = exact_6hz(tmp_path, 3, parameters=bounds, global_points=8, profile_points=0, noise_m=5e-5)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        clean = calibrate(scene, 2)[0]
        table = pd.read_parquet(scene.experiment.table)
        table["model2_floor3_mm"] = -table["model2_floor3_mm"]
        damaged = tmp_path / "reversed.parquet"
        table.to_parquet(damaged)
        exp = ExperimentConfig(table=str(damaged), channels=scene.experiment.channels)
        bad = calibrate(dataclasses.replace(scene, experiment=exp), 2)[0]
    assert not [w for w in clean.warnings if "looks reversed" in w]
    assert bad.misfit_ratio > 10.0 and not _names_reversed(bad, "b1f3")
    (named,) = _names_reversed(bad, "b2f3")
    for n in ("ks_ratio", "r"):  # negated back, the fit is the clean one's: within 4 of its standard errors
        shown = float(re.search(rf"\b{n} ([0-9.eE+-]+)", named).group(1))  # (plus the 4 digits shown)
        assert abs(shown - clean.estimate[n]) < 4 * clean.std_error[n] + 5e-4 * abs(shown), (n, shown)
