"""A probabilistic pounding study of a scene with a [risk] section: its runs (through the sweep layer, so they
resume exactly where an interrupted study stopped and run on any executor with bit-identical rows), then its
tables and figures, into one folder.

Runs: the contact-free runs, one per motion and intensity level (`runs_free.parquet/`, the scene's [sweep]
ensemble with the gap at gaps.study.SEPARATED_GAP_M, which no motion closes: a run's closest approach is then
the largest closing displacement, so one run answers every gap); and, with [risk] contact_gaps_m, contact runs
at those gaps (`runs_contact.parquet/`) for the consequences.

Tables (Parquet, units in the column names, the scene, its hash, [risk] and the versions in the metadata; a
CSV copy beside each): demand, probability, fragility, required_gap, code_rules, consequences, annual_rate
(analysis.py and hazard.py say what each holds). Figures: probability_vs_gap.png, fragility.png,
required_gap.png (figures.py).
"""

from __future__ import annotations

import dataclasses
import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

import pounding_sweep.risk.analysis as A
from pounding_sweep import __version__
from pounding_sweep.errors import ConfigError, OutputError
from pounding_sweep.gaps.rules import cqc_correlation, floor_heights_m, frame_first_mode
from pounding_sweep.gaps.study import SEPARATED_GAP_M
from pounding_sweep.model.coupled import CoupledModel
from pounding_sweep.model.excitation import intensity_period
from pounding_sweep.scene import Axis, Scene, validate
from pounding_sweep.sweep.metricgroups import study_metrics

#: the study folder's manifest, written after its runs: a folder holding it is a risk study's (its tables and
#: figures may be replaced)
MANIFEST = "_risk.json"
TABLES = ("demand", "probability", "fragility", "required_gap", "code_rules", "consequences", "annual_rate")
FIGURES = ("probability_vs_gap.png", "fragility.png", "required_gap.png")
#: sweep axes a risk scene may have: the ensemble and its intensity levels
ENSEMBLE_AXES = ("record", "seed", "scale")


@dataclass
class RiskStudy:
    """A study's tables (pandas DataFrames; None where not asked for) and where they went."""

    scene: Scene
    folder: Path
    facts: dict
    demand: object
    probability: object
    fragility: object
    required_gap: object
    code_rules: object
    consequences: object = None
    annual_rate: object = None
    runs: dict = field(default_factory=dict)  # 'free', 'contact': sweep.run.SweepSummary
    boot: object = None  # the bootstrap's fits over the gaps (fragility.Fit), for the figures' bands

    def tables(self) -> dict:
        return {name: getattr(self, name) for name in TABLES if getattr(self, name) is not None}


def study_folder(scene: Scene) -> Path:
    return Path(scene.risk.path)


def motion_axis(scene: Scene) -> Axis:
    for a in scene.sweep:
        if a.name in ("record", "seed"):
            return a
    raise ConfigError("[risk]: the ensemble needs a [sweep] record or seed axis")


def check_risk_scene(scene: Scene) -> None:
    """A scene a risk study can run: a [risk] section and only ensemble axes."""
    if scene.risk is None:
        raise ConfigError(f"{scene.source}: no [risk] section: nothing to study (python -m pounding_sweep --describe)")
    from pounding_sweep.scene.validate import require_two_buildings

    require_two_buildings(scene, "a study of the probability of pounding")
    from pounding_sweep.scene.risk import check_ensemble

    check_ensemble(scene)
    if scene.risk.hazard is not None:  # read before any run: a bad table is refused with nothing written
        from pounding_sweep.risk.hazard import read_hazard

        read_hazard(scene.risk.hazard)
    extra = [a.name for a in scene.sweep if a.name not in ENSEMBLE_AXES]
    if extra:
        raise ConfigError(
            f"[sweep] {extra[0]}: a risk study's [sweep] holds its ensemble (record or seed) and intensity levels "
            "(scale) only; its contact runs take [contact]'s parameters"
        )
    motion_axis(scene)


def _levels(scene: Scene) -> tuple:
    return scene.axis_values("scale") or (scene.excitation.scale,)


def readers(scene: Scene, kind: str) -> tuple[str, ...]:
    """What reads the study's `kind` runs (sweep/metricgroups.py READERS): the demand table reads the contact-free
    runs; the consequence table, with contact gaps, both kinds."""
    consequences = ("risk_consequences",) if scene.risk.contact_gaps_m else ()
    return (("risk_demand",) if kind == "free" else ()) + consequences


def _derived(scene: Scene, kind: str, axes: tuple, **changes) -> Scene:
    """The scene of the study's `kind` runs ('free', 'contact'): its axes, its folder, the metric groups the
    study reads of them (and any more the scene's [output] metrics names), nothing else of the study."""
    output = dataclasses.replace(
        scene.output,
        path=str(study_folder(scene) / f"runs_{kind}.parquet"),
        histories=(),
        metrics=study_metrics(scene, *readers(scene, kind)),
    )
    out = dataclasses.replace(
        scene,
        name=f"{scene.name}.{kind}",
        experiment=None,
        calibrate=None,
        risk=None,
        sweep=axes,
        output=output,
        **changes,
    )
    validate(out)
    return out


def free_scene(scene: Scene) -> Scene:
    """The contact-free runs: one per motion and level, the gap no motion closes (no contact, so no contact
    period to resolve: min_steps_per_contact_period 0)."""
    return _derived(
        scene,
        "free",
        (motion_axis(scene), Axis("scale", tuple(_levels(scene)))),
        contact=dataclasses.replace(scene.contact, gap_m=SEPARATED_GAP_M),
        integration=dataclasses.replace(scene.integration, min_steps_per_contact_period=0.0),
    )


def contact_scene(scene: Scene) -> Scene | None:
    """The contact runs at [risk] contact_gaps_m, at the contact intensities; None without contact gaps."""
    r = scene.risk
    if not r.contact_gaps_m:
        return None
    levels = _levels(scene)
    if scene.excitation.scaling == "intensity":
        levels = tuple(r.contact_intensities_g or r.intensities_g or levels)
    return _derived(
        scene, "contact", (motion_axis(scene), Axis("scale", tuple(levels)), Axis("gap_m", tuple(r.contact_gaps_m)))
    )


def resized(
    scene: Scene,
    motions: int | None = None,
    levels=None,
    duration_s: float | None = None,
    filter: str | None = None,
    stationary: bool = False,
    **risk,
) -> Scene:
    """A stochastic study's scene with another number of motions (seeds 0 .. motions - 1), other levels, motion
    length, filter ('kanai_tajimi' drops the high-pass), without its envelope (stationary), and [risk] keys
    changed: for trying a study small, tests and benchmarks."""
    st, exc, sweep = scene.stochastic, scene.excitation, dict((a.name, a.values) for a in scene.sweep)
    if filter == "kanai_tajimi":
        st = dataclasses.replace(st, filter=filter, highpass_frequency_Hz=None, highpass_damping=None)
    if stationary:
        st = dataclasses.replace(st, envelope="none", rise_s=None, strong_end_s=None, decay_per_s=None)
    if motions is not None:
        sweep["seed"] = tuple(float(i) for i in range(motions))
    if levels is not None:
        sweep["scale"] = tuple(levels)
    if duration_s is not None:
        exc = dataclasses.replace(exc, duration_s=duration_s)
    out = dataclasses.replace(
        scene,
        stochastic=st,
        excitation=exc,
        sweep=tuple(Axis(k, v) for k, v in sweep.items()),
        risk=dataclasses.replace(scene.risk, **risk) if scene.risk is not None and risk else scene.risk,
    )
    validate(out)
    return out


RUN_FOLDERS = ("runs_free.parquet", "runs_contact.parquet")


def check_folder(folder: Path) -> None:
    """The study folder may be used: absent, empty, a risk study's (its manifest), or holding only the study's
    run datasets (an interrupted first study: run_scene guards those itself). A file at that path, or a folder of
    something else, is refused, never written into."""
    if folder.exists() and not folder.is_dir():
        raise OutputError(f"{folder}: a file, not a risk study folder: give another --out, or move it away")
    if not folder.is_dir() or (folder / MANIFEST).is_file():
        return
    foreign = sorted(p.name for p in folder.iterdir() if p.name not in RUN_FOLDERS)
    if foreign:
        raise OutputError(
            f"{folder} exists and is not a risk study folder (no {MANIFEST}; it holds {', '.join(foreign[:3])}"
            f"{' ...' if len(foreign) > 3 else ''}): give another --out, or move it away"
        )


def mark_folder(folder: Path) -> None:
    """Write the study folder's manifest (after its runs: a study refused before them leaves nothing behind)."""
    try:
        tmp = folder / f".{MANIFEST}.tmp"
        tmp.write_text(json.dumps({"package": "pounding_sweep", "kind": "risk_study", "version": __version__}))
        tmp.replace(folder / MANIFEST)
    except OSError as e:
        raise OutputError(f"{folder}: cannot write the study here ({e.strerror or e})") from None


def run_runs(scene: Scene, threads=None, executor=None, progress_for=None, overwrite=False, confirmed=False) -> dict:
    """Run (or resume) the study's contact-free and contact runs; their sweep summaries by name ('free',
    'contact'). `progress_for(name)` gives each sweep's progress callback (run_scene's `progress`)."""
    from pounding_sweep.sweep.run import run_scene

    out = {}
    for name, sub in (("free", free_scene(scene)), ("contact", contact_scene(scene))):
        if sub is None:
            continue
        p = progress_for(name) if progress_for is not None else None
        out[name] = run_scene(
            sub, threads=threads, progress=p, executor=executor, overwrite=overwrite, confirmed=confirmed,
            contact_free=name == "free",  # no contact is their point: not a finding (nor stored as one)
        )  # fmt: skip
    return out


def _read_runs(folder: Path, columns: list[str] | None = None):
    import pyarrow.parquet as pq

    from pounding_sweep.sweep.results import part_files

    parts = part_files(folder)
    if not parts:
        raise OutputError(f"{folder}: no runs (part-*.parquet): run the study first")
    import pyarrow as pa

    tables = [pq.read_table(p, columns=columns) for p in parts]
    return pa.concat_tables(tables).to_pandas()


def _with_motion(df, sub: Scene):
    """motion_index (the run's place on the motion axis) and motion (the record's name or the seed)."""
    shape = tuple(len(a.values) for a in sub.sweep)
    idx = np.unravel_index(df.run_id.to_numpy(), shape)
    df["motion_index"] = idx[0]
    axis = sub.sweep[0]
    if axis.name == "record":
        names = [Path(v).stem for v in axis.values]
        df["motion"] = [names[i] for i in idx[0]]
    else:
        df["motion"] = np.asarray(axis.values, dtype=np.int64)[idx[0]].astype(str)
    return df


def model_facts(scene: Scene) -> dict:
    """The buildings' first modes, the DDC correlation, the top facing floor's height, the intensity measure."""
    model = CoupledModel.from_scene(scene)
    w1, z1 = frame_first_mode(model.b1)
    w2, z2 = frame_first_mode(model.b2)
    h = scene.building1.story_heights()
    lam = float(scene.excitation.length_scale)
    top = None
    if h:
        heights = floor_heights_m(h)
        top = float(heights[model.n_pairs - 1]) * lam
    e = scene.excitation
    return {
        "periods_s": [2 * np.pi / w1, 2 * np.pi / w2],
        "damping_ratios": [z1, z2],
        "ddc_rho": float(cqc_correlation(w1, w2, z1, z2)),
        "n_pairs": model.n_pairs,
        "floors": list(model.floors),
        "top_pair_height_full_scale_m": top,
        "length_scale": lam,
        "intensity": {
            "measure": e.intensity,
            "period_s": intensity_period(scene),
            "damping": 0.05 if e.intensity == "sa" else None,
            "scaling": e.scaling,
            "unit": "g",
        },
        "ensemble": {
            "axis": motion_axis(scene).name,
            "motions": len(motion_axis(scene).values),
            "levels": list(_levels(scene)),
        },
    }


def analyse(scene: Scene, summaries: dict | None = None, progress=None) -> RiskStudy:
    """The study's tables from its runs in the study folder; `progress(done, total)` follows the bootstrap's
    replicates (a cloud of thousands of runs takes minutes)."""
    r, e = scene.risk, scene.excitation
    folder = study_folder(scene)
    facts = model_facts(scene)
    n_pairs = facts["n_pairs"]
    fsub = free_scene(scene)
    cols = ["run_id", "scale", "intensity_g", "status"]
    cols += [f"closest_approach_f{j}_m" for j in range(1, n_pairs + 1)]
    cols += [f"peak_disp_b{b}f{j}_m" for j in range(1, n_pairs + 1) for b in (1, 2)]
    free = _with_motion(_read_runs(Path(fsub.output.path), cols), fsub)
    bad = free.status.str.contains("diverged")
    if bad.any():
        raise ConfigError(
            f"[risk] {scene.name}: {int(bad.sum())} contact-free run(s) diverged; the study needs finite runs"
        )
    demand = A.demand_table(free, n_pairs, facts["ddc_rho"])
    _check_gap_units(r, float(demand.required_gap_m.max()))
    gaps = np.asarray(r.gaps_m) if r.gaps_m else A.default_gaps(demand)
    gaps = np.sort(gaps)
    prob = A.probability_table(demand, gaps, e.scaling, r.confidence)
    data = A.FragilityData(demand, e.scaling)
    mult, boot = A.bootstrap(data, gaps, r.bootstrap, r.bootstrap_seed, progress)
    if boot is None:
        from pounding_sweep.warn import warn

        warn(
            "no_bootstrap",
            "[risk] bootstrap = 0: the fragilities, the lognormal required gaps and the annual rates come without "
            "intervals (a fitted value without its uncertainty is half an answer); 1000 resamples is the default",
        )
    frag = A.fragility_table(data, gaps, boot, r.confidence)
    _check_few_events(frag)
    fit = data.fit(gaps)
    if r.intensities_g:
        intensities = list(r.intensities_g)
    elif e.scaling == "intensity":
        intensities = list(_levels(scene))
    else:
        intensities = [float(np.median(demand.intensity_g))]
    req = A.required_gap_table(demand, data, gaps, fit, boot, intensities, r.targets, e.scaling, r.confidence)
    rules = A.code_rule_table(
        demand, data, n_pairs, facts["ddc_rho"], facts["top_pair_height_full_scale_m"], facts["length_scale"],
        intensities, e.scaling, r.confidence, mult,
    )  # fmt: skip
    cons = None
    csub = contact_scene(scene)
    if csub is not None:
        contact = _with_motion(_read_runs(Path(csub.output.path)), csub)
        full = _with_motion(_read_runs(Path(fsub.output.path)), fsub)
        cons = A.consequence_table(contact, full, tuple(facts["floors"]), n_pairs)
    annual = None
    if r.hazard is not None:
        from pounding_sweep.risk.hazard import annual_rate, read_hazard

        hz = read_hazard(r.hazard)
        levels = sorted(set(demand.intensity_g.astype(float)))
        annual = A.annual_rate_table(hz, fit, boot, gaps, r.confidence, annual_rate, levels)
    return RiskStudy(scene, folder, facts, demand, prob, frag, req, rules, cons, annual, dict(summaries or {}), boot)


def _check_few_events(frag) -> None:
    """A warning naming the gaps whose fitted fragility rests on fewer than analysis.MIN_EVENTS of its rarer
    outcome (a helper's cloud: the 150 mm gap fitted from 4 poundings in 4000 runs, status ok, its curve above the
    100 mm gap's from 0.3 g on)."""
    from pounding_sweep.warn import warn

    few = A.few_events(frag)
    if few.any():
        rows = frag[few]
        rare = np.minimum(rows.poundings, rows.outcomes - rows.poundings)
        gaps = ", ".join(f"{g * 1e3:.4g}" for g in rows.gap_m[:6]) + (", ..." if len(rows) > 6 else "")
        counts = f"{int(rare.min())}" if rare.min() == rare.max() else f"{int(rare.min())}-{int(rare.max())}"
        warn(
            "few_events",
            f"[risk] the fragility at {int(few.sum())} gap(s) ({gaps} mm; fragility.parquet: poundings, outcomes) "
            f"rests on {counts} of its {int(rows.outcomes.iloc[0])} outcomes "
            f"pounding (or not), fewer than {A.MIN_EVENTS}: its median and beta are weakly identified (see their "
            "intervals) and its curve may cross its neighbours'; more motions, or gaps nearer the runs' required "
            "gaps, identify it",
        )


#: gaps all beyond this many times the largest required gap of any run: metres written for millimetres, likely
GAP_UNITS_FACTOR = 10.0


def _check_gap_units(r, largest_m: float) -> None:
    """A warning where every gap of [risk] gaps_m (or contact_gaps_m) lies beyond GAP_UNITS_FACTOR times the largest
    gap any run requires: no run comes near them (every probability 0, every contact run free), as when
    millimetres are written in a key in metres."""
    from pounding_sweep.warn import warn

    if not largest_m > 0.0:  # no gap is too large for a demand of 0: say what the 0 is instead
        warn(
            "no_relative_motion",
            "[risk]: no run requires a gap (largest required gap 0 m: the facing floors never move relative to "
            "each other, as identical buildings do): every probability of pounding is 0",
        )
        return
    for key in ("gaps_m", "contact_gaps_m"):
        values = getattr(r, key)
        if values and min(values) > GAP_UNITS_FACTOR * largest_m:
            warn(
                "gap_units",
                f"[risk] {key} = {list(values)}: every gap is more than {GAP_UNITS_FACTOR:g} times the largest gap any "
                f"run requires ({largest_m:.4g} m at the highest level): no motion comes near them; the key is in "
                f"metres (for {values[0]:g} mm write {values[0] / 1e3:g})",
            )


def risk_study(
    scene: Scene, threads=None, executor=None, progress_for=None, overwrite=False, confirmed=False
) -> RiskStudy:
    """Run (or resume) a scene's risk study and compute its tables (write them with write_study). `executor`:
    sweep.executors' (default: the scene's [execution]); `progress_for(name)`: a progress callback per sweep."""
    check_risk_scene(scene)
    if scene.contact is not None and scene.contact.gap_m > 0.0:
        from pounding_sweep.warn import warn

        warn(
            "gap_not_studied",
            f"[contact] gap_m = {scene.contact.gap_m:g} plays no part in a risk study: it sets the gaps itself "
            f"([risk] gaps_m for the probability of pounding, contact_gaps_m for the contact runs, in metres); "
            f"for {scene.contact.gap_m * 1e3:g} mm add {scene.contact.gap_m:g} to gaps_m",
        )
    check_folder(study_folder(scene))
    summaries = run_runs(scene, threads, executor, progress_for, overwrite, confirmed)
    mark_folder(study_folder(scene))
    return analyse(scene, summaries, progress_for("bootstrap") if progress_for is not None else None)


def metadata(study: RiskStudy, table: str) -> dict[bytes, bytes]:
    """A table's key-value metadata: what it is, the scene (TOML, canonical config, hash), [risk], the model
    facts, the versions, what each column means."""
    from pounding_sweep.risk.columns import COLUMN_DOCS
    from pounding_sweep.sweep.results import versions

    scene = study.scene
    info = {
        **versions(),
        "kind": f"risk_{table}",
        "scene_name": scene.name,
        "scene_file": str(Path(scene.source).resolve()),
        "config_hash": scene.config_hash(),
        "config": scene.canonical(),
        "risk": dataclasses.asdict(scene.risk),
        "model": study.facts,
        "units": "SI: m, s, N; intensities in g (9.80665 m/s^2); unit suffix in each column name",
        "columns": COLUMN_DOCS.get(table, {}),
    }
    return {b"pounding_sweep": json.dumps(info, default=str).encode(), b"scene_toml": scene.toml_text.encode()}


def write_study(study: RiskStudy, figures: bool = True) -> list[Path]:
    """Every table (Parquet and CSV) and, with matplotlib, the figures, into the study folder; the paths."""
    import pyarrow as pa

    from pounding_sweep.sweep.results import write_table_atomic
    from pounding_sweep.warn import warn

    folder = study.folder
    written = []
    for name, df in study.tables().items():
        t = pa.Table.from_pandas(df, preserve_index=False)
        written.append(write_table_atomic(folder / f"{name}.parquet", t, metadata(study, name)))
        df.to_csv(folder / f"{name}.csv", index=False)
        written.append(folder / f"{name}.csv")
    if figures:
        try:
            from pounding_sweep.risk.figures import fragility_figure, probability_figure, required_gap_figure
        except ImportError:
            return written
        try:
            for fname, fig in (
                ("probability_vs_gap.png", probability_figure(study)),
                ("fragility.png", fragility_figure(study)),
                ("required_gap.png", required_gap_figure(study)),
            ):
                if fig is None:
                    (folder / fname).unlink(missing_ok=True)  # an earlier run's, in the study's own folder
                    warn(
                        "empty_figure",
                        f"{fname} not drawn: no intensity of the study has a required gap to show (every run "
                        "pounds at every gap studied, or none does; required_gap's notes say which)",
                    )
                    continue
                fig.savefig(folder / fname, dpi=120)
                written.append(folder / fname)
        except SystemExit:  # no matplotlib: the tables are the study
            pass
    return written


__all__ = [
    "MANIFEST",
    "TABLES",
    "FIGURES",
    "RiskStudy",
    "study_folder",
    "check_risk_scene",
    "free_scene",
    "contact_scene",
    "resized",
    "check_folder",
    "mark_folder",
    "run_runs",
    "analyse",
    "risk_study",
    "metadata",
    "write_study",
]
