"""The whole chain on rendered videos of the real model: free vibration -> video -> tracked table
-> f1 within 0.5 % -> model update; and a forced pounding test with hidden contact parameters ->
video -> tracked table -> sweep, which finds the hidden (k_s/k, r)."""

from __future__ import annotations

import numpy as np
import pytest

cv2 = pytest.importorskip("cv2")

from conftest import SWEEPS  # noqa: E402

from pounding_sweep.identify.modes import identify  # noqa: E402
from pounding_sweep.identify.update import update_building  # noqa: E402
from pounding_sweep.model.coupled import CoupledModel  # noqa: E402
from pounding_sweep.scene import load_scene  # noqa: E402
from pounding_sweep.scene.video import VideoSpec  # noqa: E402
from pounding_sweep.sweep.run import run_scene  # noqa: E402
from pounding_sweep.sweep.simulate import simulate  # noqa: E402
from pounding_sweep.synthetic import make_experiment  # noqa: E402
from pounding_sweep.video.render import (  # noqa: E402
    RenderOptions,
    harmonic_table,
    motion_from_history,
    render_video,
    shake_table_layout,
    table_from_ground_acceleration,
    write_pulse_record,
)
from pounding_sweep.video.tracker import track_video, write_tracked_table  # noqa: E402

FREE_SCENE = """name = "knock"
[building1]
masses_kg = [1.7, 1.7, 1.6]
story_stiffness_N_per_m = {k1}
damping_ratio = 0.0105
[building2]
masses_kg = [0.56, 0.56, 0.45]
story_stiffness_N_per_m = {k2}
damping_ratio = 0.0107
[contact]
gap_m = 0.05          # apart: free vibration of each building
ks_ratio = 1.0
r = 0.4
[excitation]
type = "record"
record = "knock.csv"  # one sine cycle of table acceleration, then zeros
units = "m/s2"
duration_s = 4.0
"""


@pytest.fixture(scope="module")
def free_vibration(tmp_path_factory):
    """The paper's models knocked by the table, filmed for 4 s at 100 fps (noise 2 grey levels)."""
    d = tmp_path_factory.mktemp("free")
    write_pulse_record(d / "knock.csv", peak_m_s2=3.0, frequency_Hz=10.0)
    (d / "knock.toml").write_text(FREE_SCENE.format(k1=5920.0, k2=5140.0))
    scene = load_scene(d / "knock.toml")
    hist, m = simulate(scene, channels=[f"disp_b{b}f{f}" for b in (1, 2) for f in (1, 2, 3)] + ["ground_acc"])
    assert m["status"] == "ok" and m["impacts_f3"] == 0
    table = table_from_ground_acceleration(hist.t_s.to_numpy(), hist.ground_acc_m_s2.to_numpy())
    lay = shake_table_layout()
    rv = render_video(d / "knock.mkv", lay, motion_from_history(hist, table), 400, RenderOptions(noise=2.0, seed=11))
    res = track_video(
        VideoSpec(path=str(rv.path), markers=lay.names, references=lay.references, mm_per_px=lay.mm_per_px)
    )
    return scene, res


def test_first_frequency_from_a_rendered_free_vibration_video_within_half_a_percent(free_vibration):
    scene, res = free_vibration
    model = CoupledModel.from_scene(scene)
    for b, frame in ((1, model.b1), (2, model.b2)):
        names = [f"b{b}f{f}" for f in (1, 2, 3)]
        X = np.column_stack([res.displacement_mm[:, res.floor_markers.index(n)] for n in names])
        r = identify(X, res.fps, names, n_modes=1, free_vibration=True, start_s=0.2)
        f1 = frame.modes().frequency_Hz[0]
        assert r.modes[0].frequency_Hz == pytest.approx(f1, rel=0.005)
        # first-mode shape ratios against the model's (floor 3 = 1)
        phi = frame.modes().shapes[:, 0] / frame.modes().shapes[-1, 0]
        got = np.array([r.modes[0].shape[n] for n in names])
        assert got == pytest.approx(phi, abs=0.03)
        # damping by logarithmic decrement: the model's 1.05 % / 1.07 %, within a quarter
        assert r.modes[0].damping_log_decrement == pytest.approx(frame.modes().damping_ratio[0], rel=0.25)
        # asked for three modes, it reports only peaks above the tracking noise, each a model mode
        r3 = identify(X, res.fps, names, n_modes=3, free_vibration=True, start_s=0.2)
        assert len(r3.modes) >= 1
        for m in r3.modes:
            assert np.min(np.abs(frame.modes().frequency_Hz / m.frequency_Hz - 1)) < 0.01, m.frequency_Hz


def test_model_update_from_the_video_recovers_the_true_stiffness(free_vibration):
    """Start from the paper's initial model (EI = 5.4 N m^2, 4 columns, h = 0.336 m); the f1 read
    from the video (the 'experiment', whose story stiffness is 5920 N/m) updates it to 5920 within 1 %."""
    scene, res = free_vibration
    names = ["b1f1", "b1f2", "b1f3"]
    X = np.column_stack([res.displacement_mm[:, res.floor_markers.index(n)] for n in names])
    f1 = identify(X, res.fps, names, n_modes=1, start_s=0.2).modes[0].frequency_Hz
    initial = scene.building1.__class__(
        masses_kg=(1.7, 1.7, 1.6), column_EI_Nm2=(5.4,), n_columns=4, story_height_m=(0.336,), damping_ratio=0.0105
    )
    u = update_building(initial, f1)
    assert u.factor < 1  # the paper's direction: the columns are softer than 5.4 N m^2
    assert u.story_stiffness_N_per_m[0] == pytest.approx(5920.0, rel=0.01)
    assert u.updated.column_EI_Nm2[0] == pytest.approx(5920.0 * 0.336**3 / 48, rel=0.01)


def test_video_to_tracked_table_to_sweep_finds_the_hidden_contact_parameters(tmp_path):
    """make_experiment's hidden (k_s/k = 5, r = 0.4) on a perturbed structure (the model error the
    shipped synthetic experiment has), rendered with sensor noise, camera shake and roll instead of
    table noise, tracked with automatic layout, written as Parquet and scored by the paper's grid."""
    base = load_scene(SWEEPS / "scored_6hz.toml")
    truth, prov = make_experiment(base, {"ks_ratio": 5.0, "r": 0.4}, noise_mm=0.0, fps=100.0)
    cols = {f"b{b}f{f}": f"model{b}_floor{f}_mm" for b in (1, 2) for f in (1, 2, 3)}
    motion = motion_from_history(truth, harmonic_table(2.0, 6.0), columns=cols, scale=1.0)
    lay = shake_table_layout()
    rv = render_video(
        tmp_path / "run.mkv", lay, motion, len(truth), RenderOptions(noise=2.0, shake_px=0.3, roll_deg=0.1, seed=3)
    )
    res = track_video(
        VideoSpec(path=str(rv.path), markers=lay.names, references=lay.references, mm_per_px=lay.mm_per_px)
    )
    for j, n in enumerate(res.floor_markers):
        assert np.sqrt(np.mean((res.displacement_mm[:, j] - rv.truth_rel_mm[n]) ** 2)) < 0.1, n
    write_tracked_table(res.table(), res.provenance, tmp_path / "tracked.parquet")
    text = (SWEEPS / "scored_6hz.toml").read_text()
    for old, new in (
        ('table = "experiments/synthetic_6hz.parquet"', 'table = "tracked.parquet"'),
        (
            'channels = { model1_floor3_mm = "b1f3", model2_floor3_mm = "b2f3" }',
            'channels = { b1f3 = "b1f3", b2f3 = "b2f3" }',
        ),
        ("refine = true", "refine = false"),
        ('path = "../results/scored_6hz.parquet"', 'path = "out.parquet"'),
    ):
        assert old in text
        text = text.replace(old, new)
    (tmp_path / "scene.toml").write_text(text)
    summary = run_scene(load_scene(tmp_path / "scene.toml"), threads=2)
    best = summary.best.set_index("criterion")
    for crit in ("rel_rms_combined_pct", "rel_rms_b1f3_pct"):
        assert (best.loc[crit, "ks_ratio"], best.loc[crit, "r"]) == (5.0, 0.4), best
