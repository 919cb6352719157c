"""Do accelerometers narrow the contact parameters once the sensor is modelled? Calibrations of synthetic tests
whose accelerations went through a stated sensor filter, fitted on displacement alone, on displacement and
acceleration with the sensor modelled ([experiment] sensor_filter: sweep/sensor.py), and on both without it
(the model's acceleration sampled at the table's instants: the calibration before issue 28's item 1).

Family (--cases, --seed): the 6 Hz and 4.613 Hz harmonic tests, 4 s, made by the continuous-time reference
(solve_ivp with contact events, classic Kelvin-Voigt law: pounding_sweep.synthetic.make_ivp_experiment, no
discretisation shared with the kernels) at a 1 ms output step, hidden k_s/k log-uniform in [1, 10] and r uniform
in [0.4, 0.8], each building's stiffness perturbed by up to +/-2 %; 0.05 mm tracking noise at 100 samples/s and
top-floor accelerometers with 0.02 m/s^2 noise whose filter alternates between cases: a moving average of 10
samples at 1 kHz (a MEMS decimation filter) and a 2-pole Butterworth at 44 Hz run at 1 kHz (the MPU-6050's
44 Hz digital low-pass setting, its form assumed). Each fit: k_s/k, r and both stiffness scales; the noise given
as made ([experiment] noise, as a quiet window would measure it); the Gauss-Newton 95 % intervals (inflated for
the residuals' correlation: sweep/calibrate.py).

Printed per case and fit: estimate, 95 % interval and its width for k_s/k and r, whether it covers the truth,
misfit (residual RMS / noise floor), runs and seconds; then per fit the coverage, the median width against the
displacement-only fit's and the median |error| / half-width (bias in interval units), and the run times.

The step: --dt-s 2.5e-5 for the figures in docs/how-to/calibrate.md. At the scenes' 1e-4 s the kernel's own
error in the 10 ms-averaged top-floor acceleration of such a test is 0.08-0.31 m/s^2 RMS against the
continuous-time reference (0.005-0.019 at 2.5e-5 s: second order), 4-16 times the accelerometers' 0.02 m/s^2
noise, so a fit could not reach that noise floor for numerical reasons alone.

--sweep-cost: instead, what the sensor costs a sweep: one batch of runs (a k_s/k ladder on the 6 Hz scene, 4 s,
the scene's dt) scored against an accelerometer table with and without sensor_filter, best of 3, per run, and
the step history it holds per run.

--step-error CASE: instead, the model's own error at the hidden values of that case (its sensor-read accelerations
and its displacements against the noise-free reference's) at dt = 1e-4, 5e-5 and 2.5e-5 s.

Usage: python benchmarks/bench_sensor.py [--cases 4] [--threads 2] [--seed 7] [--dt-s 2.5e-5] [--sweep-cost]
       [--step-error CASE]
(about 1-2 min per case on 2 busy cores at the scenes' dt, 4 times that at 2.5e-5 s)
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from bench_lawcompare import ACC, DISP, SWEEPS, harmonic_case

from pounding_sweep.scene import load_scene
from pounding_sweep.scene.schema import CalibrateConfig, ExperimentConfig
from pounding_sweep.sweep.calibrate import calibrate
from pounding_sweep.synthetic import make_ivp_experiment, write_experiment
from pounding_sweep.warn import collecting

NOISE_MM, ACC_NOISE = 0.05, 0.02
SENSORS = (
    ("average", None, {"sensor_filter": "average", "sensor_rate_Hz": 1000.0}),
    (
        "butter 2 poles 44 Hz",
        (2, 44.0),
        {"sensor_filter": "butter", "sensor_rate_Hz": 1000.0, "sensor_cutoff_Hz": 44.0},
    ),
)
FITS = ("displacement", "with sensor", "without sensor")
SHOWN = ("ks_ratio", "r")


def make_case(i: int, rng, folder: Path, duration_s: float, dt_s: float | None = None) -> dict:
    kind = ("6hz", "4.6hz")[i % 2]
    label, butter, keys = SENSORS[(i // 2) % 2]
    scene, hidden, kf = harmonic_case(kind, rng, duration_s, dt_s)
    df, prov = make_ivp_experiment(
        scene,
        {**hidden, "law": "classic"},
        stiffness_factor=kf,
        seed=200 + i,
        noise_mm=NOISE_MM,
        acc_noise_m_s2=ACC_NOISE,
        sensor_butter=butter,
    )
    table = folder / f"sensor{i}.parquet"
    write_experiment(df, prov, table)
    return dict(case=i, kind=kind, sensor=label, keys=keys, scene=scene, table=table, kf=kf, truth=hidden)


def fit_case(c: dict, how: str, threads: int):
    noise = {"model1_floor3_mm": NOISE_MM, "model2_floor3_mm": NOISE_MM, "b1f3_acc": ACC_NOISE, "b2f3_acc": ACC_NOISE}
    if how == "displacement":
        exp = ExperimentConfig(table=str(c["table"]), channels=DISP, noise={k: noise[k] for k in DISP})
    else:
        keys = c["keys"] if how == "with sensor" else {}
        exp = ExperimentConfig(
            table=str(c["table"]), channels={**DISP, **ACC}, use="both", weights="noise", noise=noise, **keys
        )
    params = {"ks_ratio": [0.5, 20.0], "r": [0.05, 0.99]} | {f"stiffness_scale_b{b}": [0.9, 1.1] for b in (1, 2)}
    scene = dataclasses.replace(
        c["scene"],
        experiment=exp,
        calibrate=CalibrateConfig(parameters=params, global_points=16, starts=2, profile_points=0),
    )
    t0 = time.perf_counter()
    with collecting():
        fit = calibrate(scene, threads=threads)[0]
    return fit, time.perf_counter() - t0


def sweep_cost(threads: int, runs: int = 32) -> None:
    """Seconds per run of one batch scored with and without the sensor (module docstring)."""
    from pounding_sweep.sweep.prepare import prepare

    scene = load_scene(SWEEPS / "paper_6hz.toml")
    scene = dataclasses.replace(scene, sweep=(), excitation=dataclasses.replace(scene.excitation, duration_s=4.0))
    with tempfile.TemporaryDirectory() as d:
        df, prov = make_ivp_experiment(scene, {"ks_ratio": 3.0, "r": 0.5, "law": "classic"}, acc_noise_m_s2=ACC_NOISE)
        table = Path(d) / "cost.parquet"
        write_experiment(df, prov, table)
        preps = {}
        for name, keys in (("plain", {}), ("sensor", SENSORS[0][2])):
            exp = ExperimentConfig(table=str(table), channels={**DISP, **ACC}, use="both", **keys)
            preps[name] = prepare(dataclasses.replace(scene, experiment=exp))
        base = preps["plain"].grid.chunk(0, 1)
        params = {k: np.repeat(v, runs) for k, v in base.items()}
        params["run_id"] = np.arange(runs)
        params["ks_ratio"] = np.linspace(1.0, 10.0, runs)
        params["ks_N_per_m"] = np.full(runs, np.nan)
        best = {}
        for prep in preps.values():
            prep.run({k: v[:1] for k, v in params.items()}, threads)  # compile outside the timing
        for _ in range(3):
            for name, prep in preps.items():
                t0 = time.perf_counter()
                prep.run(params, threads)
                best[name] = min(best.get(name, np.inf), time.perf_counter() - t0)
        steps = int(round(4.0 / preps["plain"].dt)) + 1
    print(f"sweep cost: {runs} runs of 4 s at dt {preps['plain'].dt:g} s, {threads} thread(s), best of 3")
    for name, secs in best.items():
        print(f"  {name:7s} {secs / runs * 1e3:8.2f} ms per run")
    print(
        f"  ratio sensor / plain {best['sensor'] / best['plain']:.2f}; step history held: {2 * steps * 8 / 1e3:.0f} kB "
        f"per run (2 acceleration channels x {steps} steps x 8 bytes)"
    )


def step_error(case: int, seed: int, duration_s: float, steps=(1e-4, 5e-5, 2.5e-5)) -> None:
    """The model's own error at the hidden values of family case `case`: its accelerations through the stated sensor
    (and its displacements) against the noise-free reference's, per simulation step."""
    from pounding_sweep.sweep.sensor import Sensor
    from pounding_sweep.sweep.simulate import simulate

    rng = np.random.default_rng(seed)
    for i in range(case + 1):
        kind = ("6hz", "4.6hz")[i % 2]
        label, butter, keys = SENSORS[(i // 2) % 2]
        scene, hidden, kf = harmonic_case(kind, rng, duration_s)
    df, _ = make_ivp_experiment(
        scene, {**hidden, "law": "classic"}, stiffness_factor=kf, noise_mm=0.0, acc_noise_m_s2=0.0, sensor_butter=butter
    )
    sensor = Sensor("average", 1000.0, 10) if butter is None else Sensor("butter", 1000.0, 1, butter[1], butter[0])
    t = df.t_s.to_numpy()
    print(f"case {case}: {kind}, {duration_s:g} s, sensor {label}, k_s/k {hidden['ks_ratio']:.4f}, r {hidden['r']:.4f}")
    for dt in steps:
        h, _ = simulate(
            scene,
            channels=["abs_acc_b1f3", "abs_acc_b2f3", "disp_b1f3", "disp_b2f3"],
            dt_s=dt,
            stiffness_scale_b1=kf[0],
            stiffness_scale_b2=kf[1],
            **hidden,
        )
        cells = []
        for b in (1, 2):
            e = sensor.read(h[f"abs_acc_b{b}f3_m_s2"].to_numpy(), dt, t) - df[f"b{b}f3_acc"].to_numpy()
            u = np.interp(t, h.t_s, h[f"disp_b{b}f3_m"]) * 1e3 - df[f"model{b}_floor3_mm"].to_numpy()
            cells.append(
                f"b{b}f3 acceleration {np.sqrt(np.mean(e * e)):.4f} m/s^2, displacement {np.sqrt(np.mean(u * u)):.4f} mm"
            )
        print(f"  dt {dt:g} s: RMS error " + "; ".join(cells), flush=True)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", type=int, default=4)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--duration-s", type=float, default=4.0)
    ap.add_argument("--fits", default=",".join(FITS), help=f"which fits, of {','.join(FITS)}")
    ap.add_argument("--from-case", type=int, default=0, help="draw but skip the cases before this one")
    ap.add_argument("--dt-s", type=float, default=None, help="the calibrations' step (default: the scenes', 1e-4 s)")
    ap.add_argument("--seed", type=int, default=7)
    ap.add_argument("--sweep-cost", action="store_true", help="time a sweep's batch with and without the sensor")
    ap.add_argument("--step-error", type=int, default=None, metavar="CASE", help="the model's error per step, CASE")
    args = ap.parse_args(argv)
    if args.step_error is not None:
        step_error(args.step_error, args.seed, args.duration_s)
        return 0
    if args.sweep_cost:
        sweep_cost(args.threads)
        return 0
    rng = np.random.default_rng(args.seed)
    rows = []
    with tempfile.TemporaryDirectory() as d:
        for i in range(args.cases):
            c = make_case(i, rng, Path(d), args.duration_s, args.dt_s)
            if i < args.from_case:
                continue
            tr = c["truth"]
            print(
                f"\ncase {i}: {c['kind']}, sensor {c['sensor']}; truth k_s/k {tr['ks_ratio']:.4f}, r {tr['r']:.4f}, "
                f"stiffness x{c['kf'][0]:.4f}/x{c['kf'][1]:.4f}",
                flush=True,
            )
            for how in args.fits.split(","):
                fit, secs = fit_case(c, how, args.threads)
                parts = []
                row = {"case": i, "fit": how, "misfit": fit.misfit_ratio, "seconds": secs, "runs": fit.evaluations}
                for n in SHOWN:
                    lo, hi = fit.ci95[n]
                    est, true = fit.estimate[n], tr[n]
                    row[n] = {"width": hi - lo, "covers": lo <= true <= hi, "bias": abs(est - true) / ((hi - lo) / 2)}
                    parts.append(
                        f"{n} {est:.4f} [{lo:.4f}, {hi:.4f}] width {hi - lo:.4f} "
                        f"{'covers' if lo <= true <= hi else 'MISSES'} (|error| {abs(est - true) / true * 100:.2f} %)"
                    )
                    if fit.quote == "model_error":  # the misfit called for the interval with the model's error
                        ma, mb = fit.ci95_model[n]
                        row[n]["covers_quoted"] = ma <= true <= mb
                        parts.append(
                            f"quoted (model error) [{ma:.4f}, {mb:.4f}] {'covers' if ma <= true <= mb else 'MISSES'}"
                        )
                rows.append(row)
                print(
                    f"  {how:15s} misfit {fit.misfit_ratio:7.2f}  {'  '.join(parts)}  {fit.evaluations} runs {secs:.1f} s",
                    flush=True,
                )
    print("\nsummary (Gauss-Newton 95 % intervals; width ratio against the displacement-only fit of the same case)")
    base = {r["case"]: r for r in rows if r["fit"] == "displacement"}
    for how in args.fits.split(","):
        sel = [r for r in rows if r["fit"] == how]
        cells = []
        for n in SHOWN:
            cover = sum(r[n]["covers"] for r in sel)
            quoted = sum(r[n].get("covers_quoted", r[n]["covers"]) for r in sel)
            ratio = np.median([r[n]["width"] / base[r["case"]][n]["width"] for r in sel]) if base else np.nan
            bias = np.median([r[n]["bias"] for r in sel])
            cells.append(
                f"{n}: covers {cover}/{len(sel)} (the quoted interval {quoted}), width x{ratio:.2f} (median), |error|/half-width {bias:.2f} (median)"
            )
        secs = [r["seconds"] for r in sel]
        print(
            f"  {how:15s} {'; '.join(cells)}; misfit {min(r['misfit'] for r in sel):.2f}-"
            f"{max(r['misfit'] for r in sel):.2f}; time median {np.median(secs):.1f} s, total {sum(secs):.0f} s, "
            f"runs median {np.median([r['runs'] for r in sel]):.0f}"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
