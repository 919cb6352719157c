"""`python -m pounding_sweep plot RESULTS [--out DIR]`: the figures of a result file as PNGs."""

from __future__ import annotations

import sys

from pounding_sweep.cli.common import EXIT_BAD_INPUT, OneLineParser
from pounding_sweep.errors import InputError


def plot_main(argv: list[str]) -> int:
    """`python -m pounding_sweep plot RESULTS [--out DIR]`: the figures of a result file as PNGs."""
    p = OneLineParser(
        prog="python -m pounding_sweep plot",
        description="Write PNG figures of a sweep's result: error or peak-response heatmaps over two swept "
        "axes ((k_s/k, r) where both are swept), the best run's displacement and force histories over the "
        "experiment's, numerical-against-experimental plots, and error against run time. Needs the 'plot' "
        "extra (matplotlib).",
    )
    p.add_argument("results", help="a sweep's result: the dataset folder it wrote (results/<scene>.parquet)")
    p.add_argument("--out", help="folder for the PNGs (default: <results>_plots next to the file)")
    args = p.parse_args(argv)
    from pounding_sweep.plots import plot_results

    skipped: dict[str, str] = {}
    try:
        paths = plot_results(args.results, args.out, skipped=skipped)
    except InputError as e:  # ResultError (not a sweep's result) and the scene, record, table errors
        msg = str(e)
        print(f"error: {msg if msg.startswith(args.results) else f'{args.results}: {msg}'}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except OSError as e:
        print(f"error: {args.results}: cannot plot ({e.strerror or e})", file=sys.stderr)
        return EXIT_BAD_INPUT
    print("\n".join(str(x) for x in paths))
    for name, why in skipped.items():
        print(f"{name}.png not drawn: {why}")
    return 0
