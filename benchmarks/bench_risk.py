"""Probabilistic pounding at scale (issue 29): the oracles with large Monte Carlo samples, the fragility recovery,
throughput of contact-free runs against the ensemble size up to a million runs, the same study on Dask compared
bit for bit, and the shipped studies' tables.

    python benchmarks/bench_risk.py                      # everything (about 15-30 min on 2 shared cores)
    python benchmarks/bench_risk.py --only throughput --sizes 1000,10000
    python benchmarks/bench_risk.py --only oracles --oracle-runs 20000
    python benchmarks/bench_risk.py --only groups --rounds 3   # the study's metric groups against all

Runs go through run_scene (the lane kernel, Parquet parts) into --work (default a temporary folder, removed
afterwards). Timings are wall times on this machine with its load at the time (printed: the machine is shared),
compile times excluded (the kernels are compiled, or loaded from the cache, before the clock starts).
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import os
import shutil
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from pounding_sweep.engine import layout as L  # noqa: E402
from pounding_sweep.model.coupled import CoupledModel  # noqa: E402
from pounding_sweep.model.excitation import Excitation  # noqa: E402
from pounding_sweep.risk import oracle as O  # noqa: E402
from pounding_sweep.scene import load_scene  # noqa: E402
from pounding_sweep.sweep.prepare import prepare  # noqa: E402

SWEEPS = REPO / "sweeps"


def load() -> str:
    return "load average " + ", ".join(f"{x:.2f}" for x in os.getloadavg())


def stochastic(seeds: int, levels=None, duration=None, filt=None, envelope=True, histories=(), gap=None):
    """The shipped stochastic study's scene, resized (risk.study.resized); without levels every motion at its own
    S0 level (no scaling); with `gap`, a plain sweep scene at that gap (no contact period to resolve)."""
    from pounding_sweep.risk.study import resized

    s = load_scene(SWEEPS / "risk_stochastic.toml")
    s = resized(
        s if levels else dataclasses.replace(s, risk=None), seeds, levels or (1.0,), duration, filt, not envelope
    )
    if levels is None:
        s = dataclasses.replace(
            s,
            excitation=dataclasses.replace(s.excitation, intensity="none", scaling="factor"),
            sweep=tuple(a for a in s.sweep if a.name == "seed"),
            risk=None,
        )
    s = dataclasses.replace(s, output=dataclasses.replace(s.output, histories=histories))
    if gap is not None:
        s = dataclasses.replace(
            s,
            risk=None,
            contact=dataclasses.replace(s.contact, gap_m=gap),
            integration=dataclasses.replace(s.integration, min_steps_per_contact_period=0.0),
        )
    return s


# ------------------------------------------------------------------------------------------------- oracles


def section_oracles(n_hist: int, n_fp: int) -> None:
    print(f"\n== 1. Oracles: the paper's models at full scale, Kanai-Tajimi stationary, from rest ({load()})")
    scene = stochastic(n_hist, duration=10.0, filt="kanai_tajimi", envelope=False, gap=100.0,
                       histories=("disp_b1f1", "disp_b2f1", "disp_b1f3", "disp_b2f3", "vel_b1f1", "vel_b2f1",
                                  "vel_b1f3", "vel_b2f3"))  # fmt: skip
    prep = prepare(scene)
    t0 = time.perf_counter()
    _, _, hist, _, _ = prep.run(prep.grid.chunk(0, n_hist), 2)
    print(f"{n_hist} runs with histories (scalar kernel): {time.perf_counter() - t0:.1f} s")
    model = CoupledModel.from_scene(scene)
    motion = Excitation.from_scene(scene, scene.integration.dt_s).motion
    sys_ = O.linear_system(model, motion.ground)
    n = hist.shape[2] - 1
    t = np.arange(n + 1) * motion.dt_s
    vd, vv, cov = O.pair_moments(sys_, O.covariance_history(sys_, O.initial_covariance(sys_, motion.ground), t))
    disc = O.newmark_covariance_history(model, motion, n)
    sd, sv, _ = O.pair_moments(sys_, O.stationary_covariance(sys_))
    from scipy.stats import chi2

    print("variance of the relative displacement d and its rate v (pair j, time t): Monte Carlo / oracle")
    print(f"{'pair':>4} {'t [s]':>6} {'qty':>4} {'Lyapunov':>12} {'Newmark exact':>14} {'MC':>12} {'MC/exact':>9} "
          f"{'chi2 95 % band':>16}")  # fmt: skip
    band = chi2.ppf([0.025, 0.975], n_hist) / n_hist
    for k in (n // 2, n):
        for p, (i1, i2) in ((1, (0, 1)), (3, (2, 3))):
            for q, off, cont in (("d", 0, vd), ("v", 4, vv)):
                x = hist[:, i1 + off, k] - hist[:, i2 + off, k]
                mc = float((x * x).mean())
                ex = float(disc[k, p - 1, 0 if q == "d" else 1])
                print(f"{p:>4} {t[k]:>6.1f} {q:>4} {cont[k, p - 1]:>12.5g} {ex:>14.5g} {mc:>12.5g} {mc / ex:>9.4f} "
                      f"{band[0]:>7.4f}-{band[1]:.4f}")  # fmt: skip
    print(f"largest |Newmark exact - Lyapunov| / stationary variance: d {np.abs(disc[:, :, 0] - vd).max(0) / sd}, "
          f"v {np.abs(disc[:, :, 1] - vv).max(0) / sv}")  # fmt: skip
    print("\nup-crossings of b = r sigma_stationary by the top pair's d over 10 s: mean per run, Monte Carlo against "
          "Rice (nonstationary, integrated)")  # fmt: skip
    d = hist[:, 2, :] - hist[:, 3, :]
    for r in (1.0, 2.0, 3.0):
        b = r * math.sqrt(sd[2])
        c = ((d[:, :-1] <= b) & (d[:, 1:] > b)).sum(1)
        e = float(O.expected_upcrossings(t, O.upcrossing_rate(b, vd[:, 2], vv[:, 2], cov[:, 2])))
        se = c.std(ddof=1) / math.sqrt(n_hist)
        print(f"  r = {r}: MC {c.mean():.4f} +- {se:.4f} (1 s.e.; Poisson s.e. {math.sqrt(c.mean() / n_hist):.4f}), "
              f"Rice {e:.4f}, z = {(c.mean() - e) / se:+.2f}")  # fmt: skip
    print(
        f"\nprobability of pounding in 20 s at gap b = r sigma (closest approach, lane kernel, {n_fp} runs), "
        "95 % Clopper-Pearson"
    )
    scene = stochastic(n_fp, duration=20.0, filt="kanai_tajimi", envelope=False, gap=100.0)
    prep = prepare(scene)
    t0 = time.perf_counter()
    rows = []
    for a in range(0, n_fp, 4096):
        rows.append(prep.run(prep.grid.chunk(a, min(n_fp, a + 4096)), 2)[0])
    m = np.concatenate(rows)
    print(f"({time.perf_counter() - t0:.1f} s)")
    names = L.metric_columns(prep.model.floors, prep.model.n_pairs)
    n = int(round(20.0 / scene.integration.dt_s))
    t = np.arange(n + 1) * motion.dt_s
    vd, vv, cov = O.pair_moments(sys_, O.covariance_history(sys_, O.initial_covariance(sys_, motion.ground), t))
    from pounding_sweep.risk.probability import clopper_pearson

    print(f"{'pair':>4} {'delta':>6} {'r':>4} {'MC':>9} {'95 % CI':>19} {'Rice bound EN':>13} {'Poisson':>9} "
          f"{'Vanmarcke':>9} {'MC/Vanm.':>8}")  # fmt: skip
    for p in (1, 3):
        delta = O.bandwidth(O.spectral_moments(model, motion.ground, p - 1))
        req = 100.0 - m[:, names.index(f"closest_approach_f{p}_m")]
        for r in (2.0, 2.5, 3.0, 3.5, 4.0):
            b = r * math.sqrt(sd[p - 1])
            k = int((req > b).sum())
            lo, hi = clopper_pearson(k, n_fp)
            en = float(O.expected_upcrossings(t, O.upcrossing_rate(b, vd[:, p - 1], vv[:, p - 1], cov[:, p - 1])))
            pv = float(O.vanmarcke_first_passage(t, b, vd[:, p - 1], vv[:, p - 1], delta, cov[:, p - 1]))
            print(f"{p:>4} {delta:>6.3f} {r:>4} {k / n_fp:>9.5f} {float(lo):>9.5f}-{float(hi):.5f} {en:>13.5f} "
                  f"{O.poisson_first_passage(en):>9.5f} {pv:>9.5f} {k / n_fp / pv:>8.3f}")  # fmt: skip


# ------------------------------------------------------------------------------------------------- fragility


def section_fragility() -> None:
    from scipy.special import ndtr

    from pounding_sweep.risk.fragility import (
        bootstrap_multiplicities,
        fit_lognormal,
        percentile_interval,
        weighted_exceedance,
    )

    print("\n== 2. Fragility recovery: outcomes drawn from a known lognormal (median 0.5 g, beta 0.4)")
    theta, beta = 0.5, 0.4
    print(f"{'design':>34} {'median':>8} {'beta':>6} {'median 95 % (bootstrap)':>24} {'beta 95 %':>14}")
    for motions in (30, 100, 1000):
        rng = np.random.default_rng(motions)
        cap = theta * np.exp(beta * rng.standard_normal(motions))
        x = np.geomspace(0.1, 2.5, 12)
        demand = x[:, None] / cap[None, :]
        k = (demand > 1.0).sum(1)
        fit = fit_lognormal(x, k, np.full(x.size, motions))
        mult = bootstrap_multiplicities(motions, 1000, 1)
        kb = weighted_exceedance(demand, [1.0], mult)[:, :, 0]
        bf = fit_lognormal(np.broadcast_to(x, kb.shape), kb, np.full(kb.shape, float(motions)))
        ok = bf.status == "ok"
        tl, th = percentile_interval(np.where(ok, bf.theta, np.nan))
        bl, bh = percentile_interval(np.where(ok, bf.beta, np.nan))
        print(f"{f'IDA, {motions} motions x 12 levels':>34} {float(fit.theta):>8.4f} {float(fit.beta):>6.3f} "
              f"{tl:>11.4f}-{th:.4f} {bl:>7.3f}-{bh:.3f}")  # fmt: skip
    rng = np.random.default_rng(7)
    x = np.exp(rng.uniform(math.log(0.1), math.log(2.5), 3000))
    y = (rng.uniform(size=x.size) < ndtr(np.log(x / theta) / beta)).astype(float)
    fit = fit_lognormal(x, y, np.ones_like(x))
    print(f"{'cloud, 3000 motions':>34} {float(fit.theta):>8.4f} {float(fit.beta):>6.3f}")
    print(
        "coverage of the bootstrap interval of the median over 400 IDA studies of 60 motions (300 resamples):", end=" "
    )
    covered = 0
    for rep in range(400):
        cap = theta * np.exp(beta * rng.standard_normal(60))
        x = np.geomspace(0.1, 2.5, 14)
        mult = bootstrap_multiplicities(60, 300, rep)
        kb = weighted_exceedance(x[:, None] / cap[None, :], [1.0], mult)[:, :, 0]
        bf = fit_lognormal(np.broadcast_to(x, kb.shape), kb, np.full(kb.shape, 60.0))
        lo, hi = percentile_interval(np.where(bf.status == "ok", bf.theta, np.nan))
        covered += bool(lo <= theta <= hi)
    print(f"{covered / 400:.3f} (nominal 0.95)")


# ------------------------------------------------------------------------------------------------- throughput


def table_frame(folder: Path):
    import pandas as pd

    return pd.read_parquet(folder).drop(columns=["run_time_s"]).sort_values("run_id").reset_index(drop=True)


def compare_datasets(a: Path, b: Path) -> tuple[int, int]:
    """(parts, differing parts): part by part, every column but run_time_s, bit for bit."""
    import pyarrow.parquet as pq

    from pounding_sweep.sweep.results import part_files

    pa_, pb = part_files(a), part_files(b)
    assert [p.name for p in pa_] == [p.name for p in pb]
    differ = 0
    for x, y in zip(pa_, pb):
        tx, ty = pq.read_table(x).drop(["run_time_s"]), pq.read_table(y).drop(["run_time_s"])
        differ += not tx.equals(ty)
    return len(pa_), differ


def section_throughput(sizes, work: Path, dask: bool) -> None:
    from pounding_sweep.risk.study import free_scene
    from pounding_sweep.sweep.run import run_scene

    levels = (0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.8, 1.0, 1.2, 1.5)
    print(f"\n== 3. Contact-free runs of the stochastic study (Clough-Penzien, enveloped, 25 s at dt 0.005 s = 5000 "
          f"steps; {len(levels)} Sa levels per motion) through run_scene on the lane kernel, 2 threads")  # fmt: skip
    print(f"{'runs':>9} {'motions':>8} {'wall [s]':>9} {'runs/s':>9} {'M steps/s':>10} {'generation [s]':>15} "
          f"{'kernel core-s':>13}  load before / after")  # fmt: skip
    warm = free_scene(_risk_scene(10, levels, work / "warm"))
    run_scene(warm, threads=2, overwrite=True)  # compile or load the kernel, the generator, pyarrow
    last = None
    for size in sizes:
        motions = max(1, size // len(levels))
        scene = free_scene(_risk_scene(motions, levels, work / f"n{size}"))
        before = load()
        gen = _generation_time(scene, min(motions, 200))
        t0 = time.perf_counter()
        s = run_scene(scene, threads=2, overwrite=True, confirmed=True)
        wall = time.perf_counter() - t0
        print(f"{s.runs:>9,} {motions:>8,} {wall:>9.1f} {s.runs / wall:>9.0f} {s.steps / wall / 1e6:>10.1f} "
              f"{gen * motions:>15.1f} {s.kernel_s:>13.1f}  {before} / {load()}")  # fmt: skip
        last = (scene, s)
    if dask and last is not None:
        from pounding_sweep.sweep.executors import DaskExecutor

        scene, s = last
        dscene = dataclasses.replace(scene, output=dataclasses.replace(scene.output, path=str(work / "dask.parquet")))
        ex = DaskExecutor(workers=2)
        try:
            t0 = time.perf_counter()
            d = run_scene(dscene, executor=ex, overwrite=True, confirmed=True)
            wall = time.perf_counter() - t0
        finally:
            ex.close()
        parts, differ = compare_datasets(Path(scene.output.path), Path(dscene.output.path))
        print(f"\nDask LocalCluster (2 worker processes, 1 thread each): {d.runs:,} runs in {wall:.1f} s "
              f"({d.runs / wall:.0f} runs/s); identity with the local run: {parts} parts compared, {differ} differing "
              f"(every column but run_time_s, bit for bit) ({load()})")  # fmt: skip


def _risk_scene(motions: int, levels, folder: Path):
    s = stochastic(motions, levels=levels)
    chunk = 100 * len(levels)
    return dataclasses.replace(
        s,
        risk=dataclasses.replace(s.risk, path=str(folder)),
        execution=dataclasses.replace(s.execution, chunk_runs=chunk, max_runs=10_000_000),
    )


def _generation_time(scene, motions: int) -> float:
    """Seconds per motion to generate and measure (Sa) a chunk's realisations on 2 threads."""
    exc = Excitation.from_scene(scene, scene.integration.dt_s)
    seeds = np.arange(motions, dtype=float)
    params = {"seed": seeds, "scale": np.full(motions, 0.4), "run_id": np.arange(motions)}
    t0 = time.perf_counter()
    exc.chunk_inputs(params, 2)
    return (time.perf_counter() - t0) / motions


# ------------------------------------------------------------------------------------------------- metric groups


def section_groups(work: Path, rounds: int, motions: int, scheme: str | None = None) -> None:
    """The shipped stochastic study's runs (contact-free and contact) computing only the metric groups the study
    reads (its default: sweep/metricgroups.py) against every group ([output] metrics = 'all', what every sweep
    computed before the key), in turn, `rounds` times; CPU seconds of the whole process over each sweep
    (time.process_time: every thread's), and the ratios within each round; `scheme`: another integration scheme."""
    from pounding_sweep.risk.study import contact_scene, free_scene, resized
    from pounding_sweep.sweep.run import run_scene

    base = load_scene(SWEEPS / "risk_stochastic.toml")
    if motions:
        base = resized(base, motions)
    if scheme:
        base = dataclasses.replace(base, integration=dataclasses.replace(base.integration, scheme=scheme))
    print(f"\n== 5. Metric groups: the stochastic study ({len(base.axis_values('seed'))} motions) computing what it "
          f"reads against every group, {base.integration.scheme} scheme, CPU seconds of this process, 2 threads "
          f"({load()})")  # fmt: skip
    variants = {}
    for name, metrics in (("study's", None), ("all", ("all",))):
        s = dataclasses.replace(
            base,
            output=dataclasses.replace(base.output, metrics=metrics),
            risk=dataclasses.replace(base.risk, path=str(work / f"groups_{name}")),
            execution=dataclasses.replace(base.execution, max_runs=10_000_000),
        )
        variants[name] = {"free": free_scene(s), "contact": contact_scene(s)}
    for kind, sub in variants["study's"].items():
        print(f"  {kind} runs: {sub.output.metrics} against {variants['all'][kind].output.metrics}")
    warm = run_scene(variants["all"]["free"], threads=2, overwrite=True, confirmed=True)  # compile or load
    print(f"  (warm-up: {warm.runs:,} runs)")
    print(f"{'round':>5} {'kind':>8} {'runs':>6} {'CPU s, study':>13} {'CPU s, all':>11} {'ratio':>7} "
          f"{'kernel wall-s ratio':>20}")  # fmt: skip
    lean = "study's"
    ratios: dict = {"free": [], "contact": []}
    for r in range(rounds):
        for kind in ("free", "contact"):
            cpu, kern = {}, {}
            for name in (lean, "all") if r % 2 == 0 else ("all", lean):  # alternate which goes first
                scene = variants[name][kind]
                shutil.rmtree(scene.output.path, ignore_errors=True)
                t0 = time.process_time()
                summary = run_scene(scene, threads=2, overwrite=True, confirmed=True)
                cpu[name], kern[name] = time.process_time() - t0, summary.kernel_s
            ratios[kind].append(cpu[lean] / cpu["all"])
            print(f"{r + 1:>5} {kind:>8} {summary.runs:>6,} {cpu[lean]:>13.2f} {cpu['all']:>11.2f} "
                  f"{cpu[lean] / cpu['all']:>7.3f} {kern[lean] / kern['all']:>20.3f}")  # fmt: skip
    _median_ratios(ratios)
    print(f"({load()})")
    _groups_kernel_alone(variants, rounds)


def _groups_kernel_alone(variants: dict, rounds: int) -> None:
    """The lane kernel alone on the same inputs (the motions generated once, before the clock), the study's groups
    against every group, in turn: CPU seconds of this process (2 threads) per call, and their ratio."""
    from pounding_sweep.engine.driver import run_chunk
    from pounding_sweep.sweep.metricgroups import sweep_groups

    print("\nthe lane kernel alone (same inputs; motions generated before the clock), CPU s per call")
    print(f"{'round':>5} {'kind':>8} {'runs':>6} {'CPU s, study':>13} {'CPU s, all':>11} {'ratio':>7}")
    inputs = {}
    for kind, scene in variants["study's"].items():
        prep = prepare(scene)
        n = min(prep.grid.size, 4400)
        runs, rec, _ = prep.kernel_inputs(prep.grid.chunk(0, n), 2)
        inputs[kind] = (prep, runs, rec, {"study's": sweep_groups(scene), "all": L.GROUPS_ALL})
    ratios: dict = {kind: [] for kind in inputs}
    for r in range(rounds):
        for kind, (prep, runs, rec, masks) in inputs.items():
            cpu = {}
            for name in ("study's", "all") if r % 2 == 0 else ("all", "study's"):
                opts = prep.opts._replace(groups=masks[name])
                t0 = time.process_time()
                run_chunk(prep.sysarr, runs, rec, prep.hist, opts, 2, 0, prep.score, prep.kernel)
                cpu[name] = time.process_time() - t0
            lean, full = cpu["study's"], cpu["all"]
            ratios[kind].append(lean / full)
            print(f"{r + 1:>5} {kind:>8} {runs.n:>6,} {lean:>13.3f} {full:>11.3f} {lean / full:>7.3f}")
    _median_ratios(ratios)
    print(f"({load()})")


def _median_ratios(ratios: dict) -> None:
    """The CPU-time ratios' median and range per kind of run (each ratio from one round: the same load)."""
    for kind, r in ratios.items():
        print(f"  {kind}: ratio median {np.median(r):.3f} (range {min(r):.3f}-{max(r):.3f}, {len(r)} rounds)")


# ------------------------------------------------------------------------------------------------- shipped


def section_shipped(work: Path) -> None:
    from pounding_sweep.risk.study import risk_study, write_study

    print(f"\n== 4. The shipped studies ({load()})")
    for name in ("risk_records", "risk_stochastic"):
        s = load_scene(SWEEPS / f"{name}.toml")
        s = dataclasses.replace(s, risk=dataclasses.replace(s.risk, path=str(work / f"{name}.risk")))
        t0 = time.perf_counter()
        st = risk_study(s, threads=2, overwrite=True)
        write_study(st)
        print(f"\n{name}: {time.perf_counter() - t0:.1f} s; {st.facts['ensemble']['motions']} motions x "
              f"{len(st.facts['ensemble']['levels'])} levels; periods {st.facts['periods_s'][0]:.3f} / "
              f"{st.facts['periods_s'][1]:.3f} s; Sa at T* = {st.facts['intensity']['period_s']:.3f} s")  # fmt: skip
        req = st.required_gap
        rules = st.code_rules
        for x in sorted(set(req.intensity_g)):
            print(f"  Sa(T*) = {x:g} g:")
            for r in req[req.intensity_g == x].itertuples():
                print(f"    required gap for P = {r.target_probability:g}: lognormal {r.lognormal_gap_m * 1e3:.0f} mm "
                      f"(95 % {r.lognormal_ci_low_m * 1e3:.0f}-{r.lognormal_ci_high_m * 1e3:.0f}); order statistics "
                      f"{r.empirical_gap_m * 1e3:.0f} mm ({r.empirical_ci_low_m * 1e3:.0f}-"
                      f"{r.empirical_ci_high_m * 1e3:.0f})")  # fmt: skip
            for r in rules[rules.intensity_g == x].itertuples():
                print(f"    {r.rule:<13} gap {r.gap_m * 1e3:6.0f} mm leaves P = {r.probability:.3f} "
                      f"(95 % {r.ci_low:.3f}-{r.ci_high:.3f}; {r.pounding}/{r.motions}); lognormal "
                      f"{r.lognormal_probability:.3f}")  # fmt: skip


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--only", choices=["oracles", "fragility", "throughput", "groups", "shipped"], action="append")
    p.add_argument("--rounds", type=int, default=3, help="rounds of the metric groups' comparison")
    p.add_argument("--motions", type=int, default=0, help="motions of the groups' comparison (0: the shipped 1000)")
    p.add_argument("--scheme", help="integration scheme of the groups' comparison (default: the study's)")
    p.add_argument("--sizes", default="1000,10000,100000,1000000", help="ensemble sizes in runs")
    p.add_argument("--oracle-runs", type=int, default=20000, help="runs of the first-passage comparison")
    p.add_argument("--history-runs", type=int, default=4000, help="runs with histories (variance, crossings)")
    p.add_argument("--no-dask", action="store_true")
    p.add_argument("--work", help="folder for the runs (default: a temporary one, removed afterwards)")
    args = p.parse_args()
    only = set(args.only or ["oracles", "fragility", "throughput", "groups", "shipped"])
    work = Path(args.work) if args.work else Path(tempfile.mkdtemp(prefix="bench_risk_"))
    print(f"bench_risk: {os.cpu_count()} cores, {load()}, work folder {work}")
    try:
        if "oracles" in only:
            section_oracles(args.history_runs, args.oracle_runs)
        if "fragility" in only:
            section_fragility()
        if "throughput" in only:
            section_throughput([int(float(x)) for x in args.sizes.split(",")], work, not args.no_dask)
        if "groups" in only:
            section_groups(work, args.rounds, args.motions, args.scheme)
        if "shipped" in only:
            section_shipped(work)
    finally:
        if not args.work:
            shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
