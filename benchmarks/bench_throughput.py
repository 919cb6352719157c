"""Throughput of the engine against its peers and against the issue-9 targets, in one process run.

Usage (from the repository root, dev install; OpenSeesPy optional: `pip install openseespy`, needs
Debian's libblas3 and liblapack3):

    python benchmarks/bench_throughput.py            # the full set, about 5-10 min on 2 idle cores
    python benchmarks/bench_throughput.py --quick    # smoke test of every section, about 1-2 min

Sections (each prints a table):
  0. machine: CPU, SIMD flags, cores, load average (this machine is shared: ratios measured in
     the same run are the claim; absolute times move with the load);
  1. compile time of each kernel with an empty cache and from the warm cache, in subprocesses,
     apart from run time;
  2. one run of the paper's model (6 Hz, k_s = k, r = 0.4, gap 0, dt = 1e-4 s, implicit scheme,
     classic law) by every method: the lane kernel (per run inside a grid, on 1 and all cores; and
     alone), the scalar kernel, the plain NumPy loop of the same scheme (tests/reference.py), solve_ivp
     with contact events (tests/reference.py) and OpenSeesPy (benchmarks/peers): time per step,
     steps/s, ratio to the engine, agreement with the engine;
  3. grid throughput on 1 and 2 threads (parallel efficiency) on a grid of very uneven impact counts;
  4. scaling over grid size (1 .. 1e5 runs) and record length, through the sweep (run_scene:
     grid, kernel, Parquet);
  5. peak memory of a 1,000,000-run metrics-only sweep (subprocess, getrusage) against a 100,000-run
     one, and the Parquet file growing while the sweep runs;
  6. the paper's Duzce grid through the CLI with a warm cache (wall time of the whole command);
  7. profile: the lane kernel's four vector functions timed alone, with their instruction mix, against
     the whole kernel.

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
sys.path.insert(0, str(REPO / "tests"))
sys.path.insert(0, str(REPO / "benchmarks" / "peers"))

from pounding_sweep import driver  # noqa: E402
from pounding_sweep import metrics_layout as L  # noqa: E402
from pounding_sweep.config import Axis, load_scene  # noqa: E402
from pounding_sweep.driver import HistorySpec, RunArrays  # noqa: E402
from pounding_sweep.sweep import contact_arrays, prepare, run_scene  # noqa: E402

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


def scene(base=SCENE_6HZ, duration=None, sweep=None, **contact):
    """The shipped scene with the implicit scheme and the classic law (what the lane kernel and the
    peers compute), another duration, contact values and sweep (none: the one run the contact values
    describe)."""
    s = load_scene(base)
    s = dataclasses.replace(s, integration=dataclasses.replace(s.integration, scheme="implicit", dt_s=DT),
                            contact=dataclasses.replace(s.contact, law="classic", **contact))
    if duration is not None:
        s = dataclasses.replace(s, excitation=dataclasses.replace(s.excitation, duration_s=duration))
    return dataclasses.replace(s, sweep=tuple(Axis(n, tuple(float(x) for x in v)) for n, v in (sweep or ())))


def run_inputs(prep, copies=1):
    """Kernel inputs of the scene's first grid point, repeated `copies` times."""
    params = prep.grid.chunk(0, 1)
    ks, c, _, _, status = contact_arrays(prep.model, prep.scene, params, prep.dt)
    ex = prep.excitation.run_arrays(params)
    one = RunArrays(ks, c, params["gap_m"], ex["exc_kind"], ex["exc_amp"], ex["exc_omega"], ex["rec_id"],
                    ex["nsteps"], status)
    runs = RunArrays(*(np.ascontiguousarray(np.repeat(getattr(one, f.name), copies, axis=0))
                       for f in dataclasses.fields(RunArrays)))
    rec = (prep.excitation.rec_flat, prep.excitation.rec_off, prep.excitation.rec_len)
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


def machine() -> None:
    header("0. machine")
    flags, model = set(), "?"
    with open("/proc/cpuinfo") as f:
        for line in f:
            if line.startswith("model name") and model == "?":
                model = line.split(":", 1)[1].strip()
            if line.startswith("flags"):
                flags = set(line.split(":", 1)[1].split())
    import numba

    simd = [x for x in ("avx2", "fma", "avx512f") if x in flags]
    print(f"CPU {model}, {cpu_threads()} cores, SIMD {' '.join(simd)}"
          f"{'' if 'avx512f' in flags else ' (no AVX-512: 4 float64 per instruction)'}; "
          f"Python {platform.python_version()}, NumPy {np.__version__}, Numba {numba.__version__}")


# ----------------------------------------------------------------------------------------- 1. compile

COMPILE_SNIPPET = """
import dataclasses, json, time
t0 = time.perf_counter()
import numpy as np
from pounding_sweep import driver
from pounding_sweep.config import load_scene
from pounding_sweep.sweep import prepare
s = load_scene(r"{scene}")
s = dataclasses.replace(s, integration=dataclasses.replace(s.integration, scheme="implicit"))
p = prepare(s)
one = driver.RunArrays(np.ones(1), np.zeros((1, 3)), np.zeros(1), np.zeros(1, np.int64), np.zeros(1), np.ones(1),
                       np.zeros(1, np.int64), np.ones(1, np.int64), np.zeros(1, np.int64))
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
    header(f"2. one run by every method: 6 Hz, k_s = k, r = 0.4, gap 0, dt = 1e-4 s, {duration:g} s "
           f"({int(round(duration / DT)):,} steps), implicit scheme, classic law")
    from reference import ivp_reference, newmark_reference
    from pounding_sweep.simulate import simulate

    s = scene(duration=duration, **RUN)
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
    t_scalar, (ms, *_) = best_of(lambda: driver.run_chunk_scalar(prep.sysarr, runs1, rec, HistorySpec.none(),
                                                                  prep.opts), 3)
    same = bool(np.array_equal(ml.view(np.int64), ms.view(np.int64))
                and np.array_equal(mg.view(np.int64), np.repeat(ms, grid_copies, axis=0).view(np.int64)))
    names = L.metric_columns(prep.model.floors, prep.model.n_pairs)
    peak_engine = float(ms[0, names.index("peak_force_f3_N")])
    hist, _ = simulate(s, channels=["disp_b1f3", "disp_b2f3", "force_f3", "ground_acc"])  # engine histories
    x1, x2 = hist["disp_b1f3_m"].to_numpy(), hist["disp_b2f3_m"].to_numpy()

    def agree(u1, u2, peak):
        return f"{rel_rms(u1, x1):.1e} / {rel_rms(u2, x2):.1e}", f"{abs(peak - peak_engine) / peak_engine:.1e}"

    engine = t_grid_all / grid_copies
    rows = []

    def row(name, t_run, agreement=("identical rows", "0")):
        rows.append([name, f"{t_run:.4g}", f"{t_run / nst * 1e9:,.1f}", fmt_rate(nst / t_run), f"{t_run / engine:,.1f}",
                     *agreement])

    ident = ("identical rows" if same else "ROWS DIFFER", "0" if same else "?")
    row(f"lane kernel, per run in a {grid_copies}-run grid, {ncores} cores [the engine]", engine, ident)
    row(f"lane kernel, per run in a {grid_copies}-run grid, 1 core", t_grid_one / grid_copies, ident)
    row("lane kernel, the run alone (15 idle lanes)", t_lane_alone, ident)
    row("scalar kernel, the run alone", t_scalar, ("reference", "reference"))
    t0 = time.perf_counter()
    ref = newmark_reference(s)
    t_np = time.perf_counter() - t0
    row("NumPy loop, same scheme (tests/reference.py)", t_np,
        agree(ref["u"][:, 2], ref["u"][:, 5], float(ref["F"][:, 2].max())))
    t0 = time.perf_counter()
    ivp = ivp_reference(s, dt_out=DT)
    t_ivp = time.perf_counter() - t0
    row("solve_ivp DOP853 + contact events, rtol 1e-10", t_ivp,
        agree(ivp["u"][:, 2], ivp["u"][:, 5], float(np.max(ivp["F"][:, 2])) if "F" in ivp else float("nan")))
    if with_opensees:
        try:
            from opensees_pounding import run_opensees
            from pounding_sweep.contact import dashpot_coefficient

            m1, m2 = prep.model.pair_masses()
            ks = RUN["ks_ratio"] * s.contact.k_ref_N_per_m
            c = dashpot_coefficient(ks, RUN["r"], m1, m2)
            ag = hist["ground_acc_m_s2"].to_numpy()
            res = min((run_opensees(prep.model, ks, c, RUN["gap_m"], ag, DT) for _ in range(2)),
                      key=lambda r: r["wall_s"])
            row("OpenSeesPy 3.7 (ViscoelasticGap, Newton 1e-12, analysis only)", res["wall_s"],
                agree(res["u"][:, 2], res["u"][:, 5], float(res["F"][:, 2].max())))
        except ImportError as e:
            rows.append([f"OpenSeesPy: not installed ({e})", "", "", "", "", "", ""])
    table(rows, ["method", "s per run", "ns per step", "steps/s", "x engine", "top floor rel RMS b1 / b2",
                 "peak F13 rel diff"])
    print(f"(engine: lane kernel, {ncores} threads, the run repeated {grid_copies} times; agreement against the "
          f"engine's history, peak F13 = {peak_engine:.6f} N)")
    return engine


# ----------------------------------------------------------------------------------------- 3. threads


def uneven_scene(n_r: int, duration: float):
    # k_s/k from 0.01 (soft, long contacts) to 100 (stiff, many short ones) and gaps from 0 to
    # 20 mm (no contact at all): runs of very different cost in one grid
    return scene(duration=duration, sweep=[("gap_m", (0.0, 0.002, 0.02)), ("ks_ratio", np.geomspace(0.01, 100, 6)),
                                           ("r", np.linspace(0.0, 1.0, n_r))])


def threads_table(n_r: int, duration: float) -> None:
    s = uneven_scene(n_r, duration)
    prep = prepare(s)
    params = prep.grid.chunk(0, prep.grid.size)
    header(f"3. grid throughput and parallel efficiency: gaps 0/2/20 mm x k_s/k 0.01..100 (6, log) x r 0..1 ({n_r}); "
           f"{prep.grid.size} runs of {duration:g} s")
    ncores = cpu_threads()
    names = L.metric_columns(prep.model.floors, prep.model.n_pairs)
    rows = []
    for kern in ("lanes", "scalar"):
        driver.FORCE_KERNEL = "scalar" if kern == "scalar" else None
        try:
            prep.run(params, threads=1)  # warm
            base = None
            for th in sorted({1, ncores}):
                t, out = best_of(lambda: prep.run(params, threads=th), 3)
                m = out[0]
                steps = float(m[:, names.index("steps")].sum())
                rate = steps / t
                base = base or rate
                imp = m[:, names.index("impacts_f3")]
                rows.append([f"{kern} kernel", th, f"{t:.3f}", fmt_rate(rate), f"{t / steps * th * 1e9:.1f}",
                             f"{rate / (base * th):.0%}", f"{int(imp.min())}..{int(imp.max())}"])
        finally:
            driver.FORCE_KERNEL = None
    table(rows, ["kernel", "threads", "wall [s]", "steps/s", "ns/step/core", "efficiency", "impacts f3 per run"])


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
    sweep = [("ks_ratio", np.geomspace(0.1, 10.0, a) if a > 1 else [1.0]),
             ("r", np.linspace(0.0, 1.0, b) if b > 1 else [0.4]),
             ("gap_m", np.linspace(0.0, 0.005, c) if c > 1 else [0.0])]
    return scene(duration=duration, sweep=sweep)


def scaling(sizes: list[int], run_s: float, lengths: list[float], n_len: int) -> None:
    header(f"4. scaling through the sweep (run_scene: grid, kernel, Parquet; {cpu_threads()} threads)")
    rows = []
    with tempfile.TemporaryDirectory() as d:
        for n in sizes:
            s = grid_of(n, run_s)
            summ = run_scene(s, out_path=Path(d) / f"n{n}.parquet")
            rows.append([f"{summ.runs:,} runs x {run_s:g} s", f"{summ.compile_s:.2f}", f"{summ.run_s:.3f}",
                         fmt_rate(summ.steps / summ.run_s), f"{summ.run_s / summ.runs * 1e3:.3f}"])
        for dur in lengths:
            s = grid_of(n_len, dur)
            summ = run_scene(s, out_path=Path(d) / f"l{dur}.parquet")
            rows.append([f"{summ.runs:,} runs x {dur:g} s", f"{summ.compile_s:.2f}", f"{summ.run_s:.3f}",
                         fmt_rate(summ.steps / summ.run_s), f"{summ.run_s / summ.runs * 1e3:.3f}"])
    table(rows, ["grid", "cache load [s]", "sweep wall [s]", "steps/s", "ms per run"])
    print("(grids over k_s/k 0.1..10 x r 0..1 x gap 0..5 mm, 6 Hz table motion at 2 mm; sweep wall excludes the "
          "cache load, includes writing the Parquet)")


# ----------------------------------------------------------------------------------------- 5. memory

MEMORY_SNIPPET = """
import dataclasses, json, resource, sys, time
import numpy as np
from pounding_sweep.config import Axis, load_scene
from pounding_sweep.sweep import run_scene
n, dur, out = int(sys.argv[1]), float(sys.argv[2]), sys.argv[3]
s = load_scene(r"{scene}")
a = 100; b = 100; c = n // (a * b)
s = dataclasses.replace(s, integration=dataclasses.replace(s.integration, scheme="implicit"),
    excitation=dataclasses.replace(s.excitation, duration_s=dur),
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
            p = subprocess.Popen([sys.executable, "-c", code, str(n), str(dur), str(out)], stdout=subprocess.PIPE,
                                 text=True)

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
            rows.append([f"{n:,}", f"{r['maxrss_kb'] / 1024:.0f}", f"{r['run_s']:.1f}", fmt_rate(r["steps"] / r["run_s"]),
                         f"{size / 2**20:.0f}", f"{len(parts)}", f"{nrows:,}",
                         f"yes: {len(grew)} part counts seen, {grew[0]}..{grew[-1]}" if len(grew) > 2
                         else ("too short to watch" if r["wall"] < 2.0 else "no")])
    table(rows, ["runs", "peak RSS [MiB]", "sweep wall [s]", "steps/s", "Parquet [MiB]", "parts", "rows",
                 "written as it went"])


# ----------------------------------------------------------------------------------------- 6. CLI


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
            subprocess.run([sys.executable, "-c", "import pounding_sweep.cli"], check=True)
            imp.append(time.perf_counter() - t0)
        rows.append(["python -c 'import pounding_sweep.cli' (start-up floor)", f"{min(imp):.2f}",
                     f"{statistics.median(imp):.2f}", "", "", ""])
        for label, path in (("shipped scene (its scheme: " + load_scene(SCENE_DUZCE).integration.scheme
                             + ")", SCENE_DUZCE), ("same scene, scheme = implicit (lane kernel)", implicit)):
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
            rows.append([label, f"{min(walls):.2f}", f"{statistics.median(walls):.2f}",
                         info.get("compile (or cache load)", "?"), info.get("run", "?").split(" wall")[0],
                         info.get("runs", "?")])
    table(rows, ["command", "best [s]", "median [s]", "cache load", "sweep", "runs"])


# ----------------------------------------------------------------------------------------- 7. profile

def _profile_child() -> None:
    """Runs in a subprocess with an empty NUMBA_CACHE_DIR (so the generated code can be inspected):
    each vector function called 20,000 times from a compiled loop, on a 16-lane work array."""
    import re

    import numba

    from pounding_sweep import kernel_lanes as K

    sa = prepare(load_scene(SCENE_6HZ)).sysarr
    nt, n1t = K.size_tuples(sa)
    n, p = sa.m.size, sa.i1.size
    W = np.zeros(K.n_rows(n, p) * K.LANES)
    m, C, Kinv, H, S = sa.m, sa.C, sa.Kinv, sa.H, sa.S
    on = np.ones(p, np.int64)
    pq_, fq_, pc_, fc_ = K._predict_quiet, K._finish_quiet, K._predict_contact, K._finish_contact

    @numba.njit
    def loop(which, reps, W, nt, n1t, m, C, Kinv, H, S, on):
        acc = 0
        for k in range(reps):
            if which == 0:
                acc += pq_(W, 1e-4, nt, n1t, m, C, Kinv)
            elif which == 1:
                acc += fq_(W, 1e-4, k, nt, n1t, m, C)
            elif which == 2:
                acc += pc_(W, 1e-4, 0, nt, n1t, m, C, Kinv, S, on)
            else:
                a, b = fc_(W, 1e-4, k, nt, n1t, m, C, H, on, on)
                acc += a + b
        return acc

    out = {}
    for which, (name, fn) in enumerate((("predict_quiet", pq_), ("finish_quiet", fq_), ("predict_contact", pc_),
                                        ("finish_contact", fc_))):
        loop(which, 2, W, nt, n1t, m, C, Kinv, H, S, on)
        asm = list(fn.inspect_asm().values())[0].split("\n_ZN")[1]  # the function, not its Python wrapper
        ops = [ln.split()[0] for ln in asm.splitlines() if ln.startswith("\t") and not ln.strip().startswith(".")]
        reps, best = 20000, float("inf")
        for _ in range(7):
            t0 = time.thread_time()
            loop(which, reps, W, nt, n1t, m, C, Kinv, H, S, on)
            best = min(best, time.thread_time() - t0)
        out[name] = dict(ns=best / reps / K.LANES * 1e9, instr=len(ops),
                         fp=sum(1 for op in ops if re.match(r"v(add|sub|mul|div)pd$", op)),
                         mem=sum(1 for ln in asm.splitlines() if re.search(r"vmov(u|a)p[sd]\s.*\(", ln)),
                         masked=sum(1 for op in ops if "maskmov" in op))
    print(json.dumps(out))


def profile(prep_cpu) -> None:
    header("7. profile: the lane kernel's vector functions, each alone (CPU time; instruction mix from the "
           "generated code, fresh cache in a subprocess)")
    with tempfile.TemporaryDirectory() as cache:
        env = dict(os.environ, NUMBA_CACHE_DIR=cache)
        p = subprocess.run([sys.executable, __file__, "--profile-child"], env=env, capture_output=True, text=True,
                           check=True)
    r = json.loads(p.stdout.strip().splitlines()[-1])
    rows = [[k, f"{v['ns']:.2f}", v["instr"], v["fp"], v["mem"], v["masked"]] for k, v in r.items()]
    table(rows, ["function (one call = 16 lanes)", "ns per lane-step", "instructions (static)",
                 "vector add/sub/mul/div", "vector loads/stores", "masked moves"])
    quiet = r["predict_quiet"]["ns"] + r["finish_quiet"]["ns"]
    contact = r["predict_contact"]["ns"] + r["finish_contact"]["ns"]
    whole = prep_cpu()
    print(f"sum of parts: no contact {quiet:.1f} ns, every pair in contact {contact:.1f} ns per lane-step; whole kernel "
          f"(CPU time, 1 thread): grid without contact {whole['quiet']:.1f} ns, grid at gap 0 {whole['contact']:.1f} ns "
          f"(the rest: per-step calls and checks, the scalar active-set iterations at impacts and separations, "
          f"partly idle lanes)")


def whole_kernel_cpu() -> dict:
    out = {}
    for label, gaps in (("quiet", (0.05,)), ("contact", (0.0,))):
        s = scene(duration=2.0, sweep=[("gap_m", gaps), ("ks_ratio", np.geomspace(0.01, 100, 6)),
                                       ("r", np.linspace(0, 1, 8))])
        prep = prepare(s)
        params = prep.grid.chunk(0, prep.grid.size)
        m = prep.run(params, threads=1)[0]
        steps = m[:, L.metric_columns(prep.model.floors, prep.model.n_pairs).index("steps")].sum()
        best = float("inf")
        for _ in range(5):
            t0 = time.thread_time()
            prep.run(params, threads=1)
            best = min(best, time.thread_time() - t0)
        out[label] = best / steps * 1e9
    return out


# ----------------------------------------------------------------------------------------- main


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="small sizes: a smoke test of every section")
    ap.add_argument("--no-opensees", action="store_true", help="leave OpenSeesPy out of section 2")
    ap.add_argument("--sections", default="01234567", help="which sections to run, e.g. 023")
    ap.add_argument("--profile-child", action="store_true", help=argparse.SUPPRESS)
    a = ap.parse_args()
    if a.profile_child:
        _profile_child()
        return
    q = a.quick
    t0 = time.perf_counter()
    secs = a.sections
    if "0" in secs:
        machine()
    if "1" in secs:
        compile_times()
    if "2" in secs:
        peers(duration=1.0 if q else 5.0, grid_copies=64 if q else 512, with_opensees=not a.no_opensees)
    if "3" in secs:
        threads_table(n_r=4 if q else 20, duration=0.5 if q else 2.0)
    if "4" in secs:
        scaling(sizes=[1, 10, 100, 1000] if q else [1, 10, 100, 1000, 10_000, 100_000], run_s=0.2 if q else 1.0,
                lengths=[0.5, 2.0] if q else [0.5, 2.0, 8.0, 32.0], n_len=100 if q else 1000)
    if "5" in secs:
        memory(sizes=[10_000, 100_000] if q else [100_000, 1_000_000], dur=0.01 if q else 0.05)
    if "6" in secs:
        cli_duzce(repeats=2 if q else 5)
    if "7" in secs:
        profile(whole_kernel_cpu)
    print(f"\n(total {time.perf_counter() - t0:.0f} s; load average at the end {load()})")


if __name__ == "__main__":
    main()
