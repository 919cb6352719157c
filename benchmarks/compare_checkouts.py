"""Lane-kernel throughput of two checkouts of the package, side by side in one run (ratios).

    python benchmarks/compare_checkouts.py OTHER_CHECKOUT [--rounds 7] [--threads 2] [--repeats 5]

Each round runs the same timing in a fresh process for this checkout and for OTHER_CHECKOUT (a folder
holding another version's pounding_sweep/, e.g. a `git worktree` of an older commit), alternating which
goes first, and prints the ratio this / other of the kernel time; the median ratio over the rounds is
the claim (the machine's speed drifts between rounds, not within one). The timing: the throughput
benchmark's uneven grid (gaps 0/2/20 mm x k_s/k 0.01..100 x r 0..1, 378 runs of 5 s at dt = 1e-4 s,
the 6 Hz scene), event and implicit schemes, through the lane kernel after a warm-up call (compile time
excluded), the least of 5 calls per process (--repeats).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]

SNIPPET = r"""
import dataclasses, json, sys, time
import numpy as np
try:  # the layered package
    from pounding_sweep.scene import Axis, load_scene
    from pounding_sweep.sweep.prepare import prepare
    from pounding_sweep.engine import driver
except ImportError:  # the flat package before it
    from pounding_sweep.config import Axis, load_scene
    from pounding_sweep.sweep import prepare
    from pounding_sweep import driver
scene_file, threads, repeats = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
out = {}
for scheme in ("event", "implicit"):
    s = load_scene(scene_file)
    s = dataclasses.replace(s, integration=dataclasses.replace(s.integration, scheme=scheme, dt_s=1e-4),
                            contact=dataclasses.replace(s.contact, law="classic"),
                            excitation=dataclasses.replace(s.excitation, duration_s=5.0),
                            sweep=(Axis("gap_m", (0.0, 0.002, 0.02)), Axis("ks_ratio", tuple(np.geomspace(0.01, 100, 6))),
                                   Axis("r", tuple(np.linspace(0.0, 1.0, 21)))))
    prep = prepare(s)
    runs, rec, _ = prep.kernel_inputs(prep.grid.chunk(0, prep.grid.size))
    driver.run_chunk_lanes(prep.sysarr, runs, rec, prep.opts, threads)
    best = float("inf")
    for _ in range(repeats):
        t0 = time.perf_counter()
        m, _ = driver.run_chunk_lanes(prep.sysarr, runs, rec, prep.opts, threads)
        best = min(best, time.perf_counter() - t0)
    out[scheme] = best
print(json.dumps(out))
"""


def one(checkout: Path, threads: int, repeats: int = 5) -> dict:
    env = dict(os.environ, PYTHONPATH=str(checkout))
    r = subprocess.run(
        [sys.executable, "-c", SNIPPET, str(REPO / "sweeps" / "paper_6hz.toml"), str(threads), str(repeats)],
        env=env,
        capture_output=True,
        text=True,
        cwd=checkout,
    )
    if r.returncode:
        raise SystemExit(f"{checkout}: {r.stderr.strip()[-600:]}")
    return json.loads(r.stdout.strip().splitlines()[-1])


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("other", type=Path, help="another checkout (a folder holding pounding_sweep/)")
    ap.add_argument("--rounds", type=int, default=7)
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--repeats", type=int, default=5, help="timed calls per process (the least counts)")
    args = ap.parse_args(argv)
    this, other = REPO, args.other.resolve()
    ratios: dict[str, list[float]] = {"event": [], "implicit": []}
    print(f"this: {this}\nother: {other}\nround  scheme     this [s]  other [s]  this / other")
    for k in range(args.rounds):
        pair = [(this, "this"), (other, "other")]
        if k % 2:
            pair.reverse()
        got = {name: one(path, args.threads, args.repeats) for path, name in pair}
        for scheme in ratios:
            a, b = got["this"][scheme], got["other"][scheme]
            ratios[scheme].append(a / b)
            print(f"{k + 1:5d}  {scheme:9s} {a:9.3f} {b:10.3f} {a / b:13.3f}")
    for scheme, rs in ratios.items():
        print(f"{scheme}: median this / other {statistics.median(rs):.3f} (rounds {min(rs):.3f} .. {max(rs):.3f})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
