"""Kernel throughput of two checkouts of the package, side by side in one run (ratios).

    python benchmarks/compare_checkouts.py OTHER_CHECKOUT [--paired 30] [--cases event,implicit,...]
    python benchmarks/compare_checkouts.py OTHER_CHECKOUT --rounds 7 [--repeats 5]

The timings (each a call of the driver on a chunk of the 6 Hz scene at dt = 1e-4 s after a warm-up call:
compile time excluded):
  event, implicit: the lane kernel on the throughput benchmark's uneven grid (gaps 0/2/20 mm x k_s/k
      0.01..100 x r 0..1, 378 runs of 5 s), classic law;
  quiet: the lane kernel, event scheme, the same k_s/k and r at a 1 m gap (126 runs that never touch: its
      vector steps alone);
  scalar-event, scalar-implicit: the scalar kernel (engine/scalar.py) on 72 runs of 2 s of that grid
      (gaps 0/2/20 mm x k_s/k 0.01..100 x r 0, 1/3, 2/3, 1);
  hertz-event, hertz-implicit: the Hertz-type kernel (engine/nonlinear.py), hertzdamp law, on 36 runs of 2 s
      (the same gaps and k_s/k, r 0.3 and 0.8).
Times are the calling thread's CPU time with --threads 1 (the default: the kernel runs in that thread, so
time the machine gives other processes is not counted; caches and memory bandwidth shared with them still
are), wall time otherwise.
--paired N (the default, 30): one warm worker process per checkout, the calls alternated call by call and
the order swapped every pair, so a load that comes and goes on a shared machine falls on both alike; prints
per case the median ratio this / other with its quartiles and 5-95 % range over the N pairs.
--rounds K: each round times every case in a fresh process for this checkout and for OTHER_CHECKOUT (a
folder holding another version's pounding_sweep/, e.g. a `git archive` of an older commit), alternating
which goes first, the least of --repeats calls per process; the median ratio over the rounds is the claim.

paired() is also bench_laws.py's section 2.
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
LANE_CASES = ("event", "implicit")
CASES = LANE_CASES + ("quiet", "scalar-event", "scalar-implicit", "hertz-event", "hertz-implicit")

SETUP = r"""
import dataclasses, json, sys, time
import numpy as np
try:  # the layered package
    from pounding_sweep.scene import Axis, load_scene
    from pounding_sweep.sweep.prepare import prepare
    from pounding_sweep.engine import driver
    from pounding_sweep.engine.inputs import HistorySpec
except ImportError:  # the flat package before it
    from pounding_sweep.config import Axis, load_scene
    from pounding_sweep.sweep import prepare
    from pounding_sweep import driver
    from pounding_sweep.driver import HistorySpec
scene_file, threads, wanted = sys.argv[1], int(sys.argv[2]), sys.argv[3].split(",")


def prepared(scheme, law, duration, r, gaps=(0.0, 0.002, 0.02)):
    s = load_scene(scene_file)
    s = dataclasses.replace(s, integration=dataclasses.replace(s.integration, scheme=scheme, dt_s=1e-4),
                            contact=dataclasses.replace(s.contact, law=law),
                            excitation=dataclasses.replace(s.excitation, duration_s=duration),
                            sweep=(Axis("gap_m", gaps), Axis("ks_ratio", tuple(np.geomspace(0.01, 100, 6))),
                                   Axis("r", tuple(r))))
    prep = prepare(s)
    runs, rec, _ = prep.kernel_inputs(prep.grid.chunk(0, prep.grid.size))
    return prep, runs, rec


calls = {}
for case in wanted:
    kind, _, scheme = case.rpartition("-")
    if kind == "" or case == "quiet":
        gaps = (1.0,) if case == "quiet" else (0.0, 0.002, 0.02)
        p, r, c = prepared("event" if case == "quiet" else scheme, "classic", 5.0, np.linspace(0.0, 1.0, 21), gaps)
        calls[case] = lambda p=p, r=r, c=c: driver.run_chunk_lanes(p.sysarr, r, c, p.opts, threads)
    else:
        law, rs = ("classic", np.linspace(0.0, 1.0, 4)) if kind == "scalar" else ("hertzdamp", (0.3, 0.8))
        p, r, c = prepared(scheme, law, 2.0, rs)
        calls[case] = lambda p=p, r=r, c=c: driver.run_chunk_scalar(p.sysarr, r, c, HistorySpec.none(), p.opts, threads)
    calls[case]()  # compile or load, outside the timing


def timed(case):
    clock = time.thread_time if threads == 1 else time.perf_counter
    t0 = clock()
    calls[case]()
    return clock() - t0
"""

# one process, the least of `repeats` calls per case
SNIPPET = (
    SETUP
    + r"""
repeats = int(sys.argv[4])
print(json.dumps({case: min(timed(case) for _ in range(repeats)) for case in calls}))
"""
)

# a process that times one call per line read (a case's name) until its input closes
WORKER = (
    SETUP
    + r"""
print("ready", flush=True)
for line in sys.stdin:
    print(json.dumps(timed(line.strip())), flush=True)
"""
)


def one(checkout: Path, threads: int, repeats: int = 5, cases=LANE_CASES) -> dict:
    env = dict(os.environ, PYTHONPATH=str(checkout))
    scene = str(REPO / "sweeps" / "paper_6hz.toml")
    r = subprocess.run(
        [sys.executable, "-c", SNIPPET, scene, str(threads), ",".join(cases), str(repeats)],
        env=env,
        capture_output=True,
        text=True,
        cwd=checkout,
    )
    if r.returncode:
        raise SystemExit(f"{checkout}: {r.stderr.strip()[-600:]}")
    return json.loads(r.stdout.strip().splitlines()[-1])


class Worker:
    """A process holding `checkout`'s kernels, warm, that times one call of a case on request."""

    def __init__(self, checkout: Path, threads: int, cases=LANE_CASES):
        env = dict(os.environ, PYTHONPATH=str(checkout))
        args = [sys.executable, "-c", WORKER, str(REPO / "sweeps" / "paper_6hz.toml"), str(threads), ",".join(cases)]
        self.p = subprocess.Popen(args, env=env, cwd=checkout, stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
        if self.p.stdout.readline().strip() != "ready":
            raise SystemExit(f"{checkout}: the timing worker did not start")

    def time(self, case: str) -> float:
        self.p.stdin.write(case + "\n")
        self.p.stdin.flush()
        return float(self.p.stdout.readline())

    def close(self):
        self.p.stdin.close()
        self.p.wait()


def paired(this: Path, other: Path, threads: int, pairs: int, cases=LANE_CASES) -> dict[str, list[tuple[float, float]]]:
    """One warm worker per checkout, the calls alternated (this, other, then other, this, ...): per case,
    `pairs` (this, other) times taken moments apart, so a load that comes and goes hits both alike."""
    a, b = Worker(this, threads, cases), Worker(other, threads, cases)
    out: dict[str, list[tuple[float, float]]] = {case: [] for case in cases}
    try:
        for k in range(pairs):
            for case in out:
                if k % 2:
                    tb = b.time(case)
                    ta = a.time(case)
                else:
                    ta = a.time(case)
                    tb = b.time(case)
                out[case].append((ta, tb))
    finally:
        a.close()
        b.close()
    return out


def _load() -> str:
    with open("/proc/loadavg") as f:
        return " ".join(f.read().split()[:3])


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("other", type=Path, help="another checkout (a folder holding pounding_sweep/)")
    ap.add_argument("--cases", default=",".join(CASES), help=f"comma-separated, of {', '.join(CASES)}")
    ap.add_argument("--paired", type=int, default=30, help="alternated call pairs in two warm workers")
    ap.add_argument("--rounds", type=int, default=0, help="instead: rounds of fresh processes")
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--repeats", type=int, default=5, help="--rounds: timed calls per process (the least counts)")
    args = ap.parse_args(argv)
    cases = tuple(c for c in args.cases.split(",") if c)
    unknown = [c for c in cases if c not in CASES]
    if unknown:
        ap.error(f"unknown case(s) {', '.join(unknown)}: expected some of {', '.join(CASES)}")
    this, other = REPO, args.other.resolve()
    print(f"this: {this}\nother: {other}\nthreads: {args.threads}; load average before: {_load()}")
    if args.rounds <= 0:
        got = paired(this, other, args.threads, args.paired, cases)
        print(f"{args.paired} alternated call pairs per case; load average after: {_load()}")
        print("case              this least [s]  other least [s]  median this / other  quartiles      5-95 %")
        for case, tt in got.items():
            rs = [a / b for a, b in tt]
            q = statistics.quantiles(rs, n=20) if len(rs) > 1 else [rs[0]] * 19
            print(
                f"{case:17s} {min(a for a, _ in tt):14.3f} {min(b for _, b in tt):16.3f} {statistics.median(rs):20.3f}"
                f"  {q[4]:.3f}..{q[14]:.3f}  {q[0]:.3f}..{q[18]:.3f}"
            )
        return 0
    ratios: dict[str, list[float]] = {case: [] for case in cases}
    print("round  case              this [s]  other [s]  this / other")
    for k in range(args.rounds):
        pair = [(this, "this"), (other, "other")]
        if k % 2:
            pair.reverse()
        got = {name: one(path, args.threads, args.repeats, cases) for path, name in pair}
        for case in ratios:
            a, b = got["this"][case], got["other"][case]
            ratios[case].append(a / b)
            print(f"{k + 1:5d}  {case:16s} {a:9.3f} {b:10.3f} {a / b:13.3f}")
    for case, rs in ratios.items():
        print(f"{case}: median this / other {statistics.median(rs):.3f} (rounds {min(rs):.3f} .. {max(rs):.3f})")
    print(f"load average after: {_load()}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
