"""`python -m pounding_sweep identify TABLE ...`: modal identification of a displacement table and, with
--scene, the model update that matches each building's first frequency (identify/table.py does the work;
identify/safety.py says when not to trust it).

Exit status 0 when done, 2 with one line `error: <file>: <what> (<value>)` on stderr and no file written
(the updated sections go to `.<out>.<pid>.tmp`, renamed when complete) on bad input, an --out that holds
anything but an update identify wrote before (a user's file is never replaced), a single-frequency table
motion, no mode found, or a model update refused (f1 at a forcing frequency, a stiffness changed by more
than 30 %; --force-update writes it anyway, with a warning). The modes found are printed before the
last two errors, so that the numbers can be seen.
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

from pounding_sweep.cli.common import (
    EXIT_BAD_INPUT,
    Bad,
    OneLineParser,
    check_replaceable,
    first_line,
    hidden_temporary,
    split_list,
)

VIDEO_SUFFIXES = {".mkv", ".avi", ".mp4", ".mov", ".m4v", ".webm"}
#: the first line of every file identify writes: what marks an existing --out as one it may replace
WRITTEN_BY = "# written by python -m pounding_sweep identify"


def _written_by_identify(path: Path) -> bool:
    return first_line(path).startswith(WRITTEN_BY)


def _identify_parser() -> argparse.ArgumentParser:
    p = OneLineParser(
        prog="python -m pounding_sweep identify",
        description="Modal identification from a displacement table (e.g. one written by track): spectrum peaks, "
        "damping (half-power bandwidth; logarithmic decrement with --free-vibration) and mode-shape ratios per "
        "building; with --scene, the model update that matches each building's first frequency (paper sec. 3).",
    )
    p.add_argument("table", help="displacement table, .csv or .parquet, with a time column")
    p.add_argument("--columns", help="columns to analyse, comma-separated (default: every displacement column)")
    p.add_argument("--time-column", default="t_s", help="time column [s] (default t_s)")
    p.add_argument("--modes", type=int, default=3, help="modes per building (default 3)")
    p.add_argument("--fmin", type=float, default=0.0, help="lowest frequency considered [Hz]")
    p.add_argument("--fmax", type=float, help="highest frequency considered [Hz]")
    p.add_argument("--start", type=float, default=0.0, help="analyse from this time on [s] (e.g. after the release)")
    p.add_argument(
        "--input",
        default="auto",
        help="column with the table's motion: modes from the transmissibility floor / table; 'none': from the "
        "floors alone (default: the column named table* or ground*, if there is one; with --free-vibration none)",
    )
    p.add_argument(
        "--input-kind",
        choices=["displacement", "velocity", "acceleration"],
        help="what the table's column measures (default: the table's metadata, as import writes it, else "
        "displacement); it weighs the harmonic-table test",
    )
    p.add_argument(
        "--free-vibration",
        action="store_true",
        help="the record is free vibration (the table at rest): modes from the floors alone (the table's column "
        "is only checked to be quiet, unless --input names it), no harmonic refusal, logarithmic decrement too",
    )
    p.add_argument("--scene", help="scene whose buildings are updated to the identified first frequencies")
    p.add_argument(
        "--update-damping", action="store_true", help="with --scene, also set damping_ratio to the identified one"
    )
    p.add_argument("--out", help="with --scene: write the updated [buildingN] sections to this TOML file")
    p.add_argument(
        "--modes-out",
        help="write the identified modes (per building: frequencies, damping ratios with their intervals and "
        "methods) to this TOML file: a calibration's start values ([calibrate] start_from)",
    )
    p.add_argument(
        "--force-update",
        action="store_true",
        help="write the update (and --modes-out) even when f1 is at a forcing frequency or a stiffness changes by "
        "more than 30 %%",
    )
    return p


def _print_identification(ident, forcing) -> None:
    import numpy as np

    from pounding_sweep.identify.safety import HARMONIC_OVER_NOISE, forcing_notes

    print(f"method: {ident.method}")
    if ident.table_line is not None:
        line = ident.table_line
        # "noise" here is the table spectrum's median level over the band (identify/modes.py input_line), which
        # a shaking table's own broadband motion may set: a line below HARMONIC_OVER_NOISE times it is not called a
        # forcing, but the table is not called quiet either (a helper's Sine 1.5 table, 160 times its sensor noise)
        what = "broadband" if line.fraction < 0.5 else "one line dominates"
        if not line.fraction > 0:
            what = "no line above the median of its spectrum: broadband, or at rest"
        if line.fraction >= 0.5 and line.over_noise < HARMONIC_OVER_NOISE:
            what = f"not {HARMONIC_OVER_NOISE:g} times above the rest: not a forcing"
        used = "" if ident.input_column else " (not the input)"
        head = f"table motion '{ident.table_column}'{used} ({line.kind}, from {ident.input_kind_source}): "
        if line.fraction > 0:
            print(
                head + f"largest line {line.frequency_Hz:.3f} Hz holds {100 * line.fraction:.1f} % of its acceleration "
                "power above 4 times the median of its spectrum"
                + (f", {line.over_noise:.3g} times the median's power over the band" if line.fraction >= 0.5 else "")
                + f" ({what})"
            )
        else:  # no bin above the noise floor: no line to name (it printed 'nan Hz holds 0.0 %')
            print(head + what)
    for b, r in sorted(ident.results.items()):
        head = f"building {b}" if b else "other columns"
        print(
            f"{head} ({', '.join(r.channels)}; shapes relative to {r.reference}; {ident.fs:g} samples/s, "
            f"resolution {r.spectrum.resolution_Hz:.3g} Hz, band {r.band_Hz[0]:.4g}-{r.band_Hz[1]:.4g} Hz)"
        )
        if not r.modes:
            print("  no mode")
        for k, m in enumerate(r.modes, 1):
            ld = ""
            if m.damping_log_decrement is not None:
                se = m.damping_log_decrement_se
                pm = f" +/- {100 * se:.2f}" if se is not None and np.isfinite(se) else ""
                ld = f", log decrement {100 * m.damping_log_decrement:.2f}{pm} %"
            lo, hi = m.damping_half_power_interval
            hp = "n/a" if not np.isfinite(m.damping_half_power) else f"{100 * m.damping_half_power:.2f} %"
            if np.isfinite(m.damping_half_power):
                hp += f" (within {100 * lo:.2f}-{100 * hi:.2f} %: +/- a resolution on the band)"
            elif np.isfinite(hi):
                hp += f" (at most {100 * hi:.2f} %: the band less the window's decay, plus a resolution)"
            if np.isfinite(m.damping_fit):
                a, b = m.damping_fit_ci95
                ld += f", fitted {100 * m.damping_fit:.2f} % (95 % {100 * a:.2f} to {100 * b:.2f} %)"
            merged = f"; merged peaks {', '.join(f'{f:.3f}' for f in m.merged_Hz)} Hz" if m.merged_Hz else ""
            shape = ", ".join(f"{c} {v:+.3f}" for c, v in m.shape.items())
            print(f"  mode {k}: {m.frequency_Hz:.4f} Hz, damping half-power {hp}{ld}; shape {shape}{merged}")
        for n in list(r.notes) + forcing_notes(r, forcing):
            print(f"  note: {n}")


def identify_main(argv: list[str]) -> int:
    args = _identify_parser().parse_args(argv)
    from pounding_sweep.errors import InputError
    from pounding_sweep.identify.safety import forcing_frequencies, method_warnings, modes_problems, update_problems
    from pounding_sweep.identify.startfile import modes_toml
    from pounding_sweep.identify.table import empty_reason, identify_table, model_updates
    from pounding_sweep.model.experiment import read_table
    from pounding_sweep.scene import load_scene

    src = args.table
    try:
        if Path(src).suffix.lower() in VIDEO_SUFFIXES:
            raise Bad(
                src,
                "identify reads a displacement table: track the video first",
                "python -m pounding_sweep track VIDEO",
            )
        _check_outputs(args)
        df, md = read_table(src)
        scene = load_scene(args.scene) if args.scene else None
        ident = identify_table(
            df,
            src,
            args.time_column,
            split_list(args.columns) if args.columns else None,
            args.modes,
            args.fmin,
            args.fmax,
            args.start,
            args.free_vibration,
            args.input,
            args.input_kind,
            md,
        )
        forcing = forcing_frequencies(ident, scene)
        _print_identification(ident, forcing)
        for w in method_warnings(ident, scene):
            sys.stdout.flush()
            print(f"warning: {w}", file=sys.stderr)
        if ident.empty:
            raise Bad(src, empty_reason(ident))
        updates = model_updates(ident, scene, args.update_damping) if scene is not None else []
        problems = update_problems(updates, ident, forcing, args.update_damping)
        if updates:
            print()
            for u in updates:
                print(f"{u.section}: f1 {u.f1_model_Hz:.4f} -> {u.f1_target_Hz:.4f} Hz: stiffness x {u.factor:.4f}")
        wrong_modes = modes_problems(ident, forcing) if args.modes_out else []
        if (problems or wrong_modes) and not args.force_update:
            refused = ["model update refused: " + "; ".join(problems)] if problems else []
            if wrong_modes:  # a calibration would start from the forcing
                refused.append(
                    "modes file refused: " + "; ".join(wrong_modes) + " (--fmin above it, or --start after the "
                    "forcing stops, finds the modes)"
                )
            raise Bad(src, "; ".join(refused), "--force-update writes it anyway")
        for pr in problems:
            print(f"warning: model update forced although {pr}", file=sys.stderr)
        for pr in wrong_modes:
            print(f"warning: modes file forced although {pr}", file=sys.stderr)
        text = "".join(u.toml() + "\n" for u in updates)
        if args.out:
            _write(Path(args.out), f"{WRITTEN_BY} {src}\n" + text)
        if args.modes_out:
            _write(Path(args.modes_out), modes_toml(ident, f"{WRITTEN_BY} {src}"))
    except (Bad, InputError) as e:
        sys.stdout.flush()  # the modes printed so far come before the error
        print(f"error: {e}", file=sys.stderr)
        return EXIT_BAD_INPUT
    if updates:
        print()
        print(text if not args.out else f"updated sections written to {args.out}")
    if args.modes_out:
        print(f"identified modes written to {args.modes_out} (a calibration's start: [calibrate] start_from)")
    return 0


def _check_outputs(args) -> None:
    """Before any work: --out needs --scene; each output path free or identify's own; not both one file."""
    if args.out and not args.scene:
        raise Bad(args.out, "--out writes updated buildings: it needs --scene", "--out without --scene")
    for out in (args.out, args.modes_out):
        if out:
            check_replaceable(Path(out), _written_by_identify, "identify")
    if args.out and args.modes_out and Path(args.out).resolve() == Path(args.modes_out).resolve():
        raise Bad(args.modes_out, "--out and --modes-out name one file", "give each its own")


def _write(out: Path, text: str) -> None:
    """`text` into `out` through a hidden temporary renamed when complete (Bad when it cannot be written)."""
    tmp = hidden_temporary(out)
    try:
        tmp.write_text(text, encoding="utf-8")
        os.replace(tmp, out)
    except OSError as e:
        tmp.unlink(missing_ok=True)
        raise Bad(out, "cannot write", e.strerror or e) from None
