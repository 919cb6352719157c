"""Engine throughput against its peers, measured side by side in one process run.

Usage (from the repository root, after `pip install ".[test]"`):

    python benchmarks/bench_engine.py [--quick]

Prints: kernel compile time (empty cache) and cache-load time, apart from run time; time per
Newmark step for the Numba engine, the plain NumPy loop of the same scheme
(tests/reference.py) and scipy's solve_ivp with contact events, with the ratio to the engine
and the agreement of their top-floor histories; and the grid throughput on 1 and 2 threads
(parallel efficiency) on a grid whose runs have very different impact counts.
Ratios, not absolute times, are the claim: this machine is shared and noisy.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]

from pounding_sweep.scene import Axis, load_scene  # noqa: E402
from pounding_sweep.sweep.run import run_scene  # noqa: E402
from pounding_sweep.sweep.simulate import simulate  # noqa: E402

SCENE = REPO / "sweeps" / "paper_6hz.toml"

COMPILE_SNIPPET = """
import time
t0 = time.perf_counter()
from pounding_sweep.scene import load_scene
from pounding_sweep.sweep.prepare import prepare
from pounding_sweep.engine.driver import compile_kernel
p = prepare(load_scene(r"{scene}"))
t1 = time.perf_counter()
print(t1 - t0, compile_kernel(p.sysarr, p.opts))
"""


def compile_times() -> tuple[float, float, float]:
    """(import + prepare, compile with an empty cache, load from the warm cache) in seconds."""
    with tempfile.TemporaryDirectory() as cache:
        env = dict(os.environ, NUMBA_CACHE_DIR=cache)
        code = COMPILE_SNIPPET.format(scene=SCENE)
        cold = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True)
        warm = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True)
    imp, c_cold = map(float, cold.stdout.split())
    _, c_warm = map(float, warm.stdout.split())
    return imp, c_cold, c_warm


def rel_rms(x, ref):
    return float(np.sqrt(np.mean((x - ref) ** 2)) / np.sqrt(np.mean(ref**2)))


def per_run_table(duration: float) -> list[tuple]:
    from pounding_sweep.reference import ivp_reference, newmark_reference

    scene = load_scene(SCENE)
    scene = dataclasses.replace(scene, excitation=dataclasses.replace(scene.excitation, duration_s=duration))
    kw = dict(ks_ratio=1.0, r=0.4, dt_s=1e-4)
    n_steps = int(round(duration / 1e-4))
    simulate(scene, channels=["disp_b1f3"], **kw)  # compile / load outside the timing
    t0 = time.perf_counter()
    reps = 5
    for _ in range(reps):
        hist, m = simulate(scene, channels=["disp_b1f3", "disp_b2f3"], **kw)
    t_engine = (time.perf_counter() - t0) / reps
    t_kernel = m["run_time_s"]
    t0 = time.perf_counter()
    ref = newmark_reference(scene, **kw)
    t_numpy = time.perf_counter() - t0
    t0 = time.perf_counter()
    ivp = ivp_reference(scene, dt_out=1e-4, **{k: v for k, v in kw.items() if k != "dt_s"})
    t_ivp = time.perf_counter() - t0
    x = hist["disp_b1f3_m"].to_numpy()
    rows = [
        ("engine kernel (Numba)", t_kernel, 0.0),
        ("engine incl. Python set-up", t_engine, 0.0),
        ("NumPy loop, same scheme", t_numpy, rel_rms(x, ref["u"][:, 2])),
        ("solve_ivp DOP853 + events", t_ivp, rel_rms(x, ivp["u"][: x.size, 2])),
    ]
    return [(name, t, t / n_steps, t / t_kernel, err) for name, t, err in rows]


def grid_scaling(n_r: int) -> list[tuple]:
    scene = load_scene(SCENE)
    # k_s/k from 0.01 (soft, long contacts) to 100 (stiff, many short ones) and gaps from 0 to
    # 20 mm (no contact at all): runs of very different cost in one grid
    sweep = (
        Axis("gap_m", (0.0, 0.002, 0.02)),
        Axis("ks_ratio", tuple(np.geomspace(0.01, 100, 6))),
        Axis("r", tuple(np.linspace(0.0, 1.0, n_r))),
    )
    scene = dataclasses.replace(scene, sweep=sweep, excitation=dataclasses.replace(scene.excitation, duration_s=2.0))
    out = []
    with tempfile.TemporaryDirectory() as d:
        for threads in (1, 2):
            s = run_scene(scene, out_path=Path(d) / f"t{threads}.parquet", threads=threads)
            out.append((threads, s.runs, s.run_s, s.steps / s.run_s))
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="shorter runs (a smoke test of the benchmark)")
    args = ap.parse_args()
    imp, cold, warm = compile_times()
    print(
        f"import + scene preparation: {imp:.2f} s; kernel compile (empty cache): {cold:.2f} s; "
        f"load from cache: {warm:.3f} s\n"
    )
    duration = 0.5 if args.quick else 2.0
    print(
        f"One run: 6 Hz scene, k_s/k = 1, r = 0.4, dt = 1e-4 s, {duration} s ({int(duration / 1e-4)} steps), one thread"
    )
    print(f"{'method':<30} {'time [s]':>10} {'per step [us]':>14} {'x engine':>10} {'top-floor rel RMS vs engine':>28}")
    for name, t, per, ratio, err in per_run_table(duration):
        print(f"{name:<30} {t:>10.4f} {per * 1e6:>14.3f} {ratio:>10.1f} {err:>28.2e}")
    print("\nGrid: gaps {0, 2, 20} mm x k_s/k 0.01..100 (6, log) x r 0..1; 2 s runs; uneven impact counts")
    rows = grid_scaling(5 if args.quick else 20)
    print(f"{'threads':>7} {'runs':>6} {'wall [s]':>9} {'M steps/s':>10} {'efficiency':>11}")
    base = rows[0][3]
    for threads, runs, wall, rate in rows:
        print(f"{threads:>7} {runs:>6} {wall:>9.2f} {rate / 1e6:>10.2f} {rate / (base * threads):>11.1%}")


if __name__ == "__main__":
    main()
