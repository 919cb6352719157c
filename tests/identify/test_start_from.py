"""identify's modes as a calibration's start (issue 27 item 5): `identify --modes-out` writes each building's
identified frequencies and damping ratios; [calibrate] start_from reads them into start values (per-mode damping,
and the stiffness factor that puts the model's first mode at the identified one); a path that cannot serve is one
error naming the key and the path."""

from __future__ import annotations

import dataclasses
import math
import tomllib

import numpy as np
import pandas as pd
import pytest
from conftest import SWEEPS

from pounding_sweep.cli.identify import WRITTEN_BY, identify_main
from pounding_sweep.errors import ConfigError
from pounding_sweep.identify.startfile import modes_toml
from pounding_sweep.identify.table import identify_table
from pounding_sweep.model.coupled import CoupledModel
from pounding_sweep.scene import load_scene, validate
from pounding_sweep.scene.schema import CalibrateConfig, ExperimentConfig
from pounding_sweep.scene.starts import read_modes
from pounding_sweep.sweep.calibrate import calibrate, identified_starts
from pounding_sweep.sweep.simulate import simulate
from pounding_sweep.warn import collecting

TABLE = SWEEPS / "experiments" / "imu_northridge" / "table.parquet"
STORIES = {f"story_stiffness_scale_b1_s{k}": [0.5, 2.0] for k in (1, 2, 3)}
MODES = {f"modal_damping_ratio_b1_m{j}": [0.0005, 0.05] for j in (1, 2, 3)}


def frame(duration_s: float = 8.0):
    """The shipped real-data scene as a frame with per-mode damping (0.5 % each), its first `duration_s`."""
    s = load_scene(SWEEPS / "real_northridge.toml")
    b1 = dataclasses.replace(s.building1, damping_ratio=None, modal_damping_ratios=(0.005, 0.005, 0.005))
    exc = dataclasses.replace(s.excitation, duration_s=duration_s)
    return dataclasses.replace(s, sweep=(), building1=b1, excitation=exc, calibrate=None)


def test_identify_writes_its_modes_for_a_calibration(tmp_path, capsys):
    out = tmp_path / "modes.toml"
    assert identify_main([str(TABLE), "--modes-out", str(out)]) == 0
    printed = capsys.readouterr().out
    text = out.read_text()
    assert text.startswith(WRITTEN_BY) and "start_from" in text
    modes = read_modes(str(out))[1]
    for k, f in enumerate(modes.frequencies_Hz, 1):  # the printed modes, to their 4 printed decimals
        assert f"mode {k}: {f:.4f} Hz" in printed
    raw = tomllib.loads(text)["building1"]
    assert len(raw["damping_ci95"]) == len(modes.damping_ratios) == len(raw["damping_methods"]) == 3
    # the estimates identify calls unreliable (a helper's trial: negative damping written without a word) are
    # marked: on Northridge mode 1's fitted damping is not above 0 (false), mode 2's is trusted (true), though its
    # half-power (0.07-0.27 %) and fitted (0.36-0.69 %) intervals do not overlap, which is noted
    assert len(modes.damping_reliable) == 3 and all(
        z > 0 for z, r in zip(modes.damping_ratios, modes.damping_reliable) if r
    )
    assert not modes.damping_reliable[0] and modes.damping_ratios[0] < 0 and modes.damping_reliable[1]
    assert "25.097 Hz: half-power damping 0.17 % (0.07 to 0.27 %) and fitted damping 0.53 %" in printed
    assert "damping_reliable: false where identify does not trust the damping" in text
    assert identify_main([str(TABLE), "--modes-out", str(out)]) == 0  # its own file: replaced
    mine = tmp_path / "mine.toml"
    mine.write_text("a user's notes\n")
    assert identify_main([str(TABLE), "--modes-out", str(mine)]) == 2  # a user's file: never
    assert mine.read_text() == "a user's notes\n" and "never replaces" in capsys.readouterr().err


def _modes_file(path, f1: float, zeta, reliable: str = "") -> str:
    z = ", ".join("nan" if math.isnan(v) else repr(v) for v in zeta)
    path.write_text(f"[building1]\nfrequencies_Hz = [{f1!r}, 30.0, 45.0]\ndamping_ratios = [{z}]\n{reliable}")
    return str(path)


def test_the_start_puts_the_first_mode_at_the_identified_one(tmp_path):
    """Every fitted story factor times c = (f1 identified / f1 model)^2 scales K by c, so the model's first mode
    lands on the identified one to the eigensolver's rounding (relative 1e-12 on a 3 x 3 problem: LAPACK's
    backward error is a few u times the matrix norm, its condition here a few); damping ratios mode by mode, a
    negative one at its lower bound, a NaN one none (the scene's value stays)."""
    s = frame()
    f1 = float(CoupledModel.from_scene(s).b1.modes().frequency_Hz[0])
    path = _modes_file(tmp_path / "m.toml", 1.1 * f1, [-0.002, 0.007, math.nan])
    cal = CalibrateConfig(parameters=STORIES | MODES, start_from=path)
    s = dataclasses.replace(s, calibrate=cal)
    start = identified_starts(s, list(cal.parameters))
    assert start["modal_damping_ratio_b1_m1"] == 0.0005 and start["modal_damping_ratio_b1_m2"] == 0.007
    assert "modal_damping_ratio_b1_m3" not in start
    scales = tuple(start[f"story_stiffness_scale_b1_s{k}"] for k in (1, 2, 3))
    moved = dataclasses.replace(s, building1=dataclasses.replace(s.building1, story_stiffness_scales=scales))
    assert float(CoupledModel.from_scene(moved).b1.modes().frequency_Hz[0]) == pytest.approx(1.1 * f1, rel=1e-12)
    # a file written before damping_reliable reads as it did (no flags); one that flags mode 1's start warns
    assert read_modes(path)[1].damping_reliable == ()
    flagged = _modes_file(
        tmp_path / "f.toml", 1.1 * f1, [-0.002, 0.007, math.nan], "damping_reliable = [false, true, true]\n"
    )
    with collecting() as got:
        identified_starts(
            dataclasses.replace(s, calibrate=dataclasses.replace(cal, start_from=flagged)), list(cal.parameters)
        )
    (w,) = [w.message for w in got.items if w.kind == "start_unreliable"]
    assert w.startswith(
        "[calibrate] start_from: modal_damping_ratio_b1_m1 = -0.002 start from damping identify does not trust"
    )
    bad = _modes_file(tmp_path / "b.toml", 1.1 * f1, [0.01, 0.007, 0.01], "damping_reliable = [1, 0, 1]\n")
    with pytest.raises(ConfigError, match="damping_reliable = \\[1, 0, 1\\]: true or false per mode"):
        read_modes(bad)
    uniform = dataclasses.replace(cal, parameters={"stiffness_scale_b1": [0.5, 2.0]})
    s2 = dataclasses.replace(s, building1=dataclasses.replace(s.building1, stiffness_scale=1.05), calibrate=uniform)
    assert identified_starts(s2, ["stiffness_scale_b1"])["stiffness_scale_b1"] == pytest.approx(1.21, rel=1e-12)
    # a mode 1 far below the model's (a helper's trial: the forcing of a 2 Hz sine taken for an 8 Hz mode, c =
    # 0.06; here 0.25 f1, c = 0.0625) starts at the bound, and says so; one inside the bounds says nothing
    far = _modes_file(tmp_path / "far.toml", 0.25 * f1, [0.01, 0.007, 0.01])
    with collecting() as got:
        low = identified_starts(dataclasses.replace(s2, calibrate=dataclasses.replace(uniform, start_from=far)),
                                ["stiffness_scale_b1"])  # fmt: skip
    assert low["stiffness_scale_b1"] == 0.5
    (w,) = [w.message for w in got.items if w.kind == "start_outside"]
    assert (
        "stiffness_scale_b1 = 0.0625" in w
        and "lies outside [calibrate] parameters.stiffness_scale_b1 = [0.5, 2.0]" in w
    )
    with collecting() as got:
        identified_starts(s2, ["stiffness_scale_b1"])
    assert not [w for w in got.items if w.kind == "start_outside"]


@pytest.mark.parametrize(
    ("content", "message"),
    [
        (None, "cannot read identify's modes"),
        ("not = [toml", "not a modes file identify wrote"),
        ("[building1]\nfrequencies_Hz = [0.0, 20.0]\n", "one frequency > 0 per mode"),
        ("[building2]\nfrequencies_Hz = [5.0]\n", "the fit names no parameter of their structure"),
    ],
)
def test_a_start_from_that_cannot_serve_is_refused(tmp_path, content, message):
    path = tmp_path / "modes.toml"
    if content is not None:
        path.write_text(content)
    s = dataclasses.replace(frame(), calibrate=CalibrateConfig(parameters=MODES, start_from=str(path)))
    s = dataclasses.replace(
        s, experiment=ExperimentConfig(table=str(TABLE), channels={"b1f3_acc_m_s2": "abs_acc_b1f3"})
    )
    with pytest.raises(ConfigError, match=message) as e:
        validate(s)
    assert f"[calibrate] start_from = {str(path)!r}" in str(e.value)


TRUTH = {"scales": (1.08, 0.95, 1.0), "zeta": (0.004, 0.008, 0.003)}


def test_a_fit_started_from_identified_modes_finds_the_frame(tmp_path):
    """A frame made by the engine (story factors 1.08, 0.95, 1.0; modal damping 0.4, 0.8, 0.3 %), driven by the
    real Northridge table record, its floors' absolute acceleration at the record's instants plus 0.01 m/s^2 of
    noise: identified (the transmissibility against the table's column), written as a modes file, and fitted
    from it with no global stage (global_points = 0: the start is the one local start). The fit reaches the
    noise (misfit within 1.5 of it: 1 +/- a few 1/sqrt(2N) with N = 2880) and every value lies within 4 of its
    standard errors of its truth (six 95 % intervals miss one in a quarter of noise draws; 4 sigma one in 10^4);
    the start is recorded."""
    s = frame()
    b1 = dataclasses.replace(s.building1, story_stiffness_scales=TRUTH["scales"], modal_damping_ratios=TRUTH["zeta"])
    hist, _ = simulate(dataclasses.replace(s, building1=b1), channels=[f"abs_acc_b1f{f}" for f in (1, 2, 3)])
    rec = pd.read_csv(s.excitation.record)
    rec = rec[rec.t_s <= hist.t_s.iloc[-1]]
    t = rec.t_s.to_numpy()
    rng = np.random.default_rng(3)
    df = pd.DataFrame({"t_s": t, "ground_acc_m_s2": rec.acc_m_s2.to_numpy()})
    for f in (1, 2, 3):
        a = np.interp(t, hist.t_s.to_numpy(), hist[f"abs_acc_b1f{f}_m_s2"].to_numpy())
        df[f"b1f{f}_acc_m_s2"] = a + rng.normal(0.0, 0.01, t.size)
    table = tmp_path / "frame.parquet"
    df.to_parquet(table)
    with collecting():
        ident = identify_table(df, str(table), input_kind_given="acceleration")
    # a linear frame's peaks are one mode each: its half-power and fitted damping agree within their intervals
    assert not [n for n in ident.results[1].notes if "disagree" in n]
    modes = tmp_path / "modes.toml"
    modes.write_text(modes_toml(ident, f"{WRITTEN_BY} {table}"))
    assert read_modes(str(modes))[1].damping_reliable == (True, True, True)
    channels = {f"b1f{f}_acc_m_s2": f"abs_acc_b1f{f}" for f in (1, 2, 3)}
    exp = ExperimentConfig(table=str(table), channels=channels, use="acceleration", noise=dict.fromkeys(channels, 0.01))
    cal = CalibrateConfig(
        parameters=STORIES | MODES, global_points=0, starts=1, profile_points=0, start_from=str(modes)
    )
    scene = dataclasses.replace(s, experiment=exp, calibrate=cal)
    validate(scene)
    with collecting():
        fit = calibrate(scene, 2)[0]
    print(f"\nstart {fit.start}\nfit {fit.estimate}\nintervals {fit.ci95}\nmisfit {fit.misfit_ratio:.3f}")
    assert {v["from"] for v in fit.start.values()} == {"start_from"}
    assert fit.misfit_ratio < 1.5
    truth = {f"story_stiffness_scale_b1_s{k}": v for k, v in enumerate(TRUTH["scales"], 1)}
    truth |= {f"modal_damping_ratio_b1_m{j}": v for j, v in enumerate(TRUTH["zeta"], 1)}
    for n, v in truth.items():
        assert abs(fit.estimate[n] - v) <= 4 * fit.std_error[n], (n, v, fit.estimate[n], fit.std_error[n])
