"""Dask distributed against the local executor on the same sweep: row-for-row equality and overhead.

    python benchmarks/bench_dask.py            # 100,000 runs (6 Hz scene, 0.2 s each at dt = 1e-4 s)
    python benchmarks/bench_dask.py --runs 5000 --quick

Both executors run the same grid into their own dataset folder; the tables must be identical
(every column but the per-run wall time). The cluster's start-up is timed apart from the sweep.
Overhead = Dask wall time / local wall time - 1 at equal cores (2 worker processes with one thread
each against 2 threads), measured for two part sizes since each part is one task.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd

from pounding_sweep.scene import Axis, load_scene
from pounding_sweep.sweep.executors import DaskExecutor, LocalExecutor
from pounding_sweep.sweep.run import run_scene

REPO = Path(__file__).resolve().parents[1]


def scene(runs: int, chunk_runs: int, duration_s: float):
    s = load_scene(REPO / "sweeps" / "paper_6hz.toml")
    n_r = 50
    n_gap = 20
    n_ks = max(1, math.ceil(runs / (n_r * n_gap)))
    return dataclasses.replace(
        s,
        excitation=dataclasses.replace(s.excitation, duration_s=duration_s),
        sweep=(
            Axis("ks_ratio", tuple(np.geomspace(0.05, 50.0, n_ks).tolist())),
            Axis("r", tuple(np.linspace(0.0, 1.0, n_r).tolist())),
            Axis("gap_m", tuple(np.linspace(0.0, 0.004, n_gap).tolist())),
        ),
        execution=dataclasses.replace(s.execution, chunk_runs=chunk_runs),
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--runs", type=int, default=100_000)
    ap.add_argument("--duration", type=float, default=0.2, help="seconds simulated per run")
    ap.add_argument("--quick", action="store_true", help="5,000 runs, one part size")
    args = ap.parse_args()
    runs = 5000 if args.quick else args.runs
    chunk_sizes = [4096] if args.quick else [4096, 512]

    t0 = time.perf_counter()
    dask = DaskExecutor(workers=2)
    startup = time.perf_counter() - t0
    local = LocalExecutor(threads=2)
    rows = []
    try:
        with tempfile.TemporaryDirectory() as d:
            for chunk in chunk_sizes:
                s = scene(runs, chunk, args.duration)
                times = {}
                for ex in (local, dask, local, dask):  # interleaved: load on this shared machine hits both
                    out = Path(d) / f"{ex.name}_{chunk}.parquet"
                    t = time.perf_counter()
                    res = run_scene(s, out_path=out, executor=ex, overwrite=True)
                    times.setdefault(ex.name, []).append(time.perf_counter() - t)
                a = pd.read_parquet(Path(d) / f"local_{chunk}.parquet").drop(columns="run_time_s")
                b = pd.read_parquet(Path(d) / f"dask_{chunk}.parquet").drop(columns="run_time_s")
                same = a.shape == b.shape and a.equals(b)
                tl, td = min(times["local"]), min(times["dask"])
                rows.append(
                    dict(
                        runs=res.runs,
                        steps_per_run=int(res.steps / res.runs),
                        part_runs=chunk,
                        parts=res.parts,
                        local_s=tl,
                        dask_s=td,
                        overhead_pct=100 * (td / tl - 1),
                        runs_per_s_local=res.runs / tl,
                        runs_per_s_dask=res.runs / td,
                        identical=same,
                    )
                )
    finally:
        dask.close()
    df = pd.DataFrame(rows)
    print(f"Dask LocalCluster start-up (2 worker processes): {startup:.2f} s (not in the times below)")
    print(df.to_string(index=False, float_format=lambda x: f"{x:,.3f}"))
    if not df.identical.all():
        raise SystemExit("local and Dask tables differ")


if __name__ == "__main__":
    main()
