"""Posterior samples of the 6 Hz calibration (sweep/posterior.py) beside its profile intervals, and their time.

The shipped scene sweeps/calibrate_6hz.toml against its SYNTHETIC experiment (hidden k_s/k 5, r 0.4, stiffness
x1.015 / x0.985, damping x1.05 / x0.95, 0.05 mm noise), calibrated over k_s/k, r and both stiffness scales
(profiles of k_s/k and r, 9 points), then sampled: the ensemble's walkers (4 per parameter) as one batch of runs
per half-step, --steps steps. Printed: the sampler's time and runs, acceptance, autocorrelation times and
effective sample count; per parameter the 95 % credible interval against the profile interval (k_s/k, r) and
the Gauss-Newton one, their endpoints' differences in Gauss-Newton standard errors beside the Monte Carlo error
of a 2.5 % quantile from that many effective samples. Writes the corner plot to --out.

Usage: python benchmarks/bench_posterior.py [--steps 150] [--threads 2] [--out posterior_corner.png]
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from pathlib import Path

from pounding_sweep.plots import posterior_corner_figure
from pounding_sweep.scene import load_scene
from pounding_sweep.sweep.calibrate import calibrate
from pounding_sweep.sweep.posterior import quantile_error, sample_posterior
from pounding_sweep.warn import collecting

SWEEPS = Path(__file__).resolve().parents[1] / "sweeps"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=150)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--out", type=Path, default=Path("posterior_corner.png"))
    args = ap.parse_args(argv)
    s = load_scene(SWEEPS / "calibrate_6hz.toml")
    params = {k: v for k, v in s.calibrate.parameters.items() if k in ("ks_ratio", "r") or k.startswith("stiffness")}
    s = dataclasses.replace(
        s, sweep=(), calibrate=dataclasses.replace(s.calibrate, parameters=params, profile_points=9, global_points=16)
    )
    t0 = time.perf_counter()
    with collecting():
        fit = calibrate(s, threads=args.threads)[0]
    print(f"calibration: {time.perf_counter() - t0:.1f} s, {fit.evaluations} runs, misfit {fit.misfit_ratio:.2f}")
    post = sample_posterior(fit, steps=args.steps, seed=1)
    print(
        f"posterior: {post.seconds:.1f} s, {post.runs} runs ({post.chain_z.shape[1]} walkers x {args.steps} steps), "
        f"acceptance {post.acceptance:.2f}, autocorrelation times {', '.join(f'{t:.1f}' for t in post.tau)} steps, "
        f"{post.samples.shape[0]} samples kept, ~{post.ess:.0f} effective"
    )
    qe = quantile_error(post.ess)
    print(f"Monte Carlo error of a 2.5 % quantile from {post.ess:.0f} effective samples: {qe:.2f} standard deviations")
    for n in post.names:
        a, b = post.intervals[n]
        ga, gb = fit.ci95[n]
        se = fit.std_error[n]
        ok, pa, pb = fit.identified.get(n, (None, float("nan"), float("nan")))
        ref = (pa, pb) if ok is not None else (ga, gb)
        what = "profile" if ok is not None else "Gauss-Newton"
        print(
            f"  {n:20s} {fit.estimate[n]:.5g}  credible [{a:.5g}, {b:.5g}]  {what} [{ref[0]:.5g}, {ref[1]:.5g}]  "
            f"Gauss-Newton [{ga:.5g}, {gb:.5g}]  endpoints differ by {(a - ref[0]) / se:+.2f} / {(b - ref[1]) / se:+.2f} "
            "standard errors"
        )
    fig = posterior_corner_figure(post, fit)
    fig.savefig(args.out, dpi=110)
    print(f"corner plot: {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
