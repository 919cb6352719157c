"""Seismic-gap studies: the rules against hand calculations, the exact required gap against the closed-form
time history, and the study's invariants (a gap at least the required one makes the contact run the
separated run, bit for bit)."""

from __future__ import annotations

import dataclasses
import math
import subprocess
import sys
import tomllib

import numpy as np
import pandas as pd
import pytest
from conftest import REPO, SWEEPS
from scipy.integrate import quad

from pounding_sweep.gaps import combined_gap, cqc_correlation, gap_study, required_gaps, tbec2018_minimum_gap_m
from pounding_sweep.model.coupled import CoupledModel
from pounding_sweep.reference import modal_harmonic_response
from pounding_sweep.scene import load_scene, scene_from_dict
from pounding_sweep.sweep import simulate

U = 2.0**-53


def white_noise_correlation(w1, w2, z1, z2) -> float:
    """The correlation of two oscillators' stationary displacements under the same white-noise base
    acceleration, integrated numerically: int Re(H1 H2*) / sqrt(int |H1|^2 int |H2|^2), H = 1 / (w_n^2 - w^2 + 2 i z w_n w)."""

    def h(w, wn, z):
        return 1.0 / (wn * wn - w * w + 2j * z * wn * w)

    edges = [0.0, *sorted({w1, w2}), np.inf]  # the integrands peak at w1 and w2: integrate piece by piece

    def integral(f):
        return sum(quad(f, a, b, limit=2000, epsabs=0, epsrel=1e-12)[0] for a, b in zip(edges[:-1], edges[1:]))

    cross = integral(lambda w: (h(w, w1, z1) * np.conj(h(w, w2, z2))).real)
    a11 = integral(lambda w: abs(h(w, w1, z1)) ** 2)
    a22 = integral(lambda w: abs(h(w, w2, z2)) ** 2)
    return cross / math.sqrt(a11 * a22)


@pytest.mark.parametrize(
    "w1, w2, z1, z2",
    [(26.7, 45.0, 0.0105, 0.0107), (10.0, 9.0, 0.02, 0.08), (10.0, 12.0, 0.05, 0.05), (10.0, 20.0, 0.05, 0.02)],
)
def test_cqc_correlation_is_the_white_noise_correlation(w1, w2, z1, z2):
    """Der Kiureghian's closed form against the defining integral (to the quadrature's 1e-8), symmetric
    under swapping both frequencies and damping ratios."""
    rho = cqc_correlation(w1, w2, z1, z2)
    assert rho == pytest.approx(white_noise_correlation(w1, w2, z1, z2), rel=1e-7)
    assert rho == pytest.approx(cqc_correlation(w2, w1, z2, z1), rel=1e-14)
    assert 0 < rho < 1


def test_rules_by_hand():
    """ABS, SRSS and DDC of 3 and 4 mm; identical frames (rho = 1): DDC exactly 0."""
    assert combined_gap(3.0, 4.0, "ABS") == 7.0 and combined_gap(3.0, 4.0, "SRSS") == 5.0
    assert combined_gap(3.0, 4.0, "DDC", rho=0.5) == pytest.approx(math.sqrt(9 + 16 - 12))
    rho = cqc_correlation(30.0, 30.0, 0.02, 0.02)
    assert rho == 1.0 and combined_gap(5.0, 5.0, "DDC", rho) == 0.0
    with pytest.raises(ValueError, match="rule"):
        combined_gap(1.0, 1.0, "MAX")


@pytest.mark.parametrize("h, gap_mm", [(3.0, 30), (6.0, 30), (6.5, 40), (9.0, 40), (9.5, 50), (11.0, 50), (15.12, 70)])
def test_tbec2018_minimum(h, gap_mm):
    """30 mm up to 6 m, 10 mm more per started 3 m above."""
    assert tbec2018_minimum_gap_m(h) == pytest.approx(gap_mm * 1e-3, abs=1e-15)


def one_storey(k1=5920.0, k2=20000.0, z=0.05, duration=3.0, amplitude=0.002, freq=6.0) -> object:
    raw = tomllib.loads((SWEEPS / "paper_6hz.toml").read_text())
    raw["building1"] = {"masses_kg": [1.6], "story_stiffness_N_per_m": k1, "damping_ratio": z, "story_height_m": 0.336}
    raw["building2"] = {"masses_kg": [0.45], "story_stiffness_N_per_m": k2, "damping_ratio": z, "story_height_m": 0.336}
    raw["excitation"].update(duration_s=duration, amplitude_m=amplitude, frequency_Hz=freq)
    raw.pop("sweep", None)
    return scene_from_dict(raw, base_dir=SWEEPS, source=str(SWEEPS / "one_storey.toml"))


def test_exact_required_gap_of_two_single_storey_frames_is_the_closed_forms():
    """Two single-storey frames on a 6 Hz table from rest: max (u1 - u2) of the closed-form solution (each
    frame an oscillator: Chopra sec. 3.2), densely sampled, against the study's exact gap. Bound:
    Newmark average acceleration's amplitude and phase error over the run, (w dt)^2 / 12 per radian
    of phase (Chopra sec. 5.5), times w T radians, of the relative displacement's amplitude, plus the
    sampling of a maximum at the step ends, (w dt)^2 / 8 of it."""
    s = one_storey()
    req = required_gaps(s)
    M, C, K = CoupledModel.from_scene(s).matrices()
    t = np.linspace(0.0, 3.0, 300001)
    u = modal_harmonic_response(M, C, K, 0.002, 2 * math.pi * 6.0, t)
    rel = u[:, 0] - u[:, 1]
    w = math.sqrt(20000.0 / 0.45)
    bound = ((w * 1e-4) ** 2 / 12 * w * 3.0 + (w * 1e-4) ** 2 / 8) * np.abs(rel).max()
    exact = float(req.exact_m.iloc[0])
    assert exact == pytest.approx(rel.max(), abs=bound)
    assert exact <= float(req.abs_m.iloc[0])  # ABS bounds the one-sided requirement
    # the time-history truth at the step ends: the run's own history, exactly
    h, _ = simulate(s, channels=["disp_b1f1", "disp_b2f1"], gap_m=100.0)
    assert exact == (100.0 - (100.0 - (h.disp_b1f1_m - h.disp_b2f1_m).to_numpy()).min())


def test_identical_buildings_need_no_gap():
    s = one_storey(k2=5920.0 * 0.45 / 1.6)  # the same frequency and damping: they move as one
    req = required_gaps(s)
    assert req.rho.iloc[0] == pytest.approx(1.0, abs=1e-12) and req.ddc_m.iloc[0] == pytest.approx(0.0, abs=1e-9)
    assert req.exact_m.iloc[0] < 1e-12


def test_study_on_duzce_invariants():
    """At a gap of at least the required one nothing ever touches: the runs are the separated run bit for
    bit (every ratio exactly 1, no impact); below it the buildings pound. ABS bounds every pair's
    requirement; the study's floors carry the scene's heights and TBEC's minimum at full scale."""
    s = load_scene(SWEEPS / "paper_duzce.toml")
    st = gap_study(s, relative_gaps=(0.0, 0.5, 0.9, 1.0, 1.5), ks_ratio=1.0, r=0.4)
    r = st.ratios
    above = r[r.relative_gap >= 1.0]
    assert (above[["disp_ratio", "drift_ratio", "acc_ratio"]] == 1.0).all().all() and (above.impacts == 0).all()
    assert (r[r.relative_gap < 1.0].impacts > 0).all()
    req = st.required
    assert (req.exact_m <= req.abs_m).all() and (req.exact_m > 0).all()
    assert req.height_m.tolist() == pytest.approx([0.336, 0.672, 1.008])
    assert req.tbec2018_min_full_scale_m.tolist() == pytest.approx([0.03, 0.05, 0.07])
    assert st.length_scale == 15.0 and req.exact_full_scale_m.iloc[2] == pytest.approx(15 * req.exact_m.iloc[2])


def test_gaps_command_writes_the_study_and_refuses_bad_options(tmp_path):
    scene = SWEEPS / "paper_duzce.toml"
    out = tmp_path / "g"
    r = subprocess.run(
        [sys.executable, "-m", "pounding_sweep", "gaps", str(scene), "--out", str(out), "--relative-gaps", "0,1"],
        capture_output=True,
        text=True,
        cwd=REPO,
    )
    assert r.returncode == 0, r.stderr
    assert "required gap per floor pair" in r.stdout
    assert {p.name for p in out.iterdir()} >= {"required_gaps.parquet", "response_ratios.parquet", "required_gaps.png"}
    assert len(pd.read_parquet(out / "required_gaps.parquet")) == 3
    # the ratio runs' contact in full (a helper's trial read "contact {'r': 0.2}", k_s/k nowhere)
    assert "response adjacent / separated (contact: law classic, k_s/k = 1, r = 0.2):" in r.stdout
    import json

    import pyarrow.parquet as pq

    md = json.loads(pq.read_schema(out / "required_gaps.parquet").metadata[b"pounding_sweep"])
    assert {"version", "numpy_version", "scipy_version", "numba_version", "python_version"} <= set(md)  # what made it
    c = md["contact"]
    assert (c["law"], c["ks_ratio"], c["ks_N_per_m"], c["r"]) == ("classic", 1.0, None, 0.2)
    # the scene's own k_s/k and r axes (4 x 5 values): one point of them is run, and said
    assert (
        "[sweep] ks_ratio = [0.1, 1.0, 5.0, 10.0]: the study's response ratios take one contact point, ks_ratio = 1.0"
        in r.stderr
    )
    assert r.stderr.count("warning:") == 2  # ks_ratio and r, nothing else
    assert "TBEC 2018 minimum" in md["columns"]["required_gaps"]["tbec2018_min_m"]
    bad = tmp_path / "bad"
    r = subprocess.run(
        [sys.executable, "-m", "pounding_sweep", "gaps", str(scene), "--out", str(bad), "--relative-gaps", "0,x"],
        capture_output=True,
        text=True,
        cwd=REPO,
    )
    assert r.returncode == 2 and r.stderr.startswith("error: --relative-gaps") and not bad.exists()


def test_a_study_whose_figure_fails_writes_nothing_and_a_rerun_replaces_its_own_files(tmp_path, monkeypatch):
    """Every file of a study is made in memory before the first is written (a figure that failed used to leave 5
    of the 6 files); a second study into the same folder replaces the first's files (its table says it is a
    study's), a user's file there is refused (the corpus: gaps_out_holds_a_users_csv)."""
    import pounding_sweep.gaps.figures as figures
    from pounding_sweep.cli.gaps import FILES, check_study_folder, write_study

    s = load_scene(SWEEPS / "paper_6hz.toml")
    s = dataclasses.replace(s, excitation=dataclasses.replace(s.excitation, duration_s=0.3))
    study = gap_study(s, relative_gaps=(0.0, 1.0), ks_ratio=1.0, r=0.4)
    out = tmp_path / "study"

    def broken(*a, **k):
        raise OverflowError("a figure that cannot be drawn")

    monkeypatch.setattr(figures, "response_ratio_figure", broken)
    with pytest.raises(OverflowError):
        write_study(study, s, out)
    assert not out.exists()
    monkeypatch.undo()
    write_study(study, s, out)
    assert sorted(p.name for p in out.iterdir()) == sorted(FILES)
    check_study_folder(out)  # its own files: may be replaced
    first = (out / "required_gaps.parquet").stat().st_mtime_ns
    write_study(study, s, out)
    assert (out / "required_gaps.parquet").stat().st_mtime_ns >= first
    assert sorted(p.name for p in out.iterdir()) == sorted(FILES)  # no temporaries left


def test_a_sweep_axis_the_study_does_not_take_is_named():
    """A helper's trial: [sweep] scale = [0.5, 1, 2] gave one row per pair, the unscaled scene's, and no word: the
    study runs each record once at the scene's own values. Now said (and the records' axis still taken)."""
    from pounding_sweep.scene import Axis
    from pounding_sweep.warn import collecting

    s = load_scene(SWEEPS / "paper_duzce.toml")
    s = dataclasses.replace(
        s, sweep=(Axis("scale", (0.5, 1.0)),), excitation=dataclasses.replace(s.excitation, duration_s=2.0)
    )
    with collecting() as got:
        gap_study(s, relative_gaps=(0.0, 1.0), ks_ratio=1.0, r=0.4)
    (w,) = [w.message for w in got.items if w.kind == "gaps_axis_ignored"]
    assert w.startswith("[sweep] scale = [0.5, 1.0]: not studied: a gap study runs each motion once")
    # the scene's own checks, as a sweep of it gets them (a helper's trial: a vertical component, warned by a
    # sweep and by `risk`, was studied silently); here a step coarser than the record's samples
    coarse = dataclasses.replace(s, integration=dataclasses.replace(s.integration, dt_s=0.02))
    with collecting() as got:
        gap_study(coarse, relative_gaps=(0.0, 1.0), ks_ratio=1.0, r=0.4)
    assert [w for w in got.items if w.kind == "record_step"]
    # and only its motions' checks: not the experiment it does not read (a review: a scene whose table had moved
    # away was refused), nor an r axis it does not run
    scored = load_scene(SWEEPS / "scored_duzce.toml").experiment
    away = dataclasses.replace(s, experiment=dataclasses.replace(scored, table=str(SWEEPS / "moved_away.parquet")))
    with collecting() as got:
        gap_study(away, relative_gaps=(0.0, 1.0), ks_ratio=1.0, r=0.4)
    assert not [w for w in got.items if w.kind == "r_ignored"]


def test_a_hertz_scene_with_k_h_only_and_a_stiffness_only_swept_are_studied(tmp_path, capsys):
    """A review found `gaps` on a valid hertzdamp scene giving k_h alone writing its study and then stopping with a
    traceback (its summary formatted a missing k_s), and a scene whose k_s/k is only a [sweep] axis refused
    ('missing key ks_ratio') though the study takes the axis's first value for its ratio runs."""
    from pounding_sweep.cli.gaps import gaps_main

    text = (SWEEPS / "paper_duzce.toml").read_text()
    text = text.replace('record = "records/', f'record = "{SWEEPS.as_posix()}/records/')
    text = text.replace("[excitation]\n", "[excitation]\nduration_s = 2.0\n")
    hertz = text.replace("ks_ratio = 1.0\n", 'law = "hertzdamp"\nkh_N_per_m1_5 = 1e6\n')
    hertz = hertz.split("[sweep]")[0] + "[output]" + hertz.split("[output]")[1]
    (tmp_path / "hertz.toml").write_text(hertz)
    assert gaps_main([str(tmp_path / "hertz.toml"), "--out", str(tmp_path / "h"), "--relative-gaps", "0,1"]) == 0
    assert "(contact: law hertzdamp, k_h = 1e+06 N/m^1.5, r = 0.2):" in capsys.readouterr().out
    swept = text.replace("ks_ratio = 1.0\n", "")  # k_s/k only on the [sweep] axis
    (tmp_path / "swept.toml").write_text(swept)
    assert gaps_main([str(tmp_path / "swept.toml"), "--out", str(tmp_path / "s"), "--relative-gaps", "0,1"]) == 0
    assert "(contact: law classic, k_s/k = 0.1, r = 0.2):" in capsys.readouterr().out
