"""dt = "auto" (issue 5): each run's dt chosen by step doubling, and the estimate is honest.

The check of honesty: for every run of a small grid, the error of the metrics at the chosen dt
against the same run at a much finer dt is within a small factor of the tolerance.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pandas as pd
import pytest
from conftest import SWEEPS

from pounding_sweep.scene import Axis, ConfigError, load_scene, validate
from pounding_sweep.sweep.run import run_scene
from pounding_sweep.sweep.simulate import simulate


def scene(tol=1e-3, dt_min=1e-6, duration=1.0, **integration):
    s = load_scene(SWEEPS / "paper_6hz.toml")
    return dataclasses.replace(
        s,
        excitation=dataclasses.replace(s.excitation, duration_s=duration),
        integration=dataclasses.replace(s.integration, dt_s="auto", dt_tolerance=tol, dt_min_s=dt_min, **integration),
        sweep=(Axis("ks_ratio", (0.1, 1.0, 10.0)), Axis("r", (0.2, 0.8))),
    )


def rel_err(df: pd.DataFrame, ref: pd.DataFrame) -> np.ndarray:
    """Per run: the largest error of the peak displacements and forces, relative to the largest of each kind."""
    out = np.zeros(len(df))
    for prefix in ("peak_disp_b", "peak_force_f"):
        cols = [c for c in df if c.startswith(prefix) and (c.endswith("_m") or c.endswith("_N"))]
        scale = ref[cols].abs().max(axis=1).to_numpy()
        out = np.maximum(out, (df[cols] - ref[cols]).abs().max(axis=1).to_numpy() / scale)
    return out


def test_auto_dt_meets_its_tolerance_against_a_fine_run(tmp_path):
    tol = 1e-3
    auto = pd.read_parquet(run_scene(scene(tol), out_path=tmp_path / "auto.parquet").path)
    fine_scene = dataclasses.replace(scene(), integration=dataclasses.replace(scene().integration, dt_s=1e-5))
    fine = pd.read_parquet(run_scene(fine_scene, out_path=tmp_path / "fine.parquet").path)
    actual = rel_err(auto, fine)
    print(
        "\n[auto dt] chosen",
        auto.dt_s.tolist(),
        "\n estimate",
        np.round(auto.dt_error_estimate, 6).tolist(),
        "\n actual  ",
        np.round(actual, 6).tolist(),
    )
    assert (auto.dt_error_estimate <= tol).all() and (auto.status == "ok").all()
    assert (actual <= 3 * tol).all()  # the estimate is of the right size, not wildly optimistic
    assert auto.dt_s.nunique() > 1  # it does adapt per run (stiffer contact needs smaller steps)
    assert auto.dt_s[auto.ks_ratio == 10.0].min() <= auto.dt_s[auto.ks_ratio == 0.1].min()


def test_a_tighter_tolerance_takes_smaller_steps(tmp_path):
    loose = pd.read_parquet(run_scene(scene(1e-2), out_path=tmp_path / "a.parquet").path)
    tight = pd.read_parquet(run_scene(scene(1e-4), out_path=tmp_path / "b.parquet").path)
    assert (tight.dt_s <= loose.dt_s).all() and (tight.dt_s < loose.dt_s).any()


def test_unreachable_tolerance_is_flagged(tmp_path):
    df = pd.read_parquet(run_scene(scene(1e-9, dt_min=5e-4), out_path=tmp_path / "o.parquet").path)
    assert df.status.str.contains("dt_tolerance_not_met").all()
    assert (df.dt_s == 5e-4).all() and (df.dt_error_estimate > 1e-9).all()


def test_simulate_with_auto_dt_keeps_histories_at_the_chosen_step():
    df, m = simulate(scene(1e-3), channels=["disp_b1f3"], ks_ratio=1.0, r=0.4)
    assert m["dt_error_estimate"] <= 1e-3
    assert np.diff(df.t_s.to_numpy())[0] == pytest.approx(m["dt_s"])


@pytest.mark.parametrize(
    "changes, message",
    [
        (dict(dt_s="fast"), r"dt_s = 'fast': expected a time step in seconds or 'auto'"),
        (dict(dt_s="auto", dt_max_s=1e-6, dt_min_s=1e-5), r"dt_max_s = 1e-06: must be larger than dt_min_s"),
        (dict(dt_s="auto", dt_tolerance=0.0), r"dt_tolerance"),
    ],
)
def test_bad_auto_settings_are_refused(changes, message):
    s = load_scene(SWEEPS / "paper_6hz.toml")
    with pytest.raises(ConfigError, match=message):
        validate(dataclasses.replace(s, integration=dataclasses.replace(s.integration, **changes)))


def test_auto_dt_with_histories_is_refused():
    s = load_scene(SWEEPS / "paper_6hz.toml")
    s = dataclasses.replace(
        s,
        integration=dataclasses.replace(s.integration, dt_s="auto"),
        output=dataclasses.replace(s.output, histories=("disp_b1f3",)),
    )
    with pytest.raises(ConfigError, match=r"histories need one time step"):
        validate(s)


def test_auto_dt_from_toml(tmp_path):
    text = (SWEEPS / "paper_6hz.toml").read_text().replace("dt_s = 1e-4", 'dt_s = "auto"\ndt_tolerance = 1e-3')
    f = tmp_path / "auto.toml"
    f.write_text(text)
    s = load_scene(f)
    assert s.integration.auto and s.integration.first_dt_s == 2e-3
