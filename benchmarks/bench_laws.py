"""Time per step of each contact law on the same pounding grid, and the classic law's lane-kernel
throughput against the checkout before the contact-law work (issue 21: unchanged within 5 %).

    python benchmarks/bench_laws.py                          # section 1, about 1 min on 2 cores
    git worktree add /tmp/pre21 47d30d0                      # the commit before the contact-law work
    python benchmarks/bench_laws.py --before /tmp/pre21      # sections 1 and 2, about 3.5 min (+30 s the
                                                             # first time: the old checkout's kernels compile)
    git worktree remove /tmp/pre21
    python benchmarks/bench_laws.py --quick [--before ...]   # 1 s of motion, 2 repeats; 2 rounds of 4 pairs

1. Every law (classic, no_tension, hertz, hertzdamp, jankowski) on the same grid: each shipped scene's
   k_s/k in {0.1, 1, 5, 10} x r in {0.2, 0.4, 0.6, 0.8, 1.0} (20 runs, gap 0, dt = 1e-4 s, the whole
   motion: 6 Hz 5 s, Duzce 6.68 s), the event scheme (the default) and the implicit one, metrics only,
   the same threads for every law (--threads, default 1: this machine is shared). Each kernel is called
   once before timing (compiled or loaded from the cache); the timed calls are interleaved across the
   laws (one call of each law per round) and the best of the rounds is kept. ns per step = best wall /
   (runs x steps). The linear laws run where a sweep runs them, on the lane kernel (engine/lanes.py, SIMD
   lanes), and also on the scalar kernel (engine/scalar.py, one run at a time, as engine/nonlinear.py
   runs the Hertz-type laws), so both ratios are shown: against classic on the lanes (what a sweep
   costs) and against classic on the scalar kernel (the same per-run structure).
2. With --before CHECKOUT: compare_checkouts.py's grid (the uneven 378-run grid, classic law, lane
   kernel, event and implicit schemes, 5 s at dt = 1e-4 s) timed by compare_checkouts.paired: one warm
   worker process per checkout, the calls alternated one by one (which goes first swaps every pair), so
   the two times of a pair are taken moments apart and a load that comes and goes on this shared
   machine falls on both; --rounds rounds of fresh workers, --pairs pairs each. Printed: per round the
   least call of each checkout and the median and range of the pairs' ratios; over all pairs the median
   ratio this / before, its quartiles and 5-95 % range, and the ratio of the fastest calls.

Measured (2 cores, 1 thread, load average 1.0-1.8 while it ran; two earlier runs at 2.5-4 gave the
same ratios within about 15 %):

1. ns per step (x classic on the lanes, x classic on the scalar kernel); impacts per run 120-180:

   grid, scheme      classic lanes  classic scalar  no_tension lanes/scalar  hertz            hertzdamp        jankowski
   6 Hz, event       26             209 (8.0)       26 / 211                 352 (13.5, 1.68)  365 (14.0, 1.74)  365 (14.0, 1.74)
   6 Hz, implicit    18             195 (10.9)      18 / 194                 322 (18.0, 1.66)  340 (19.0, 1.75)  332 (18.6, 1.71)
   Duzce, event      26             198 (7.6)       28 / 201                 365 (14.1, 1.85)  385 (14.9, 1.95)  383 (14.8, 1.94)
   Duzce, implicit   19             185 (9.8)       19 / 193                 346 (18.4, 1.87)  379 (20.2, 2.05)  358 (19.1, 1.94)

   A Hertz-type law costs 1.7-2.1 x the classic law on the same one-run-at-a-time structure (the pair-space
   Newton solve and the law's powers in every step in contact), and 14-20 x the classic law on the lane
   kernel, which the Hertz-type laws do not run on. no_tension costs what classic does.
2. Classic law, lane kernel, this checkout (issue 21's contact laws, 0994e33) / 47d30d0, 100 pairs per
   scheme: event median 1.007 (quartiles 0.985-1.035, 5-95 % 0.78-1.32), fastest calls 0.277 s both
   (1.000); implicit median 1.005 (0.982-1.041, 0.77-1.25), fastest 0.199 s both (1.001). main at
   0f77c9c (issue 19 merged since) / 47d30d0: event 0.988 (0.955-1.015), fastest 1.003; implicit 0.995
   (0.952-1.025), fastest 0.999. The classic law's throughput is unchanged within 1 % (the issue asks 5 %);
   the wide 5-95 % ranges are other sessions' load hitting one call of a pair.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import statistics
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(REPO), str(REPO / "benchmarks")]

from bench_throughput import cpu_threads, header, load, table
from compare_checkouts import paired

from pounding_sweep.engine import driver
from pounding_sweep.engine import layout as L
from pounding_sweep.scene import load_scene
from pounding_sweep.sweep.prepare import prepare

SCENES = {"6 Hz": REPO / "sweeps" / "paper_6hz.toml", "Duzce": REPO / "sweeps" / "paper_duzce.toml"}
# (label, law, kernel)
CASES = [
    ("classic, lanes", "classic", "auto"),
    ("no_tension, lanes", "no_tension", "auto"),
    ("classic, scalar", "classic", "scalar"),
    ("no_tension, scalar", "no_tension", "scalar"),
    ("hertz", "hertz", "auto"),
    ("hertzdamp", "hertzdamp", "auto"),
    ("jankowski", "jankowski", "auto"),
]


def timed_call(path, law, kernel, scheme, threads, duration):
    """The grid's kernel inputs for one law, and a call that integrates them (kernel time only)."""
    s = load_scene(path)
    s = dataclasses.replace(
        s,
        contact=dataclasses.replace(s.contact, law=law),
        integration=dataclasses.replace(s.integration, scheme=scheme, dt_s=1e-4),
    )
    if duration is not None:
        s = dataclasses.replace(s, excitation=dataclasses.replace(s.excitation, duration_s=duration))
    prep = prepare(s, kernel=kernel)
    params = prep.grid.chunk(0, prep.grid.size)
    runs, rec, _ = prep.kernel_inputs(params)  # each run's law in runs.law

    def call():
        return driver.run_chunk(prep.sysarr, runs, rec, prep.hist, prep.opts, threads, 0, prep.score, kernel)

    names = L.metric_columns(prep.model.floors, prep.model.n_pairs)
    return call, int(runs.nsteps.sum()), runs.n, names


def law_times(threads: int, repeats: int, duration) -> None:
    for sname, path in SCENES.items():
        for scheme in ("event", "implicit"):
            header(
                f"1. {sname} grid, {scheme} scheme: 4 k_s/k x 5 r, gap 0, dt 1e-4 s"
                + (f", {duration:g} s" if duration else ", whole motion")
                + f", {threads} thread(s), best of {repeats} interleaved rounds"
            )
            calls = {}
            for label, law, kernel in CASES:
                call, steps, n, names = timed_call(path, law, kernel, scheme, threads, duration)
                metrics = call()[0]  # compile or load, and the rows
                calls[label] = (call, steps, n, names, metrics)
            best = {label: float("inf") for label in calls}
            for _ in range(repeats):
                for label, (call, *_) in calls.items():
                    t0 = time.perf_counter()
                    call()
                    best[label] = min(best[label], time.perf_counter() - t0)
            rows = []
            ref_lanes = best["classic, lanes"] / calls["classic, lanes"][1]
            ref_scalar = best["classic, scalar"] / calls["classic, scalar"][1]
            for label, (_call, steps, _n, names, m) in calls.items():
                per = best[label] / steps
                cols = [i for i, x in enumerate(names) if x.startswith("impacts_f")]
                unsettled = m[:, names.index("unsettled_steps")].sum()
                rows.append(
                    [
                        label,
                        f"{best[label]:.3f}",
                        f"{per * 1e9:,.0f}",
                        f"{per / ref_lanes:.2f}",
                        f"{per / ref_scalar:.2f}",
                        f"{m[:, cols].sum(axis=1).mean():.0f}",
                        f"{unsettled:.0f}",
                    ]
                )
            table(
                rows,
                [
                    "law, kernel",
                    "best s (20 runs)",
                    "ns per step",
                    "x classic lanes",
                    "x classic scalar",
                    "impacts per run",
                    "unsettled steps",
                ],
            )
            print(f"(load average after: {load()})")


def before_after(this: Path, other: Path, rounds: int, threads: int, pairs: int) -> None:
    header(
        f"2. classic law, lane kernel: this checkout ({this}) / before ({other}), {threads} thread(s); "
        f"{rounds} rounds of {pairs} alternated call pairs (compare_checkouts.paired: 378 runs x 5 s per call)"
    )
    ratios: dict[str, list[float]] = {"event": [], "implicit": []}
    least: dict[str, list[float]] = {"event": [math.inf, math.inf], "implicit": [math.inf, math.inf]}
    rows = []
    for k in range(rounds):
        got = paired(this, other, threads, pairs)
        row = [k + 1]
        for scheme, tt in got.items():
            rs = [a / b for a, b in tt]
            ratios[scheme] += rs
            least[scheme][0] = min(least[scheme][0], *(a for a, _ in tt))
            least[scheme][1] = min(least[scheme][1], *(b for _, b in tt))
            row += [
                f"{min(a for a, _ in tt):.3f}",
                f"{min(b for _, b in tt):.3f}",
                f"{statistics.median(rs):.3f}",
                f"{min(rs):.3f} .. {max(rs):.3f}",
            ]
        rows.append(row + [load()])
    heads = ["round"]
    for scheme in ratios:
        heads += [f"{scheme}: this least [s]", "before least [s]", "median this / before", "pairs' range"]
    table(rows, heads + ["load average"])
    for scheme, rs in ratios.items():
        q = statistics.quantiles(rs, n=20)  # 5 % steps
        print(
            f"{scheme}: {len(rs)} pairs, median this / before {statistics.median(rs):.3f}, quartiles "
            f"{q[4]:.3f} .. {q[14]:.3f}, 5-95 % {q[0]:.3f} .. {q[18]:.3f}; fastest calls: this "
            f"{least[scheme][0]:.3f} s, before {least[scheme][1]:.3f} s, ratio {least[scheme][0] / least[scheme][1]:.3f}"
        )


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="1 s of motion, 2 repeats, 3 rounds")
    ap.add_argument("--threads", type=int, default=1, help="threads for every law (default 1)")
    ap.add_argument("--repeats", type=int, default=None, help="timed rounds per law (default 7, quick 2)")
    ap.add_argument("--before", type=Path, default=None, help="a checkout of the commit before the law work")
    ap.add_argument("--this", type=Path, default=REPO, help="section 2: the checkout timed against it (default: this)")
    ap.add_argument("--rounds", type=int, default=None, help="section 2: worker pairs started (default 5, quick 2)")
    ap.add_argument("--pairs", type=int, default=None, help="section 2: call pairs per round (default 20, quick 4)")
    ap.add_argument("--skip-laws", action="store_true", help="section 2 only")
    a = ap.parse_args(argv)
    repeats = a.repeats or (2 if a.quick else 7)
    print(f"{cpu_threads()} cores; load average {load()}; NumPy {np.__version__}")
    t0 = time.perf_counter()
    if not a.skip_laws:
        law_times(a.threads, repeats, 1.0 if a.quick else None)
    if a.before is not None:
        before_after(
            a.this.resolve(),
            a.before.resolve(),
            a.rounds or (2 if a.quick else 5),
            a.threads,
            a.pairs or (4 if a.quick else 20),
        )
    print(f"\n(total {time.perf_counter() - t0:.0f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
