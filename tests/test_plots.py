"""Figures and tables of a result file: `python -m pounding_sweep plot` and pounding_sweep.plots."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pandas as pd
import pytest
from conftest import REPO, SWEEPS

pytest.importorskip("matplotlib", reason="plots need the 'plot' extra (matplotlib)")

from pounding_sweep import plots
from pounding_sweep.scene import load_scene  # noqa: E402
from pounding_sweep.sweep.results import read_metadata  # noqa: E402

FIGURES = {"heatmaps", "displacement_history", "pounding_force", "ssp", "measured_vs_model", "error_vs_runtime"}


@pytest.fixture(scope="module")
def scored(tmp_path_factory):
    """The shipped scored 6 Hz sweep (20 runs, refined), run once for this module."""
    from pounding_sweep.sweep.run import run_scene

    out = tmp_path_factory.mktemp("scored") / "scored.parquet"
    run_scene(load_scene(SWEEPS / "scored_6hz.toml"), out_path=out, threads=1)
    return out


def test_plot_command_writes_pngs(tmp_path):
    out = tmp_path / "scored.parquet"
    run = subprocess.run(
        [sys.executable, "-m", "pounding_sweep", str(SWEEPS / "scored_6hz.toml"), "--out", str(out), "--quiet"],
        capture_output=True,
        text=True,
        cwd=REPO,
    )
    assert run.returncode == 0, run.stderr
    p = subprocess.run(
        [sys.executable, "-m", "pounding_sweep", "plot", str(out), "--out", str(tmp_path / "png")],
        capture_output=True,
        text=True,
        cwd=REPO,
    )
    assert p.returncode == 0, p.stderr
    names = {line.rsplit("/", 1)[-1] for line in p.stdout.split()}
    assert names == {f"{n}.png" for n in FIGURES}
    for n in names:
        data = (tmp_path / "png" / n).read_bytes()
        assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 10_000
    plots.check_plot_folder(out, tmp_path / "png", plots.FIGURE_NAMES)  # its own figures: a rerun may replace them
    assert not [q for q in (tmp_path / "png").iterdir() if q.name.startswith(".")]  # no temporaries left


def test_plot_of_a_missing_file_is_a_clear_error(tmp_path):
    p = subprocess.run(
        [sys.executable, "-m", "pounding_sweep", "plot", str(tmp_path / "nope.parquet")],
        capture_output=True,
        text=True,
        cwd=REPO,
    )
    assert p.returncode == 2 and "nope.parquet" in p.stderr and "Traceback" not in p.stderr


def test_error_tables_are_the_result_rows(scored):
    df = pd.read_parquet(scored)
    assert plots.score_codes(df) == ["b1f3", "b2f3"]
    for code in ("b1f3", "b2f3"):
        t = plots.error_table(df, code)
        assert list(t.index) == [0.1, 1.0, 5.0, 10.0] and list(t.columns) == [0.2, 0.4, 0.6, 0.8, 1.0]
        for _, row in df.iterrows():
            assert t.loc[row.ks_ratio, row.r] == row[f"rel_rms_{code}_pct"]


def test_peak_difference_table_is_table_4(scored):
    df, md = pd.read_parquet(scored), read_metadata(scored)
    peaks = plots.experiment_peaks(plots.scene_of(scored), md)
    t4 = plots.peak_difference_table(df, md, peaks)
    assert t4.shape == (20, 2 * 2) and t4.index.names == ["k_s/k", "r"]  # (k_s/k, r) x 2 channels x (Disp., Diff.)
    assert list(t4.index.get_level_values(0).unique()) == [0.1, 1.0, 5.0, 10.0]
    head1 = t4.columns[0][0]
    pe, te = peaks["b1f3"]
    assert head1.startswith("Model-1, floor 3") and f"{pe * 1e3:.2f} mm at {te:.2f} s" in head1
    row = df[(df.ks_ratio == 5.0) & (df.r == 0.4)].iloc[0]
    assert t4.loc[(5.0, 0.4), (head1, "Disp. [mm]")] == pytest.approx(row.peak_num_b1f3_m * 1e3)
    # Table 4's sign: (experiment - numerical) / experiment
    assert t4.loc[(5.0, 0.4), (head1, "Diff. [%]")] == pytest.approx((pe - row.peak_num_b1f3_m) / pe * 100)
    # without the experiment, the headers recover its peak from the columns
    assert f"experiment {pe * 1e3:.2f} mm)" in plots.peak_difference_table(df, md).columns[0][0]
    # the paper's layout and subset: rows k_s/k in {1, 5, 10}, per channel r in {0.2, 0.4, 0.6} x (Disp., Diff.)
    paper = plots.peak_difference_table(df, md, peaks, r_values=[0.2, 0.4, 0.6], ks_values=[1, 5, 10], layout="paper")
    assert list(paper.index) == [1.0, 5.0, 10.0] and paper.shape == (3, 2 * 3 * 2)
    assert list(paper.columns[:3]) == [
        (head1, "r = 0.2", "Disp. [mm]"),
        (head1, "r = 0.2", "Diff. [%]"),
        (head1, "r = 0.4", "Disp. [mm]"),
    ]
    assert paper.loc[5.0, (head1, "r = 0.4", "Disp. [mm]")] == t4.loc[(5.0, 0.4), (head1, "Disp. [mm]")]


def test_heatmap_marks_the_best_cell_and_flagged_runs(scored):
    from matplotlib.patches import Rectangle

    df, md = pd.read_parquet(scored), read_metadata(scored)
    fig = plots.heatmap_figure(df, md, pd.read_parquet(scored.with_name("scored.best.parquet")))
    axes = [ax for ax in fig.axes if ax.get_label() != "<colorbar>"]
    assert [ax.get_title() for ax in axes] == ["Model-1, floor 3", "Model-2, floor 3"]
    for ax, code in zip(axes, ("b1f3", "b2f3")):
        best = df.loc[df[f"rel_rms_{code}_pct"].idxmin()]
        (box,) = [p for p in ax.patches if isinstance(p, Rectangle)]
        i, j = [0.1, 1.0, 5.0, 10.0].index(best.ks_ratio), [0.2, 0.4, 0.6, 0.8, 1.0].index(best.r)
        assert box.get_xy() == (j - 0.5, i - 0.5)
        texts = [t.get_text() for t in ax.texts]
        assert len(texts) == 20
        assert sum(t.endswith("*") for t in texts) == int((df.status != "ok").sum())
    assert "refined optimum k_s/k = " in fig.get_supxlabel()


def test_accuracy_ladder_converges_and_checks_its_steps():
    scene = load_scene(SWEEPS / "scored_6hz.toml")
    t = plots.accuracy_ladder(
        scene,
        dts=[4e-4, 2e-4, 1e-4],
        schemes=("implicit",),
        ref_dt=2.5e-5,
        duration_s=1.0,
        repeats=1,
        ks_ratio=1.0,
        r=0.4,
    )
    assert list(t.columns[:6]) == ["scheme", "dt_s", "steps", "run_time_s", "rel_rms_pct", "status"]
    assert list(t.dt_s) == [4e-4, 2e-4, 1e-4] and list(t.steps) == [2500, 5000, 10000]
    assert np.all(np.diff(t.rel_rms_pct) < 0) and t.rel_rms_pct.iloc[-1] < 1.0
    assert (t.run_time_s > 0).all() and (t.ref_dt_s == 2.5e-5).all()
    with pytest.raises(ValueError, match="does not divide"):
        plots.accuracy_ladder(scene, dts=[4e-4, 3e-4], ref_dt=1e-4, duration_s=0.2, repeats=1)
    with pytest.raises(ValueError, match="ref_dt"):
        plots.accuracy_ladder(scene, dts=[4e-4, 2e-4], ref_dt=2e-4, duration_s=0.2, repeats=1)


def test_error_vs_runtime_from_a_csv(tmp_path):
    csv = tmp_path / "accuracy.csv"
    pd.DataFrame(
        {
            "scheme": ["implicit"] * 3 + ["paper"] * 3,
            "dt_s": [4e-4, 2e-4, 1e-4] * 2,
            "run_time_s": [1e-3, 2e-3, 4e-3, 0.8e-3, 1.6e-3, 3.2e-3],
            "rel_rms_pct": [1.0, 0.3, 0.08, 2.0, 0.7, np.nan],
            "extra": 0,
        }
    ).to_csv(csv, index=False)
    t = plots.read_accuracy_table(csv)
    fig = plots.error_vs_runtime_figure(t, "test")
    ax_dt, ax_t = fig.axes
    curves = [line for line in ax_t.lines if line.get_linestyle() == "-"]  # one per scheme; markers are separate
    assert [len(line.get_xdata()) for line in curves] == [3, 2]  # the NaN error is left out, and said so
    # a time step is a marker shape, named in the legend: no dt label beside a point can overlap another
    assert not ax_t.texts and [t.get_text() for t in ax_t.get_legend().get_texts()] == [
        "dt = 0.0001 s",
        "dt = 0.0002 s",
        "dt = 0.0004 s",
    ]
    shapes = {line.get_marker() for line in ax_t.lines if line.get_linestyle() == "None"}
    assert len(shapes) == 3
    assert "paper dt = 0.0001 s" in fig.get_supxlabel()
    assert ax_dt.get_xscale() == ax_t.get_yscale() == "log"
    assert "[s]" in ax_dt.get_xlabel() and "[ms]" in ax_t.get_xlabel() and "[%]" in ax_t.get_ylabel()
    pd.DataFrame({"scheme": ["implicit"], "dt": [1e-4]}).to_csv(tmp_path / "bad.csv", index=False)
    with pytest.raises(ValueError, match="missing dt_s, run_time_s, rel_rms_pct"):
        plots.read_accuracy_table(tmp_path / "bad.csv")


def test_figures_carry_units_and_legends(scored):
    figs = plots.figures(
        scored,
        accuracy=pd.DataFrame(
            {
                "scheme": ["implicit", "implicit"],
                "dt_s": [2e-4, 1e-4],
                "run_time_s": [1e-3, 2e-3],
                "rel_rms_pct": [0.3, 0.1],
            }
        ),
    )
    assert set(figs) == FIGURES
    for name, fig in figs.items():
        for ax in fig.axes:
            if ax.get_label() == "<colorbar>":
                assert "[" in ax.get_ylabel(), name
                continue
            assert "[" in ax.get_xlabel() and "[" in ax.get_ylabel(), (name, ax.get_xlabel(), ax.get_ylabel())
    disp = figs["displacement_history"]
    assert [t.get_text() for t in disp.legends[0].get_texts()][:2] == [
        "numerical",
        "experiment (tracked, 100 samples/s)",
    ]
    assert "eq. 20 error" in disp.axes[0].get_title(loc="left")


def test_ssp_draws_the_compared_samples_at_the_fitted_clocks(scored):
    """The sub-space plot holds exactly the samples the scoring and calibration compare (measured_residuals: the
    window, the run's clock offset and each channel's fitted one), and its caption's eq. 20 error is theirs: a
    fitted per-channel offset moves that channel's points and no other's."""
    from pounding_sweep.engine.score import relative_rms_error_pct

    scene, md = plots.scene_of(scored), read_metadata(scored)
    base = {"ks_ratio": 5.0, "r": 0.4}

    for pick in (base, {**base, "time_offset_s_b2f3": 0.02}):
        want = plots.measured_residuals(scene, pick, md)
        axes = plots.history_figures(scene, pick, "test", md)["ssp"].axes
        assert len(axes) == len(want) == 2
        for ax, (_t, xe, xm, _r) in zip(axes, want.values()):
            pts = ax.lines[1]
            np.testing.assert_array_equal(pts.get_xdata(), xe * 1e3)  # displacements drawn in mm
            np.testing.assert_array_equal(pts.get_ydata(), xm * 1e3)
            assert f"eq. 20 error {relative_rms_error_pct(xm, xe):.1f} %" in ax.get_title()
    plain = plots.measured_residuals(scene, base, md)
    late = plots.measured_residuals(scene, {**base, "time_offset_s_b2f3": 0.02}, md)
    np.testing.assert_array_equal(plain["b1f3"][2], late["b1f3"][2])
    assert not np.array_equal(plain["b2f3"][2], late["b2f3"][2])


# ------------------------------------------------------------------ issue 16: wrong files, any two axes, captions


def plot_cli(*argv) -> tuple[int, str, str]:
    import contextlib
    import io

    from pounding_sweep.cli.plot import plot_main

    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = plot_main([str(a) for a in argv])
    return code, out.getvalue(), err.getvalue()


def test_plot_of_the_wrong_file_is_one_error_line(scored, tmp_path):
    from pounding_sweep.sweep.run import run_scene

    s = load_scene(SWEEPS / "paper_6hz.toml")
    import dataclasses

    s = dataclasses.replace(
        s,
        excitation=dataclasses.replace(s.excitation, duration_s=0.2),
        output=dataclasses.replace(s.output, histories=("disp_b1f3",)),
    )
    run_scene(s, out_path=tmp_path / "h.parquet")
    (tmp_path / "notes.parquet").write_text("not parquet")
    cases = {
        SWEEPS / "paper_6hz.toml": "a scene file, not a result: run it first",
        tmp_path
        / "h.histories.parquet": f"the time histories of a sweep, not its result: plot {tmp_path / 'h.parquet'}",
        scored.with_name("scored.best.parquet"): f"the best-runs table of a sweep, not its result: plot {scored}",
        tmp_path / "notes.parquet": "not a pounding_sweep result (",
        tmp_path / "nope.parquet": "no such file or folder",
        tmp_path: "not a pounding_sweep result (no result parts",
    }
    for path, what in cases.items():
        code, out, err = plot_cli(path, "--out", tmp_path / "png")
        assert code == 2 and out == "", (path, err)
        assert err.splitlines() == [err.strip()] and err.startswith(f"error: {path}: {what}"), err
    assert not (tmp_path / "png").exists()


def _run(tmp_path, name, scene, **changes):
    import dataclasses

    from pounding_sweep.sweep.run import run_scene

    s = load_scene(SWEEPS / scene)
    sections = {k: dataclasses.replace(getattr(s, k), **v) for k, v in changes.items() if isinstance(v, dict)}
    extra = {k: v for k, v in changes.items() if not isinstance(v, dict)}
    s = dataclasses.replace(s, **sections, **extra)
    out = tmp_path / f"{name}.parquet"
    run_scene(s, out_path=out)
    return out


ACCURACY = pd.DataFrame(
    {"scheme": ["event"] * 2, "dt_s": [2e-4, 1e-4], "run_time_s": [1e-3, 2e-3], "rel_rms_pct": [0.3, 0.1]}
)


def test_heatmaps_for_a_gap_by_stiffness_grid(tmp_path):
    from pounding_sweep.scene import Axis

    out = _run(
        tmp_path,
        "gapks",
        "paper_6hz.toml",
        excitation={"duration_s": 1.0},
        sweep=(Axis("gap_m", (0.0, 0.001, 0.002)), Axis("ks_ratio", (0.1, 1.0, 10.0))),
    )
    skipped = {}
    figs = plots.figures(out, accuracy=ACCURACY, skipped=skipped)
    assert "heatmaps" in figs and not skipped
    fig = figs["heatmaps"]
    maps = [ax for ax in fig.axes if ax.get_label() != "<colorbar>"]
    assert len(maps) == 2
    for ax in maps:
        assert ax.get_ylabel() == "gap d [mm]" and ax.get_xlabel().startswith("contact stiffness ratio")
        assert [t.get_text() for t in ax.get_yticklabels()] == ["0", "1", "2"]
        assert len(ax.texts) == 9
    assert "swept: gap [mm] = 0, 1, 2; k_s/k = 0.1, 1, 10" in fig.get_suptitle()
    # the run shown is named by its value on every swept axis
    assert "gap [mm] = " in figs["displacement_history"].get_suptitle()
    assert "k_s/k = " in figs["pounding_force"].get_suptitle()


def test_force_zoom_holds_the_peak_force_and_captions_follow_the_law(tmp_path):
    """On Duzce the zoom was 1.54-2.04 s around the largest displacement while the peak force is at 1.47 s."""
    out = _run(tmp_path, "duzce", "paper_duzce.toml")
    figs = plots.figures(out, accuracy=ACCURACY)
    df = pd.read_parquet(out)
    row = df.loc[df.peak_force_f3_N.idxmax()]
    whole, zoomed = figs["pounding_force"].axes
    lo, hi = zoomed.get_xlim()
    assert lo <= row.peak_force_time_f3_s <= hi and hi - lo == pytest.approx(0.5)
    assert f"zoom {lo:.2f}".rstrip("0").rstrip(".") in zoomed.get_title()
    # r = 1: no dashpot, no pull; a least force of -1e-10 N is the switch residue, not 'the classic law's pull'
    assert row.r == 1.0 and "pull" not in whole.get_title(loc="left")
    m = {
        "peak_force_f3_N": 30.0,
        "peak_force_time_f3_s": 1.0,
        "compression_phases_f3": 3,
        "median_compression_phase_f3_s": 0.02,
    }
    assert "the classic law's pull" in plots.force_caption({**m, "min_force_f3_N": -2.0}, 3, "classic")
    assert "pull" not in plots.force_caption({**m, "min_force_f3_N": -1e-9}, 3, "classic")
    nt = plots.force_caption({**m, "min_force_f3_N": -1e-9}, 3, "no_tension")
    assert "classic" not in nt and nt.endswith("no_tension law: the force never pulls")


def test_a_separated_scene_gets_no_empty_force_plot(tmp_path):
    out = _run(tmp_path, "sep", "paper_duzce_separated.toml")
    skipped = {}
    figs = plots.figures(out, accuracy=ACCURACY, skipped=skipped)
    assert "pounding_force" not in figs and "no contact at floor 3 in the run shown" in skipped["pounding_force"]
    maps = [ax for ax in figs["heatmaps"].axes if ax.get_label() != "<colorbar>"]
    assert len(maps) == 1 and "no run made contact" in figs["heatmaps"].get_supxlabel()
    code, stdout, _ = plot_cli(out, "--out", tmp_path / "png")
    assert code == 0 and "pounding_force.png not drawn: no contact at floor 3" in stdout
    assert sorted(p.name for p in (tmp_path / "png").iterdir()) == [
        "displacement_history.png",
        "error_vs_runtime.png",
        "heatmaps.png",
    ]


def test_a_scene_whose_records_are_only_a_sweep_axis_is_plotted_with_its_ladder(tmp_path):
    """A helper's trial: `plot` of a valid result whose records are a [sweep] record axis and no [excitation]
    record stopped at the accuracy ladder ('[excitation] missing key record'), whose scene drops the sweep; the
    ladder now runs on the shown run's record (by path, or by the result's record name)."""
    import dataclasses

    from pounding_sweep.accuracy import ladder_duration
    from pounding_sweep.sweep.run import run_scene

    recs = [str(SWEEPS / "records" / f"RSN1605_DUZCE_DZC{c}.AT2") for c in ("180", "270")]
    text = (SWEEPS / "paper_duzce.toml").read_text()
    text = "\n".join(ln for ln in text.splitlines() if not ln.startswith("record =") and not ln.startswith("path ="))
    text = text.replace("ks_ratio = [0.1, 1.0, 5.0, 10.0]\nr = [0.2, 0.4, 0.6, 0.8, 1.0]", f"record = {recs!r}")
    text = text.replace("[excitation]\n", "[excitation]\nduration_s = 2.0\n")
    (tmp_path / "recaxis.toml").write_text(text)
    out = tmp_path / "recaxis.parquet"
    run_scene(load_scene(tmp_path / "recaxis.toml"), out_path=out)
    skipped = {}
    figs = plots.figures(out, skipped=skipped)
    assert "error_vs_runtime" in figs and "displacement_history" in figs
    scene = plots.scene_of(out)
    assert scene.excitation.record is None
    # the window follows the run's record, named by path or by the result's name: uncapped by the test's 2 s, DZC180
    # (its strongest sample at 1.234 s of the 1/15 record, + 1 s) runs 2.234 s, DZC270 (0.88 s) the 2 s least
    whole = dataclasses.replace(scene, excitation=dataclasses.replace(scene.excitation, duration_s=None))
    assert ladder_duration(whole, "RSN1605_DUZCE_DZC270") == ladder_duration(whole, recs[1]) == 2.0
    assert (
        ladder_duration(whole, "RSN1605_DUZCE_DZC180")
        == ladder_duration(whole, recs[0])
        == pytest.approx(2.234, abs=1e-3)
    )


def test_the_accuracy_ladder_measures_the_quantity_a_scene_scores():
    """An acceleration-scored scene's error-against-run-time figure is the error of a scored acceleration (a
    helper's real-data calibration showed a displacement it never scored); a displacement-scored one keeps the
    top floor's displacement."""
    from pounding_sweep.plots import _ladder_channel

    assert _ladder_channel(load_scene(SWEEPS / "real_northridge.toml")) == "abs_acc_b1f3"
    assert _ladder_channel(load_scene(SWEEPS / "scored_6hz.toml")) is None


def test_measured_figure_quotes_the_scenes_own_noise_without_a_calibration(tmp_path):
    """A helper's trial: a scored scene without [calibrate] but with [experiment] noise_window_s got every panel
    titled 'no noise value for this channel: give [experiment] noise or noise_window_s'. The scene's noise (here
    [experiment] noise, in the table's mm) is the band and the title's yardstick: 0.05 mm."""
    text = (SWEEPS / "scored_6hz.toml").read_text()
    out = tmp_path / "noise.parquet"
    for old, new in (
        ("duration_s = 5.0", "duration_s = 0.5"),
        ("ks_ratio = [0.1, 1.0, 5.0, 10.0]", "ks_ratio = [5.0]"),
        ("r = [0.2, 0.4, 0.6, 0.8, 1.0]", "r = [0.4, 0.6]"),
        ("refine = true", "refine = false\nnoise = { model1_floor3_mm = 0.05, model2_floor3_mm = 0.05 }"),
        ('table = "experiments/', f'table = "{SWEEPS}/experiments/'),
    ):
        assert old in text
        text = text.replace(old, new)
    scene = tmp_path / "noise.toml"
    scene.write_text(text)
    from pounding_sweep.sweep.run import run_scene

    run_scene(load_scene(scene), out_path=out, threads=1)
    fig = plots.figures(out)["measured_vs_model"]
    titles = [ax.get_title(loc="left") for ax in fig.axes if ax.get_title(loc="left")]
    assert len(titles) == 2 and all("times the channel's noise 0.05 mm" in t for t in titles), titles
