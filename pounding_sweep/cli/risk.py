"""`python -m pounding_sweep risk SCENE.toml`: a probabilistic pounding study of a scene with a [risk] section
(pounding_sweep.risk): over its ensemble of ground motions, the probability of pounding against the gap, lognormal
fragility curves, the gap a target probability needs, the probability each code rule's gap leaves, the
consequences of pounding at chosen gaps and, with a hazard curve, the annual rate of pounding.

Writes the study folder ([risk] path, default results/<scene>.risk/): the runs (Parquet datasets, resumed where
an interrupted study stopped), the tables (Parquet with CSV copies) and the figures; prints the required-gap and
code-rule tables. Exit 0, or 2 with one `error:` line on bad input (nothing written).
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
from pathlib import Path

from pounding_sweep.cli.common import EXIT_BAD_INPUT, OneLineParser, print_warning


def _parser() -> argparse.ArgumentParser:
    p = OneLineParser(prog="python -m pounding_sweep risk", description=__doc__.split("\n\n")[0])
    p.add_argument("scene", help="scene file (TOML) with a [risk] section and a [sweep] record or seed axis")
    p.add_argument("--out", help="study folder (default: the scene's [risk] path)")
    p.add_argument("--threads", type=int, default=None, help="worker threads (default: the scene's, 0 = all cores)")
    p.add_argument("--executor", choices=["local", "dask"], help="who runs the chunks (default: the scene's)")
    p.add_argument("--dask-address", help="Dask scheduler address (default: a LocalCluster here)")
    p.add_argument("--workers", type=int, help="LocalCluster worker processes (default: the scene's, 0 = all cores)")
    p.add_argument("--overwrite", action="store_true", help="replace the runs of another study in the folder")
    p.add_argument("--yes", action="store_true", help="run more runs than [execution] max_runs")
    p.add_argument("--no-figures", action="store_true", help="tables only")
    p.add_argument("--quiet", action="store_true", help="no progress and no tables")
    return p


def risk_main(argv: list[str]) -> int:
    args = _parser().parse_args(argv)
    from pounding_sweep.cli.run import _with_execution, check_execution_options  # the main command's rules
    from pounding_sweep.errors import InputError
    from pounding_sweep.progress import Progress
    from pounding_sweep.scene import load_scene
    from pounding_sweep.warn import collecting

    try:
        check_execution_options(args)
        scene = load_scene(args.scene)
        from pounding_sweep.risk.study import check_risk_scene, risk_study, write_study

        check_risk_scene(scene)
        if args.out:
            scene = dataclasses.replace(scene, risk=dataclasses.replace(scene.risk, path=str(Path(args.out).resolve())))
        scene = _with_execution(scene, args)

        def progress(name):
            unit = {"free": "contact-free runs", "bootstrap": "bootstrap replicates"}.get(name, "contact runs")
            return Progress(not args.quiet, unit=unit)

        with collecting(echo=print_warning):
            study = risk_study(scene, args.threads, None, progress, args.overwrite, args.yes)
            written = write_study(study, figures=not args.no_figures)
    except InputError as e:
        msg = str(e)
        if msg.startswith("["):
            msg = f"{args.scene}: {msg}"
        print(f"error: {msg}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except OSError as e:
        print(f"error: {getattr(e, 'filename', None) or args.out}: cannot write the study ({e.strerror or e})",
              file=sys.stderr)  # fmt: skip
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:
        print("interrupted: the finished parts are kept; run the same command again to resume", file=sys.stderr)
        return 130
    if not args.quiet:
        print_study(study, written)
    return 0


def print_study(study, written) -> None:
    """The ensemble, the required gaps and the code rules' probabilities, and where the files went."""
    f = study.facts
    im = f["intensity"]
    what = f"Sa({im['period_s']:.3g} s, 5 %)" if im["measure"] == "sa" else "PGA"
    conf = f"{study.scene.risk.confidence * 100:g} %"
    print(
        f"ensemble: {f['ensemble']['motions']} motions ({f['ensemble']['axis']}), intensity {what} "
        f"({im['scaling']}), periods {f['periods_s'][0]:.3f} / {f['periods_s'][1]:.3f} s"
    )
    req = study.required_gap.copy()
    print(f"\nrequired gap [mm] for a target probability of pounding ({conf} intervals):")
    cols = {
        "intensity_g": "intensity [g]",
        "target_probability": "target",
        "empirical_gap_m": "empirical",
        "empirical_ci_low_m": "low",
        "empirical_ci_high_m": "high",
        "lognormal_gap_m": "lognormal",
        "lognormal_ci_low_m": "low ",
        "lognormal_ci_high_m": "high ",
    }
    show = req[[c for c in cols if c in req]].copy()
    for c in show.columns:
        if c.endswith("_m"):
            show[c] = show[c] * 1e3
    print(show.rename(columns=cols).to_string(index=False, float_format=lambda x: f"{x:.4g}"))
    for row in req.itertuples():
        if getattr(row, "note", ""):
            print(f"  at {row.intensity_g:g} g, target {row.target_probability:g}: {row.note}")
    if study.annual_rate is not None:
        rates = study.annual_rate.sort_values("gap_m").reset_index(drop=True)
        unknown = rates[rates.status != "ok"]
        for _status, d in unknown.groupby("status", sort=False):
            # one band of gaps, or gaps scattered among those with a rate: say which
            band = d.index.max() - d.index.min() + 1 == len(d)
            where = (
                f"{len(d)} gap(s), {1e3 * d.gap_m.min():.4g}-{1e3 * d.gap_m.max():.4g} mm"
                if band
                else f"{len(d)} of the {len(rates)} gaps, scattered between {1e3 * d.gap_m.min():.4g} and "
                f"{1e3 * d.gap_m.max():.4g} mm among gaps with a rate (annual_rate.parquet names each)"
            )
            print(f"annual rate not given at {where}: {d.note.iloc[0]}")
    rules = study.code_rules
    print(f"\nprobability of pounding each code rule's gap leaves ({conf} Clopper-Pearson):")
    show = rules[["intensity_g", "rule", "gap_m", "pounding", "motions", "probability", "ci_low", "ci_high"]].copy()
    show["gap_m"] = show.gap_m * 1e3
    print(show.rename(columns={"gap_m": "gap [mm]"}).to_string(index=False, float_format=lambda x: f"{x:.4g}"))
    figures = sum(1 for w in written if str(w).endswith(".png"))
    what = "tables, CSV copies" + (f", {figures} figures" if figures else "; no figures")
    print(f"\nwritten: {study.folder} ({len(written)} files: {what})")
