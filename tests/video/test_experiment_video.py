"""A scene scored straight from a video: `[experiment.video]` tracks it into the experiment table.

The video is rendered from the model with hidden contact parameters (k_s/k = 5, r = 0.4) on a
perturbed structure; the sweep over the paper's grid must pick the hidden cell. Bad video input
is one clear error and leaves no output.
"""

from __future__ import annotations

import dataclasses
import subprocess
import sys

import pytest
from conftest import REPO, SWEEPS

from pounding_sweep.scene import ConfigError, load_scene
from pounding_sweep.sweep.run import run_scene

pytest.importorskip("cv2")

VIDEO_SECTION = """
[experiment.video]
path = "{video}"
markers = {markers}
references = {references}
mm_per_px = {mm_per_px}
"""


def _scene_text(video: str, markers, references, mm_per_px: float, duration: float = 2.0) -> str:
    text = (SWEEPS / "scored_6hz.toml").read_text()
    for old, new in (
        ("table = \"experiments/synthetic_6hz.parquet\"   # SYNTHETIC: see its Parquet metadata ('provenance')\n", ""),
        (
            'channels = { model1_floor3_mm = "b1f3", model2_floor3_mm = "b2f3" }   # 3rd floors, as Tables 2-3',
            'channels = { b1f3 = "b1f3", b2f3 = "b2f3" }',
        ),
        ("refine = true", "refine = false"),
        ("duration_s = 5.0", f"duration_s = {duration}"),
        ('path = "../results/scored_6hz.parquet"', 'path = "out.parquet"'),
    ):
        assert old in text, old
        text = text.replace(old, new)
    fmt = lambda xs: "[" + ", ".join(f'"{x}"' for x in xs) + "]"  # noqa: E731
    return text + VIDEO_SECTION.format(
        video=video, markers=fmt(markers), references=fmt(references), mm_per_px=mm_per_px
    )


@pytest.fixture(scope="module")
def rendered(tmp_path_factory):
    from pounding_sweep.synthetic import make_experiment
    from pounding_sweep.video.render import (
        RenderOptions,
        harmonic_table,
        motion_from_history,
        render_video,
        shake_table_layout,
    )

    d = tmp_path_factory.mktemp("video_scene")
    base = load_scene(SWEEPS / "scored_6hz.toml")
    base = dataclasses.replace(base, excitation=dataclasses.replace(base.excitation, duration_s=2.0))
    truth, _ = make_experiment(base, {"ks_ratio": 5.0, "r": 0.4}, noise_mm=0.0, fps=100.0)
    cols = {f"b{b}f{f}": f"model{b}_floor{f}_mm" for b in (1, 2) for f in (1, 2, 3)}
    lay = shake_table_layout()
    motion = motion_from_history(truth, harmonic_table(2.0, 6.0), columns=cols, scale=1.0)
    render_video(d / "run.mkv", lay, motion, len(truth), RenderOptions(noise=2.0, seed=5))
    return d, lay


def test_sweep_scored_from_a_video_finds_the_hidden_contact_parameters(rendered):
    d, lay = rendered
    (d / "scene.toml").write_text(_scene_text("run.mkv", lay.names, lay.references, lay.mm_per_px))
    scene = load_scene(d / "scene.toml")
    assert scene.experiment.video is not None and scene.experiment.table is None
    summary = run_scene(scene, threads=2)
    best = summary.best.set_index("criterion")
    assert (best.loc["rel_rms_combined_pct", "ks_ratio"], best.loc["rel_rms_combined_pct", "r"]) == (5.0, 0.4), best
    assert best.loc["rel_rms_combined_pct", "error_pct"] < 10.0


def test_loading_a_video_scene_does_not_import_opencv(rendered):
    d, lay = rendered
    (d / "lazy.toml").write_text(_scene_text("run.mkv", lay.names, lay.references, lay.mm_per_px))
    code = (
        "import sys; from pounding_sweep.scene import load_scene; s = load_scene(sys.argv[1]); "
        "print(s.experiment.video is not None, 'cv2' in sys.modules)"
    )
    out = subprocess.run([sys.executable, "-c", code, str(d / "lazy.toml")], capture_output=True, text=True, cwd=REPO)
    assert out.stdout.split() == ["True", "False"], out.stderr


def test_missing_video_is_one_error_and_no_output(rendered, tmp_path):
    _, lay = rendered
    (tmp_path / "scene.toml").write_text(_scene_text("nowhere.mkv", lay.names, lay.references, lay.mm_per_px))
    p = subprocess.run(
        [sys.executable, "-m", "pounding_sweep", str(tmp_path / "scene.toml")], capture_output=True, text=True, cwd=REPO
    )
    assert p.returncode == 2 and "Traceback" not in p.stderr
    assert "nowhere.mkv" in p.stderr and "not found" in p.stderr
    assert not (tmp_path / "out.parquet").exists()


def test_unreadable_video_is_one_error_and_no_output(rendered, tmp_path):
    _, lay = rendered
    (tmp_path / "fake.mkv").write_bytes(b"this is not a video" * 100)
    (tmp_path / "scene.toml").write_text(_scene_text("fake.mkv", lay.names, lay.references, lay.mm_per_px))
    p = subprocess.run(
        [sys.executable, "-m", "pounding_sweep", str(tmp_path / "scene.toml")], capture_output=True, text=True, cwd=REPO
    )
    assert p.returncode == 2 and "Traceback" not in p.stderr and "fake.mkv" in p.stderr, p.stderr
    assert not (tmp_path / "out.parquet").exists()


def test_table_and_video_together_are_refused(rendered, tmp_path):
    _, lay = rendered
    text = _scene_text("run.mkv", lay.names, lay.references, lay.mm_per_px).replace(
        "[experiment]\n", '[experiment]\ntable = "t.csv"\n'
    )
    (tmp_path / "scene.toml").write_text(text)
    with pytest.raises(ConfigError, match=r"either table = .* or an \[experiment.video\] section.*not both"):
        load_scene(tmp_path / "scene.toml")
