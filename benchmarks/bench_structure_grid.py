"""Grid throughput with per-run structure against the same grid without it.

The Duzce scene, metrics only (the lane kernel): 4 k_s/k x 5 r x 6 structures (stiffness_scale_b1 x
stiffness_scale_b2 in {0.98, 1.02} x {0.98, 1.0, 1.02}) = 120 runs, against 120 runs of the nominal structure
(4 k_s/k x 30 r). Each structure is its own group of runs on its own matrices (sweep/prepare.py); the engine
is the same. Both after a warm-up (compile), same threads, best of --repeats, alternated; printed: runs/s and
the ratio.

Usage: python benchmarks/bench_structure_grid.py [--threads 2] [--repeats 5]
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from pathlib import Path

import numpy as np

from pounding_sweep.scene import load_scene
from pounding_sweep.scene.schema import Axis
from pounding_sweep.sweep.prepare import prepare

SWEEPS = Path(__file__).resolve().parents[1] / "sweeps"


def grids():
    s = load_scene(SWEEPS / "paper_duzce.toml")
    ks = Axis("ks_ratio", (0.1, 1.0, 5.0, 10.0))
    structured = dataclasses.replace(
        s,
        sweep=(
            ks,
            Axis("r", (0.2, 0.4, 0.6, 0.8, 1.0)),
            Axis("stiffness_scale_b1", (0.98, 1.02)),
            Axis("stiffness_scale_b2", (0.98, 1.0, 1.02)),
        ),
    )
    plain = dataclasses.replace(s, sweep=(ks, Axis("r", tuple(np.round(np.linspace(0.2, 1.0, 30), 4)))))
    return {"per-run structure": prepare(structured), "nominal structure": prepare(plain)}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args(argv)
    preps = grids()
    params = {k: p.grid.chunk(0, p.grid.size) for k, p in preps.items()}
    for k, p in preps.items():  # warm-up: compile or load the kernel
        p.run({n: v[:2] for n, v in params[k].items()}, args.threads)
    best = {k: np.inf for k in preps}
    for _ in range(args.repeats):
        for k, p in preps.items():
            t0 = time.perf_counter()
            p.run(params[k], args.threads)
            best[k] = min(best[k], time.perf_counter() - t0)
    for k in preps:
        n = preps[k].grid.size
        print(f"{k:18s}: {n} runs in {best[k]:.2f} s, {n / best[k]:.1f} runs/s")
    print(f"ratio (per-run structure / nominal), run time: {best['per-run structure'] / best['nominal structure']:.3f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
