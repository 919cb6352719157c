"""Command line: `python -m pounding_sweep SCENE.toml` runs a scene's sweep and writes Parquet.

Owns stdout/stderr, exit codes and progress. Bad input gives one line naming the file, key
and value, exit status 2, and no output file.
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import signal
import sys
import threading

from pounding_sweep.cli.common import EXIT_BAD_INPUT, OneLineParser, interruptible, print_warning
from pounding_sweep.errors import InputError
from pounding_sweep.progress import Progress
from pounding_sweep.scene import describe, load_scene
from pounding_sweep.scene.validate import check_dask_address, check_workers
from pounding_sweep.warn import collecting

# subcommands: `python -m pounding_sweep NAME ...` -> module:function(argv) -> exit code (imported lazily,
# so a sweep never imports OpenCV or matplotlib)
SUBCOMMANDS = {
    "plot": "pounding_sweep.cli.plot:plot_main",
    "track": "pounding_sweep.cli.track:track_main",
    "identify": "pounding_sweep.cli.identify:identify_main",
    "gaps": "pounding_sweep.cli.gaps:gaps_main",
    "import": "pounding_sweep.cli.import_:import_main",
    "risk": "pounding_sweep.cli.risk:risk_main",
}
#: one line per subcommand for --help (each has its own: python -m pounding_sweep NAME --help)
SUBCOMMAND_HELP = {
    "track": "track VIDEO --out TABLE: LED markers of a shake-table video -> a tracked-displacement table",
    "identify": "identify TABLE [--scene S --out T]: frequencies, damping and mode shapes; the model update",
    "plot": "plot RESULTS: PNG figures of a result file (heatmaps, best run's histories, error vs run time)",
    "gaps": "gaps SCENE [--out T]: the seismic gap each floor pair needs, by rule and from the histories",
    "import": "import NAME=FILE ... --out DIR: raw sensor exports -> an experiment table, a record, provenance",
    "risk": "risk SCENE [--out D]: probability of pounding against the gap, fragility, required gap ([risk])",
}


def _parser() -> argparse.ArgumentParser:
    p = OneLineParser(
        prog="python -m pounding_sweep",
        usage="%(prog)s [options] SCENE.toml\n       %(prog)s {track,identify,plot,gaps,import,risk} ... (see below)",
        description="Run a pounding scene: every grid point of its [sweep] through the Newmark/Kelvin-Voigt "
        "kernel, one Parquet row per run (metrics with units in the column names; the scene, its hash and "
        "the package versions in the file metadata).",
        epilog="subcommands (python -m pounding_sweep NAME --help for each):\n"
        + "\n".join(f"  {line}" for line in SUBCOMMAND_HELP.values())
        + "\n\nScene keys: python -m pounding_sweep --describe. Shipped scenes: sweeps/*.toml.",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("scene", nargs="?", help="scene file (TOML), e.g. sweeps/paper_6hz.toml")
    p.add_argument("--out", help="result file (default: the scene's [output] path)")
    p.add_argument("--threads", type=int, default=None, help="worker threads (default: the scene's, 0 = all cores)")
    p.add_argument(
        "--executor", choices=["local", "dask"], help="who runs the chunks (default: the scene's [execution])"
    )
    p.add_argument("--dask-address", help="Dask scheduler address, e.g. tcp://host:8786 (default: a LocalCluster here)")
    p.add_argument("--workers", type=int, help="LocalCluster worker processes (default: the scene's, 0 = all cores)")
    p.add_argument(
        "--overwrite",
        action="store_true",
        help="replace results of another sweep at --out (by default a rerun of the same scene resumes: "
        "finished parts are kept, the rest is run)",
    )
    p.add_argument("--yes", action="store_true", help="run a grid larger than [execution] max_runs (2,000,000)")
    p.add_argument("--quiet", action="store_true", help="no progress and no summary")
    p.add_argument("--describe", action="store_true", help="list every scene section and key, then exit")
    return p


def _run_text(s) -> str:
    """The summary's run line: wall time and rate over the runs this call ran (not the resumed ones)."""
    if s.new_runs == 0:
        return f"nothing to run: all {s.runs:,} runs kept from an earlier run"
    rate = s.new_steps / s.new_kernel_s if s.new_kernel_s > 0 else float("nan")
    who = "thread" if s.executor == "local" else "Dask worker"
    kept = f"; {s.runs - s.new_runs:,} kept from an earlier run" if s.new_runs < s.runs else ""
    return (
        f"{s.run_s:.2f} s wall on {s.threads} {who}(s) for {s.new_runs:,} runs{kept}; "
        f"{s.new_steps:,} steps, {rate / 1e6:.1f} M steps/s per core"
    )


def _force_text(x: dict) -> str:
    """The largest pounding force, and where a run whose force is no answer holds it (diverged, or its contact
    made energy: sweep/run.py untrusted_force), the largest of the other runs beside it."""
    from pounding_sweep.sweep.run import UNTRUSTED_FORCE_FLAGS, untrusted_force

    top, ok, status = x["peak_force_N"], x.get("peak_force_ok_N", x["peak_force_N"]), x.get("peak_status", "ok")
    if not untrusted_force(status) or top <= ok:
        return f"{top:.3f} N"
    others = f"the runs not flagged {' or '.join(UNTRUSTED_FORCE_FLAGS)}"
    among_ok = f"{ok:.3f} N in {others}" if ok == ok else f"no run among {others}"
    return f"{among_ok}; {top:.4g} N in a run flagged {status}"


def _print_summary(s) -> None:
    rows = [
        ("scene", s.scene),
        ("runs", f"{s.runs}"),
        ("status", ", ".join(f"{k}: {v}" for k, v in sorted(s.statuses.items()))),
        ("largest pounding force", _force_text(s.extremes))
        if "peak_force_N" in s.extremes
        else ("largest pounding force", "none: one building, no contact"),
        ("compile (or cache load)", f"{s.compile_s:.2f} s" if s.compile_s > 0 else "none needed"),
        ("run", _run_text(s)),
        (
            "results",
            f"{s.path} (Parquet dataset, {s.parts} part(s)"
            + (f"; {s.resumed_parts} kept from an earlier run)" if s.resumed_parts else ")"),
        ),
    ]
    if s.histories_path:
        rows.append(("histories", str(s.histories_path)))
    if s.warnings:
        rows.append(("warnings", f"{len(s.warnings)} (below; also in the result metadata)"))
    w = max(len(k) for k, _ in rows)
    print("\n".join(f"{k:<{w}}  {v}" for k, v in rows))
    for msg in s.warnings:
        print(f"  warning: {msg}")
    if s.best is not None and s.best.empty:
        print("\nno run could be scored against the experiment (all diverged or ended before its window)")
    elif s.best is not None:
        print(f"\nbest runs against the experiment (lowest relative RMS error, eq. 20; {s.best_path}):")
        show = [
            c
            for c in ("criterion", "contact_law", "error_pct", "run_id", "ks_ratio", "r", "gap_m", "record", "status")
            if c in s.best
        ]
        print(s.best[show].to_string(index=False, float_format=lambda x: f"{x:.4g}"))
        if s.refinement is not None:
            rf = s.refinement
            opt = ", ".join(f"{k} = {v:.4g}" for k, v in rf.optimum.items())
            how = "kept from the earlier run; " if s.refinement_reused else ""
            print(
                f"refined from the best cell ({how}{rf.evaluations} runs): {opt}, combined error {rf.error_pct:.3f} % "
                f"(grid best {rf.start_error_pct:.3f} %)"
            )
    if s.calibration_summary:
        _print_calibration(s.calibration_summary, s.calibration_reused)


def _print_calibration(md: dict, reused: bool) -> None:
    """The calibration's answer (calibrate.calibration_metadata: new, or kept from an earlier run): per law each
    fitted value with its 95 % interval and whether the data identify it, the error against the noise floor, and
    (several laws) the comparison."""
    import pandas as pd

    ft, lt = pd.DataFrame(md["fits"]), pd.DataFrame(md["laws"])
    kept = "; kept from an earlier run of this calibration" if reused else ""
    from pounding_sweep.sweep.calibrate import NO_CONTACT

    one = list(lt.contact_law) == [NO_CONTACT]
    what = "one building's structure, no contact" if one else "contact and structure fitted together"
    print(f"\ncalibration ({what}; 95 % intervals; stored in the best table's metadata{kept}):")
    for f in lt.itertuples():
        step = getattr(f, "step_error_over_noise", float("nan"))
        print(
            f"  {'the building' if one else f.contact_law}: relative RMS {f.rel_rms_pct:.3f} %, residual {f.misfit_over_noise:.2f} x the noise "
            f"floor"
            + (f" (the time step's own error {step:.2g} x, by halving it)" if step == step else "")
            + f", {f.evaluations} runs, {f.seconds:.0f} s"
        )
        for r in ft[ft.contact_law == f.contact_law].itertuples():
            ident = (
                "" if r.identified else f"  NOT IDENTIFIED: any value in [{r.profile_low:.4g}, {r.profile_high:.4g}]"
            )
            model = (
                f"; with model error {r.ci95_model_low:.5g} .. {r.ci95_model_high:.5g}, quote this"
                + (
                    " (the bounds: too few windows identify it)"
                    if getattr(r, "model_error_windows_identifying", 2) < 2
                    else ""
                )
                if getattr(r, "quote", "noise") == "model_error"
                else ""
            )
            print(
                f"    {r.parameter:<20} {r.estimate:.5g}  (95 % {r.ci95_low:.5g} .. {r.ci95_high:.5g}{model}; "
                f"bounds {r.lower_bound:g} .. {r.upper_bound:g}){ident}"
            )
    if len(lt) > 1:
        lt = lt.sort_values("aic")
        print("  laws compared (sweep/lawcompare.py: AIC/BIC on one effective count, blocked cross-validation):")
        cols = ["contact_law", "parameters", "rel_rms_pct", "misfit_over_noise", "delta_aic", "delta_bic"]
        print(lt[cols + [c for c in ("cv_dm_z",) if c in lt]].to_string(index=False, float_format=lambda x: f"{x:.3g}"))
        if md.get("comparison"):
            print(f"  {md['comparison']['text']}")


class SweepProgress(Progress):
    """The progress meter, and a line for each stage of the calibration after the grid (which runs for a minute
    or more between them): on stderr, terminal or not (a log keeps them), not with --quiet."""

    def stage(self, message: str) -> None:
        if self.announce:
            print(message, file=sys.stderr, flush=True)


def check_execution_options(args) -> None:
    """--threads, --workers and --dask-address, checked before anything is read (shared by the subcommands)."""
    if args.threads is not None:
        check_workers(args.threads, "--threads")
    if args.workers is not None:
        check_workers(args.workers, "--workers")
    if args.dask_address:
        check_dask_address(args.dask_address, "--dask-address")


def _with_execution(scene, args):
    """The scene with the command line's executor choices in place of its [execution] ones."""
    import dataclasses

    changes = {
        k: v
        for k, v in (("executor", args.executor), ("dask_address", args.dask_address), ("dask_workers", args.workers))
        if v is not None
    }
    if args.dask_address and "executor" not in changes:
        changes["executor"] = "dask"
    return dataclasses.replace(scene, execution=dataclasses.replace(scene.execution, **changes)) if changes else scene


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    with interruptible():
        if argv and argv[0] in SUBCOMMANDS:
            module, func = SUBCOMMANDS[argv[0]].split(":")
            try:
                return getattr(importlib.import_module(module), func)(argv[1:])
            except KeyboardInterrupt:  # a subcommand that does not say more itself (track does)
                print("interrupted", file=sys.stderr)
                return 130
        return _sweep_main(argv)


def _sweep_main(argv: list[str]) -> int:
    args = _parser().parse_args(argv)
    if args.describe:
        try:
            print(describe())
        except BrokenPipeError:  # `--describe | head`: the reader had enough; no traceback at exit either
            import os

            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
    if not args.scene:
        _parser().print_usage(sys.stderr)
        print("error: give a scene file (TOML); see --help", file=sys.stderr)
        return EXIT_BAD_INPUT
    scene = None
    try:
        with _terminated_as_interrupt():
            check_execution_options(args)
            scene = load_scene(args.scene)
            from pounding_sweep.sweep.run import (
                run_scene,
            )  # Numba and pyarrow: after the scene is read, so bad input fails fast

            scene = _with_execution(scene, args)
            with collecting(echo=print_warning):  # printed as they happen, before the long part of a run
                summary = run_scene(
                    scene,
                    out_path=args.out,
                    threads=args.threads,
                    progress=SweepProgress(not args.quiet),
                    overwrite=args.overwrite,
                    confirmed=args.yes,
                )
    except InputError as e:  # the scene, its files, the output folder, the cluster: one line each
        msg = str(e)
        if scene is not None and msg.startswith("["):  # a key of the scene, found after loading: name the file too
            msg = f"{args.scene}: {msg}"
        print(f"error: {msg}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except OSError as e:  # an unwritable place not caught by name (the output checks name theirs)
        where = f" ({e.filename})" if getattr(e, "filename", None) and str(e.filename) not in str(e) else ""
        print(f"error: cannot write results: {e}{where}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except Terminated:
        print(
            "terminated (SIGTERM): the finished parts are kept; run the same command again to resume",
            file=sys.stderr,
        )
        return 128 + signal.SIGTERM
    except KeyboardInterrupt:
        print("interrupted: the finished parts are kept; run the same command again to resume", file=sys.stderr)
        return 130
    if not args.quiet:
        _print_summary(summary)
    return 0


class Terminated(KeyboardInterrupt):
    """SIGTERM (what batch schedulers send before they kill a job), raised where Ctrl-C would be."""


@contextlib.contextmanager
def _terminated_as_interrupt():
    """While a sweep runs, SIGTERM unwinds it like Ctrl-C: the finished parts stay, the output folder is
    released, the executor closed, and one line says so (the previous handler is restored after)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def handler(signum, frame):
        raise Terminated()

    previous = signal.signal(signal.SIGTERM, handler)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)
