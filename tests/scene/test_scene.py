"""Scene loading: every shipped scene validates; bad scenes give one clear error naming key and value."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest
from conftest import REPO, SWEEPS

from pounding_sweep.model.grid import Grid
from pounding_sweep.scene import describe, load_scene

BASE = (SWEEPS / "paper_6hz.toml").read_text()
SHIPPED = sorted(SWEEPS.glob("*.toml"))


def test_there_are_shipped_scenes():
    names = {p.stem for p in SHIPPED}
    assert {"paper_6hz", "paper_4613hz", "paper_duzce", "paper_duzce_separated"} <= names


@pytest.mark.parametrize("path", SHIPPED, ids=lambda p: p.stem)
def test_shipped_scene_validates(path):
    scene = load_scene(path)
    grid = Grid.from_scene(scene)
    assert grid.size >= 1
    if scene.name.startswith("paper_"):
        assert dict(grid.axes)["ks_ratio"] == (0.1, 1.0, 5.0, 10.0)
        assert dict(grid.axes)["r"] == (0.2, 0.4, 0.6, 0.8, 1.0)
    if scene.excitation.record:
        assert Path(scene.excitation.record).is_file()  # shipped records live in the repo


def write(tmp_path, text, name="scene.toml"):
    p = tmp_path / name
    p.write_text(text)
    return p


def edit(old, new, text=BASE):
    assert re.search(old, text, flags=re.M), old
    return re.sub(old, new, text, count=1, flags=re.M)


BAD = {
    "toml_syntax": (edit(r"^r = 0.4$", "r = = 0.4"), r"TOML syntax error"),
    "misspelled_key": (
        edit(r"^ks_ratio = 1.0$", "ks_ration = 1.0"),
        r"unknown key 'ks_ration' in \[contact\]; did you mean 'ks_ratio'",
    ),
    "misspelled_section": (
        edit(r"^\[contact\]$", "[contcat]"),
        r"unknown key 'contcat' in top level; did you mean 'contact'",
    ),
    "missing_r": (edit(r"^r = 0.4\n", ""), r"missing key 'r' in \[contact\]"),
    "r_above_1": (edit(r"^r = 0.4$", "r = 1.5"), r"\[contact\] r = 1.5: .* \[0, 1\]"),
    "r_negative_in_sweep": (edit(r"^r = \[0.2, .*$", "r = [0.2, -0.1]"), r"\[sweep\] r = -0.1"),
    "negative_mass": (
        edit(r"^masses_kg = \[1.7, 1.7, 1.6\]", "masses_kg = [1.7, -1.7, 1.6]"),
        r"\[building1\] masses_kg = -1.7: must be > 0",
    ),
    "zero_mass": (
        edit(r"^masses_kg = \[0.56, 0.56, 0.45\]", "masses_kg = [0.56, 0.0, 0.45]"),
        r"\[building2\] masses_kg = 0.0: must be > 0",
    ),
    "zero_stiffness": (
        edit(r"^story_stiffness_N_per_m = 5920.0", "story_stiffness_N_per_m = 0"),
        r"story_stiffness_N_per_m = 0.0: must be > 0",
    ),
    "nan_value": (
        edit(r"^amplitude_m = 0.002$", "amplitude_m = nan"),
        r"\[excitation\] amplitude_m = nan: must be finite",
    ),
    "inf_value": (edit(r"^dt_s = 1e-4$", "dt_s = inf"), r"\[integration\] dt_s = inf: must be finite"),
    "string_for_number": (
        edit(r"^frequency_Hz = 6.0$", 'frequency_Hz = "6 Hz"'),
        r"frequency_Hz = '6 Hz': expected a number",
    ),
    "negative_gap": (edit(r"^gap_m = 0.0", "gap_m = -0.001"), r"gap_m = -0.001: must be >= 0"),
    "dt_longer_than_run": (edit(r"^dt_s = 1e-4$", "dt_s = 6.0"), r"dt_s = 6.0: must be shorter than"),
    "unknown_law": (edit(r'^law = "classic"$', 'law = "hertz-mindlin"'), r"law = 'hertz-mindlin'"),
    "unknown_scheme": (edit(r'^scheme = "event" .*$', 'scheme = "euler"'), r"scheme = 'euler'"),
    "empty_axis": (edit(r"^r = \[0.2, .*$", "r = []"), r"\[sweep\] r = \[\]"),
    "unknown_axis": (edit(r"^r = \[0.2, .*$", "damping = [0.1]"), r"unknown key 'damping' in \[sweep\]"),
    "both_ks_forms": (
        edit(r"^ks_ratio = 1.0$", "ks_ratio = 1.0\nks_N_per_m = 6830.0"),
        r"give ks_ratio or ks_N_per_m, not both",
    ),
    "bad_channel": (BASE + '\nhistories = ["disp_b3f1"]\n', r"channel 'disp_b3f1'.*there is no building 3"),
    "floor_out_of_range": (BASE + '\nhistories = ["disp_b1f4"]\n', r"building 1 has floors 1..3"),
    "missing_record": (
        BASE.replace('type = "harmonic"', 'type = "record"\nrecord = "nowhere.AT2"')
        .replace("amplitude_m = 0.002\n", "")
        .replace("frequency_Hz = 6.0\n", ""),
        r"nowhere.AT2",
    ),
    "log_range_nonpositive": (
        edit(r"^ks_ratio = \[0.1.*$", "ks_ratio = {start = 0, stop = 10, num = 5, spacing = 'log'}"),
        r"log spacing needs start and stop > 0",
    ),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_scene_message(tmp_path, case):
    text, pattern = BAD[case]
    path = write(tmp_path, text)
    with pytest.raises(Exception) as exc:
        scene = load_scene(path)
        from pounding_sweep.model.excitation import Excitation

        Excitation.from_scene(scene, scene.integration.dt_s)  # records are read here
    msg = str(exc.value)
    assert str(path) in msg or case == "missing_record"
    assert re.search(pattern, msg), msg


@pytest.mark.parametrize("case", ["misspelled_key", "r_above_1", "negative_mass", "missing_record", "toml_syntax"])
def test_cli_bad_input_exits_2_without_output(tmp_path, case):
    text, pattern = BAD[case]
    out = tmp_path / "out.parquet"
    path = write(tmp_path, text)
    p = subprocess.run(
        [sys.executable, "-m", "pounding_sweep", str(path), "--out", str(out)], capture_output=True, text=True, cwd=REPO
    )
    assert p.returncode == 2
    assert "Traceback" not in p.stderr
    assert p.stderr.startswith("error: ") and re.search(pattern, p.stderr)
    assert not out.exists() and not list(tmp_path.glob("*.parquet*"))


def test_ranges_linear_and_log(tmp_path):
    text = edit(r"^ks_ratio = \[0.1.*$", "ks_ratio = {start = 0.01, stop = 100, num = 5, spacing = 'log'}")
    text = edit(r"^r = \[0.2, .*$", "r = {start = 0, stop = 1, num = 3}", text)
    g = Grid.from_scene(load_scene(write(tmp_path, text)))
    axes = dict(g.axes)
    assert axes["ks_ratio"] == pytest.approx((0.01, 0.1, 1, 10, 100))
    assert axes["r"] == (0.0, 0.5, 1.0)
    assert g.size == 15


def test_grid_is_the_cartesian_product_last_axis_fastest(tmp_path):
    text = BASE.replace("[sweep]\n", "[sweep]\ngap_m = [0.0, 0.001]\n")
    g = Grid.from_scene(load_scene(write(tmp_path, text)))
    assert g.shape == (2, 4, 5) and g.size == 40
    c = g.chunk(0, 40)
    assert list(c["gap_m"][:21:20]) == [0.0, 0.001]
    assert list(c["ks_ratio"][:10:5]) == [0.1, 1.0]
    assert list(c["r"][:5]) == [0.2, 0.4, 0.6, 0.8, 1.0]
    assert c["frequency_Hz"].tolist() == [6.0] * 40  # fixed parameters broadcast
    # chunks agree with the whole
    part = g.chunk(17, 23)
    assert part["r"].tolist() == c["r"][17:23].tolist() and part["run_id"].tolist() == list(range(17, 23))


def test_config_hash_changes_with_content_only(tmp_path):
    a = load_scene(write(tmp_path, BASE, "a.toml"))
    b = load_scene(write(tmp_path, BASE.replace("# adjacent", "# a comment changed"), "b.toml"))
    c = load_scene(write(tmp_path, edit(r"^r = 0.4$", "r = 0.5"), "c.toml"))
    assert a.config_hash() == b.config_hash() != c.config_hash()


def test_column_properties_give_stiffness(tmp_path):
    import re

    text = re.sub(
        r"story_stiffness_N_per_m = 5920\.0[^\n]*\nstory_height_m = [^\n]*",
        "column_EI_Nm2 = 5.4\nn_columns = 4\nstory_height_m = 0.33609",
        BASE,
        count=1,
    )
    from pounding_sweep.model.coupled import CoupledModel

    m = CoupledModel.from_scene(load_scene(write(tmp_path, text)))
    assert m.b1.story_stiffness_N_per_m[0] == pytest.approx(6830.0, rel=1e-3)


def test_describe_lists_every_key():
    d = describe()
    for key in ("masses_kg", "ks_ratio", "length_scale", "dt_s", "histories", "threads"):
        assert key in d


def test_describe_states_the_engine_limits():
    """--describe says what the engine supports (issue 17): the lane kernel's size, the scalar kernel
    beyond it, the switch limit per step for the whole model, the sizes a scene and its files may have."""
    from pounding_sweep.engine.events import MAX_EVENTS
    from pounding_sweep.engine.simd import SCRATCH
    from pounding_sweep.scene.describe import MAX_EVENTS as STATED

    assert STATED == MAX_EVENTS  # the scene layer's copy (it loads no Numba)
    assert 6 * 24 + 12 <= SCRATCH < 6 * 26 + 13  # "up to 12 + 12 floors"
    d = describe()
    for words in (
        "up to 12 + 12 floors",
        "scalar kernel",
        "for the whole model",
        "contact_unsettled",
        "1,000 per building",
    ):
        assert words in d, words


def test_describe_lists_the_top_level_keys_and_marks_what_is_required():
    """Issue 16: name and description were missing, and a required key read 'default None'."""
    import dataclasses

    from pounding_sweep.scene.schema import SECTIONS, ExperimentConfig

    lines = describe().splitlines()
    assert lines[1].startswith("  name: ") and lines[2].startswith("  description: ")
    assert "None" not in describe()
    keyed = {line.split(":")[0].strip(): line for line in lines if line.startswith("  ")}
    for key in ("masses_kg", "r", "type"):
        assert keyed[key].endswith("(required)"), keyed[key]
    assert keyed["ks_ratio"].endswith("(required unless ks_N_per_m is given, or either swept)")
    assert keyed["amplitude_m"].endswith("(required for type = 'harmonic')")
    assert keyed["gap_m"].endswith("(default 0.0)")
    for name in ("building1", "excitation"):
        assert f"[{name}] (required section)" in describe()
    for name in ("building2", "contact"):  # both, or neither: one building on its own
        assert f"[{name}] (required with the other of building2 and contact; without both: one building" in (describe())
    # every key of every section is listed, once per section
    for name, cls in {**SECTIONS, "experiment": ExperimentConfig}.items():
        section = describe().split(f"[{name}]", 1)[1].split("\n[", 1)[0]
        for f in dataclasses.fields(cls):
            assert f"\n  {f.name}: " in section, (name, f.name)


# ------------------------------------------------------------------ acceleration channels and weights

SCORED = (SWEEPS / "scored_6hz.toml").read_text().replace('"experiments/', f'"{SWEEPS}/experiments/')
CHANNELS = 'channels = { model1_floor3_mm = "b1f3", model2_floor3_mm = "b2f3" }'
ACC = 'channels = { model1_floor3_mm = "b1f3", b1f3_acc = "abs_acc_b1f3" }'

BAD_ACC = {
    "acc_units": (
        ACC + '\nacc_units = "cm/s2"',
        r"\[experiment\] acc_units = 'cm/s2': expected one of \['m/s2', 'g'\]",
    ),
    "acc_building_3": (
        'channels = { b1f3_acc = "abs_acc_b3f1" }',
        r"channels.b1f3_acc = 'abs_acc_b3f1': there is no building 3",
    ),
    "acc_floor_4": (
        'channels = { b1f3_acc = "abs_acc_b1f4" }',
        r"channels.b1f3_acc = 'abs_acc_b1f4': building 1 has floors 1..3, so it maps to no floor",
    ),
    "acc_misspelled": (
        'channels = { b1f3_acc = "acc_b1f3" }',
        r"channels.b1f3_acc = 'acc_b1f3': an experiment channel is .* abs_acc_b<building>f<floor>",
    ),
    "lowpass_without_acceleration": (
        CHANNELS + "\nlowpass_Hz = 20.0",
        r"lowpass_Hz = 20.0: it filters acceleration channels, and none is mapped",
    ),
    "lowpass_zero": (ACC + "\nlowpass_Hz = 0", r"lowpass_Hz = 0.0: a cut-off frequency must be > 0"),
    "lowpass_order": (ACC + "\nlowpass_Hz = 20.0\nlowpass_order = 0", r"lowpass_order = 0: expected 1 to 12"),
    "sensor_unknown": (ACC + '\nsensor_filter = "kalman"', r"sensor_filter = 'kalman': expected one of \['none'"),
    "sensor_average_without_rate": (ACC + '\nsensor_filter = "average"', r"'average': give sensor_rate_Hz"),
    "sensor_rate_negative": (
        ACC + '\nsensor_filter = "average"\nsensor_rate_Hz = -1.0',
        r"sensor_rate_Hz = -1.0: a sample rate must be > 0 Hz",
    ),
    "sensor_average_with_cutoff": (
        ACC + '\nsensor_filter = "average"\nsensor_rate_Hz = 1000\nsensor_cutoff_Hz = 40',
        r"sensor_cutoff_Hz = 40.0: sensor_filter = 'average' has no cut-off",
    ),
    "sensor_butter_without_cutoff": (ACC + '\nsensor_filter = "butter"', r"'butter': give sensor_cutoff_Hz"),
    "sensor_cutoff_above_nyquist": (
        ACC + '\nsensor_filter = "butter"\nsensor_rate_Hz = 1000\nsensor_cutoff_Hz = 500',
        r"sensor_cutoff_Hz = 500.0: at or above the Nyquist frequency 500 Hz of sensor_rate_Hz = 1000.0",
    ),
    "sensor_order": (
        ACC + '\nsensor_filter = "butter"\nsensor_cutoff_Hz = 40\nsensor_order = 13',
        r"sensor_order = 13: expected 1 to 12",
    ),
    "sensor_rate_without_filter": (ACC + "\nsensor_rate_Hz = 1000", r"sensor_rate_Hz = 1000.0: sensor_filter = 'none'"),
    "sensor_without_acceleration": (
        CHANNELS + '\nsensor_filter = "average"\nsensor_rate_Hz = 1000',
        r"sensor_filter = 'average': it models accelerometers, and no acceleration channel is mapped",
    ),
    "use_unknown": (
        ACC + '\nuse = "accel"',
        r"use = 'accel': expected one of \['displacement', 'acceleration', 'both'\]",
    ),
    "use_no_such_channel": (
        CHANNELS + '\nuse = "acceleration"',
        r"use = 'acceleration': no acceleration channel is mapped",
    ),
    "weights_unknown": (ACC + '\nweights = "snr"', r"weights = 'snr': expected one of \['equal', 'noise'\]"),
    "weights_unmapped": (
        ACC + "\nweights = { model1_floor3_mm = 1.0, b2f3_acc = 1.0 }",
        r"weights.b2f3_acc = 1.0: 'b2f3_acc' is not a mapped channel",
    ),
    "weights_negative": (
        ACC + "\nweights = { model1_floor3_mm = 1.0, b1f3_acc = -1 }",
        r"weights.b1f3_acc = -1.0: a weight must be >= 0",
    ),
    "weights_missing": (ACC + "\nweights = { b1f3_acc = 1.0 }", r"weights: no weight for channel 'model1_floor3_mm'"),
    "weights_unused": (
        ACC + '\nuse = "acceleration"\nweights = { model1_floor3_mm = 1.0, b1f3_acc = 1.0 }',
        r"weights.model1_floor3_mm = 1.0: use = 'acceleration' leaves this channel out",
    ),
    "weights_all_zero": (
        ACC + "\nweights = { model1_floor3_mm = 0, b1f3_acc = 0 }",
        r"at least one weight must be > 0",
    ),
    "weights_text": (ACC + '\nweights = { b1f3_acc = "1" }', r"weights.b1f3_acc = '1': expected a number"),
}


@pytest.mark.parametrize("case", sorted(BAD_ACC))
def test_bad_acceleration_keys(tmp_path, case):
    text, pattern = BAD_ACC[case]
    path = write(tmp_path, SCORED.replace(CHANNELS, text))
    with pytest.raises(Exception) as exc:
        load_scene(path)
    assert str(path) in str(exc.value) and re.search(pattern, str(exc.value)), str(exc.value)


def test_acceleration_keys_in_the_hash_only_when_used(tmp_path):
    """A scene without the acceleration keys hashes as before they existed (its canonical form has none of
    them); each one set changes the hash."""
    from pounding_sweep.scene.hashing import ADDED_EXPERIMENT_KEYS

    plain = load_scene(write(tmp_path, SCORED))
    assert not set(ADDED_EXPERIMENT_KEYS) & set(plain.canonical()["experiment"])
    hashes = {plain.config_hash()}
    for extra in (
        "",
        "lowpass_Hz = 20.0",
        "lowpass_Hz = 20.0\nacc_units = 'g'",
        "use = 'displacement'",
        "weights = 'noise'",
        "sensor_filter = 'average'\nsensor_rate_Hz = 1000",
        "sensor_filter = 'butter'\nsensor_cutoff_Hz = 40",
    ):
        text = SCORED.replace(CHANNELS, ACC + "\n" + extra)
        hashes.add(load_scene(write(tmp_path, text, f"s{len(hashes)}.toml")).config_hash())
    assert len(hashes) == 8


def test_describe_documents_the_acceleration_keys():
    text = describe()
    for key in ("acc_units", "lowpass_Hz", "lowpass_order", "use", "weights", "abs_acc_b1f3", "sensor_filter"):
        assert key in text


def test_a_video_gives_no_accelerations(tmp_path):
    head, _, _ = BASE.partition("[sweep]")
    text = head + (
        '[experiment]\nunits = "mm"\nchannels = { b1f3 = "abs_acc_b1f3" }\n\n[experiment.video]\npath = "run.mkv"\n'
        'markers = ["table_left", "table_right", "b1f3"]\nreferences = ["table_left", "table_right"]\nmm_per_px = 5.0\n'
    )
    with pytest.raises(Exception, match=r"channels.b1f3 = 'abs_acc_b1f3': a tracked video gives displacements only"):
        load_scene(write(tmp_path, text))


def test_one_parse_of_a_floor_name():
    """scene/channels.py building_floor: the one reading of b<building>f<floor> that the import, the checks, identify
    and the plots share (floors past 9 included: the ladder sorted f10 above f9)."""
    from pounding_sweep.scene.channels import building_floor

    assert building_floor("b1f3") == (1, 3)
    assert building_floor("abs_acc_b2f10") == (2, 10)
    assert building_floor("disp_b1f1") == (1, 1)
    assert building_floor("abs_acc_b1f3", bare=True) is None  # a sensor is named b1f3 itself
    assert building_floor("b2f1", bare=True) == (2, 1)
    for other in ("ground", "model1_floor3_mm", "b1", "bf3", "acc_b1f3", "b1f3_mm"):
        assert building_floor(other) is None, other
