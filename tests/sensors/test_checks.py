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
    assert "column 'b1f2_acc_m_s2' (abs_acc_b1f2): reversed against the other floors of its building" in w
    assert "multiply the column by -1" in w
    # the lowest floor reversed is named too (the majority of the building decides, not the floor below)
    d = clean.copy()
    d["b1f1_acc_m_s2"] *= -1
    (w,) = _messages(d)
    assert "column 'b1f1_acc_m_s2' (abs_acc_b1f1): reversed against the other floors" in w


def test_two_channels_reversed_against_each_other_are_named_as_a_pair(clean):
    d = clean.drop(columns="b1f3_acc_m_s2")
    d["b1f2_acc_m_s2"] *= -1
    cfg = ExperimentConfig(table="t.csv", channels={f"b1f{k}_acc_m_s2": f"abs_acc_b1f{k}" for k in (1, 2)})
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        experiment_from_table(d, {}, "t.csv", cfg, (3, 3))
    (w,) = [str(c.message) for c in caught]
    assert "(abs_acc_b1f2): reversed against t.csv: column 'b1f1_acc_m_s2'" in w and "cannot tell which" in w


def test_a_channel_delayed_40_ms_is_named_with_its_lag(clean):
    (w,) = _messages(_damaged(clean, "delayed"))
    assert "column 'b1f3_acc_m_s2' (abs_acc_b1f3): lags the other floors of its building by +" in w
    lag_ms = float(w.split(" building by ")[1].split(" ms")[0])
    fs = 1 / float(np.median(np.diff(clean["t_s"])))
    # the delay is 40 ms rounded to a sample; the floors' own delay in the band where they move together is
    # below 1.5 samples (checks.consensus_problems' bound): the lag found within 1.5 samples of it
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


SCENE = """name = "imu_check"
building1 = { masses_kg = [0.142, 0.142, 0.142], story_stiffness_N_per_m = 1700.0, damping_ratio = 0.01 }
building2 = { masses_kg = [0.01], story_stiffness_N_per_m = 1e5, damping_ratio = 0.01 }
contact = { gap_m = 1.0, r = 0.5, ks_ratio = 1.0 }
excitation = { type = "record", record = "imp/record.csv", units = "m/s2" }
integration = { dt_s = 1e-3 }
output = { path = "out.parquet" }
experiment = { table = "{table}", acc_units = "m/s2", channels = { b1f1_acc_m_s2 = "abs_acc_b1f1", \
b1f2_acc_m_s2 = "abs_acc_b1f2", b1f3_acc_m_s2 = "abs_acc_b1f3" } }
"""


def test_at_the_sweep_the_lowest_floor_is_checked_against_the_record_and_the_rate_against_the_modes(tmp_path):
    """A scene driven by an import's record and scored against its table: clean, nothing; floor 1 reversed,
    named against the record (and by its building); the table decimated to 30 samples/s, building 1's modes 2
    and 3 named as aliased (building 2 has no channel: its modes do not matter)."""
    from synthetic_xsens import write_sensor

    from pounding_sweep.cli.run import main
    from pounding_sweep.scene import load_scene
    from pounding_sweep.sweep.prepare import prepare

    tr = shear_frame_test(duration_s=20.0)
    for k, n in enumerate(["ground", "b1f1", "b1f2", "b1f3"]):
        write_sensor(tmp_path / f"{n}.csv", tr.acc[n], 2042652963, 0, seed=k, tilt=0.05)
    argv = ["import", *[f"{n}={tmp_path / n}.csv" for n in ("ground", "b1f1", "b1f2", "b1f3")]]
    assert main([*argv, "--out", str(tmp_path / "imp")]) == 0
    df = pd.read_parquet(tmp_path / "imp" / "table.parquet")
    rev = df.assign(b1f1_acc_m_s2=-df["b1f1_acc_m_s2"])
    rev.to_csv(tmp_path / "rev.csv", index=False)
    df.iloc[::4].to_csv(tmp_path / "slow.csv", index=False)

    def warned(table):
        (tmp_path / "s.toml").write_text(SCENE.replace("{table}", table))
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            prepare(load_scene(tmp_path / "s.toml"))
        return [str(c.message) for c in caught]

    assert warned("imp/table.parquet") == []
    msgs = warned("rev.csv")
    assert any("(abs_acc_b1f1): reversed against the record record.csv" in m for m in msgs)
    (w,) = warned("slow.csv")
    assert "below building 1's modes: mode 2 at 21.71 Hz folds onto" in w and "building 2" not in w


def test_the_aliasing_check_takes_a_slow_sensors_own_rate_for_its_building_only():
    """An import's table on a 120 Hz grid with building 1's top floor from a 60 Hz sensor (its metadata says so):
    building 1's 40 Hz mode is above that sensor's 30 Hz Nyquist frequency and named with its column; building 2,
    measured at 120 Hz, is not (a review found the slowest rate applied to every building, and to the sign and
    lag checks, which run on the table's own samples)."""
    import json
    from types import SimpleNamespace

    from pounding_sweep.model.experiment import Experiment
    from pounding_sweep.sweep.scoring import sensor_warnings

    t = np.arange(1200) / 120.0
    frame = SimpleNamespace(modes=lambda: SimpleNamespace(frequency_Hz=np.array([8.0, 25.0, 40.0])))
    exp = Experiment(  # the real record: its sensor_import reader is the one under test
        path="table.parquet",
        time_s=t,
        channels={"abs_acc_b1f3": np.zeros_like(t), "abs_acc_b2f3": np.zeros_like(t)},
        columns={"abs_acc_b1f3": "b1f3_acc_m_s2", "abs_acc_b2f3": "b2f3_acc_m_s2"},
        metadata={"sensor_import": json.dumps({"sensors": {"b1f3": {"rate_Hz": 60.0}, "b2f3": {"rate_Hz": 120.0}}})},
    )
    out = sensor_warnings(exp, None, SimpleNamespace(b1=frame, b2=frame), SimpleNamespace(kind="harmonic"))
    (w,) = [m for k, m in out if k == "aliasing"]
    assert "column 'b1f3_acc_m_s2' (its sensor's own rate; the table's 120 Hz): sampled at 60 Hz" in w
    assert "building 1's modes: mode 3 at 40 Hz folds onto 20 Hz" in w
