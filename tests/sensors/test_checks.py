"""The checks that name a sensor's problem (model/sensors/checks.py, model/experiment.py, model/records.py): each
fires on a deliberately damaged copy of a table (gravity kept, one channel reversed, one delayed 40 ms, time in
us) and stays silent on the clean one: on a known test made here and on the real IMU tests in ../shared."""

from __future__ import annotations

import sys
import warnings
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from conftest import SHARED

sys.path.insert(0, str(Path(__file__).parent))
from synthetic_xsens import FINE, RATE, shear_frame_test  # noqa: E402

from pounding_sweep.errors import ExperimentError  # noqa: E402
from pounding_sweep.model.experiment import experiment_from_table  # noqa: E402
from pounding_sweep.model.records import GroundRecord, implausible_timing  # noqa: E402
from pounding_sweep.model.sensors.checks import aliasing_problems, offset_problem, record_problem  # noqa: E402
from pounding_sweep.scene.schema import ExperimentConfig  # noqa: E402

CFG = ExperimentConfig(table="t.csv", channels={f"b1f{k}_acc_m_s2": f"abs_acc_b1f{k}" for k in (1, 2, 3)})
G = 9.80665
IMU = SHARED / "data" / "imu_shake_table" / "stiff_3story"


def _clean_synthetic() -> pd.DataFrame:
    tr = shear_frame_test()
    rng = np.random.default_rng(5)
    cols = {
        f"b1f{k}_acc_m_s2": tr.acc[f"b1f{k}"][::FINE] + rng.normal(0, 0.01, tr.fine_t[::FINE].size) for k in (1, 2, 3)
    }
    return pd.DataFrame({"t_s": np.arange(tr.fine_t[::FINE].size) / RATE, **cols})


def _clean_real(test: str) -> pd.DataFrame:
    if not IMU.is_dir():
        pytest.skip(f"{IMU} not present: the real IMU tests need ../shared beside the repo")
    from pounding_sweep.model.sensors.assemble import import_sensors

    files = {"ground": IMU / test / "ground.csv", **{f"b1f{k}": IMU / test / f"floor{k}.csv" for k in (1, 2, 3)}}
    im = import_sensors({n: str(p) for n, p in files.items()}, "ground")
    return pd.DataFrame({"t_s": im.time_s, **{c: v for c, v in im.columns.items() if c != "ground_acc_m_s2"}})


def _messages(df: pd.DataFrame) -> list[str]:
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        experiment_from_table(df, {}, "t.csv", CFG, (3, 3))
    return [str(w.message) for w in caught]


def _damaged(df: pd.DataFrame, how: str) -> pd.DataFrame:
    d = df.copy()
    fs = 1 / float(np.median(np.diff(d["t_s"])))
    if how == "gravity":
        d["b1f1_acc_m_s2"] += G
    elif how == "reversed":
        d["b1f2_acc_m_s2"] *= -1
    elif how == "delayed":
        k = int(round(0.040 * fs))
        x = d["b1f3_acc_m_s2"].to_numpy()
        d["b1f3_acc_m_s2"] = np.concatenate([np.zeros(k), x[:-k]])
    elif how == "us":
        d["t_s"] *= 1e6
    return d


@pytest.fixture(scope="module", params=["synthetic", "northridge", "bonus_event"])
def clean(request):
    return _clean_synthetic() if request.param == "synthetic" else _clean_real(request.param)


def test_the_clean_table_raises_no_warning(clean):
    assert _messages(clean) == []


def test_gravity_kept_is_named_with_its_channel_and_fix(clean):
    (w,) = _messages(_damaged(clean, "gravity"))
    assert "column 'b1f1_acc_m_s2' (abs_acc_b1f1): mean 9.8" in w and "about +g: gravity is in it" in w
    assert "subtract the mean of a quiet window" in w


def test_a_reversed_channel_is_named_once(clean):
    (w,) = _messages(_damaged(clean, "reversed"))
    assert "column 'b1f2_acc_m_s2' (abs_acc_b1f2): reversed against 'b1f1_acc_m_s2'" in w
    assert "multiply the column by -1" in w


def test_a_channel_delayed_40_ms_is_named_with_its_lag(clean):
    (w,) = _messages(_damaged(clean, "delayed"))
    assert "column 'b1f3_acc_m_s2' (abs_acc_b1f3): lags 'b1f2_acc_m_s2'" in w
    lag_ms = float(w.split(" by ")[1].split(" ms")[0])
    fs = 1 / float(np.median(np.diff(clean["t_s"])))
    # the delay is 40 ms rounded to a sample; the floors' own delay in the band where they move together is
    # below 1.5 samples (checks.pair_problems' bound): the lag found within 1.5 samples of it
    assert lag_ms == pytest.approx(1e3 * round(0.040 * fs) / fs, abs=1.5e3 / fs)


def test_time_in_microseconds_is_one_error_naming_the_unit(clean):
    with pytest.raises(ExperimentError) as e:
        _messages(_damaged(clean, "us"))
    msg = str(e.value)
    assert (
        msg.startswith("t.csv: column 't_s' steps by ")
        and "is it in us?" in msg
        and "divide the column by 1e+06" in msg
    )


def test_the_offset_check_separates_an_offset_from_a_stretch_of_motion():
    """A truncated sine's mean is at most twice its peak velocity over its length (no warning); a constant offset
    of 1 % of its amplitude over 100 periods is 10 times more (a warning)."""
    dt, f = 0.001, 2.0
    t = np.arange(0, 50.25 / f, dt)  # a quarter period past 50 full ones: a mean as large as a cut sine has
    x = np.sin(2 * np.pi * f * t)
    assert offset_problem("x", x, dt) is None
    assert "sensor offset" in offset_problem("x", x + 0.05, dt)
    assert "gravity" in offset_problem("x", x + G, dt)
    rec = GroundRecord("r", "r.csv", dt, x + G)
    assert "r.csv (record): mean" in record_problem(rec) and "drives the model as read" in record_problem(rec)


def test_a_record_in_microseconds_is_named_as_such():
    rec = GroundRecord("r", "r.csv", 8333.0, np.sin(np.arange(100.0)))
    w = implausible_timing(rec)
    assert "is its time in us rather than s? (in us the step is 0.008333 s: divide the time column by 1e+06)" in w


def test_aliasing_names_the_building_and_the_folded_frequency():
    (w,) = aliasing_problems("t.csv", 100.0, {"building 1": [7.7, 21.7, 31.4], "building 2": [40.0, 60.0, 75.0]})
    assert "below building 2's modes: mode 2 at 60 Hz folds onto 40 Hz, mode 3 at 75 Hz folds onto 25 Hz" in w
