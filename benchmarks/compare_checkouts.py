"""Lane-kernel throughput of two checkouts of the package, side by side in one run (ratios).

    python benchmarks/compare_checkouts.py OTHER_CHECKOUT [--rounds 7] [--threads 2] [--repeats 5]

Each round runs the same timing in a fresh process for this checkout and for OTHER_CHECKOUT (a folder
holding another version's pounding_sweep/, e.g. a `git worktree` of an older commit), alternating which
goes first, and prints the ratio this / other of the kernel time; the median ratio over the rounds is
the claim (the machine's speed drifts between rounds, not within one). The timing: the throughput
benchmark's uneven grid (gaps 0/2/20 mm x k_s/k 0.01..100 x r 0..1, 378 runs of 5 s at dt = 1e-4 s,
the 6 Hz scene), event and implicit schemes, through the lane kernel after a warm-up call (compile time
excluded), the least of 5 calls per process (--repeats).

paired() times the same calls in two warm worker processes, one per checkout, alternating call by call
(bench_laws.py section 2): on a shared machine a load that comes and goes then falls on both alike.
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

SETUP = r"""
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
scene_file, threads = sys.argv[1], int(sys.argv[2])
calls = {}
for scheme in ("event", "implicit"):
    s = load_scene(scene_file)
    s = dataclasses.replace(s, integration=dataclasses.replace(s.integration, scheme=scheme, dt_s=1e-4),
                            contact=dataclasses.replace(s.contact, law="classic"),
                            excitation=dataclasses.replace(s.excitation, duration_s=5.0),
                            sweep=(Axis("gap_m", (0.0, 0.002, 0.02)), Axis("ks_ratio", tuple(np.geomspace(0.01, 100, 6))),
                                   Axis("r", tuple(np.linspace(0.0, 1.0, 21)))))
    prep = prepare(s)
    runs, rec, _ = prep.kernel_inputs(prep.grid.chunk(0, prep.grid.size))
    calls[scheme] = lambda p=prep, r=runs, c=rec: driver.run_chunk_lanes(p.sysarr, r, c, p.opts, threads)
    calls[scheme]()  # compile or load, outside the timing


def timed(scheme):
    t0 = time.perf_counter()
    calls[scheme]()
    return time.perf_counter() - t0
"""

# one process, the least of `repeats` calls per scheme
SNIPPET = (
    SETUP
    + r"""
repeats = int(sys.argv[3])
print(json.dumps({scheme: min(timed(scheme) for _ in range(repeats)) for scheme in calls}))
"""
)

# a process that times one call per line read ("event" or "implicit") until its input closes
WORKER = (
    SETUP
    + r"""
print("ready", flush=True)
for line in sys.stdin:
    print(json.dumps(timed(line.strip())), flush=True)
"""
)


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


class Worker:
    """A process holding `checkout`'s lane kernel, warm, that times one call of a scheme on request."""

    def __init__(self, checkout: Path, threads: int):
        env = dict(os.environ, PYTHONPATH=str(checkout))
        args = [sys.executable, "-c", WORKER, str(REPO / "sweeps" / "paper_6hz.toml"), str(threads)]
        self.p = subprocess.Popen(args, env=env, cwd=checkout, stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
        if self.p.stdout.readline().strip() != "ready":
            raise SystemExit(f"{checkout}: the timing worker did not start")

    def time(self, scheme: str) -> float:
        self.p.stdin.write(scheme + "\n")
        self.p.stdin.flush()
        return float(self.p.stdout.readline())

    def close(self):
        self.p.stdin.close()
        self.p.wait()


def paired(this: Path, other: Path, threads: int, pairs: int) -> dict[str, list[tuple[float, float]]]:
    """One warm worker per checkout, the calls alternated (this, other, then other, this, ...): per scheme,
    `pairs` (this, other) times taken moments apart, so a load that comes and goes hits both alike."""
    a, b = Worker(this, threads), Worker(other, threads)
    out: dict[str, list[tuple[float, float]]] = {"event": [], "implicit": []}
    try:
        for k in range(pairs):
            for scheme in out:
                if k % 2:
                    tb = b.time(scheme)
                    ta = a.time(scheme)
                else:
                    ta = a.time(scheme)
                    tb = b.time(scheme)
                out[scheme].append((ta, tb))
    finally:
        a.close()
        b.close()
    return out


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
