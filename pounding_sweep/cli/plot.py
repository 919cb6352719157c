"""`python -m pounding_sweep plot RESULTS [--out DIR]`: the figures of a result file as PNGs."""

from __future__ import annotations

import argparse
import sys

from pounding_sweep.cli.common import EXIT_BAD_INPUT
from pounding_sweep.errors import ConfigError, ExperimentError, RecordError


def plot_main(argv: list[str]) -> int:
    """`python -m pounding_sweep plot RESULTS [--out DIR]`: the figures of a result file as PNGs."""
    p = argparse.ArgumentParser(
        prog="python -m pounding_sweep plot",
        description="Write PNG figures of a sweep's result file: error or force heatmaps over "
        "(k_s/k, r), the best run's displacement and force histories over the experiment's, "
        "and numerical-against-experimental plots. Needs the 'plot' extra (matplotlib).",
    )
    p.add_argument("results", help="a result file written by a sweep (.parquet)")
    p.add_argument("--out", help="folder for the PNGs (default: <results>_plots next to the file)")
    args = p.parse_args(argv)
    from pounding_sweep.plots import plot_results

    try:
        paths = plot_results(args.results, args.out)
    except (ConfigError, RecordError, ExperimentError, OSError, KeyError) as e:
        print(f"error: {args.results}: cannot plot ({type(e).__name__}: {e})", file=sys.stderr)
        return EXIT_BAD_INPUT
    print("\n".join(str(x) for x in paths))
    return 0
