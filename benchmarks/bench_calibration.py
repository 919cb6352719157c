"""The calibration's global stage on a family of synthetic experiments that includes stiff contact, high
restitution and low noise: does every calibration end in the basin of the best fit (no local minimum left),
and how long does it take, before and after (another checkout's calibration on the same cases).

Family (--cases, default 30; case i of regime i % 3, scene (i // 3) % 3: the 6 Hz, 4.613 Hz and Duzce
(cut to --record-s seconds) tests):
- regime 0, the previous family's: k_s/k log-uniform in [0.5, 10], r uniform in [0.2, 0.8], 0.05 mm noise;
- regime 1, stiff contact and high r: k_s/k log-uniform in [8, 15], r uniform in [0.8, 0.95], 0.02 mm noise;
- regime 2, anything: k_s/k log-uniform in [0.5, 15], r uniform in [0.2, 0.95], 0.02 mm noise;
each building's story stiffness perturbed by up to +/-3 %, its damping ratio by up to +/-20 %, the table's
clock offset by up to +/-20 ms, tracking at 100 samples/s; the truth simulated by the implicit scheme at
dt = 2e-5 s (the fits use the event scheme at the scene's 1e-4 s: another discretisation, as a real test's is).
[calibrate] fits k_s/k, r, both stiffness scales, both damping ratios and the clock (7 parameters), noise floor
estimated from the data, global_points 32, starts 2, no profiles.

Local minimum: a calibration whose residual sum of squares exceeds the best one known for the case by more than
chi^2_1(0.95) = 3.84 times the residual variance there (inflated for correlation: calibrate.py's profile scale),
i.e. it stopped where the data exclude it while a better fit exists. The best known: the least of both
checkouts' answers and of a local fit started at the hidden values (the optimum in their basin). Every answer is
scored by this checkout's residual function (the same data, noise floors and model).

Printed per case: the hidden values, each checkout's misfit (residual / noise floor), k_s/k and r errors, its
residual against the hidden values' (delta chi^2), whether it is a local minimum, its time; then the counts and
the median and total times, and their ratio (cases run one after the other, the two checkouts alternating, so a
load that comes and goes falls on both; the other checkout's kernels compiled before the first timing).

Usage: python benchmarks/bench_calibration.py [--cases 30] [--threads 2] [--record-s 4]
       [--before DIR]   (DIR: a folder holding another version's pounding_sweep/, e.g. made by
                         `git archive 1d4c0af pounding_sweep | tar -x -C DIR`; run in a subprocess)
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import pickle
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from pounding_sweep.scene import load_scene
from pounding_sweep.scene.schema import CalibrateConfig, ExperimentConfig
from pounding_sweep.sweep.calibrate import CHI2_1_95, Problem, calibrate
from pounding_sweep.sweep.fitstats import gauss_newton, local_fit, misfit_of
from pounding_sweep.synthetic import make_experiment, write_experiment
from pounding_sweep.warn import collecting

SWEEPS = Path(__file__).resolve().parents[1] / "sweeps"
FIT = (
    "ks_ratio",
    "r",
    "stiffness_scale_b1",
    "stiffness_scale_b2",
    "damping_ratio_b1",
    "damping_ratio_b2",
    "time_offset_s",
)
REGIMES = {
    0: dict(ks=(0.5, 10.0), r=(0.2, 0.8), noise_mm=0.05),
    1: dict(ks=(8.0, 15.0), r=(0.8, 0.95), noise_mm=0.02),
    2: dict(ks=(0.5, 15.0), r=(0.2, 0.95), noise_mm=0.02),
}
RUNNER = r"""
import json, pickle, sys, time
from pounding_sweep.sweep.calibrate import calibrate
from pounding_sweep.warn import collecting
scene, threads = pickle.load(open(sys.argv[1], "rb")), int(sys.argv[2])
t0 = time.perf_counter()
with collecting():
    fit = calibrate(scene, threads=threads)[0]
print(json.dumps({"estimate": fit.estimate, "seconds": time.perf_counter() - t0, "evaluations": fit.evaluations}))
"""


def case_scene(kind: str, record_s: float):
    s = load_scene(SWEEPS / {"6hz": "paper_6hz.toml", "4.6hz": "paper_4613hz.toml", "duzce": "paper_duzce.toml"}[kind])
    if kind == "duzce":
        s = dataclasses.replace(s, excitation=dataclasses.replace(s.excitation, duration_s=record_s))
    return dataclasses.replace(s, sweep=())


def family_bounds(scene) -> dict:
    """The fitted parameters' bounds: k_s/k, r, each building's stiffness scale (+/-10 %) and damping ratio (x0.5 to
    x1.5 of the scene's), the clock (+/-50 ms)."""
    b1, b2 = scene.building1.damping_ratio, scene.building2.damping_ratio
    return {
        "ks_ratio": [0.1, 20.0],
        "r": [0.05, 1.0],
        "stiffness_scale_b1": [0.9, 1.1],
        "stiffness_scale_b2": [0.9, 1.1],
        "damping_ratio_b1": [0.5 * b1, 1.5 * b1],
        "damping_ratio_b2": [0.5 * b2, 1.5 * b2],
        "time_offset_s": [-0.05, 0.05],
    }


def make_case(i: int, rng, folder: Path, record_s: float) -> dict:
    regime = REGIMES[i % 3]
    kind = ("6hz", "4.6hz", "duzce")[(i // 3) % 3]
    scene = case_scene(kind, record_s)
    hidden = {
        "ks_ratio": float(np.exp(rng.uniform(*np.log(regime["ks"])))),
        "r": float(rng.uniform(*regime["r"])),
    }
    kf = tuple(float(x) for x in rng.uniform(0.97, 1.03, 2))
    zf = tuple(float(x) for x in rng.uniform(0.8, 1.2, 2))
    offset = float(rng.uniform(-0.02, 0.02))
    truth = dataclasses.replace(scene, integration=dataclasses.replace(scene.integration, scheme="implicit"))
    df, prov = make_experiment(
        truth,
        hidden,
        stiffness_factor=kf,
        damping_factor=zf,
        noise_mm=regime["noise_mm"],
        seed=1000 + i,
        time_offset_s=offset,
    )
    table = folder / f"case{i}.parquet"
    write_experiment(df, prov, table)
    b1, b2 = scene.building1.damping_ratio, scene.building2.damping_ratio
    bounds = family_bounds(scene)
    exp = ExperimentConfig(table=str(table), channels={"model1_floor3_mm": "b1f3", "model2_floor3_mm": "b2f3"})
    cal = CalibrateConfig(parameters=bounds, global_points=32, starts=2, profile_points=0)
    truth_theta = np.array([hidden["ks_ratio"], hidden["r"], kf[0], kf[1], b1 * zf[0], b2 * zf[1], offset])
    return dict(
        case=i,
        regime=i % 3,
        kind=kind,
        scene=dataclasses.replace(scene, experiment=exp, calibrate=cal),
        hidden=truth_theta,
        noise_mm=regime["noise_mm"],
    )


def judge(prob: Problem, thetas: dict[str, np.ndarray], hidden: np.ndarray, max_evals: int) -> dict:
    """Per answer its misfit and delta chi^2 above the best point known for the case (module docstring), by this
    checkout's residuals: the best of the answers and of a local fit started at the hidden values (the optimum in
    their basin: the hidden values themselves are not the fit's optimum, the truth having been made by another
    scheme at another dt)."""
    ref = local_fit(prob, prob.to_z(hidden), max_evals)
    cand = {**thetas, "hidden basin": prob.to_theta(ref.z)}
    r = prob.residuals(np.array(list(cand.values())))
    rss = {k: float(x @ x) for k, x in zip(cand, r)}
    best = min(rss, key=rss.get)
    zb = prob.to_z(cand[best])
    gn = gauss_newton(prob.jac(zb), r[list(cand).index(best)], prob.sizes(), len(prob.names))
    s2_eff = gn.s2 * r.shape[1] / gn.n_eff
    out = {}
    for k, rr in zip(cand, r):
        d = (rss[k] - rss[best]) / s2_eff
        out[k] = {"misfit": misfit_of(rr, prob.sizes()), "dchi2": d, "local": d > CHI2_1_95}
    return out


def run_before(scene, threads: int, before: Path, folder: Path) -> dict:
    path = folder / "scene.pickle"
    path.write_bytes(pickle.dumps(scene))
    env = dict(os.environ, PYTHONPATH=str(before))
    out = subprocess.run(
        [sys.executable, "-c", RUNNER, str(path), str(threads)],
        env=env,
        cwd=before,
        capture_output=True,
        text=True,
        check=True,
    )
    return json.loads(out.stdout.strip().splitlines()[-1])


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", type=int, default=30)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--record-s", type=float, default=4.0)
    ap.add_argument("--seed", type=int, default=2028)
    ap.add_argument("--before", type=Path, default=None)
    ap.add_argument("--json", type=Path, default=None, help="write the rows here")
    args = ap.parse_args(argv)
    rng = np.random.default_rng(args.seed)
    rows = []
    with tempfile.TemporaryDirectory() as d:
        folder = Path(d)
        if args.before is not None:  # compile (or load) the other checkout's kernels outside the timings
            warm = make_case(0, np.random.default_rng(0), folder, args.record_s)["scene"]
            warm = dataclasses.replace(warm, excitation=dataclasses.replace(warm.excitation, duration_s=0.5))
            run_before(
                dataclasses.replace(warm, calibrate=dataclasses.replace(warm.calibrate, global_points=2)),
                1,
                args.before,
                folder,
            )
        for i in range(args.cases):
            c = make_case(i, rng, folder, args.record_s)
            answers = {}
            order = ["after", "before"] if i % 2 == 0 else ["before", "after"]
            for which in order:
                if which == "before" and args.before is None:
                    continue
                if which == "after":
                    t0 = time.perf_counter()
                    with collecting():
                        fit = calibrate(c["scene"], threads=args.threads)[0]
                    answers["after"] = {"estimate": fit.estimate, "seconds": time.perf_counter() - t0}
                    answers["after"]["evaluations"] = fit.evaluations
                else:
                    answers["before"] = run_before(c["scene"], args.threads, args.before, folder)
            prob = Problem(c["scene"], list(FIT), c["scene"].calibrate.parameters, None, args.threads)
            thetas = {w: np.array([a["estimate"][n] for n in FIT]) for w, a in answers.items()}
            judged = judge(prob, thetas, c["hidden"], c["scene"].calibrate.max_evals)
            row = {"case": i, "regime": c["regime"], "kind": c["kind"], "hidden": c["hidden"].tolist()}
            text = []
            for which, a in answers.items():
                j = judged[which]
                theta = thetas[which]
                row[which] = {**a, **j, "ks_err": theta[0] / c["hidden"][0] - 1, "r_err": theta[1] / c["hidden"][1] - 1}
                text.append(
                    f"{which} misfit {j['misfit']:6.2f} ks {100 * row[which]['ks_err']:+7.2f} % r "
                    f"{100 * row[which]['r_err']:+7.2f} % dchi2 {j['dchi2']:9.1f}{' LOCAL' if j['local'] else '      '} "
                    f"{a['seconds']:5.1f} s {a['evaluations']:4d} runs"
                )
            text.append(f"hidden basin misfit {judged['hidden basin']['misfit']:6.2f}")
            h = c["hidden"]
            print(
                f"case {i:2d} {c['kind']:5s} regime {c['regime']} ks {h[0]:6.3f} r {h[1]:.3f} k x{h[2]:.3f}/x{h[3]:.3f} "
                f"noise {c['noise_mm']} mm | " + " | ".join(text),
                flush=True,
            )
            rows.append(row)
            if args.json is not None:
                args.json.write_text(json.dumps(rows, indent=1, default=float))
    print()
    for which in ("before", "after"):
        got = [r[which] for r in rows if which in r]
        if not got:
            continue
        t = np.array([g["seconds"] for g in got])
        within = sum(abs(g["ks_err"]) <= 0.1 and abs(g["r_err"]) <= 0.1 for g in got)
        print(
            f"{which}: local minima {sum(g['local'] for g in got)}/{len(got)}; k_s/k and r within 10 %: {within}/"
            f"{len(got)}; time median {np.median(t):.1f} s, total {t.sum():.0f} s (min {t.min():.1f}, max {t.max():.1f})"
        )
    both = [r for r in rows if "before" in r and "after" in r]
    if both:
        ratio = np.array([r["after"]["seconds"] / r["before"]["seconds"] for r in both])
        print(
            f"time after / before, per case: median {np.median(ratio):.2f} (range {ratio.min():.2f}-{ratio.max():.2f}); "
            f"totals {sum(r['after']['seconds'] for r in both) / sum(r['before']['seconds'] for r in both):.2f}"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
