"""Single-building scenes (issue 27 item 3) and the shipped real walkthrough (item 8).

A scene without [building2] and [contact] is one building on its own: its model has no contact pairs (the
engine's P = 0 path, tests/engine/test_registry.py: building 1's rows equal those it gets beside a neighbour too
far away to touch), its results no contact columns, its runs no contact warnings; scoring, calibration,
identification and the figures work on it. The shipped walkthrough (sweeps/real_northridge.toml, the Northridge
test of ../shared's stiff 3-story IMU model, trimmed into sweeps/experiments/imu_northridge/) loads and a small
version of its calibration runs, its figures drawn from the calibrated run.
"""

from __future__ import annotations

import dataclasses
import json
import tomllib

import numpy as np
import pandas as pd
import pytest
from conftest import SWEEPS
from tolerances import U, interpolation_bound

from pounding_sweep.errors import ConfigError
from pounding_sweep.model.coupled import CoupledModel
from pounding_sweep.scene import load_scene, scene_from_dict
from pounding_sweep.sweep.prepare import prepare
from pounding_sweep.sweep.run import run_scene
from pounding_sweep.warn import collecting

SCENE = SWEEPS / "real_northridge.toml"
TEXT = SCENE.read_text()


def raw_scene() -> dict:
    return tomllib.loads(TEXT)


def from_raw(raw: dict):
    return scene_from_dict(raw, base_dir=SWEEPS, source=str(SCENE))


def test_the_shipped_walkthrough_is_one_building():
    """Its model is building 1 alone (P = 0) with the very matrices building 1 has beside a second building: the
    engine's P = 0 path then gives the rows tests/engine/test_registry.py compares with the coupled model's."""
    s = load_scene(SCENE)
    assert s.single and s.building2 is None and s.contact is None and s.floors == (3, 0)
    prep = prepare(dataclasses.replace(s, calibrate=None))
    assert prep.model.n_pairs == 0 and prep.sysarr.H.shape == (3, 0) and prep.sysarr.i1.size == 0
    raw = raw_scene()
    raw["building2"] = dict(raw["building1"])
    raw["contact"] = {"gap_m": 0.3, "ks_ratio": 1.0, "r": 0.5}
    pair = CoupledModel.from_scene(from_raw(raw)).system_arrays(prep.dt)
    n = 3
    assert np.array_equal(prep.sysarr.m, pair.m[:n])
    assert np.array_equal(prep.sysarr.K, pair.K[:n, :n]) and np.array_equal(prep.sysarr.C, pair.C[:n, :n])
    # the same formula on the same blocks: Keff^-1 of building 1 alone (the test_registry twin's construction)
    keff = pair.K[:n, :n] + (2.0 / prep.dt) * pair.C[:n, :n] + (4.0 / prep.dt**2) * np.diag(pair.m[:n])
    assert np.array_equal(prep.sysarr.Kinv, np.linalg.inv(keff))


@pytest.mark.parametrize(
    "edit, message",
    [
        (lambda r: r.update(contact={"r": 0.5, "ks_ratio": 1.0}), r"\[contact\] without \[building2\]"),
        (lambda r: r.update(building2=dict(r["building1"])), r"missing section \[contact\]"),
        (lambda r: r["sweep"].update(gap_m=[0.01]), r"\[sweep\] gap_m: a single-building scene.*no contact"),
        (
            lambda r: r["calibrate"]["parameters"].update(stiffness_scale_b2=[0.9, 1.1]),
            r"\[calibrate\] parameters.stiffness_scale_b2: a single-building scene.*no building 2",
        ),
        (
            lambda r: r["experiment"]["channels"].update(b1f1_acc_m_s2="abs_acc_b2f1"),
            r"'abs_acc_b2f1': there is no building 2 \(a single-building scene",
        ),
        (
            lambda r: r["output"].update(histories=["force_f1"]),
            r"'force_f1': a single-building scene has no contact force",
        ),
    ],
)
def test_a_single_building_scene_refuses_what_needs_two(edit, message):
    raw = raw_scene()
    edit(raw)
    with pytest.raises(ConfigError, match=message):
        from_raw(raw)


def test_a_single_building_sweep_has_no_contact_columns_or_warnings(tmp_path):
    """The grid of the shipped scene: building 1's columns, its scores, the swept structure; nothing of contact
    (no k_s, r, gap, law, force, closest approach, steps per contact period) and no contact warning."""
    s = dataclasses.replace(load_scene(SCENE), calibrate=None)
    with collecting() as outer:
        summary = run_scene(s, out_path=tmp_path / "one.parquet")
    assert summary.warnings == [] and outer.messages() == []
    df = pd.read_parquet(tmp_path / "one.parquet")
    assert len(df) == 9 and set(df.status) == {"ok"}
    params = ("ks_ratio", "ks_N_per_m", "kh_N_per_m1_5", "r", "gap_m", "contact_law", "contact_damping_ratio")
    pairs = ("peak_force_f", "min_force_f", "impacts_f", "contact_time_f", "compression_", "max_penetration_f")
    pairs += ("median_compression_phase_f", "closest_approach_f", "steps_per_contact_period", "r_single_impact")
    assert not [c for c in df.columns if c in params or c.startswith(pairs)]
    assert not [c for c in df.columns if "b2" in c or c.endswith(tuple(f"_f{j}_N" for j in (1, 2, 3)))]
    assert {"stiffness_scale_b1", "damping_ratio_b1", "peak_abs_acc_b1f3_m_s2", "rel_rms_abs_acc_b1f3_pct"} <= set(
        df.columns
    )


def small_walkthrough(tmp_path):
    """The shipped scene, its first 8 s (the quiet lead-in and the first burst), a smaller grid and calibration;
    written beside the results (its files by absolute path) so that the figures rebuild it from the metadata."""
    text = TEXT.replace('"experiments/', f'"{SWEEPS.as_posix()}/experiments/')
    text = text.replace('units = "m/s2"\n', 'units = "m/s2"\nduration_s = 8.0\n', 1)
    text = text.replace("stiffness_scale_b1 = [0.95, 1.0, 1.05]\n", "stiffness_scale_b1 = [1.0, 1.05]\n")
    text = text.replace(
        "global_points = 16\nstarts = 2\n", "global_points = 8\nstarts = 1\nmax_evals = 60\nprofile_points = 3\n"
    )
    text = text.replace('path = "../results/real_northridge.parquet"', 'path = "small.parquet"')
    assert text.count("duration_s = 8.0") == 1 and "max_evals = 60" in text and "[1.0, 1.05]" in text
    (tmp_path / "small.toml").write_text(text)
    return load_scene(tmp_path / "small.toml")


@pytest.fixture(scope="module")
def calibrated(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("walkthrough")
    s = small_walkthrough(tmp)
    summary = run_scene(s, out_path=tmp / "small.parquet")
    return s, tmp / "small.parquet", summary


def test_the_small_walkthrough_calibrates_one_building(calibrated):
    """A fit with intervals and the misfit against each sensor's measured noise: the linear frame cannot explain the
    real structure to its noise (../shared SOURCES.md says so), and the calibration says so and quotes intervals
    that hold the model's error; the first mode lands near the import's 7.75 Hz resonance."""
    from pounding_sweep.sweep.calibrate import NO_CONTACT, read_calibration

    s, out, summary = calibrated
    cal = read_calibration(out.with_name("small.best.parquet"))
    fits = cal["fits"].set_index("parameter")
    assert list(cal["laws"].contact_law) == [NO_CONTACT]
    k = fits.loc["stiffness_scale_b1"]
    assert k.lower_bound < k.estimate < k.upper_bound and k.ci95_low <= k.estimate <= k.ci95_high
    assert k.ci95_model_low <= k.estimate <= k.ci95_model_high  # misfit > misfit_factor: model-error intervals
    per = cal["per_law"][NO_CONTACT]
    assert set(per["noise_floor_m_s2"]) == {"abs_acc_b1f1", "abs_acc_b1f2", "abs_acc_b1f3"} and not per["noise_floor_m"]
    # noise_window_s measures each sensor's noise in the quiet lead-in: the import's 0.008-0.016 m/s^2 (PROVENANCE.md)
    assert all(0.005 < v < 0.03 for v in per["noise_floor_m_s2"].values())
    assert per["misfit_over_noise"] > s.calibrate.misfit_factor
    assert any("times the noise floor" in w for w in summary.warnings)
    f1 = CoupledModel.from_scene(
        dataclasses.replace(
            s, building1=dataclasses.replace(s.building1, stiffness_scale=k.estimate, damping_ratio=None)
        )
    ).b1.modes()
    assert 7.0 < f1.frequency_Hz[0] < 8.5


def test_a_window_whose_optimum_is_on_a_bound_does_not_bound_the_model_error(tmp_path):
    """The clock offset bounded away from the sensors' true one (about -1.7 ms, docs/tutorials/real-shake-table.md):
    every window's optimum sits on the lower bound, where the noise-based interval (a normal approximation at an
    interior optimum) says nothing. No window identifies it, so its model-error interval is the bounds and the
    report says why, naming the fit without a contact law (one building). The first window (0-2 s) is the table at
    rest: its data are noise (RMS about the noise floor), and it identifies nothing, whatever its fit's standard
    errors say. A window counted as identifying lies inside the bounds (sweep/fitstats.py on_bound), and the fit
    table counts those windows."""
    from pounding_sweep.scene.schema import CalibrateConfig
    from pounding_sweep.sweep.calibrate import calibrate, fit_table

    s = small_walkthrough(tmp_path)
    params = {"stiffness_scale_b1": (0.7, 1.3), "damping_ratio_b1": (0.0005, 0.05), "time_offset_s": (0.005, 0.02)}
    cal = CalibrateConfig(parameters=params, global_points=8, starts=1, max_evals=60, profile_points=0)
    with collecting():
        [fit] = calibrate(dataclasses.replace(s, calibrate=cal), 2)
    assert fit.quote == "model_error" and len(fit.windows) == 4
    assert not any(w["identified_time_offset_s"] for w in fit.windows)
    quiet = fit.windows[0]
    assert quiet["signal_over_noise"] < 2.0 and not any(quiet[f"identified_{n}"] for n in params)
    assert all(w["signal_over_noise"] > 50.0 for w in fit.windows[1:])  # the shaking: far above the noise
    assert fit.ci95_model["time_offset_s"] == (0.005, 0.02)
    assert fit.estimate["time_offset_s"] == pytest.approx(0.005, abs=1e-3 * 0.015)  # on its bound (BOUND_FRACTION)
    quoted = next(w for w in fit.warnings if "intervals with the model's error" in w)
    assert quoted.startswith("calibration: ") and "(the bounds: 0 of 4 windows identify it, 2 are needed)" in quoted
    for w in fit.windows:
        for n, (lo, hi) in params.items():
            if w[f"identified_{n}"]:
                assert lo < w[n] < hi
    table = fit_table([fit]).set_index("parameter")
    assert table.loc["time_offset_s", "model_error_windows_identifying"] == 0
    assert table.loc["stiffness_scale_b1", "model_error_windows_identifying"] == sum(
        w["identified_stiffness_scale_b1"] for w in fit.windows
    )


def test_a_lower_residual_a_profile_finds_is_where_the_fit_goes_on(tmp_path, capsys):
    """The real Sine 1.5 test (../shared), imported by the command, its first 30 s fitted by the walkthrough's model:
    the search settles at stiffness scale 1.04 (the first mode), but the profile of the stiffness, refitting the
    damping and clock at the bound 1.3, finds a residual lower by far more than 3.84 (the uniform chain's second
    mode then sits near the frame's 25 Hz, which floor 1's sensor is full of). The optimum was not global: the fit
    goes on from there, says so, and no profile point of the fit it reports lies that far below it."""
    from conftest import SHARED

    from pounding_sweep.cli.run import main
    from pounding_sweep.scene.schema import CalibrateConfig
    from pounding_sweep.sweep.calibrate import CHI2_1_95, calibrate

    test = SHARED / "data" / "imu_shake_table" / "stiff_3story" / "sine_1.5"
    if not test.is_dir():
        pytest.skip(f"{test} not present: the real IMU tests need ../shared beside the repo")
    sensors = {"ground": "ground.csv", "b1f1": "floor1.csv", "b1f2": "floor2.csv", "b1f3": "floor3.csv"}
    assert main(["import", *[f"{n}={test / f}" for n, f in sensors.items()], "--out", str(tmp_path / "imp")]) == 0
    quiet = json.loads(pq_metadata(tmp_path / "imp" / "table.parquet")["sensor_import"])["settings"]["quiet_s"]
    capsys.readouterr()
    raw = raw_scene()
    raw["excitation"] |= {"record": str(tmp_path / "imp" / "record.csv"), "duration_s": 30.0}
    raw["experiment"] |= {"table": str(tmp_path / "imp" / "table.parquet"), "noise_window_s": quiet}
    params = {"stiffness_scale_b1": (0.7, 1.3), "damping_ratio_b1": (0.0005, 0.05), "time_offset_s": (-0.02, 0.02)}
    cal = CalibrateConfig(
        parameters=params, global_points=8, starts=1, max_evals=60, profile_points=3, profile=("stiffness_scale_b1",)
    )
    with collecting():
        [fit] = calibrate(dataclasses.replace(from_raw(raw), calibrate=cal), 2)
    went_on = [w for w in fit.warnings if "the search's optimum was not the global one" in w]
    assert len(went_on) == 1 and "at stiffness_scale_b1 = 1.3" in went_on[0]
    assert any("profile_restart" in stage for stage in fit.search)
    assert fit.estimate["stiffness_scale_b1"] == pytest.approx(1.3, abs=1e-3 * 0.6)  # on its bound
    assert min(r["delta_chi2"] for r in fit.profiles["stiffness_scale_b1"]) >= -CHI2_1_95
    assert not any("may not be the global one" in w for w in fit.warnings)


def pq_metadata(path) -> dict:
    """A Parquet file's key-value metadata, decoded."""
    import pyarrow.parquet as pq

    return {k.decode(): v.decode() for k, v in pq.read_schema(path).metadata.items()}


def test_the_walkthrough_figures_show_the_calibrated_run(calibrated, tmp_path):
    """Every figure drawn or its absence said; the measured-against-model figure is of the calibrated run: its
    residuals are the calibration's (the same samples: linear interpolation between steps at the table's instants,
    calibrate.Problem), up to the rounding of two interpolations (tolerances.interpolation_bound) and of two RMS
    sums ((N + 2) u relative each)."""
    pytest.importorskip("matplotlib")
    from pounding_sweep import plots
    from pounding_sweep.sweep.calibrate import NO_CONTACT, read_calibration
    from pounding_sweep.sweep.results import read_metadata

    s, out, _ = calibrated
    skipped = {}
    written = plots.plot_results(out, tmp_path / "figs", skipped=skipped)
    names = {p.stem for p in written}
    assert {"heatmaps", "displacement_history", "ssp", "measured_vs_model", "calibration_profiles"} <= names
    assert "pounding_force" not in names and "one building" in skipped["pounding_force"]
    best = pd.read_parquet(out.with_name("small.best.parquet"))
    pick, label = plots.calibrated_run(best)
    assert label.startswith("calibrated run (stiffness_scale_b1 = ")
    md = read_metadata(out)
    data = plots.measured_residuals(s, pick, md)
    stored = read_calibration(out.with_name("small.best.parquet"))["per_law"][NO_CONTACT]["rms_residual_m_s2"]
    for code, (t, xe, xm, res) in data.items():
        rms = float(np.sqrt(np.mean(res * res)))
        bound = interpolation_bound(xm, t[-1], s.integration.dt_s) + 2 * (res.size + 2) * U * rms
        assert abs(rms - stored[code]) <= bound, (code, rms, stored[code])
        assert np.array_equal(res, xe - xm)


def test_profiles_of_nothing_draw_no_figure(calibrated, tmp_path):
    """A calibration that profiled nothing gets no empty axes: no figure (plots.figures then says why)."""
    pytest.importorskip("matplotlib")
    import pyarrow.parquet as pq

    from pounding_sweep import plots
    from pounding_sweep.sweep.calibrate import read_calibration
    from pounding_sweep.sweep.results import META_KEY

    _, out, _ = calibrated
    best = out.with_name("small.best.parquet")
    fig = plots.calibration_profile_figure(best)
    # the misfit exceeds misfit_factor: the interval to quote (with model error) is drawn beside the noise's
    quoted = [q for ax in fig.axes for q in ax.patches if "(quote this)" in str(q.get_label())]
    fits = read_calibration(best)["fits"]
    profiled = fits[fits.parameter.isin({"stiffness_scale_b1", "damping_ratio_b1"}) & (fits["quote"] == "model_error")]
    assert len(quoted) == len(profiled) > 0
    table = pq.read_table(best)
    meta = json.loads(table.schema.metadata[META_KEY])
    meta["calibration"]["profiles"] = []
    none = tmp_path / "none.best.parquet"
    pq.write_table(table.replace_schema_metadata({**table.schema.metadata, META_KEY: json.dumps(meta).encode()}), none)
    assert plots.calibration_profile_figure(none) is None


def test_identify_updates_the_one_building(tmp_path, capsys):
    """identify --scene on the shipped table: the first mode against building 1's, the [building1] section to paste
    (a single-building scene has no building 2 to update), which loads in place of the scene's own."""
    from pounding_sweep.cli.identify import identify_main

    out = tmp_path / "update.toml"
    table = SWEEPS / "experiments" / "imu_northridge" / "table.parquet"
    assert identify_main([str(table), "--scene", str(SCENE), "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    update = tomllib.loads(out.read_text())
    assert set(update) == {"building1"} and "building 2" not in printed
    f1 = float(printed.split("building 1 (")[1].split("mode 1: ")[1].split(" Hz")[0])
    assert 7.5 < f1 < 8.5  # the source's notebooks: periods of 0.125-0.134 s
    raw = raw_scene()
    raw["building1"] = update["building1"]
    frame = CoupledModel.from_scene(from_raw(raw)).b1
    # f1 printed to 4 decimals (6e-6 relative) and the stiffness written to 0.01 N/m (3e-6 in f = sqrt(k)): 1e-5
    assert frame.modes().frequency_Hz[0] == pytest.approx(f1, rel=1e-5)


def test_a_single_building_without_an_experiment_is_plotted(tmp_path):
    """No experiment, no contact: the peak-displacement map alone, the displacement history, no force figure (said
    why), no empty axes."""
    pytest.importorskip("matplotlib")
    from pounding_sweep import plots

    (tmp_path / "one.toml").write_text(
        "\n".join(
            [
                'name = "one_harmonic"',
                "[building1]",
                "masses_kg = [1.7, 1.7, 1.6]",
                "story_stiffness_N_per_m = 5920.0",
                "damping_ratio = 0.0105",
                "[excitation]",
                'type = "harmonic"',
                "amplitude_m = 0.002",
                "frequency_Hz = 6.0",
                "duration_s = 0.5",
                "[integration]",
                "dt_s = 1e-3",
                "[sweep]",
                "frequency_Hz = [4.0, 6.0]",
                "stiffness_scale_b1 = [0.9, 1.0]",
                "[output]",
                'path = "one.parquet"',
            ]
        )
    )
    summary = run_scene(load_scene(tmp_path / "one.toml"))
    assert summary.warnings == [] and summary.extremes == {}
    skipped = {}
    ladder = pd.DataFrame(
        {"scheme": ["event"] * 2, "dt_s": [2e-3, 1e-3], "run_time_s": [1e-3, 2e-3], "rel_rms_pct": [1.0, 0.3]}
    )
    figs = plots.figures(tmp_path / "one.parquet", accuracy=ladder, skipped=skipped)
    assert set(figs) == {"heatmaps", "displacement_history", "error_vs_runtime"}
    assert set(skipped) == {"pounding_force"} and "one building" in skipped["pounding_force"]
    maps = [ax for ax in figs["heatmaps"].axes if ax.get_label() != "<colorbar>"]
    assert len(maps) == 1 and "peak displacement [mm]" in maps[0].get_title()
    assert all(ax.has_data() for ax in figs["displacement_history"].axes)
