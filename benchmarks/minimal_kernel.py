"""A minimal lane-batched Newmark kernel of the engine's model and implicit scheme, and the engine against it.

    python benchmarks/minimal_kernel.py [--quick] [--duration S] [--threads 2] [--rounds 3] [--groups ...]
        [--group-costs] [--columns] [--interleave K]

The minimal kernel keeps only what a sweep for the peak pounding force needs: per run the peak contact force
and the peak displacement of each building's top floor. Everything else the engine does per step (every
floor's peaks and drifts, closest approach, contact and compression times and phases, the energy balance,
the divergence guard, located switches) it does not. Same model and scheme as the engine's lane kernel:
each building's mass-normalised modes (model/modal.py), Newmark average acceleration as one recurrence
per mode (dq = cq q + cr r + cf fsum, r = dt/2 q'), the Kelvin-Voigt force of each pair at the step's end
with the contact set that agrees with the end state (the implicit scheme's active set: from the set of the
step's start; a set already tried means it cycles, then the union of the last two: the engine instead takes
such a step as its event scheme does, located switches, which a minimal kernel leaves out).
The runs' lanes are one SIMD value of the target's width (engine/simd.py VW: 8 with AVX-512, else 4; the engine's
vector steps take groups of VW runs too, since fb3fde6) and the floor and pair
counts are fixed at compile time (as in the engine); a lane's set of pairs is a bit mask, its forces come from
(I + diag(kappa) W)_SS^-1 of its set (NumPy inverts it for every set S before the runs), and only a lane
whose set changes leaves the vector code.

The grid (the issue's): the 6 Hz scene, gap 0, classic law, k_s/k 0.1..10 log-spaced x 32, r 0.2..1 x 80
(2,560 runs; --quick: 8 x 16), 50 s at dt = 1e-4 s (--quick: 5 s), every pair pounding. Printed: the CPU
(numba -s's name), the load, then per round the minimal kernel, the engine's event scheme and its implicit
scheme (the lane kernel, as a sweep runs it), each in M steps/s of wall time and per CPU second, and their
ratios to the minimal kernel; `--groups` gives the engine only the metric groups named (engine/layout.py
GROUPS: e.g. `--groups none` for the peaks and contact columns alone). A check first: the minimal kernel's
peaks equal the engine's implicit ones on the grid's runs where no step's set cycles (relative difference
printed); then each scheme's contact_unsettled count, and the implicit scheme's peaks against the event
scheme's on the runs with cycling steps and on the others. `--group-costs`: instead of the
rounds, the engine with no metric group, each group alone, and all (CPU seconds, the least of the rounds).
`--columns` (with `--groups none`): a fourth kernel, the minimal one also keeping what the engine computes with
no metric group (every floor's peak displacement with its time; each pair's contact time, largest penetration, peak
force with its time, least force), checked against the engine's columns and
timed in the rounds: whether the engine's distance to the minimal kernel is the work of its columns or its own
overhead (events leave the vector code, per-step exits, the scalar steps).
`--interleave K`: instead of timing each kernel on the whole grid in turn (a load that comes and goes over
seconds then falls on one kernel and not another: single rounds spread by 0.1-0.2 in ratio on a shared machine),
each of K slices of the grid is timed by every kernel in turn, and a round's ratio is that of the summed times.
Works for any version of the package on the path (PYTHONPATH=OTHER_CHECKOUT; without metric groups there).
Before 6cae336 the engine computed every floor's peak absolute acceleration with no metric group (it is the accel
group since), so `--groups none` times more engine work on a checkout from before it: compare such ratios across
versions only with that in mind.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numba
import numpy as np

REPO = Path(__file__).resolve().parents[1]

from pounding_sweep.engine import driver
from pounding_sweep.engine import layout as L
from pounding_sweep.engine.lanes import excitation_profiles
from pounding_sweep.engine.simd import VW, many, mconst, vfma, vload, vsel, vsplat, vstore
from pounding_sweep.model.modal import modal_arrays
from pounding_sweep.scene import Axis, load_scene
from pounding_sweep.sweep.prepare import prepare

LANES = VW  # one SIMD value of the target's width
MAX_ITER = 16


def set_inverses(ks, cd, W, dt):
    """R[run, s, i, j] = (I + diag(kappa) W)_SS^-1 of every set s of pairs (bit j: pair j in contact) for
    every run (kappa = k_s + 2 c / dt), zeros outside S: one batched NumPy inverse per set."""
    n, P = cd.shape
    R = np.zeros((n, 1 << P, P, P))
    for s in range(1, 1 << P):
        idx = [j for j in range(P) if (s >> j) & 1]
        kap = ks[:, None] + 2.0 * cd[:, idx] / dt  # (runs, na)
        A = np.eye(len(idx)) + kap[:, :, None] * W[np.ix_(idx, idx)][None]
        R[:, s][:, np.ix_(idx, idx)[0], np.ix_(idx, idx)[1]] = np.linalg.inv(A)
    return R


@numba.njit(nogil=True, cache=True, error_model="numpy")
def _lane_set(l, s, R, RL, Y, PF, W, seen, ncyc):
    """Lane l's set from the set s of its step start (the implicit scheme's active-set iteration: until the
    end state agrees; a set already tried means it cycles: then the union of the last two, counted in
    ncyc[l]: the engine takes such a step as its event scheme does, which a minimal kernel does not); its
    inverse copied into RL. Returns the set."""
    P = W.shape[0]
    it = 0
    while True:
        want = 0
        for j in range(P):
            e = PF[j * LANES + l]
            for i in range(P):
                f = 0.0
                for z in range(P):
                    f += R[s, i, z, l] * Y[z * LANES + l]
                e -= W[j, i] * f
            if e > 0.0:
                want |= 1 << j
        if want == s:
            break
        seen[it] = s
        it += 1
        cyc = False
        for z in range(it):
            if seen[z] == want:
                cyc = True
        if cyc or it >= MAX_ITER:
            s = s | want
            ncyc[l] += 1
            break
        s = want
    for i in range(P):
        for j in range(P):
            RL[(i * P + j) * LANES + l] = R[s, i, j, l]
    return s


#: `--columns`: what the engine computes per floor and per pair with no metric group, as the starts of its column
#: names (engine/layout.py metric_columns; a start picks one column per floor or per pair)
COLUMNS_PER_FLOOR = ("peak_disp_b", "peak_disp_time_b")
COLUMNS_PER_PAIR = ("contact_time_f", "max_penetration_f", "peak_force_f", "peak_force_time_f", "min_force_f")


def column_names(n1: int, n: int, p: int) -> list[str]:
    """ext's columns in order: each COLUMNS_PER_FLOOR kind for every floor, then each COLUMNS_PER_PAIR kind for
    every pair (the engine's names, in its floor and pair order)."""
    names = L.metric_columns((n1, n - n1), p)
    return [c for kind in COLUMNS_PER_FLOOR + COLUMNS_PER_PAIR for c in names if c.startswith(kind)]


@numba.njit(inline="always", error_model="numpy")
def _columns(X, UA, Q, F, ACT, gpv, phi, t, te, dt, n1, N, P):
    """One step's update of the --columns values: every floor's peak |u| with its time (t) from Phi q; each pair's
    contact time, largest penetration (from the floors' u), peak
    force with its time (te: the engine's step end, (step - 1) dt + dt) and least force while in its step's contact
    set. A peak is tested in registers and stored only in the steps where it grows in some lane, as the engine
    does (UA: the step's signed floor displacements)."""
    vt = vsplat(t)
    grow = mconst(False)
    for i in range(N):
        lo = 0 if i < n1 else n1
        hi = n1 if i < n1 else N
        u = vsplat(0.0)
        for k in range(lo, hi):
            u = vfma(vsplat(phi[i, k]), vload(Q, k * LANES), u)
        vstore(UA, i * LANES, u)
        grow = grow | (abs(u) > vload(X, i * LANES))
    if many(grow):
        for i in range(N):
            u = abs(vload(UA, i * LANES))
            pu = vload(X, i * LANES)
            up = u > pu
            vstore(X, i * LANES, vsel(up, u, pu))
            vstore(X, (N + i) * LANES, vsel(up, vt, vload(X, (N + i) * LANES)))
    base = 2 * N
    for j in range(P):
        act = vload(ACT, j * LANES) > 0.5
        if not many(act):
            continue
        pen = (vload(UA, j * LANES) - vload(UA, (n1 + j) * LANES)) - gpv
        f = vload(F, j * LANES)
        o = (base + j) * LANES
        vstore(X, o, vsel(act, vload(X, o) + dt, vload(X, o)))
        o = (base + P + j) * LANES
        up = act & (pen > vload(X, o))
        if many(up):
            vstore(X, o, vsel(up, pen, vload(X, o)))
        o = (base + 2 * P + j) * LANES
        up = act & (f > vload(X, o))
        if many(up):
            vstore(X, o, vsel(up, f, vload(X, o)))
            o2 = (base + 3 * P + j) * LANES
            vstore(X, o2, vsel(up, vsplat(te), vload(X, o2)))
        o = (base + 4 * P + j) * LANES
        up = act & (f < vload(X, o))
        if many(up):
            vstore(X, o, vsel(up, f, vload(X, o)))


@numba.njit(nogil=True, cache=True, error_model="numpy")
def minimal_group(lanes_in, nsteps, ks, cd, gap, coef, prof, modal, sizes, Rrun, out, ext):
    """The runs lanes_in (LANES of them; -1: an empty lane) for nsteps steps; out[run] = (peak force [N],
    peak |top displacement| of building 1 and of building 2 [m], steps whose set cycled). Rrun: set_inverses' R of every run.
    modal = (phi, psi, W, cq, cr, cf, gam, dt, n1)
    (model/modal.py; n1: building 1's floors); sizes = (a tuple of N zeros, one of P zeros, (0,) or ()): the floor
    and pair counts fixed at compile time, as the engine's lane kernel has them (its loops unrolled), and whether
    the kernel also keeps the columns the engine computes with no metric group (the third tuple not empty:
    `--columns`; ext[run] = COLUMNS' values, _columns). The lanes
    are one SIMD value (engine/simd.py, as the engine's vector steps); a lane whose set of pairs in contact
    changes is settled alone in scalar code."""
    phi, psi, W, cq, cr, cf, gam, dt, n1 = modal
    N = len(sizes[0])
    P = len(sizes[1])
    full = len(sizes[2]) > 0
    top1, top2 = n1 - 1, N - 1
    Q = np.zeros(N * LANES)  # modal displacement q
    RR = np.zeros(N * LANES)  # r = dt/2 q'
    G = np.zeros(N * LANES)  # Psi F at the step's start
    QF = np.zeros(N * LANES)  # the free step's end
    RF = np.zeros(N * LANES)
    Y = np.zeros(P * LANES)  # (k_s delta + c delta')_free
    PF = np.zeros(P * LANES)  # the free end penetration
    F = np.zeros(P * LANES)
    ACT = np.zeros(P * LANES)  # 1.0: the pair is in the lane's set
    RL = np.zeros(P * P * LANES)  # each lane's current set's inverse
    KS = np.zeros(LANES)
    C2 = np.zeros(P * LANES)  # 2 c / dt
    CF = np.zeros(LANES)
    GP = np.zeros(LANES)
    PK = np.zeros(3 * LANES)
    mask = np.zeros(LANES, np.int64)
    seen = np.zeros(MAX_ITER + 1, np.int64)
    ncyc = np.zeros(LANES, np.int64)  # steps whose set cycled, per lane
    R = np.zeros((1 << P, P, P, LANES))  # the lanes' set inverses, lane last
    UA = np.zeros(N * LANES)  # (--columns) the step's floor displacements
    X = np.zeros(len(COLUMNS_PER_FLOOR) * N * LANES + len(COLUMNS_PER_PAIR) * P * LANES)  # (--columns) their values
    for z in range(P * LANES):
        X[(2 * N + 4 * P) * LANES + z] = np.inf  # the least force starts above any force
    for l in range(LANES):
        run = lanes_in[l]
        if run >= 0:
            KS[l] = ks[run]
            for j in range(P):
                C2[j * LANES + l] = (2.0 / dt) * cd[run, j]
            CF[l] = coef[run]
            GP[l] = gap[run]
            for z in range(1 << P):
                for i in range(P):
                    for j in range(P):
                        R[z, i, j, l] = Rrun[run, z, i, j]
        else:
            KS[l] = 1.0
            GP[l] = 1.0
    ksv = vload(KS, 0)
    cfv = vload(CF, 0)
    gpv = vload(GP, 0)
    p0 = vsplat(0.0)
    p1 = vsplat(0.0)
    p2 = vsplat(0.0)
    half = vsplat(0.5)
    for step in range(1, nsteps + 1):
        asum = cfv * (prof[step - 1] + prof[step])
        for k in range(N):  # the free step (the start's forces in the load)
            o = k * LANES
            q = vload(Q, o)
            r = vload(RR, o)
            s = -gam[k] * asum - vload(G, o)
            dq = vfma(vsplat(cf[k]), s, vfma(vsplat(cq[k]), q, cr[k] * r))
            vstore(QF, o, q + dq)
            vstore(RF, o, dq - r)
        for j in range(P):
            pf = -gpv
            v = vsplat(0.0)
            for k in range(N):
                pk = vsplat(psi[k, j])
                pf = vfma(pk, vload(QF, k * LANES), pf)
                v = vfma(pk, vload(RF, k * LANES), v)
            vstore(PF, j * LANES, pf)
            vstore(Y, j * LANES, vfma(ksv, pf, vload(C2, j * LANES) * v))
        for i in range(P):  # the forces of each lane's current set
            f = vsplat(0.0)
            for j in range(P):
                f = vfma(vload(RL, (i * P + j) * LANES), vload(Y, j * LANES), f)
            vstore(F, i * LANES, f)
        differ = mconst(False)
        for j in range(P):  # does the end state agree with each lane's set?
            e = vload(PF, j * LANES)
            for i in range(P):
                e = e - W[j, i] * vload(F, i * LANES)
            differ = differ | ((e > 0.0) != (vload(ACT, j * LANES) > half))
        if many(differ):
            for l in range(LANES):
                was = mask[l]
                now = _lane_set(l, was, R, RL, Y, PF, W, seen, ncyc)
                if now != was:
                    mask[l] = now
                    for i in range(P):
                        ACT[i * LANES + l] = 1.0 if (now >> i) & 1 else 0.0
                        f = 0.0
                        for j in range(P):
                            f += RL[(i * P + j) * LANES + l] * Y[j * LANES + l]
                        F[i * LANES + l] = f
        u1 = vsplat(0.0)
        u2 = vsplat(0.0)
        for k in range(N):  # the end state: dq = dq_free - cf Psi F
            o = k * LANES
            gk = vsplat(0.0)
            for j in range(P):
                gk = vfma(vsplat(psi[k, j]), vload(F, j * LANES), gk)
            vstore(G, o, gk)
            corr = cf[k] * gk
            q = vload(QF, o) - corr
            vstore(Q, o, q)
            vstore(RR, o, vload(RF, o) - corr)
            if not full:
                u1 = vfma(vsplat(phi[top1, k]), q, u1)
                u2 = vfma(vsplat(phi[top2, k]), q, u2)
        if full:  # every floor's u, the top floors' among them
            _columns(X, UA, Q, F, ACT, gpv, phi, step * dt, (step - 1) * dt + dt, dt, n1, N, P)
            u1 = vload(UA, top1 * LANES)
            u2 = vload(UA, top2 * LANES)
        fm = vload(F, 0)
        for j in range(1, P):
            fj = vload(F, j * LANES)
            fm = vsel(fj > fm, fj, fm)
        p0 = vsel(fm > p0, fm, p0)
        a1 = abs(u1)
        p1 = vsel(a1 > p1, a1, p1)
        a2 = abs(u2)
        p2 = vsel(a2 > p2, a2, p2)
    vstore(PK, 0, p0)
    vstore(PK, LANES, p1)
    vstore(PK, 2 * LANES, p2)
    for l in range(LANES):
        if lanes_in[l] >= 0:
            for z in range(3):
                out[lanes_in[l], z] = PK[z * LANES + l]
            out[lanes_in[l], 3] = ncyc[l]
            if full:
                for z in range(ext.shape[1]):
                    ext[lanes_in[l], z] = X[z * LANES + l]


def run_minimal(prep, runs, rec, threads: int, columns: bool = False):
    """The minimal kernel on every run (one contact law, one length, harmonic): (runs, 4): the peaks and
    the steps whose set cycled; with `columns`, (that, (runs, len(column_names)): the engine's columns with no
    metric group)."""
    n1 = int(prep.sysarr.i2[0])
    ma = modal_arrays(prep.sysarr, n1)
    coef, pid, prof = excitation_profiles(runs, rec, prep.dt)
    if np.unique(pid).size != 1 or np.unique(runs.nsteps).size != 1:
        raise SystemExit("the minimal kernel runs one excitation profile and one run length")
    nst = int(runs.nsteps[0])
    modal = (ma.phi, ma.psi, ma.W, ma.cq, ma.cr, ma.cf, ma.gam, float(prep.dt), n1)
    out = np.zeros((runs.n, 4))
    N, P = ma.phi.shape[0], ma.psi.shape[1]
    ext = np.zeros((runs.n, len(column_names(n1, N, P)) if columns else 0))
    sizes = ((0,) * N, (0,) * P, (0,) if columns else ())
    R = set_inverses(runs.ks, runs.cdash, ma.W, float(prep.dt))
    groups = [
        np.array(list(range(s, min(s + LANES, runs.n))) + [-1] * max(0, s + LANES - runs.n), np.int64)
        for s in range(0, runs.n, LANES)
    ]

    def work(lanes_in):
        minimal_group(lanes_in, nst, runs.ks, runs.cdash, runs.gap, coef, prof[pid[0]], modal, sizes, R, out, ext)

    with ThreadPoolExecutor(max_workers=threads) as pool:
        list(pool.map(work, groups))
    return (out, ext) if columns else out


def grid(quick: bool, duration: float | None = None):
    s = load_scene(REPO / "sweeps" / "paper_6hz.toml")
    n_ks, n_r, dur = (8, 16, 5.0) if quick else (32, 80, 50.0)
    dur = dur if duration is None else duration
    return dataclasses.replace(
        s,
        integration=dataclasses.replace(s.integration, scheme="implicit", dt_s=1e-4),
        contact=dataclasses.replace(s.contact, law="classic", gap_m=0.0),
        excitation=dataclasses.replace(s.excitation, duration_s=dur),
        sweep=(
            Axis("ks_ratio", tuple(float(x) for x in np.geomspace(0.1, 10.0, n_ks))),
            Axis("r", tuple(float(x) for x in np.linspace(0.2, 1.0, n_r))),
        ),
    )


def cpu_name() -> str:
    r = subprocess.run([sys.executable, "-m", "numba", "-s"], capture_output=True, text=True)
    for line in r.stdout.splitlines():
        if line.strip().startswith("CPU Name"):
            return line.split(":", 1)[1].strip()
    return "unknown"


def load() -> str:
    with open("/proc/loadavg") as f:
        return " ".join(f.read().split()[:3])


def timed(fn):
    w0, c0 = time.perf_counter(), time.process_time()
    out = fn()
    return time.perf_counter() - w0, time.process_time() - c0, out


def scheme_difference(rows, cols, P, floors, cycled):
    """The implicit scheme against the event scheme (second order across impacts): relative difference of
    the peak force and of the top floors' peak displacements, on the runs with steps whose set cycles (the
    engine takes those steps as the event scheme does) beside the others."""
    imp, evt = rows["implicit"], rows["event"]

    def rel(name_cols):
        a = imp[:, name_cols].max(axis=1)
        b = evt[:, name_cols].max(axis=1)
        return np.abs(a - b) / np.maximum(np.abs(b), 1e-300)

    force = rel([cols.index(f"peak_force_f{j}_N") for j in range(1, P + 1)])
    disp = np.maximum(
        rel([cols.index(f"peak_disp_b1f{floors[0]}_m")]), rel([cols.index(f"peak_disp_b2f{floors[1]}_m")])
    )
    for label, sel in (("with cycling steps", cycled), ("without", ~cycled)):
        if sel.any():
            print(
                f"implicit vs event, runs {label} ({int(sel.sum())}): peak force relative difference median "
                f"{np.median(force[sel]):.1e}, 95th percentile {np.percentile(force[sel], 95):.1e}, max "
                f"{force[sel].max():.1e}; top displacements median {np.median(disp[sel]):.1e}, max {disp[sel].max():.1e}"
            )


def group_costs(preps, steps, threads, rounds):
    """The engine's lane kernel with no metric group, each group alone and every group: CPU seconds on the
    grid (the least of `rounds`) and the cost of each over none."""
    masks = [("none", 0)] + [(n, b) for n, b in L.GROUPS.items()] + [("all", L.GROUPS_ALL)]
    print("\nscheme    groups     CPU [s]  M steps/CPU s  x none")
    for scheme, (p, r_, c_) in preps.items():
        best = {}
        for k in range(rounds):
            for label, mask in masks if k % 2 == 0 else masks[::-1]:
                opts = p.opts._replace(groups=mask)
                _, c, _ = timed(lambda opts=opts: driver.run_chunk_lanes(p.sysarr, r_, c_, opts, threads))
                best[label] = min(best.get(label, np.inf), c)
        for label, _ in masks:
            print(
                f"{scheme:9s} {label:9s} {best[label]:8.2f} {steps / best[label] / 1e6:14.0f} "
                f"{best[label] / best['none']:7.3f}"
            )


def time_kernel(name: str, inputs: dict, threads: int) -> tuple[float, float]:
    """(wall, CPU) seconds of one kernel on one chunk: 'minimal', 'columns' (the minimal kernel keeping the engine's
    columns; both on the implicit scheme's inputs) or an engine scheme ('event', 'implicit': the lane kernel).
    inputs: scheme -> (prepared sweep, run arrays, records) of the chunk."""
    if name in ("minimal", "columns"):
        p, runs, rec = inputs["implicit"]
        return timed(lambda: run_minimal(p, runs, rec, threads, columns=name == "columns"))[:2]
    p, runs, rec = inputs[name]
    return timed(lambda: driver.run_chunk_lanes(p.sysarr, runs, rec, p.opts, threads))[:2]


def round_row(k: int, name: str, steps: int, w: float, c: float, minimal: tuple[float, float]) -> str:
    """One kernel's line of a round's table: its wall and CPU time, its throughputs and its ratios to the minimal
    kernel's (wall, CPU) times."""
    x, xc = minimal[0] / w, minimal[1] / c
    return (
        f"{k + 1:5d}  {name:16s} {w:9.2f} {steps / w / 1e6:10.0f} {c:8.2f} {steps / c / 1e6:14.0f}"
        f" {x:17.2f} {xc:16.2f}   {load()}"
    )


def interleaved(preps, steps, args) -> int:
    """--interleave K: per round, the grid in K slices (whole groups of LANES runs), each slice timed by the minimal
    kernel, the event and the implicit scheme one after another (the order turned at every slice); printed per
    round: each kernel's summed wall and CPU time and the ratios of the sums. On a shared machine whose load
    changes over seconds this is the steadier claim: every kernel meets the same load within a slice's second."""
    prep = preps["implicit"][0]
    n = prep.grid.size
    size = -(-n // args.interleave // LANES) * LANES
    slices = []
    for a in range(0, n, size):
        chunk = prep.grid.chunk(a, min(a + size, n))
        slices.append({k: (p, *p.kernel_inputs(chunk)[:2]) for k, (p, _r, _c) in preps.items()})
    kernels = ["minimal", "event", "implicit"]
    print(
        f"\n{len(slices)} slices of up to {size} runs, every kernel in turn on each\n"
        "round  kernel             wall [s]  M steps/s  CPU [s]  M steps/CPU s  x minimal (wall)  x minimal (CPU)   load"
    )
    ratios = {"event": [], "implicit": [], "event_cpu": [], "implicit_cpu": []}
    for k in range(args.rounds):
        wall = dict.fromkeys(kernels, 0.0)
        cpu = dict.fromkeys(kernels, 0.0)
        for i, sl in enumerate(slices):
            turn = (i + k) % len(kernels)
            for name in kernels[turn:] + kernels[:turn]:
                w, c = time_kernel(name, sl, args.threads)
                wall[name] += w
                cpu[name] += c
        for name in kernels:
            x, xc = wall["minimal"] / wall[name], cpu["minimal"] / cpu[name]
            if name != "minimal":
                ratios[name].append(x)
                ratios[name + "_cpu"].append(xc)
            print(round_row(k, name, steps, wall[name], cpu[name], (wall["minimal"], cpu["minimal"])))
    for name in ("event", "implicit"):
        rs, rc = ratios[name], ratios[name + "_cpu"]
        print(
            f"{name}: x minimal {min(rs):.2f} .. {max(rs):.2f}, median {float(np.median(rs)):.2f} (wall); "
            f"{min(rc):.2f} .. {max(rc):.2f} (CPU time) over {len(rs)} interleaved rounds"
        )
    return 0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="8 x 16 runs of 5 s")
    ap.add_argument("--duration", type=float, default=None, help="the runs' length [s] (default 50, --quick 5)")
    ap.add_argument("--threads", type=int, default=len(os.sched_getaffinity(0)))
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument(
        "--interleave",
        type=int,
        default=0,
        metavar="K",
        help="time the kernels slice by slice: the grid in K slices, each timed by every kernel in turn (a load "
        "that comes and goes falls on all alike); a round's ratio is that of the kernels' summed times",
    )
    ap.add_argument(
        "--groups", default=None, help="the engine's metric groups (comma-separated; none: only peaks and contact)"
    )
    ap.add_argument(
        "--group-costs", action="store_true", help="instead of the rounds: each metric group's cost in the engine"
    )
    ap.add_argument(
        "--columns",
        action="store_true",
        help="also time the minimal kernel keeping the engine's columns with no metric group (with --groups none)",
    )
    args = ap.parse_args(argv)
    if args.rounds < 1:
        ap.error(f"--rounds {args.rounds}: at least 1")
    scene = grid(args.quick, args.duration)
    print(f"CPU: {cpu_name()}; {os.cpu_count()} CPUs, {args.threads} threads; load average {load()}")
    preps = {}
    for scheme in ("implicit", "event"):
        s = dataclasses.replace(scene, integration=dataclasses.replace(scene.integration, scheme=scheme))
        prep = prepare(s)
        if args.groups is not None:
            prep = dataclasses.replace(prep, opts=prep.opts._replace(groups=L.groups_mask(args.groups.split(","))))
        elif hasattr(prep.opts, "groups"):
            prep = dataclasses.replace(prep, opts=prep.opts._replace(groups=L.GROUPS_ALL))
        runs, rec, _ = prep.kernel_inputs(prep.grid.chunk(0, prep.grid.size))
        preps[scheme] = (prep, runs, rec)
    prep, runs, rec = preps["implicit"]
    steps = int(runs.nsteps.sum())
    print(f"grid: {runs.n} runs x {int(runs.nsteps[0])} steps (6 Hz scene, gap 0, classic law, dt 1e-4 s)")
    # compile, and check the minimal kernel against the engine's implicit scheme
    mini = run_minimal(prep, runs, rec, args.threads)
    eng, _ = driver.run_chunk_lanes(prep.sysarr, runs, rec, prep.opts, args.threads)
    driver.run_chunk_lanes(preps["event"][0].sysarr, *preps["event"][1:], preps["event"][0].opts, args.threads)
    cols = L.metric_columns(prep.model.floors, prep.model.n_pairs)
    n1, n2 = prep.model.floors
    P = prep.model.n_pairs
    ref = np.column_stack(
        [
            eng[:, [cols.index(f"peak_force_f{j}_N") for j in range(1, P + 1)]].max(axis=1),
            eng[:, cols.index(f"peak_disp_b1f{n1}_m")],
            eng[:, cols.index(f"peak_disp_b2f{n2}_m")],
        ]
    )
    cycled = mini[:, 3] > 0  # the minimal kernel took the union set; the engine located the step's switches
    ok = (eng[:, cols.index("status_code")] == 0) & ~cycled
    rel = np.abs(mini[:, :3] - ref) / np.maximum(np.abs(ref), 1e-300)
    print(
        f"minimal kernel against the engine's implicit scheme on the {int(ok.sum())} of {runs.n} runs where no "
        f"step's set cycles and the engine flags nothing: largest relative difference of the peak force "
        f"{rel[ok, 0].max():.1e}, of the top displacements {rel[ok, 1:].max():.1e} (rounding: other algebra); "
        f"{int(cycled.sum())} runs have steps whose set cycles ({int(mini[:, 3].sum())} steps: the minimal kernel "
        f"takes the union set, the engine the event scheme's located step)"
    )
    if args.columns:
        names = column_names(n1, n1 + n2, P)
        _, ext = run_minimal(prep, runs, rec, args.threads, columns=True)
        eng_x = eng[:, [cols.index(c) for c in names]]
        touched = ok & (eng[:, [cols.index(f"contact_time_f{j}_s") for j in range(1, P + 1)]] > 0).all(axis=1)
        rel, differ = [], []
        for z, c in enumerate(names):
            a, b = ext[touched, z], eng_x[touched, z]
            if "_time_" in c and not c.startswith("contact_time"):  # an instant: equal, or a near tie of two steps
                differ.append(float(np.mean(a != b)) if a.size else 0.0)
                continue
            scale = b  # a force against its pair's peak force (the least force is near zero)
            if "force" in c:
                scale = eng_x[touched, names.index("peak_force_" + c.rsplit("_", 2)[1] + "_N")]
            rel.append(np.abs(a - b) / np.maximum(np.abs(scale), 1e-300))
        rel = np.array(rel)  # (value columns, runs)
        if touched.any():
            far = (rel > 1e-9).any(axis=0)
            near = f"{rel[:, ~far].max():.1e}" if (~far).any() else "-"
            print(
                f"minimal kernel with the columns against the engine on the {int(touched.sum())} of those runs where "
                f"every pair made contact: largest relative difference over the {len(rel)} value columns (forces "
                f"against the pair's peak force) {near} on {int((~far).sum())} runs; {int(far.sum())} runs differ by "
                f"more than 1e-9 (up to {rel.max():.1e}): a response that rounding changes over the run (the engine's "
                f"scalar kernel differs from its lane kernel there as much); a peak's time differs in at most "
                f"{max(differ):.1%} of runs in a column (a steady response peaks alike in every cycle, and rounding "
                f"picks the cycle)"
            )
    rows = {}
    for name, (p, r_, c_) in preps.items():
        m, _ = driver.run_chunk_lanes(p.sysarr, r_, c_, p.opts, args.threads)
        rows[name] = m
        uns = m[:, cols.index("unsettled_steps")]
        flagged = (m[:, cols.index("status_code")].astype(np.int64) & L.STATUS_UNSETTLED) != 0
        print(
            f"{name} scheme: {int(flagged.sum())} of {runs.n} runs flagged contact_unsettled; unsettled steps "
            f"per flagged run: mean {uns[flagged].mean() if flagged.any() else 0.0:.1f}, max {uns.max():.0f}"
        )
    scheme_difference(rows, cols, P, (n1, n2), cycled)
    if args.group_costs:
        group_costs(preps, steps, args.threads, args.rounds)
        return 0
    if args.interleave > 0:
        return interleaved(preps, steps, args)
    print(
        "\nround  kernel             wall [s]  M steps/s  CPU [s]  M steps/CPU s  x minimal (wall)"
        "  x minimal (CPU)   load"
    )
    ratios = {"event": [], "implicit": []}
    ratios_cpu = {"event": [], "implicit": []}
    kernels = ["minimal", "event", "implicit"] + (["columns"] if args.columns else [])
    against = {"event": [], "implicit": []}  # the engine's wall time over the columns kernel's
    for k in range(args.rounds):
        order = kernels if k % 2 == 0 else kernels[::-1]
        got = {}
        for name in order:
            got[name] = time_kernel(name, preps, args.threads)
        for name in kernels:
            w, c = got[name]
            x = got["minimal"][0] / w
            xc = got["minimal"][1] / c
            if name in ratios:
                ratios[name].append(x)
                ratios_cpu[name].append(xc)
                if args.columns:
                    against[name].append(got["columns"][0] / w)
            print(round_row(k, name, steps, w, c, got["minimal"]))
    for name, rs in ratios.items():
        rc = ratios_cpu[name]
        print(
            f"{name}: x minimal {min(rs):.2f} .. {max(rs):.2f} (wall), {min(rc):.2f} .. {max(rc):.2f} (CPU time)"
            f" over {len(rs)} rounds"
        )
    for name, rs in against.items():
        if rs:
            print(f"{name}: x minimal kernel with the columns {min(rs):.2f} .. {max(rs):.2f} (wall)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
