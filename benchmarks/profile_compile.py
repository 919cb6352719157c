"""Where a first run's compile time goes: per compiled function, per Numba pass, and how much of it is LLVM.

    python benchmarks/profile_compile.py [--case 0..3] [--opt 0..3] [--after 0..3]

Runs one of bench_compile.py's cases (default 0: the README's scored scene, cut to 10 ms) through the command
line's entry point in this process, with Numba's cache in a new temporary folder (so everything compiles), and
listens to Numba's compile events (numba.core.event: 'numba:compile' per function, 'numba:run_pass' per compiler
pass, 'numba:llvm_lock' around LLVM's work). Prints
  - the run's wall and CPU time;
  - per function the compile time including the functions it compiles on the way (callees are compiled while
    their caller is typed, so a caller's time holds theirs): what one function costs a first run in all;
  - per compiler pass the time spent in it, callees excluded (native_lowering holds the LLVM work);
  - per function the time inside LLVM (optimisation, linking and machine code), callees excluded.
Numba links every callee's module into its caller and optimises and emits the whole module again (numba
core/codegen.py CPUCodeLibrary.finalize), so code called from deep inside the kernel is compiled once per level:
the LLVM column says what that costs. --opt sets NUMBA_OPT for this run (0: no LLVM optimisation; what is left
is Numba's own typing and lowering, and machine code).
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from collections import defaultdict
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))


def _name(e) -> str:
    f = getattr(e.data.get("dispatcher"), "py_func", None)
    return f.__qualname__ if f is not None else "?"


def _exclusive(events, key) -> dict[str, float]:
    """Time per key with nested events of the same kind taken out of their parent's."""
    tot: dict[str, float] = defaultdict(float)
    stack: list[list] = []
    for ts, e in events:
        if e.is_start:
            stack.append([key(e), ts, 0.0])
        else:
            k, t0, inner = stack.pop()
            tot[k] += ts - t0 - inner
            if stack:
                stack[-1][2] += ts - t0
    return tot


def _inclusive(events) -> dict[str, float]:
    """Compile time per function, its callees' compiles included (the outermost call of a function counts)."""
    tot: dict[str, float] = defaultdict(float)
    open_: dict[str, list[float]] = defaultdict(list)
    for ts, e in events:
        k = _name(e)
        if e.is_start:
            open_[k].append(ts)
        else:
            t0 = open_[k].pop()
            if not open_[k]:
                tot[k] += ts - t0
    return tot


def _llvm_by_function(compiles, llvm) -> dict[str, float]:
    """LLVM time charged to the function being compiled when it ran."""
    merged = sorted([(ts, 0, e) for ts, e in compiles] + [(ts, 1, e) for ts, e in llvm], key=lambda x: (x[0], x[1]))
    tot: dict[str, float] = defaultdict(float)
    stack: list[str] = []
    started = 0.0
    for ts, kind, e in merged:
        if kind == 0:
            stack.append(_name(e)) if e.is_start else stack.pop()
        elif e.is_start:
            started = ts
        else:
            tot[stack[-1] if stack else "(outside a compile)"] += ts - started
    return tot


def _table(title: str, rows: dict[str, float], top: int, total: float | None = None) -> None:
    total = sum(rows.values()) if total is None else total
    print(f"\n{title} (top {top} of {len(rows)}; all {total:.1f} s)")
    for k, v in sorted(rows.items(), key=lambda kv: -kv[1])[:top]:
        print(f"  {v:7.2f}  {k}")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--case", type=int, default=0, help="bench_compile.py's case (0: the README scene)")
    ap.add_argument("--opt", type=int, choices=(0, 1, 2, 3), help="NUMBA_OPT for this run (default: Numba's, 3)")
    ap.add_argument("--top", type=int, default=15)
    ap.add_argument(
        "--after",
        type=int,
        help="first run this case (not profiled) into the same cache: e.g. --after 1 --case 2 profiles what a new pair "
        "of story counts compiles once the lane kernel is cached",
    )
    args = ap.parse_args(argv)
    tmp = Path(tempfile.mkdtemp(prefix="profile_compile_"))
    os.environ["NUMBA_CACHE_DIR"] = str(tmp / "cache")  # before Numba and the engine read it
    if args.opt is not None:
        os.environ["NUMBA_OPT"] = str(args.opt)
    import bench_compile
    from numba.core import event

    scenes = list(bench_compile.cases(tmp).items())
    name, scene = scenes[args.case]
    from pounding_sweep.cli import run

    if args.after is not None:
        run.main([str(scenes[args.after][1]), "--out", str(tmp / "before.parquet"), "--quiet", "--yes"])
        name = f"{name}, after {scenes[args.after][0]}"
    listeners = {k: event.RecordingListener() for k in ("numba:compile", "numba:run_pass", "numba:llvm_lock")}
    for k, li in listeners.items():
        event.register(k, li)

    t0, c0 = time.perf_counter(), time.process_time()
    rc = run.main([str(scene), "--out", str(tmp / "out.parquet"), "--quiet", "--yes"])
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    compiles = listeners["numba:compile"].buffer
    passes = listeners["numba:run_pass"].buffer
    llvm = listeners["numba:llvm_lock"].buffer
    by_pass = _exclusive(passes, lambda e: e.data["name"].split(" [")[0])
    print(f"{name}: exit {rc}; wall {wall:.1f} s, CPU {cpu:.1f} s (start-up, compile, the 10 ms run)")
    print(f"functions compiled: {len({_name(e) for _, e in compiles})}; NUMBA_OPT={os.environ.get('NUMBA_OPT', '3')}")
    outermost = _exclusive(compiles, lambda e: "all")["all"]  # callees' compiles inside their callers' once
    _table("compile time per function, callees included [s]", _inclusive(compiles), args.top, outermost)
    _table("per compiler pass, callees excluded [s]", by_pass, 8)
    _table("inside LLVM per function, callees excluded [s]", _llvm_by_function(compiles, llvm), args.top)
    return 0


if __name__ == "__main__":
    sys.exit(main())
