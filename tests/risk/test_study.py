"""A risk study end to end (risk/study.py, the `risk` subcommand): its tables and figures, self-describing; the
physics it rests on (a contact-free run scales with the intensity; a gap at least the run's required gap makes
the contact run the contact-free run bit for bit); the records scaled to their intensity exactly; resumed
exactly once after an interruption; bit-identical on Dask; bad input refused in one line."""

from __future__ import annotations

import dataclasses
import json
import subprocess
import sys

import numpy as np
import pandas as pd
import pyarrow.parquet as pq
import pytest
from conftest import REPO, SWEEPS
from risk_scenes import stochastic_scene
from tolerances import SAFETY, floor_steps

from pounding_sweep.errors import ConfigError
from pounding_sweep.model.excitation import Excitation
from pounding_sweep.model.intensity import intensity
from pounding_sweep.model.records import G_STANDARD
from pounding_sweep.risk.study import FIGURES, TABLES, analyse, check_risk_scene, free_scene, risk_study, write_study
from pounding_sweep.scene import Axis, load_scene, scene_from_dict
from pounding_sweep.sweep.results import part_files


def small(tmp_path, **kw):
    defaults = dict(seeds=24, levels=(0.2, 0.4, 0.8), duration_s=6.0, chunk_runs=18)
    defaults.update(kw)
    return stochastic_scene(
        folder=tmp_path / "study.risk",
        risk={
            "contact_gaps_m": (0.05, 0.15),
            "bootstrap": 100,
            "hazard": str(SWEEPS / "hazard" / "illustrative_power_law.csv"),
        },
        **defaults,
    )


def runs(folder) -> pd.DataFrame:
    return pd.read_parquet(folder).drop(columns=["run_time_s"]).sort_values("run_id").reset_index(drop=True)


def test_study_writes_self_describing_tables_and_figures(tmp_path):
    scene = small(tmp_path)
    study = risk_study(scene, threads=2)
    written = write_study(study)
    folder = study.folder
    for name in TABLES:
        t = pq.read_table(folder / f"{name}.parquet")
        md = json.loads(t.schema.metadata[b"pounding_sweep"])
        assert md["kind"] == f"risk_{name}" and md["config_hash"] == scene.config_hash()
        assert md["risk"]["targets"] == [0.1, 0.02] and md["numpy_version"] and md["scipy_version"]
        assert md["model"]["intensity"]["measure"] == "sa" and md["columns"]
        assert (folder / f"{name}.csv").is_file()
    for f in FIGURES:
        assert (folder / f).stat().st_size > 10_000  # a figure with something drawn in it
    assert len(written) == 2 * len(TABLES) + len(FIGURES)
    p = study.probability
    for _, d in p.groupby("intensity_g"):  # P falls as the gap grows, inside its interval
        assert (np.diff(d.sort_values("gap_m").probability) <= 0).all()
        assert (d.ci_low <= d.probability).all() and (d.probability <= d.ci_high).all()
    rules = study.code_rules
    assert set(rules.rule) == {"ABS", "SRSS", "DDC", "TBEC2018_min"}
    tbec = rules[rules.rule == "TBEC2018_min"].gap_m
    assert np.allclose(tbec, 0.070)  # 30 mm + 4 x 10 mm at the top facing floor, 15.12 m
    # ABS applied to each motion's own peaks bounds its required gap: nobody pounds
    assert (rules[rules.rule == "ABS"].per_motion_pounding == 0).all()
    # NaN where a gap's fragility is not fitted (not identified, or no motion / every motion pounding)
    rate = study.annual_rate.annual_rate_per_yr.dropna()
    assert rate.size == (study.annual_rate.status == "ok").sum() >= 20 and rate.is_monotonic_decreasing
    unknown = study.annual_rate[study.annual_rate.annual_rate_per_yr.isna()]
    assert (unknown.status != "ok").all() and (unknown.note != "").all()
    # every value the required-gap table lacks says why (24 motions: n p = 0.48 < 1 at the 2 % target)
    req = study.required_gap
    assert req.note[req.empirical_gap_m.isna()].str.contains("n p = 0.48 < 1").all()
    assert req.note[req.lognormal_gap_m.isna()].str.contains("lognormal: ").all()
    assert ((req.lognormal_ci_low_m.isna() & req.lognormal_gap_m.notna()) <= req.note.str.contains("interval")).all()
    assert {c for c in study.demand.columns if c.endswith("gap_m")} >= {"required_gap_m", "abs_gap_m"}


def test_contact_free_runs_scale_with_the_intensity(tmp_path):
    """The frames are linear: at level 0.8 g each motion's required gap is twice its 0.4 g one, to rounding (the
    same recursion on inputs scaled by 2 and by a ratio of intensities: SAFETY x n_steps x n_dof x u)."""
    scene = small(tmp_path)
    risk_study(scene, threads=2)
    d = analyse(scene).demand.pivot(index="motion_index", columns="scale", values="required_gap_m")
    tol = SAFETY * floor_steps(int(6.0 / 0.005), 6)
    assert np.allclose(d[0.8], 2 * d[0.4], rtol=tol, atol=0)
    assert np.allclose(d[0.4], 2 * d[0.2], rtol=tol, atol=0)


def test_a_gap_above_the_required_one_is_the_contact_free_run(tmp_path):
    """Where a motion's required gap is below a contact run's gap, nothing touches: every response ratio is exactly
    1 and no impact is counted; where it is above, the run pounds."""
    scene = small(tmp_path)
    study = risk_study(scene, threads=2)
    contact = runs(study.folder / "runs_contact.parquet")
    free = runs(study.folder / "runs_free.parquet")
    shape = (len(scene.axis_values("seed")), len(scene.risk.intensities_g), 2)
    idx = np.unravel_index(contact.run_id, shape)
    levels = np.asarray(scene.risk.intensities_g)[idx[1]]
    nlev = len(scene.axis_values("scale"))
    lev_index = {v: i for i, v in enumerate(scene.axis_values("scale"))}
    frow = idx[0] * nlev + np.array([lev_index[v] for v in levels])
    required = np.max([100.0 - free[f"closest_approach_f{j}_m"].to_numpy()[frow] for j in (1, 2, 3)], axis=0)
    impacts = contact[[f"impacts_f{j}" for j in (1, 2, 3)]].sum(axis=1).to_numpy()
    clear = required <= contact.gap_m.to_numpy()
    assert clear.any() and (~clear).any()
    assert (impacts[clear] == 0).all() and (impacts[~clear] > 0).all()
    for col in ("peak_disp_b1f3_m", "peak_disp_b2f3_m", "peak_abs_acc_b2f3_m_s2"):
        assert np.array_equal(contact[col].to_numpy()[clear], free[col].to_numpy()[frow[clear]])


def test_records_are_scaled_to_their_intensity_exactly():
    """Each record times the factor the engine applies has Sa(T*) = the level in g (computed again, here, from the
    record as read), and the run's intensity_g says so."""
    s = load_scene(SWEEPS / "risk_records.toml")
    exc = Excitation.from_scene(s, s.integration.dt_s)
    from pounding_sweep.model.grid import Grid

    params = Grid.from_scene(s).chunk(0, Grid.from_scene(s).size)
    ex, _ = exc.chunk_inputs(params)
    for i in range(0, params["run_id"].size, 5):
        rec = exc.records[ex["rec_id"][i]]
        sa = float(intensity(rec.acc_m_s2 * ex["exc_amp"][i], rec.dt_s, "sa", exc.period_s))
        assert sa / G_STANDARD == pytest.approx(params["scale"][i], rel=1e-12)
        assert ex["intensity_g"][i] == params["scale"][i]
    assert exc.period_s == pytest.approx(0.702, abs=1e-3)  # sqrt(0.912 x 0.540)


def test_the_contact_free_runs_store_no_no_contact_warning(tmp_path):
    """A helper's trial: every study's contact-free runs (at the gap no motion closes, 100 m) stored 'no run made
    contact ... gap_m = 100 is 100 m (for 100 mm write 0.1)' in their metadata: a unit hint about the study's own
    choice. They are separated on purpose; the same scene as a plain sweep still gets the warning."""
    from pounding_sweep.risk.study import run_runs
    from pounding_sweep.sweep.run import run_scene

    scene = small(tmp_path, seeds=4, levels=(0.4, 0.8))
    summaries = run_runs(scene, threads=2)
    assert summaries["free"].warnings == [w for w in summaries["free"].warnings if "no run made contact" not in w]
    plain = run_scene(free_scene(scene), out_path=tmp_path / "plain.parquet", threads=2)
    assert any("no run made contact" in w and "write 0.1" in w for w in plain.warnings)


def test_a_record_cut_by_duration_is_scaled_by_the_motion_run():
    """A helper's trial: duration_s = 8 s on records whose strong motion comes later scaled each record by the whole
    record's Sa, so the runs (which see only 8 s) carried an intensity label 70 times too large. Now the motion run
    (the record up to duration_s) has Sa(T*) = the level, and the cut is warned, naming the key and both Sa."""
    from pounding_sweep.warn import collecting

    s = load_scene(SWEEPS / "risk_records.toml")
    s = dataclasses.replace(s, excitation=dataclasses.replace(s.excitation, duration_s=8.0))
    with collecting() as got:
        exc = Excitation.from_scene(s, s.integration.dt_s)
    from pounding_sweep.model.grid import Grid

    params = Grid.from_scene(s).chunk(0, Grid.from_scene(s).size)
    ex, _ = exc.chunk_inputs(params)
    for i in range(0, params["run_id"].size, 5):
        rec = exc.records[ex["rec_id"][i]]
        run = rec.acc_m_s2[rec.time_s <= 8.0]
        sa = float(intensity(run * ex["exc_amp"][i], rec.dt_s, "sa", exc.period_s))
        assert sa / G_STANDARD == pytest.approx(params["scale"][i], rel=1e-12)
    cut = [w.message for w in got.items if w.kind == "record_cut"]
    assert cut and all("[excitation] duration_s = 8.0 cuts record" in m for m in cut)
    assert any("BOL000" in m for m in cut)  # Bolu's peak acceleration comes at 10.8 s
    # a cut inside the first sample leaves no motion to measure: said so, not 'has zero sa' (a review)
    tiny = dataclasses.replace(s, excitation=dataclasses.replace(s.excitation, duration_s=0.004))
    with pytest.raises(ConfigError, match=r"\[excitation\] duration_s = 0.004: keeps 1 sample of record"):
        Excitation.from_scene(tiny, 0.001)


class Interrupt(Exception):
    pass


def test_an_interrupted_study_resumes_running_each_part_once(tmp_path):
    """Stopped after its first part, the study resumes: the second call runs only the parts the first did not
    write, and the result is the uninterrupted one, bit for bit."""
    scene = small(tmp_path)

    folder = tmp_path / "study.risk" / "runs_free.parquet"

    def stop_after_first(name):
        def progress(done, total):
            if part_files(folder):  # Ctrl-C as soon as the first part is on disk
                raise KeyboardInterrupt

        return progress

    with pytest.raises(KeyboardInterrupt):
        risk_study(scene, threads=2, progress_for=stop_after_first)
    assert len(part_files(folder)) == 1
    kept = pd.read_parquet(part_files(folder)[0])
    study = risk_study(scene, threads=2)
    free = study.runs["free"]
    assert free.resumed_parts == 1 and free.new_runs == free.runs - 18  # the kept part is not run again
    pd.testing.assert_frame_equal(pd.read_parquet(part_files(folder)[0]), kept, check_exact=True)
    clean = small(tmp_path / "clean")
    risk_study(clean, threads=2)
    pd.testing.assert_frame_equal(
        runs(folder), runs(tmp_path / "clean" / "study.risk" / "runs_free.parquet"), check_exact=True
    )


def test_dask_gives_the_same_study_bit_for_bit(tmp_path):
    pytest.importorskip("dask.distributed")
    from pounding_sweep.sweep.executors import DaskExecutor

    local = risk_study(small(tmp_path / "local"), threads=2)
    ex = DaskExecutor(workers=2)
    try:
        dask = risk_study(small(tmp_path / "dask"), executor=ex)
    finally:
        ex.close()
    assert dask.runs["free"].executor == "dask"
    for sub in ("runs_free.parquet", "runs_contact.parquet"):
        pd.testing.assert_frame_equal(runs(local.folder / sub), runs(dask.folder / sub), check_exact=True)
    for name in TABLES:
        pd.testing.assert_frame_equal(getattr(local, name), getattr(dask, name), check_exact=True)


@pytest.mark.parametrize(
    "change, message",
    [
        ({"excitation": {"intensity": "none", "scaling": "factor"}}, "needs \\[excitation\\] intensity"),
        ({"sweep": {"seed": [0.5, 1.0]}}, "a seed is a whole number"),
        ({"sweep": {"gap_m": [0.1, 0.2]}}, "a risk study sets the gaps itself"),
        ({"risk": {"intensities_g": [0.33]}}, "is not an intensity level"),
        ({"sweep": {"r": [0.2, 0.4]}}, "holds its ensemble"),
        ({"risk": {"targets": [1.5]}}, "probabilities lie in"),
        ({"stochastic": {"filter": "kanai"}}, "expected one of"),
        ({"stochastic": {"highpass_frequency_Hz": None}}, "missing key 'highpass_frequency_Hz'"),
        # no seed axis: the one motion of [excitation] (a helper's trial: it was called "0 motion(s)")
        ({"sweep": {"seed": None}}, r"the ensemble has 1 motion\(s\)"),
    ],
)
def test_bad_risk_scenes_are_refused(change, message):
    import tomllib

    raw = tomllib.loads((SWEEPS / "risk_stochastic.toml").read_text())
    for section, values in change.items():
        for k, v in values.items():
            if v is None:
                raw[section].pop(k)
                if section == "sweep" and not raw[section]:  # an empty [sweep]: one point
                    raw.pop(section)
            else:
                raw[section][k] = v
    with pytest.raises(ConfigError, match=message):  # when the scene is read, or when a study would start
        check_risk_scene(scene_from_dict(raw, base_dir=SWEEPS, source=str(SWEEPS / "x.toml")))


def test_a_risk_scene_runs_as_a_plain_sweep_and_as_one_point():
    """[risk] is the study's: the scene still runs one point (simulate) and a gap study."""
    from pounding_sweep.sweep import simulate

    s = load_scene(SWEEPS / "risk_stochastic.toml")
    s = dataclasses.replace(s, excitation=dataclasses.replace(s.excitation, duration_s=2.0))
    h, m = simulate(s, channels=["disp_b1f3"], seed=3, scale=0.4)
    assert m["status"] == "ok" and len(h) == 401


def test_cli_on_a_scene_without_risk_is_one_error_line(tmp_path):
    r = subprocess.run(
        [
            sys.executable,
            "-m",
            "pounding_sweep",
            "risk",
            str(SWEEPS / "paper_duzce.toml"),
            "--out",
            str(tmp_path / "o"),
        ],
        capture_output=True,
        text=True,
        cwd=REPO,
    )
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and "no [risk] section" in r.stderr
    assert not (tmp_path / "o").exists()


def test_cli_runs_a_study(tmp_path):
    """The subcommand on a small study: exit 0, the tables printed, the folder written; a folder of someone
    else's is refused."""
    scene = small(tmp_path, seeds=12, levels=(0.4, 0.8))
    text = scene.toml_text
    raw_path = tmp_path / "s.toml"
    import tomllib

    raw = tomllib.loads(text)
    raw["sweep"] = {"seed": [float(i) for i in range(12)], "scale": [0.4, 0.8]}
    raw["excitation"]["duration_s"] = 6.0
    raw["risk"].pop("hazard")
    raw["risk"]["path"] = str(tmp_path / "cli.risk")
    raw["risk"]["bootstrap"] = 50
    raw_path.write_text(_toml(raw))
    r = subprocess.run([sys.executable, "-m", "pounding_sweep", "risk", str(raw_path)], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert "required gap [mm]" in r.stdout and "TBEC2018_min" in r.stdout
    assert (tmp_path / "cli.risk" / "required_gap.parquet").is_file()
    (tmp_path / "theirs").mkdir()
    (tmp_path / "theirs" / "notes.txt").write_text("mine")
    r = subprocess.run(
        [sys.executable, "-m", "pounding_sweep", "risk", str(raw_path), "--out", str(tmp_path / "theirs")],
        capture_output=True,
        text=True,
    )
    assert r.returncode == 2 and "not a risk study folder" in r.stderr
    assert (tmp_path / "theirs" / "notes.txt").read_text() == "mine"


def _toml(d: dict, prefix: str = "") -> str:
    """A minimal TOML writer for the test's scene (tables of scalars and lists)."""
    out, tables = [], []
    for k, v in d.items():
        if isinstance(v, dict):
            tables.append((k, v))
        else:
            out.append(f"{k} = {json.dumps(v)}")
    for k, v in tables:
        out.append(f"\n[{prefix}{k}]")
        out.append(_toml(v, f"{prefix}{k}."))
    return "\n".join(out)


def test_free_scene_is_the_ensemble_without_contact():
    s = load_scene(SWEEPS / "risk_records.toml")
    f = free_scene(s)
    assert f.contact.gap_m == 100.0 and [a.name for a in f.sweep] == ["record", "scale"]
    assert f.risk is None and f.integration.min_steps_per_contact_period == 0.0
    assert dataclasses.replace(s, sweep=(Axis("scale", (0.1,)),)).risk is not None


def test_gaps_in_metres_beyond_every_demand_and_no_bootstrap_are_warned(tmp_path):
    """A helper's trial: gaps_m = [20, 50] (millimetres written in a key in metres) gave probabilities of 0 and
    'none' fits without a word; bootstrap = 0 gave fitted values without their intervals without a word."""
    import dataclasses

    from pounding_sweep.warn import collecting

    scene = small(tmp_path, seeds=12, levels=(0.2, 0.4, 0.8))
    scene = dataclasses.replace(scene, risk=dataclasses.replace(scene.risk, gaps_m=(20.0, 50.0), bootstrap=0))
    # and a [contact] gap_m, which a study does not use (a helper's trial: ignored without a word)
    scene = dataclasses.replace(scene, contact=dataclasses.replace(scene.contact, gap_m=0.03))
    with collecting() as got:
        risk_study(scene, threads=2)
    kinds = {w.kind: w.message for w in got.items}
    assert kinds["gap_not_studied"].startswith("[contact] gap_m = 0.03 plays no part in a risk study")
    assert "[risk] gaps_m = [20.0, 50.0]: every gap is more than 10 times the largest gap" in kinds["gap_units"]
    assert "(for 20 mm write 0.02)" in kinds["gap_units"]
    assert "[risk] bootstrap = 0" in kinds["no_bootstrap"]


def test_identical_buildings_give_probability_zero_and_no_empty_figure(tmp_path):
    """A helper's trial: two identical buildings (no relative motion, every required gap 0, the closed-form
    P = 0 at every gap) crashed the figures (a log axis with a 0 mm rule gap; the required-gap figure with nothing
    to draw) and warned that the gaps were in the wrong unit. Now: P = 0 with its Clopper-Pearson bound, the empty
    figure not drawn and said so, the others drawn, and one warning saying what the 0 is."""
    from pounding_sweep.warn import collecting

    scene = small(tmp_path, seeds=8, levels=(0.4, 0.8))
    scene = dataclasses.replace(scene, building2=dataclasses.replace(scene.building1))
    with collecting() as got:
        study = risk_study(scene, threads=2)
        written = write_study(study)
    assert (study.demand.required_gap_m == 0.0).all()
    p = study.probability
    assert (p.probability == 0.0).all() and (p.ci_low == 0.0).all()
    assert np.allclose(p.ci_high, 1.0 - 0.025 ** (1.0 / p.motions))  # Clopper-Pearson upper bound for 0 of n
    kinds = {w.kind: w.message for w in got.items}
    assert "gap_units" not in kinds and "largest required gap 0 m" in kinds["no_relative_motion"]
    assert "required_gap.png not drawn" in kinds["empty_figure"]
    pngs = sorted(f.name for f in written if f.suffix == ".png")
    assert pngs == ["fragility.png", "probability_vs_gap.png"]
    for f in pngs:
        assert (study.folder / f).stat().st_size > 10_000
