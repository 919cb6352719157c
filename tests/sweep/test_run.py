"""End to end: scenes -> Parquet, the paper's 6 Hz figures, metadata, histories, threads."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pandas as pd
import pytest
from conftest import REPO, SWEEPS
from tolerances import switch_residue_force

import pounding_sweep
from pounding_sweep.scene import load_scene
from pounding_sweep.sweep.results import read_metadata, read_schema
from pounding_sweep.sweep.run import run_scene


@pytest.fixture(scope="module")
def six_hz(tmp_path_factory):
    out = tmp_path_factory.mktemp("run") / "paper_6hz.parquet"
    p = subprocess.run(
        [sys.executable, "-m", "pounding_sweep", str(SWEEPS / "paper_6hz.toml"), "--out", str(out)],
        capture_output=True,
        text=True,
        cwd=REPO,
    )
    assert p.returncode == 0, p.stderr
    return out, p.stdout


def test_6hz_scene_writes_20_rows(six_hz):
    out, stdout = six_hz
    df = pd.read_parquet(out)
    assert len(df) == 20
    assert sorted(set(df.ks_ratio)) == [0.1, 1.0, 5.0, 10.0] and sorted(set(df.r)) == [0.2, 0.4, 0.6, 0.8, 1.0]
    assert "runs" in stdout and "20" in stdout
    assert not list(out.parent.glob("*.tmp"))


def test_6hz_peak_force_and_contact_duration_match_the_references(six_hz):
    """REFERENCE_VALUES: independent implicit Newmark check, k_s = k, r = 0.4: peak F13 ~ 30.5 N;
    the paper's numerical contact durations are 20-25 ms."""
    df = pd.read_parquet(six_hz[0]).set_index(["ks_ratio", "r"])
    row = df.loc[(1.0, 0.4)]
    assert row.peak_force_f3_N == pytest.approx(30.5, rel=0.02)
    assert 0.020 <= row.median_compression_phase_f3_s <= 0.025
    assert row.impacts_f3 > 20  # it pounds about once per cycle over 5 s at 6 Hz
    assert row.min_force_f3_N < 0  # the classic law pulls briefly before separation
    # no dashpot at r = 1: no pull; the force where a contact ends is zero up to the event scheme's switch
    # residue (k_s times kernel._switch_tolerance: a smaller penetration is not a switch)
    el = df.loc[df.index.get_level_values("r") == 1.0]
    residue = switch_residue_force(el.ks_N_per_m, el.peak_disp_b1f3_m, el.peak_disp_b2f3_m)
    assert (el.min_force_f3_N >= -residue).all()


def test_metadata_is_self_describing(six_hz):
    out = six_hz[0]
    md = read_metadata(out)
    raw = read_schema(out).metadata
    assert md["version"] == pounding_sweep.__version__ and md["numba_version"]
    assert raw[b"scene_toml"].decode() == (SWEEPS / "paper_6hz.toml").read_text()
    assert raw[b"config_hash"].decode() == md["config_hash"] == load_scene(SWEEPS / "paper_6hz.toml").config_hash()
    assert md["buildings"][0]["frequencies_Hz"][0] == pytest.approx(4.248, abs=1e-3)
    assert md["dt_s"] == 1e-4 and md["scheme"] == "event"
    assert "peak_force_f*_N" in md["columns"]
    names = read_schema(out).names
    for col in (
        "peak_disp_b1f3_m",
        "peak_abs_acc_b2f3_m_s2",
        "peak_force_f3_N",
        "contact_time_f1_s",
        "status",
        "run_time_s",
    ):
        assert col in names


def test_metrics_only_scene_writes_no_histories(six_hz):
    assert not list(six_hz[0].parent.glob("*histories*"))


def test_histories_when_asked_and_identical_across_threads(tmp_path):
    text = (
        (SWEEPS / "paper_6hz.toml")
        .read_text()
        .replace(
            'path = "../results/paper_6hz.parquet"',
            'path = "out.parquet"\nhistories = ["disp_b1f3", "force_f3"]\nhistory_decimate = 10',
        )
        .replace("duration_s = 5.0", "duration_s = 1.0")
    )
    (tmp_path / "s.toml").write_text(text)
    scene = load_scene(tmp_path / "s.toml")
    s1 = run_scene(scene, out_path=tmp_path / "one.parquet", threads=1)
    s2 = run_scene(scene, out_path=tmp_path / "two.parquet", threads=2)
    a, b = pd.read_parquet(s1.path), pd.read_parquet(s2.path)
    pd.testing.assert_frame_equal(a.drop(columns="run_time_s"), b.drop(columns="run_time_s"))  # bit-identical
    h = pd.read_parquet(s1.histories_path)
    assert list(h.columns) == ["run_id", "t_s", "disp_b1f3_m", "force_f3_N"]
    assert len(h) == 20 * (10000 // 10 + 1)
    one = h[h.run_id == 6]
    assert one.t_s.iloc[1] == pytest.approx(1e-3)
    # decimated history peaks cannot exceed the per-step metrics (the very values the history samples, in the
    # same run: no tolerance), and come close
    assert one.force_f3_N.max() <= a.loc[6, "peak_force_f3_N"]
    assert one.force_f3_N.max() > 0.9 * a.loc[6, "peak_force_f3_N"]


def test_duzce_scene_runs_with_similitude_and_record(tmp_path):
    scene = load_scene(SWEEPS / "paper_duzce.toml")
    s = run_scene(scene, out_path=tmp_path / "d.parquet")
    df = pd.read_parquet(s.path)
    assert len(df) == 20 and set(df.record) == {"RSN1605_DUZCE_DZC180"}
    # record 25.885 s at 0.005 s, time / sqrt(15) -> 6.684 s at dt 1e-4
    assert df.steps.max() == int(np.floor(5176 * 0.005 / np.sqrt(15) / 1e-4 + 1e-9))
    md = read_metadata(s.path)
    assert md["records"][0]["dt_s"] == pytest.approx(0.005 / np.sqrt(15))


def test_separated_scene_never_touches(tmp_path):
    s = run_scene(load_scene(SWEEPS / "paper_duzce_separated.toml"), out_path=tmp_path / "sep.parquet")
    df = pd.read_parquet(s.path)
    assert (df.filter(like="impacts_").to_numpy() == 0).all() and (df.peak_force_f3_N == 0).all()
    assert df.peak_disp_b1f3_m.nunique() == 1  # contact parameters cannot matter without contact
    assert (df.status == "ok").all()


def test_record_axis_and_csv_record(tmp_path, shared_dir):
    """A [sweep] record axis runs each record; a two-column CSV record gives the same run as its AT2."""
    from pounding_sweep.model.records import read_at2

    gm = shared_dir / "data" / "ground_motions"
    rec = read_at2(gm / "RSN1605_DUZCE_DZC180.AT2")
    csv = tmp_path / "dzc180.csv"
    np.savetxt(csv, np.column_stack([rec.time_s, rec.acc_m_s2]), delimiter=",", header="t_s,acc_m_s2", comments="")
    text = (SWEEPS / "paper_duzce.toml").read_text()
    text = text.replace('record = "records/RSN1605_DUZCE_DZC180.AT2"', f'record = "{gm}/RSN1605_DUZCE_DZC180.AT2"')
    text = text.replace('units = "g"\n', "").replace(
        "[sweep]\n", f'[sweep]\nrecord = ["{gm}/RSN1605_DUZCE_DZC180.AT2", "{gm}/RSN1605_DUZCE_DZC270.AT2", "{csv}"]\n'
    )
    text = text.replace("ks_ratio = [0.1, 1.0, 5.0, 10.0]", "ks_ratio = [1.0]").replace(
        "r = [0.2, 0.4, 0.6, 0.8, 1.0]", "r = [0.2]"
    )
    (tmp_path / "s.toml").write_text(text)
    s = run_scene(load_scene(tmp_path / "s.toml"), out_path=tmp_path / "o.parquet")
    df = pd.read_parquet(s.path).set_index("record")
    assert list(df.index) == ["RSN1605_DUZCE_DZC180", "RSN1605_DUZCE_DZC270", "dzc180"]
    assert df.loc["RSN1605_DUZCE_DZC180", "peak_disp_b1f3_m"] != df.loc["RSN1605_DUZCE_DZC270", "peak_disp_b1f3_m"]
    # the CSV's step, from its first and last stamps, is the AT2's to the bit, and so are its samples: the
    # same inputs give the same run, bit for bit (no tolerance: nothing rounds differently)
    metrics = [c for c in df.columns if c not in ("run_id", "run_time_s")]
    csv_row, at2_row = df.loc["dzc180", metrics], df.loc["RSN1605_DUZCE_DZC180", metrics]
    assert csv_row.equals(at2_row), csv_row.compare(at2_row)


def test_amplitude_and_frequency_axes(tmp_path):
    text = (SWEEPS / "paper_6hz.toml").read_text().replace("duration_s = 5.0", "duration_s = 1.0")
    text = text.replace("[sweep]\n", "[sweep]\namplitude_m = [0.001, 0.002]\nfrequency_Hz = [4.613, 6.0]\n")
    text = text.replace("ks_ratio = [0.1, 1.0, 5.0, 10.0]", "ks_ratio = [1.0]").replace(
        "r = [0.2, 0.4, 0.6, 0.8, 1.0]", "r = [0.4]"
    )
    (tmp_path / "s.toml").write_text(text)
    df = pd.read_parquet(run_scene(load_scene(tmp_path / "s.toml"), out_path=tmp_path / "o.parquet").path)
    assert list(zip(df.amplitude_m, df.frequency_Hz)) == [(0.001, 4.613), (0.001, 6.0), (0.002, 4.613), (0.002, 6.0)]
    assert df.peak_disp_b1f3_m.nunique() == 4
