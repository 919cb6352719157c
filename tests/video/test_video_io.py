"""Bad input, the `track` / `identify` commands, the `[experiment.video]` section, and OpenCV kept
out of a sweep's imports."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pandas as pd
import pyarrow.parquet as pq
import pytest

cv2 = pytest.importorskip("cv2")

from conftest import REPO  # noqa: E402

from pounding_sweep.cli.identify import identify_main  # noqa: E402
from pounding_sweep.cli.track import track_main  # noqa: E402
from pounding_sweep.scene import ConfigError, ExperimentConfig  # noqa: E402
from pounding_sweep.scene.video import VideoSpec, floor_code, parse_video_section  # noqa: E402
from pounding_sweep.sweep.scoring import load_experiment  # noqa: E402
from pounding_sweep.video.io import VideoError, VideoReader, write_video  # noqa: E402
from pounding_sweep.video.render import RenderOptions, harmonic_table, render_video, shake_table_layout  # noqa: E402
from pounding_sweep.video.tracker import tracked_table  # noqa: E402

NAMES = "table_left,table_right,b1f1,b1f2,b1f3,b2f1,b2f2,b2f3"


def motion(t):
    t = np.asarray(t, dtype=float)
    out = {"table": harmonic_table(1.0, 6.0)(t)}
    for b in (1, 2):
        for f in (1, 2, 3):
            out[f"b{b}f{f}"] = 1.5 * f * np.sin(2 * np.pi * (4.25 if b == 1 else 7.17) * t)
    return out


@pytest.fixture(scope="module")
def video(tmp_path_factory):
    d = tmp_path_factory.mktemp("io")
    return render_video(d / "run.mkv", shake_table_layout(), motion, 80, RenderOptions(noise=1.0))


def run_cli(main, argv, capsys):
    code = main(argv)
    out, err = capsys.readouterr()
    return code, out, err


# ------------------------------------------------------------------ reading


def test_missing_directory_unreadable_and_empty_videos_are_one_clear_error(tmp_path):
    with pytest.raises(VideoError, match="video file not found"):
        VideoReader(tmp_path / "nope.mkv")
    with pytest.raises(VideoError, match="not a file"):
        VideoReader(tmp_path)
    junk = tmp_path / "junk.mkv"
    junk.write_bytes(np.random.default_rng(0).integers(0, 256, 4000, dtype=np.uint8).tobytes())
    with pytest.raises(VideoError, match="not a video OpenCV can decode"):
        VideoReader(junk)
    empty = tmp_path / "empty.avi"
    empty.write_bytes(b"")
    with pytest.raises(VideoError, match="not a video OpenCV can decode"):
        VideoReader(empty)
    # a container with a header and no frames
    zero = tmp_path / "zero.mkv"
    w = cv2.VideoWriter(str(zero), cv2.CAP_FFMPEG, cv2.VideoWriter_fourcc(*"FFV1"), 100.0, (64, 48), True)
    w.release()
    with pytest.raises(VideoError, match="(no frames|not a video)"):
        VideoReader(zero)


def test_frames_are_counted_by_reading(video):
    with VideoReader(video.path) as r:
        n = sum(1 for _ in r.frames())
        assert r.info.fps == 100.0 and (r.info.width, r.info.height) == (320, 240)
    assert n == 80


def test_writer_refuses_unknown_codecs_and_leaves_no_partial_file(tmp_path):
    with pytest.raises(VideoError, match="codec must be one of"):
        write_video(tmp_path / "a.mkv", [np.zeros((8, 8, 3), np.uint8)], 10.0, codec="avc1")
    with pytest.raises(VideoError, match="no frames"):
        write_video(tmp_path / "b.mkv", [], 10.0)
    assert list(tmp_path.iterdir()) == []


# ------------------------------------------------------------------ track command


def test_track_writes_a_table_that_scoring_reads(video, tmp_path, capsys):
    out = tmp_path / "tracked.csv"
    code, stdout, err = run_cli(
        track_main,
        [
            str(video.path),
            "--markers",
            NAMES,
            "--references",
            "table_left,table_right",
            "--mm-per-px",
            "5",
            "--out",
            str(out),
            "--quiet",
        ],
        capsys,
    )
    assert code == 0, err
    assert err == "" and stdout == ""
    df = pd.read_csv(out)
    assert list(df.columns[:7]) == ["t_s", "b1f1", "b1f2", "b1f3", "b2f1", "b2f2", "b2f3"]
    assert "b1f3_quality" in df and "table_in_camera_mm" in df and "frame" in df
    assert np.allclose(np.diff(df.t_s), 0.01)
    # the existing [experiment] path reads it, extra columns ignored
    cfg = ExperimentConfig(table=str(out), channels={"b1f3": "b1f3", "b2f3": "b2f3"})
    exp = load_experiment(cfg, (3, 3))
    truth = video.truth_rel_mm["b1f3"] - video.truth_rel_mm["b1f3"][0]
    assert np.sqrt(np.mean((exp.channels["b1f3"] * 1e3 - truth) ** 2)) < 0.06
    assert not list(tmp_path.glob("*.tmp"))


def test_track_parquet_keeps_provenance_and_positions(video, tmp_path, capsys):
    out = tmp_path / "tracked.parquet"
    pos = [f"--marker={n}={x:.2f},{y:.2f}" for n, (x, y) in zip(video.layout.names, video.truth_px[0])]
    code, stdout, err = run_cli(
        track_main,
        [
            str(video.path),
            *pos,
            "--references",
            "table_left,table_right",
            "--scale",
            "table_left,table_right,1400",
            "--pixels",
            "--out",
            str(out),
        ],
        capsys,
    )
    assert code == 0, err
    assert "b1f3" in stdout and "every frame ok" in stdout
    t = pq.read_table(out)
    prov = json.loads(t.schema.metadata[b"provenance"])
    assert prov["mm_per_px"] == pytest.approx(5.0, rel=1e-4) and prov["frames"] == 80
    assert prov["video"].endswith("run.mkv") and prov["opencv_version"] == cv2.__version__
    df = t.to_pandas()
    assert "b1f3_x_px" in df and abs(df.b1f3_x_px.iloc[5] - video.truth("b1f3")[5, 0]) < 0.05


@pytest.mark.parametrize(
    "argv, message",
    [
        (["{missing}"], "video file not found"),
        (["{junk}"], "not a video OpenCV can decode"),
        (["{video}", "--markers", "table_left,table_right,b1f1"], "expected 3 markers in the first frame"),
        (["{video}", "--mm-per-px", "-5"], "mm_per_px = -5.0: must be > 0"),
        (["{video}", "--out", "{tmp}/x.txt"], "must be .csv or .parquet"),
        (["{video}", "--roi", "1,2,3"], "--roi"),
        (["{video}", "--references", "nobody"], "'nobody' is not one of the markers"),
        (["{video}", "--max-gap", "0", "--start-frame", "79"], "fewer than 2 frames"),
    ],
)
def test_track_bad_input_is_one_line_exit_2_and_no_table(argv, message, video, tmp_path, capsys):
    junk = tmp_path / "junk.avi"
    junk.write_bytes(b"RIFF" + bytes(500))
    subs = {
        "{missing}": str(tmp_path / "missing.mkv"),
        "{junk}": str(junk),
        "{video}": str(video.path),
        "{tmp}": str(tmp_path),
    }
    argv = [subs.get(a, a.replace("{tmp}", str(tmp_path))) for a in argv]
    base = ["--markers", NAMES, "--references", "table_left,table_right", "--mm-per-px", "5"]
    full = [argv[0], *base, *argv[1:]]  # later options override
    if "--out" not in full:
        full += ["--out", str(tmp_path / "t.csv")]
    code, stdout, err = run_cli(track_main, full, capsys)
    assert code == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and message in lines[0], err
    assert "Traceback" not in err
    assert not list(tmp_path.glob("*.csv")) and not list(tmp_path.glob("*.tmp"))


def test_track_via_the_module_entry_point_is_silent_about_ffmpeg(tmp_path):
    junk = tmp_path / "junk.mkv"
    junk.write_bytes(np.random.default_rng(1).integers(0, 256, 3000, dtype=np.uint8).tobytes())
    p = subprocess.run(
        [
            sys.executable,
            "-m",
            "pounding_sweep",
            "track",
            str(junk),
            "--markers",
            "table_left,b1f1",
            "--references",
            "table_left",
            "--mm-per-px",
            "1",
        ],
        capture_output=True,
        text=True,
        cwd=REPO,
    )
    assert p.returncode == 2
    assert p.stderr.strip().splitlines() == [f"error: {junk}: not a video OpenCV can decode (3000 bytes)"]


# ------------------------------------------------------------------ identify command


def test_identify_prints_modes_and_writes_the_update(video, tmp_path, capsys):
    table = tmp_path / "tracked.csv"
    assert (
        track_main(
            [
                str(video.path),
                "--markers",
                NAMES,
                "--references",
                "table_left,table_right",
                "--mm-per-px",
                "5",
                "--out",
                str(table),
                "--quiet",
            ]
        )
        == 0
    )
    capsys.readouterr()
    upd = tmp_path / "updated.toml"
    argv = [str(table), "--modes", "1", "--scene", str(REPO / "sweeps/paper_6hz.toml"), "--out", str(upd)]
    # the rendered table moves at 6 Hz only (table_in_camera_mm): a harmonic test, refused
    code, out, err = run_cli(identify_main, argv, capsys)
    assert code == 2 and "'table_in_camera_mm' is a single-frequency (harmonic) table motion" in err
    assert not upd.exists()
    # this video's floors are drawn at their modes whatever the table does: identify them from the floors alone;
    # 80 frames resolve 1.25 Hz, so Model-2's 7.17 Hz cannot be told from the scene's 6 Hz forcing: forced
    code, out, err = run_cli(identify_main, argv + ["--input", "none"], capsys)
    assert code == 2 and "model update refused: building2: f1 7.1" in err and not upd.exists()
    code, out, err = run_cli(identify_main, argv + ["--input", "none", "--force-update"], capsys)
    assert code == 0, err
    assert "method: output-only" in out and "warning: model update forced although building2" in err
    assert "building 1" in out and "building 2" in out and "mode 1: 4.2" in out
    text = upd.read_text()
    assert "[building1]" in text and "[building2]" in text and "story_stiffness_N_per_m" in text
    code, out, err = run_cli(identify_main, [str(video.path)], capsys)
    assert code == 2 and "track the video first" in err and len(err.strip().splitlines()) == 1
    code, out, err = run_cli(identify_main, [str(table), "--columns", "nope"], capsys)
    assert code == 2 and "no column 'nope'" in err
    code, out, err = run_cli(identify_main, [str(tmp_path / "none.csv")], capsys)
    assert code == 2 and "not found" in err


# ------------------------------------------------------------------ [experiment.video]

GOOD = {
    "path": "v.mkv",
    "markers": {"table_left": [20, 226], "table_right": [300, 226], "b1f3": [140, 24]},
    "references": ["table_left", "table_right"],
    "mm_per_px": 5.0,
}


def test_video_section_parses_and_resolves_the_path(tmp_path):
    spec = parse_video_section(dict(GOOD), tmp_path)
    assert spec.path == str((tmp_path / "v.mkv").resolve())
    assert spec.markers == ("table_left", "table_right", "b1f3") and spec.floor_markers == ("b1f3",)
    assert spec.positions_px[2] == (140.0, 24.0)
    assert spec.default_channels() == {"b1f3": "b1f3"}
    auto = parse_video_section({**GOOD, "markers": ["table_left", "table_right", "model1_floor3_mm"]}, tmp_path)
    assert auto.positions_px is None and auto.default_channels() == {"model1_floor3_mm": "b1f3"}
    assert floor_code("b2f1_mm") == "b2f1" and floor_code("table") is None


@pytest.mark.parametrize(
    "change, message",
    [
        ({"mm_per_pix": 5.0}, "unknown key 'mm_per_pix' in [experiment.video]; did you mean 'mm_per_px'?"),
        ({"mm_per_px": 0}, "[experiment.video] mm_per_px = 0: must be > 0"),
        (
            {"mm_per_px": None, "scale_markers": ["table_left", "table_right"]},
            "give the image scale either as mm_per_px",
        ),
        ({"references": []}, "name at least one marker fixed to the table"),
        ({"references": ["b9f9"]}, "'b9f9' is not one of the markers"),
        ({"markers": {"table_left": [1, 2], "b1f3": [3]}}, "markers.b1f3 = [3]: expected [x, y]"),
        ({"markers": ["table_left", "table_right", "lamp"]}, "automatic layout needs floor names"),
        ({"roi_px": [10, 10, 5, 50]}, "roi_px = [10, 10, 5, 50]"),
        ({"method": "fast"}, "method = 'fast': expected 'weighted' or 'paper'"),
        ({"median_ksize": 4}, "median_ksize = 4: must be odd"),
        ({"threshold": 1.5}, "threshold = 1.5: must be <= 1.0"),
        ({"max_gap_frames": 2.5}, "max_gap_frames = 2.5: expected an integer"),
        ({"path": 3}, "path = 3: expected a file name"),
    ],
)
def test_video_section_bad_values_name_key_and_value(change, message, tmp_path):
    table = {**GOOD, **change}
    table = {k: v for k, v in table.items() if v is not None}
    with pytest.raises(ConfigError) as e:
        parse_video_section(table, tmp_path)
    assert message in str(e.value)


def test_tracked_table_hook_and_cache(video, tmp_path):
    spec = VideoSpec(
        path=str(video.path), markers=tuple(NAMES.split(",")), references=("table_left", "table_right"), mm_per_px=5.0
    )
    df, prov = tracked_table(spec)
    assert df.columns[0] == "t_s" and set(spec.floor_markers) <= set(df.columns)
    assert prov["frames"] == 80 and prov["transform"] == "similarity"
    df1, _ = tracked_table(spec, cache_dir=tmp_path / "cache")
    files = list((tmp_path / "cache").iterdir())
    assert len(files) == 1
    df2, prov2 = tracked_table(spec, cache_dir=tmp_path / "cache")
    pd.testing.assert_frame_equal(df1, df2)
    assert prov2["frames"] == 80


def test_import_and_a_sweep_never_import_opencv():
    code = (
        "import sys, pounding_sweep, pounding_sweep.scene, pounding_sweep.sweep.run, pounding_sweep.model.experiment, "
        "pounding_sweep.cli, pounding_sweep.identify.modes, pounding_sweep.identify.update, pounding_sweep.scene.video; "
        "print('cv2' in sys.modules)"
    )
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=REPO)
    assert p.returncode == 0, p.stderr
    assert p.stdout.strip() == "False"


def test_progress_is_called_with_done_and_total_and_fps_can_be_overridden(video):
    calls = []
    spec = VideoSpec(
        path=str(video.path),
        markers=tuple(NAMES.split(",")),
        references=("table_left", "table_right"),
        mm_per_px=5.0,
        fps=50.0,
    )
    from pounding_sweep.video.tracker import track_video

    res = track_video(spec, progress=lambda done, total: calls.append((done, total)))
    assert calls[0][0] == 1 and calls[-1] == (80, 80) and len(calls) >= 80
    assert all(total >= done for done, total in calls)
    assert res.fps == 50.0 and res.t_s[1] == pytest.approx(0.02)
    assert res.provenance["container_fps"] == 100.0
