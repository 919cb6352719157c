"""How many real sub-steps the event scheme's switch search takes per located switch (engine/events.py
locate_event), counted in the scalar and Hertz-type kernels.

    python benchmarks/count_substeps.py [--duration 2]
    PYTHONPATH=OTHER_CHECKOUT python benchmarks/count_substeps.py     # another version of the package

The kernels' event step is rebuilt from their own pieces (EventOps) with two of them wrapped: `advance`
called with cold=True (the search's sub-steps: the trial and the rest of a step are taken warm) and
`switch` (once per located switch) each count a call in Python (numba objmode). The grids are
compare_checkouts.py's scalar and Hertz-type cases: the 6 Hz scene at dt = 1e-4 s, gaps 0/2/20 mm x k_s/k
0.01..100 (6, log-spaced) x r (classic and no-tension laws: 0, 1/3, 2/3, 1; hertzdamp: 0.3, 0.8), runs of
--duration s. The counting kernels compile into a temporary cache of their own (never the package's)."""

from __future__ import annotations

import os
import tempfile

os.environ["NUMBA_CACHE_DIR"] = tempfile.mkdtemp(prefix="count_substeps_")

import argparse  # noqa: E402
import collections  # noqa: E402
import dataclasses  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
from numba import njit, objmode  # noqa: E402

from pounding_sweep.engine import driver, events, nonlinear, scalar  # noqa: E402
from pounding_sweep.engine.inputs import HistorySpec  # noqa: E402
from pounding_sweep.scene import Axis, load_scene  # noqa: E402
from pounding_sweep.sweep.prepare import prepare  # noqa: E402

SCENE = Path(__file__).resolve().parents[1] / "sweeps" / "paper_6hz.toml"
COUNTS: collections.Counter = collections.Counter()


def _tick(key: str) -> None:
    COUNTS[key] += 1


def _tick_substep() -> None:
    _tick("substeps")


def _tick_switch() -> None:
    _tick("switches")


def counting(ops: events.EventOps) -> events.EventOps:
    """The kernel's pieces with the search's sub-steps and the located switches counted."""
    advance, switch = ops.advance, ops.switch

    @njit
    def counted_advance(st, h, ag_s, ag_e, cold):
        if cold:
            with objmode():
                _tick_substep()
        return advance(st, h, ag_s, ag_e, cold)

    @njit
    def counted_switch(st, t, ag):
        with objmode():
            _tick_switch()
        switch(st, t, ag)

    return ops._replace(advance=counted_advance, switch=counted_switch)


def run(law: str, rs, duration: float) -> tuple[int, int]:
    """(search sub-steps, located switches) of the grid's runs under `law`, event scheme."""
    s = load_scene(SCENE)
    s = dataclasses.replace(
        s,
        integration=dataclasses.replace(s.integration, scheme="event", dt_s=1e-4),
        contact=dataclasses.replace(s.contact, law=law),
        excitation=dataclasses.replace(s.excitation, duration_s=duration),
        sweep=(
            Axis("gap_m", (0.0, 0.002, 0.02)),
            Axis("ks_ratio", tuple(np.geomspace(0.01, 100, 6))),
            Axis("r", tuple(rs)),
        ),
    )
    prep = prepare(s)
    runs, rec, _ = prep.kernel_inputs(prep.grid.chunk(0, prep.grid.size))
    COUNTS.clear()
    driver.run_chunk_scalar(prep.sysarr, runs, rec, HistorySpec.none(), prep.opts, 1)
    return COUNTS["substeps"], COUNTS["switches"]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration", type=float, default=2.0, help="the runs' length [s]")
    args = ap.parse_args(argv)
    scalar._event_step, scalar._contradicts = events.event_functions(counting(scalar.OPS))
    nonlinear._event_step, nonlinear._contradicts = events.event_functions(counting(nonlinear.OPS))
    print(f"package: {Path(scalar.__file__).parents[2]}; runs of {args.duration} s")
    print(f"{'kernel, law':<28}{'switches':>10}{'search sub-steps':>18}{'per switch':>12}")
    for name, law, rs in (
        ("scalar, classic", "classic", np.linspace(0.0, 1.0, 4)),
        ("scalar, no_tension", "no_tension", np.linspace(0.0, 1.0, 4)),
        ("Hertz-type, hertzdamp", "hertzdamp", (0.3, 0.8)),
    ):
        sub, sw = run(law, rs, args.duration)
        print(f"{name:<28}{sw:>10,}{sub:>18,}{sub / max(sw, 1):>12.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
