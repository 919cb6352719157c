"""Throughput of the engine against its peers and against the issue-9 targets, in one process run.

Usage (from the repository root, dev install; OpenSeesPy optional: `pip install openseespy`, needs
Debian's libblas3 and liblapack3):

    python benchmarks/bench_throughput.py            # the full set, about 5-10 min on 2 idle cores
    python benchmarks/bench_throughput.py --quick    # smoke test of every section, about 1-2 min

Sections (each prints a table):
  0. machine: CPU, SIMD flags, cores, load average (this machine is shared: ratios measured in
     the same run are the claim; absolute times move with the load), and its measured peak of fused
     multiply-adds per second and core (the roofline of section 7);
  1. compile time of each kernel with an empty cache and from the warm cache, in subprocesses,
     apart from run time;
  2. one run of the paper's model (6 Hz, k_s = k, r = 0.4, gap 0, dt = 1e-4 s, implicit scheme,
     classic law: what OpenSees' Newton iteration on ViscoelasticGap elements solves) by every method:
     the lane kernel (per run inside a grid, on 1 and all cores; and alone), the scalar kernel, the plain
     NumPy loop of the same scheme (tests/reference.py), solve_ivp with contact events
     (tests/reference.py) and OpenSeesPy (benchmarks/peers): time per step, steps/s, ratio to the engine,
     agreement with the engine; and the lane kernel with the default event scheme;
  3. grid throughput on 1 and 2 threads (parallel efficiency) on a grid of very uneven impact counts,
     both schemes, in rounds (1 thread pinned to each core, then all cores), with the load balance
     (threads busy) and the work's CPU-time growth with every core busy, apart;
  4. scaling over grid size (1 .. 1e5 runs) and record length, through the sweep (run_scene:
     grid, kernel, Parquet);
  5. peak memory of a 1,000,000-run metrics-only sweep (subprocess, getrusage) against a 100,000-run
     one, and the Parquet file growing while the sweep runs;
  6. the paper's Duzce grid through the CLI with a warm cache (wall time of the whole command);
  7. profile: where the lane kernel's time goes (vector steps without and with contact, the scalar
     steps at contact switches, from its work counters) against the machine's FMA roofline.
Sections 3-7 use the default event scheme.

Timings: best of several repeats (wall clock), load average printed before each section.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "benchmarks" / "peers"))

from pounding_sweep.engine import driver
from pounding_sweep.engine import lanes as kernel_lanes
from pounding_sweep.engine import layout as L
from pounding_sweep.engine.driver import HistorySpec, RunArrays  # noqa: E402
from pounding_sweep.scene import Axis, load_scene  # noqa: E402
from pounding_sweep.sweep import prepare, run_scene  # noqa: E402

SCENE_6HZ = REPO / "sweeps" / "paper_6hz.toml"
SCENE_DUZCE = REPO / "sweeps" / "paper_duzce.toml"
DT = 1e-4
RUN = dict(ks_ratio=1.0, r=0.4, gap_m=0.0)


# ----------------------------------------------------------------------------------------- helpers


def load() -> str:
    with open("/proc/loadavg") as f:
        return " ".join(f.read().split()[:3])


def header(title: str) -> None:
    print(f"\n== {title}   [load average {load()}]")


def table(rows: list[list], heads: list[str]) -> None:
    cells = [[str(h) for h in heads]] + [[str(c) for c in r] for r in rows]
    w = [max(len(r[i]) for r in cells) for i in range(len(heads))]
    for k, r in enumerate(cells):
        print("  ".join(c.rjust(w[i]) if i else c.ljust(w[i]) for i, c in enumerate(r)))
        if k == 0:
            print("  ".join("-" * x for x in w))


def best_of(fn, repeats: int) -> tuple[float, object]:
    best, out = float("inf"), None
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return best, out


def scene(base=SCENE_6HZ, duration=None, sweep=None, scheme="event", **contact):
    """The shipped scene with a scheme (the default event scheme; the peers of section 2 solve the
    implicit one) and the classic law, another duration, contact values and sweep (none: the one run
    the contact values describe)."""
    s = load_scene(base)
    s = dataclasses.replace(
        s,
        integration=dataclasses.replace(s.integration, scheme=scheme, dt_s=DT),
        contact=dataclasses.replace(s.contact, law="classic", **contact),
    )
    if duration is not None:
        s = dataclasses.replace(s, excitation=dataclasses.replace(s.excitation, duration_s=duration))
    return dataclasses.replace(s, sweep=tuple(Axis(n, tuple(float(x) for x in v)) for n, v in (sweep or ())))


def run_inputs(prep, copies=1, points=1):
    """Kernel inputs of the scene's first `points` grid points, repeated `copies` times."""
    runs, rec, _ = prep.kernel_inputs(prep.grid.chunk(0, points))
    if copies > 1:
        runs = RunArrays(*(np.ascontiguousarray(np.repeat(a, copies, axis=0)) for a in runs))
    return runs, rec


def rel_rms(x, ref) -> float:
    n = min(len(x), len(ref))
    x, ref = np.asarray(x[:n]), np.asarray(ref[:n])
    return float(np.sqrt(np.mean((x - ref) ** 2)) / np.sqrt(np.mean(ref**2)))


def fmt_rate(steps_per_s: float) -> str:
    return f"{steps_per_s / 1e6:,.1f} M" if steps_per_s >= 1e6 else f"{steps_per_s / 1e3:,.1f} k"


def cpu_threads() -> int:
    return len(os.sched_getaffinity(0))


# ----------------------------------------------------------------------------------------- 0. machine


def machine() -> float:
    header("0. machine")
    flags, model = set(), "?"
    with open("/proc/cpuinfo") as f:
        for line in f:
            if line.startswith("model name") and model == "?":
                model = line.split(":", 1)[1].strip()
            if line.startswith("flags"):
                flags = set(line.split(":", 1)[1].split())
    import numba
    from llvmlite import binding as llvm_binding

    simd = [x for x in ("avx2", "fma", "avx512f") if x in flags]
    print(
        f"CPU {model} (LLVM: {llvm_binding.get_host_cpu_name()}), {cpu_threads()} cores, SIMD {' '.join(simd)}"
        f"{'' if 'avx512f' in flags else ' (no AVX-512: 4 float64 per instruction)'}; "
        f"Python {platform.python_version()}, NumPy {np.__version__}, Numba {numba.__version__}"
    )
    peak = fma_peak()
    print(
        f"measured peak: {peak / 1e9:.1f} G float64 fused multiply-adds per second and core "
        f"(independent chains of vector FMAs of the lane kernel's width)"
    )
    return peak


_FMA_PEAK = None


def fma_peak() -> float:
    """float64 FMAs per second on one core: 6 independent chains of simd.VW-wide llvm.fma (enough to
    hide the FMA latency on two pipes, few enough to stay in registers)."""
    global _FMA_PEAK
    if _FMA_PEAK is None:
        import numba

        from pounding_sweep.engine.simd import VW, vfma, vsplat, vstore

        @numba.njit
        def chains(n, out):
            a0 = a1 = a2 = a3 = a4 = a5 = vsplat(1.0)
            x = vsplat(0.9999999)
            y = vsplat(1e-9)
            for _ in range(n):
                a0 = vfma(a0, x, y)
                a1 = vfma(a1, x, y)
                a2 = vfma(a2, x, y)  # noqa: E702
                a3 = vfma(a3, x, y)
                a4 = vfma(a4, x, y)
                a5 = vfma(a5, x, y)  # noqa: E702
            vstore(out, 0, a0 + a1 + a2 + a3 + a4 + a5)
            return 0

        out = np.zeros(VW)
        chains(10, out)
        n = 2_000_000
        best = best_of(lambda: chains(n, out), 5)[0]
        _FMA_PEAK = n * 6 * VW / best
    return _FMA_PEAK


# ----------------------------------------------------------------------------------------- 1. compile

COMPILE_SNIPPET = """
import dataclasses, json, time
t0 = time.perf_counter()
import numpy as np
from pounding_sweep.engine import driver
from pounding_sweep.scene import load_scene
from pounding_sweep.sweep.prepare import prepare
s = load_scene(r"{scene}")
s = dataclasses.replace(s, integration=dataclasses.replace(s.integration, scheme="implicit"))
p = prepare(s)
one = driver.RunArrays(np.ones(1), np.zeros((1, 3)), np.zeros(1), np.zeros(1, np.int64), np.zeros(1), np.ones(1),
                       np.zeros(1, np.int64), np.ones(1, np.int64), np.zeros(1, np.int64), np.zeros(1, np.int64))
rec = (np.zeros(1), np.zeros(1, np.int64), np.zeros(1, np.int64))
t1 = time.perf_counter()
driver.run_chunk_lanes(p.sysarr, one, rec, p.opts)
t2 = time.perf_counter()
driver.run_chunk_scalar(p.sysarr, one, rec, driver.HistorySpec.none(), p.opts)
t3 = time.perf_counter()
print(json.dumps(dict(imports=t1 - t0, lanes=t2 - t1, scalar=t3 - t2)))
"""


def compile_times() -> None:
    header("1. compile time, apart from run time (subprocesses)")
    code = COMPILE_SNIPPET.format(scene=SCENE_6HZ)
    rows = []
    with tempfile.TemporaryDirectory() as cache:
        env = dict(os.environ, NUMBA_CACHE_DIR=cache)
        for label in ("empty cache (first call compiles)", "warm cache (loads the compiled code)"):
            p = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True)
            r = json.loads(p.stdout.strip().splitlines()[-1])
            rows.append([label, f"{r['lanes']:.2f} s", f"{r['scalar']:.2f} s", f"{r['imports']:.2f} s"])
    table(rows, ["", "lane kernel", "scalar kernel", "imports + scene"])


# ----------------------------------------------------------------------------------------- 2. peers


def peers(duration: float, grid_copies: int, with_opensees: bool) -> float:
    header(
        f"2. one run by every method: 6 Hz, k_s = k, r = 0.4, gap 0, dt = 1e-4 s, {duration:g} s "
        f"({int(round(duration / DT)):,} steps), implicit scheme, classic law"
    )
    from pounding_sweep.reference import ivp_reference, newmark_reference
    from pounding_sweep.sweep.simulate import simulate

    s = scene(duration=duration, scheme="implicit", **RUN)
    prep = prepare(s)
    nst = int(round(duration / DT))
    runs1, rec = run_inputs(prep, 1)
    runsg, _ = run_inputs(prep, grid_copies)
    ncores = cpu_threads()
    # warm up (compile or load both kernels)
    driver.run_chunk_lanes(prep.sysarr, runs1, rec, prep.opts)
    driver.run_chunk_scalar(prep.sysarr, runs1, rec, HistorySpec.none(), prep.opts)
    t_grid_all, (mg, _) = best_of(lambda: driver.run_chunk_lanes(prep.sysarr, runsg, rec, prep.opts, ncores), 3)
    t_grid_one, _ = best_of(lambda: driver.run_chunk_lanes(prep.sysarr, runsg, rec, prep.opts, 1), 3)
    t_lane_alone, (ml, _) = best_of(lambda: driver.run_chunk_lanes(prep.sysarr, runs1, rec, prep.opts), 3)
    t_scalar, (ms, *_) = best_of(
        lambda: driver.run_chunk_scalar(prep.sysarr, runs1, rec, HistorySpec.none(), prep.opts), 3
    )
    names = L.metric_columns(prep.model.floors, prep.model.n_pairs)
    peak_engine = float(ml[0, names.index("peak_force_f3_N")])
    hist, _ = simulate(s, channels=["disp_b1f3", "disp_b2f3", "force_f3", "ground_acc"])  # histories (scalar kernel)
    x1, x2 = hist["disp_b1f3_m"].to_numpy(), hist["disp_b2f3_m"].to_numpy()

    def agree(u1, u2, peak):
        return f"{rel_rms(u1, x1):.1e} / {rel_rms(u2, x2):.1e}", f"{abs(peak - peak_engine) / peak_engine:.1e}"

    def rows_vs(m):
        """Largest relative difference of the peak displacements and forces against the lane kernel's row."""
        cols = [i for i, n in enumerate(names) if n.startswith(("peak_disp_b", "peak_force_f"))]
        d = np.max(np.abs(m[0, cols] - ml[0, cols]) / np.abs(ml[0, cols]))
        return (
            f"peaks within {d:.0e}" if d > 0 else "identical peaks",
            f"{abs(m[0, names.index('peak_force_f3_N')] - peak_engine) / peak_engine:.1e}",
        )

    engine = t_grid_all / grid_copies
    rows = []

    def row(name, t_run, agreement=("identical rows", "0")):
        rows.append(
            [
                name,
                f"{t_run:.4g}",
                f"{t_run / nst * 1e9:,.1f}",
                fmt_rate(nst / t_run),
                f"{t_run / engine:,.1f}",
                *agreement,
            ]
        )

    same = bool(np.array_equal(mg, np.repeat(ml, grid_copies, axis=0)))
    row(
        f"lane kernel, per run in a {grid_copies}-run grid, {ncores} cores [the engine]",
        engine,
        ("rows equal to the run alone" if same else "ROWS DIFFER", "0"),
    )
    row(f"lane kernel, per run in a {grid_copies}-run grid, 1 core", t_grid_one / grid_copies, ("", ""))
    row(f"lane kernel, the run alone ({driver.LANES - 1} idle lanes)", t_lane_alone, ("reference", "reference"))
    row("scalar kernel (histories, scoring), the run alone", t_scalar, rows_vs(ms))
    ev = scene(duration=duration, scheme="event", **RUN)
    pev = prepare(ev)
    rev, _ = run_inputs(pev, grid_copies)
    driver.run_chunk_lanes(pev.sysarr, rev, rec, pev.opts, ncores)
    t_ev, (mev, _) = best_of(lambda: driver.run_chunk_lanes(pev.sysarr, rev, rec, pev.opts, ncores), 3)
    row(
        f"lane kernel, event scheme (the default: 2nd order across impacts), {ncores} cores",
        t_ev / grid_copies,
        ("other scheme", f"{abs(mev[0, names.index('peak_force_f3_N')] - peak_engine) / peak_engine:.1e}"),
    )
    t0 = time.perf_counter()
    ref = newmark_reference(s)
    t_np = time.perf_counter() - t0
    row(
        "NumPy loop, same scheme (tests/reference.py)",
        t_np,
        agree(ref["u"][:, 2], ref["u"][:, 5], float(ref["F"][:, 2].max())),
    )
    t0 = time.perf_counter()
    ivp = ivp_reference(s, dt_out=DT)
    t_ivp = time.perf_counter() - t0
    row(
        "solve_ivp DOP853 + contact events, rtol 1e-10",
        t_ivp,
        agree(ivp["u"][:, 2], ivp["u"][:, 5], float(np.max(ivp["F"][:, 2])) if "F" in ivp else float("nan")),
    )
    if with_opensees:
        try:
            from opensees_pounding import run_opensees

            from pounding_sweep.model.contact import dashpot_coefficient

            m1, m2 = prep.model.pair_masses()
            ks = RUN["ks_ratio"] * s.contact.k_ref_N_per_m
            c = dashpot_coefficient(ks, RUN["r"], m1, m2)
            ag = hist["ground_acc_m_s2"].to_numpy()
            res = min(
                (run_opensees(prep.model, ks, c, RUN["gap_m"], ag, DT) for _ in range(2)), key=lambda r: r["wall_s"]
            )
            row(
                "OpenSeesPy 3.7 (ViscoelasticGap, Newton 1e-12, analysis only)",
                res["wall_s"],
                agree(res["u"][:, 2], res["u"][:, 5], float(res["F"][:, 2].max())),
            )
        except ImportError as e:
            rows.append([f"OpenSeesPy: not installed ({e})", "", "", "", "", "", ""])
    table(
        rows,
        ["method", "s per run", "ns per step", "steps/s", "x engine", "top floor rel RMS b1 / b2", "peak F13 rel diff"],
    )
    print(
        f"(engine: lane kernel, {ncores} threads, the run repeated {grid_copies} times; agreement against the "
        f"scalar kernel's history of the run (the lane kernel keeps no histories) and the engine's peak "
        f"F13 = {peak_engine:.6f} N)"
    )
    return engine


# ----------------------------------------------------------------------------------------- 3. threads


def uneven_scene(n_r: int, duration: float, scheme: str = "event"):
    # k_s/k from 0.01 (soft, long contacts) to 100 (stiff, many short ones) and gaps from 0 to
    # 20 mm (no contact at all): runs of very different cost in one grid
    return scene(
        duration=duration,
        scheme=scheme,
        sweep=[
            ("gap_m", (0.0, 0.002, 0.02)),
            ("ks_ratio", np.geomspace(0.01, 100, 6)),
            ("r", np.linspace(0.0, 1.0, n_r)),
        ],
    )


def _pinned(fn, cpus: set[int]) -> float:
    """Wall time of fn() with this process's threads allowed on `cpus` only."""
    allowed = os.sched_getaffinity(0)
    os.sched_setaffinity(0, cpus)
    try:
        return best_of(fn, 1)[0]
    finally:
        os.sched_setaffinity(0, allowed)


def threads_table(n_r: int, duration: float, rounds: int) -> None:
    """Each round: the grid on one thread pinned to each core in turn, then on every core. This VM's
    cores are not equally fast for the engine at all times (the host's other tenants share their
    caches and load/store units; at times one core runs the grid 1.5x faster than the other), so the
    table gives the efficiency against the fastest core of each round and, apart, over the rounds in
    which the cores were equally fast (solo times within 5 %): the engine's own scaling."""
    cores = sorted(os.sched_getaffinity(0))
    nc = len(cores)
    rows = []
    for scheme in ("event", "implicit"):
        names = None
        for kern in ("lanes", "scalar"):
            prep = prepare(uneven_scene(n_r, duration, scheme), kernel=kern)
            params = prep.grid.chunk(0, prep.grid.size)
            names = L.metric_columns(prep.model.floors, prep.model.n_pairs)
            m = prep.run(params, threads=1)[0]  # warm
            steps = float(m[:, names.index("steps")].sum())
            imp = m[:, names.index("impacts_f3")]
            solo, alls, effs, even, busy, infl = [], [], [], [], [], []
            for _ in range(rounds if kern == "lanes" else max(2, rounds // 4)):
                ts = [_pinned(lambda: prep.run(params, threads=1), {c}) for c in cores]
                c0 = time.process_time()
                t_all = best_of(lambda: prep.run(params, threads=nc), 1)[0]
                cpu = time.process_time() - c0  # every thread's CPU time (the waiting main thread's is ~0)
                solo.append(min(ts))
                alls.append(t_all)
                effs.append(min(ts) / (nc * t_all))
                busy.append(cpu / (nc * t_all))
                infl.append(cpu / (sum(ts) / nc))
                if max(ts) <= 1.05 * min(ts):
                    even.append(effs[-1])
            med = statistics.median
            rows.append(
                [
                    scheme,
                    f"{kern} kernel",
                    f"{min(solo):.3f}",
                    f"{min(alls):.3f}",
                    fmt_rate(steps / min(alls)),
                    f"{med(effs):.0%} ({min(effs):.0%}..{max(effs):.0%})",
                    f"{med(even):.0%} ({len(even)} of {len(effs)})" if even else f"none of {len(effs)}",
                    f"{med(busy):.0%}",
                    f"{med(infl):.2f}",
                    f"{int(imp.min())}..{int(imp.max())}",
                ]
            )
    header(
        f"3. grid throughput and parallel efficiency: gaps 0/2/20 mm x k_s/k 0.01..100 (6, log) x r 0..1 ({n_r}); "
        f"{prep.grid.size} runs of {duration:g} s; each round: 1 thread pinned to each core, then {nc} threads"
    )
    table(
        rows,
        [
            "scheme",
            "kernel",
            "1 core, best [s]",
            f"{nc} cores, best [s]",
            f"steps/s on {nc}",
            "efficiency per round: median (range)",
            "rounds with equally fast cores: median",
            "threads busy",
            "CPU time x 1 core",
            "impacts f3 per run",
        ],
    )
    print(
        f"(efficiency of a round = t(fastest core alone) / ({nc} x t({nc} threads)); cores equally fast: their solo "
        f"times within 5 %. Threads busy = CPU time of the {nc}-thread run / ({nc} x its wall time): the load balance. "
        "CPU time x 1 core = that CPU time / the mean solo time: above 1, the same work cost more with every core "
        "busy (caches and load/store units shared with each other and the host's other tenants); medians)"
    )


# ----------------------------------------------------------------------------------------- 4. scaling


def _factor(n: int) -> tuple[int, int, int]:
    """n = a * b * c with the axes as even as the powers of ten allow (k_s/k, r, gap)."""
    if n == 1:
        return 1, 1, 1
    e = int(round(np.log10(n)))
    a = 10 ** ((e + 2) // 3)
    rest = n // a
    b = 10 ** ((int(round(np.log10(rest))) + 1) // 2) if rest > 1 else 1
    return a, b, rest // b


def grid_of(n: int, duration: float):
    a, b, c = _factor(n)
    sweep = [
        ("ks_ratio", np.geomspace(0.1, 10.0, a) if a > 1 else [1.0]),
        ("r", np.linspace(0.0, 1.0, b) if b > 1 else [0.4]),
        ("gap_m", np.linspace(0.0, 0.005, c) if c > 1 else [0.0]),
    ]
    return scene(duration=duration, sweep=sweep)


def scaling(sizes: list[int], run_s: float, lengths: list[float], n_len: int) -> None:
    header(f"4. scaling through the sweep (run_scene: grid, kernel, Parquet; {cpu_threads()} threads)")
    rows = []
    with tempfile.TemporaryDirectory() as d:
        for n in sizes:
            s = grid_of(n, run_s)
            summ = run_scene(s, out_path=Path(d) / f"n{n}.parquet")
            rows.append(
                [
                    f"{summ.runs:,} runs x {run_s:g} s",
                    f"{summ.compile_s:.2f}",
                    f"{summ.run_s:.3f}",
                    fmt_rate(summ.steps / summ.run_s),
                    f"{summ.run_s / summ.runs * 1e3:.3f}",
                ]
            )
        for dur in lengths:
            s = grid_of(n_len, dur)
            summ = run_scene(s, out_path=Path(d) / f"l{dur}.parquet")
            rows.append(
                [
                    f"{summ.runs:,} runs x {dur:g} s",
                    f"{summ.compile_s:.2f}",
                    f"{summ.run_s:.3f}",
                    fmt_rate(summ.steps / summ.run_s),
                    f"{summ.run_s / summ.runs * 1e3:.3f}",
                ]
            )
    table(rows, ["grid", "cache load [s]", "sweep wall [s]", "steps/s", "ms per run"])
    print(
        "(grids over k_s/k 0.1..10 x r 0..1 x gap 0..5 mm, 6 Hz table motion at 2 mm; sweep wall excludes the "
        "cache load, includes writing the Parquet)"
    )


# ----------------------------------------------------------------------------------------- 5. memory

MEMORY_SNIPPET = """
import dataclasses, json, resource, sys, time
import numpy as np
from pounding_sweep.scene import Axis, load_scene
from pounding_sweep.sweep.run import run_scene
n, dur, out = int(sys.argv[1]), float(sys.argv[2]), sys.argv[3]
s = load_scene(r"{scene}")
a = 100; b = 100; c = n // (a * b)
s = dataclasses.replace(s, excitation=dataclasses.replace(s.excitation, duration_s=dur),
    sweep=(Axis("ks_ratio", tuple(np.geomspace(0.1, 10.0, a))), Axis("r", tuple(np.linspace(0.0, 1.0, b))),
           Axis("gap_m", tuple(np.linspace(0.0, 0.005, c)))))
t0 = time.perf_counter()
summ = run_scene(s, out_path=out)
print(json.dumps(dict(runs=summ.runs, wall=time.perf_counter() - t0, run_s=summ.run_s, steps=summ.steps,
                      maxrss_kb=resource.getrusage(resource.RUSAGE_SELF).ru_maxrss)))
"""


def memory(sizes: list[int], dur: float) -> None:
    header(f"5. peak memory of metrics-only sweeps through run_scene (subprocess, {dur:g} s runs)")
    import pyarrow.parquet as pq

    code = MEMORY_SNIPPET.format(scene=SCENE_6HZ)
    rows = []
    with tempfile.TemporaryDirectory() as d:
        for n in sizes:
            out = Path(d) / f"m{n}"
            seen = []
            p = subprocess.Popen(
                [sys.executable, "-c", code, str(n), str(dur), str(out)], stdout=subprocess.PIPE, text=True
            )

            def watch():
                while p.poll() is None:
                    seen.append(len(list(out.glob("part-*.parquet"))) if out.exists() else 0)
                    time.sleep(0.25)

            w = threading.Thread(target=watch)
            w.start()
            stdout, _ = p.communicate()
            w.join()
            r = json.loads(stdout.strip().splitlines()[-1])
            parts = sorted(out.glob("part-*.parquet"))
            nrows = sum(pq.read_metadata(f).num_rows for f in parts)
            size = sum(f.stat().st_size for f in parts)
            grew = sorted(set(seen))
            rows.append(
                [
                    f"{n:,}",
                    f"{r['maxrss_kb'] / 1024:.0f}",
                    f"{r['run_s']:.1f}",
                    fmt_rate(r["steps"] / r["run_s"]),
                    f"{size / 2**20:.0f}",
                    f"{len(parts)}",
                    f"{nrows:,}",
                    f"yes: {len(grew)} part counts seen, {grew[0]}..{grew[-1]}"
                    if len(grew) > 2
                    else ("too short to watch" if r["wall"] < 2.0 else "no"),
                ]
            )
    table(
        rows,
        ["runs", "peak RSS [MiB]", "sweep wall [s]", "steps/s", "Parquet [MiB]", "parts", "rows", "written as it went"],
    )


# ----------------------------------------------------------------------------------------- 6. CLI


NUMBA_FLOOR = (
    "import numba\nfrom numba.core.registry import cpu_target\n"
    "cpu_target.target_context.refresh(); cpu_target.typing_context.refresh()"
)


def cli_duzce(repeats: int) -> None:
    header("6. the paper's Duzce grid (20 runs) through the CLI, warm cache: wall time of the whole command")
    with tempfile.TemporaryDirectory() as d:
        text = SCENE_DUZCE.read_text().replace('record = "records/', f'record = "{SCENE_DUZCE.parent}/records/')
        implicit = Path(d) / "paper_duzce_implicit.toml"
        implicit.write_text(text.replace("[integration]\n", '[integration]\nscheme = "implicit"\n'))
        rows = []
        imp = []
        for _ in range(repeats):
            t0 = time.perf_counter()
            subprocess.run([sys.executable, "-c", "import pounding_sweep.cli.run"], check=True)
            imp.append(time.perf_counter() - t0)
        rows.append(
            [
                "python -c 'import pounding_sweep.cli.run'",
                f"{min(imp):.2f}",
                f"{statistics.median(imp):.2f}",
                "",
                "",
                "",
            ]
        )
        floor = []
        for _ in range(repeats):
            t0 = time.perf_counter()
            subprocess.run([sys.executable, "-c", NUMBA_FLOOR], check=True)
            floor.append(time.perf_counter() - t0)
        rows.append(
            [
                "Numba's own start-up: import numba, first-call registry refresh",
                f"{min(floor):.2f}",
                f"{statistics.median(floor):.2f}",
                "",
                "",
                "",
            ]
        )
        for label, path in (
            ("shipped scene (its scheme: " + load_scene(SCENE_DUZCE).integration.scheme + ")", SCENE_DUZCE),
            ("same scene, scheme = implicit (lane kernel)", implicit),
        ):

            def cmd(k):  # a new output folder each time: a finished one would be resumed (nothing to run)
                return [sys.executable, "-m", "pounding_sweep", str(path), "--out", str(Path(d) / f"{path.stem}{k}")]

            subprocess.run(cmd("warm"), check=True, capture_output=True)  # warm the cache
            walls, last = [], ""
            for k in range(repeats):
                t0 = time.perf_counter()
                p = subprocess.run(cmd(k), check=True, capture_output=True, text=True)
                walls.append(time.perf_counter() - t0)
                last = p.stdout
            info = {k.strip(): v.strip() for k, v in (ln.split("  ", 1) for ln in last.splitlines() if "  " in ln)}
            rows.append(
                [
                    label,
                    f"{min(walls):.2f}",
                    f"{statistics.median(walls):.2f}",
                    info.get("compile (or cache load)", "?"),
                    info.get("run", "?").split(" wall")[0],
                    info.get("runs", "?"),
                ]
            )
    table(rows, ["command", "best [s]", "median [s]", "cache load", "sweep", "runs"])


# ----------------------------------------------------------------------------------------- 7. profile

# float64 multiply-class operations (multiplies and fused multiply-adds, which share the FMA pipes)
# per lane and step of the vector step without contact, for N modes (floors) and P pairs: the
# modal update 3 N (ek s, cr r, cq q), input work N, damping work 2 N, modal acceleration 2 N, then
# Phi q and Phi a, N_b^2 per building each. Counted from the source (engine/lanes/vector.py _quiet_step).


def fma_ops_quiet(n1: int, n2: int) -> int:
    n = n1 + n2
    return 8 * n + 2 * (n1 * n1 + n2 * n2)


def profile(peak: float) -> None:
    header("7. profile: where the lane kernel's time goes (1 thread, CPU time; work counters of the kernel)")
    rows = []
    for label, base, gaps in (
        ("no contact (gap 50 mm)", SCENE_6HZ, (0.05,)),
        ("6 Hz at gap 0: every pair pounds", SCENE_6HZ, (0.0,)),
        ("Duzce record at gap 0", SCENE_DUZCE, (0.0,)),
    ):
        for scheme in ("event", "implicit"):
            s = scene(
                base=base,
                duration=2.0 if base == SCENE_6HZ else None,
                scheme=scheme,
                sweep=[("gap_m", gaps), ("ks_ratio", np.geomspace(0.1, 10, 4)), ("r", np.linspace(0.2, 1, 4))],
            )
            prep = prepare(s)
            runs, rec = run_inputs(prep, points=prep.grid.size)
            driver.run_chunk_lanes(prep.sysarr, runs, rec, prep.opts, 1)
            best, stats = float("inf"), None
            for _ in range(3):
                counters = np.zeros(kernel_lanes.ST_N, np.int64)
                t0 = time.thread_time()
                m, _ = driver.run_chunk_lanes(prep.sysarr, runs, rec, prep.opts, 1, stats=counters)
                t = time.thread_time() - t0
                if t < best:
                    best, stats = t, counters
            steps = float(m[:, L.metric_columns(prep.model.floors, prep.model.n_pairs).index("steps")].sum())
            fix_n, fix_ns, calls, vsteps = (
                int(stats[k])
                for k in (kernel_lanes.ST_FIXUPS, kernel_lanes.ST_FIX_NS, kernel_lanes.ST_CALLS, kernel_lanes.ST_VSTEPS)
            )
            vec = best - fix_ns * 1e-9
            rows.append(
                [
                    label,
                    scheme,
                    f"{best / steps * 1e9:.1f}",
                    f"{vec / steps * 1e9:.1f}",
                    f"{fix_n / runs.n:,.0f}",
                    f"{fix_ns / max(fix_n, 1) / 1e3:.2f}",
                    f"{fix_ns * 1e-9 / best:.0%}",
                    f"{vsteps / max(calls, 1):,.0f}",
                ]
            )
    table(
        rows,
        [
            "grid (16 runs)",
            "scheme",
            "ns/step",
            "of which vector ns/step",
            "scalar steps per run",
            "us per scalar step",
            "share scalar",
            "steps per vector call",
        ],
    )
    n1, n2 = prepare(load_scene(SCENE_6HZ)).model.floors
    ops = fma_ops_quiet(n1, n2)
    roof = ops / peak * 1e9
    print(
        f"roofline of the step without contact: {ops} multiply-class operations per lane and step at the measured "
        f"{peak / 1e9:.1f} G per second and core = {roof:.1f} ns per step and core, {1e3 / roof:.0f} M steps/s "
        f"per core. The rest of the vector step is loads, stores, compares and blends: on AMD Zen 1 every AVX2 "
        f"instruction is two 128-bit operations and loads and stores share two address units, which bound it "
        f"before the FMA pipes do."
    )


# ----------------------------------------------------------------------------------------- main


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="small sizes: a smoke test of every section")
    ap.add_argument("--no-opensees", action="store_true", help="leave OpenSeesPy out of section 2")
    ap.add_argument("--sections", default="01234567", help="which sections to run, e.g. 023")
    a = ap.parse_args()
    q = a.quick
    t0 = time.perf_counter()
    secs = a.sections
    peak = machine() if "0" in secs else None  # the FMA peak: only where a section needs it
    if "1" in secs:
        compile_times()
    if "2" in secs:
        peers(duration=1.0 if q else 5.0, grid_copies=64 if q else 512, with_opensees=not a.no_opensees)
    if "3" in secs:
        threads_table(n_r=4 if q else 20, duration=0.5 if q else 2.0, rounds=2 if q else 8)
    if "4" in secs:
        scaling(
            sizes=[1, 10, 100, 1000] if q else [1, 10, 100, 1000, 10_000, 100_000],
            run_s=0.2 if q else 1.0,
            lengths=[0.5, 2.0] if q else [0.5, 2.0, 8.0, 32.0],
            n_len=100 if q else 1000,
        )
    if "5" in secs:
        memory(sizes=[10_000, 100_000] if q else [100_000, 1_000_000], dur=0.01 if q else 0.05)
    if "6" in secs:
        cli_duzce(repeats=2 if q else 5)
    if "7" in secs:
        profile(peak or fma_peak())
    print(f"\n(total {time.perf_counter() - t0:.0f} s; load average at the end {load()})")


if __name__ == "__main__":
    main()
