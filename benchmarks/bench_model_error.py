"""Model-error intervals (sweep/uncertainty.py) against what fits of separate windows of the same record give,
on synthetic data with a known model error and on the real IMU shake-table tests in ../shared.

Cases:
- softening: the Duzce record (1/15, 12 s) on the separated buildings, made by reference/softening.py with
  story springs f = k s tanh(drift / s), s = 10 mm (the equivalent stiffness falls by about 6 % at the strong
  motion's 5 mm drifts, 0.3 % at the free vibration's 1 mm), 0.05 mm white tracking noise on every floor (one
  draw per --seeds); the linear frame fitted (both stiffness scales and damping ratios).
- per-story: the 6 Hz pounding test (5 s) made by the continuous-time reference with each building's three story
  stiffnesses x(1.08, 1.0, 0.92) and x(0.92, 1.0, 1.08) where the model scales all stories alike; k_s/k, r and
  both stiffness scales fitted to the top floors.
- real (skipped when ../shared is absent): the stiff 3-story IMU tests of ../shared/data/imu_shake_table (one
  Xsens DOT per floor and on the table, about 120 samples/s; loaded by the private reader below: the shaking
  axis X, each channel's mean removed, floors aligned to the table by cross-correlation where the sensors'
  clocks are not shared, a floor's sign flipped when it moves against the table below the first mode). One
  building, its twin placed 1 m away, the three floors' absolute acceleration fitted with the table's
  acceleration as the ground motion: stiffness scale, damping ratio, clock offset; each sensor's noise measured
  in the first 1.5 s, before the shaking ([experiment] noise_window_s).

Per case: the whole record fitted; then the windows fitted alone ([experiment] window_s, the same bounds and
noise; where a refit of the window from the whole record's optimum ends lower, that one: a window's calibration
can stop in a local minimum of a parameter the window hardly sees, as building 2's stiffness in the softening
case's free vibration, 0.3 mm of motion): for the real tests the strong motion (the 5 s of the largest response) and the small amplitude (the 5 s
of the least response among those that still move at 5 % of it); for softening the strong motion (1-6 s) and
the free vibration (7-12 s); for per-story the start-up (first 1.5 s) and the steady state (last 2.5 s).
Printed per parameter: the whole-record estimate, its noise-based and model-error 95 % intervals, the window
fits, whether each interval covers every window fit that identifies the parameter (its own 95 % half-width at
most a quarter of the bounds' range, the split's rule), and whether the model error moves the parameter (the two
window values differ by more than 4 of their combined noise standard errors: each one's Gauss-Newton standard
error divided by its misfit ratio, the model-error part of the residual being the same in every noise draw).

Usage: python benchmarks/bench_model_error.py [--cases softening,per-story,northridge,bonus_event,sine_1.0,sine_2.0]
       [--threads 2] [--seeds 1]   (softening about 1.5 min a seed, per-story about 1 min, each real test 1-4 min
       on 2 busy cores)
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from pounding_sweep.scene import load_scene
from pounding_sweep.scene.parameters import is_log
from pounding_sweep.scene.schema import CalibrateConfig, ExperimentConfig
from pounding_sweep.sweep.calibrate import calibrate
from pounding_sweep.sweep.uncertainty import better_window_fit, identifies
from pounding_sweep.synthetic import make_ivp_experiment, write_experiment
from pounding_sweep.warn import collecting

REPO = Path(__file__).resolve().parents[1]
SWEEPS = REPO / "sweeps"
IMU = REPO.parent / "shared" / "data" / "imu_shake_table" / "stiff_3story"
REAL = ("northridge", "bonus_event", "sine_1.0", "sine_2.0")


# ----------------------------------------------------------------------------- the private IMU reader


def read_xsens(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """An Xsens DOT export: (device time [s] from SampleTimeFine in microseconds, the 32-bit counter unwrapped;
    Acc_X [m/s^2]); the header lines skipped, an all-zero first row dropped."""
    import pandas as pd

    lines = path.read_text().splitlines()
    head = next(i for i, line in enumerate(lines) if line.startswith("PacketCounter"))
    df = pd.read_csv(path, skiprows=head)
    if (df.loc[0, ["Acc_X", "Acc_Y", "Acc_Z"]] == 0).all():
        df = df.iloc[1:]
    us = np.unwrap(df.SampleTimeFine.to_numpy().astype(float), period=2.0**32)
    return us * 1e-6, df.Acc_X.to_numpy(float)


def _band(x: np.ndarray, fs: float, lo: float, hi: float) -> np.ndarray:
    from scipy.signal import butter, sosfiltfilt

    return sosfiltfilt(butter(4, [lo, hi], btype="band", fs=fs, output="sos"), x)


def imu_test(name: str) -> dict:
    """The table and the three floors on one uniform 120 samples/s clock from the table's first sample (module
    docstring): t [s], ground, floors (3, n) [m/s^2], and what was done."""
    folder = IMU / name
    tg, ag = read_xsens(folder / "ground.csv")
    dt = float(np.median(np.diff(tg)))
    fs = 1.0 / dt
    shared = name != "bonus_event"  # bonus_event's sensors do not share a clock (../shared SOURCES.md)
    t = np.arange(int((tg[-1] - tg[0]) / dt)) * dt
    ground = np.interp(t, tg - tg[0], ag - ag.mean())
    floors, notes = [], []
    for k in (1, 2, 3):
        tf, af = read_xsens(folder / f"floor{k}.csv")
        af = af - af.mean()
        if shared:
            lag = 0.0
            x = np.interp(t, tf - tg[0], af, left=0.0, right=0.0)
        else:  # align by cross-correlation below the first mode (~7.5 Hz), where a floor moves with the table
            x0 = np.interp(t, tf - tf[0], af, left=0.0, right=0.0)
            a, b = _band(ground, fs, 0.5, 4.0), _band(x0, fs, 0.5, 4.0)
            c = np.correlate(b, a, mode="full")[t.size - 1 - int(3 * fs) : t.size + int(3 * fs)]
            lag = (int(np.argmax(np.abs(c))) - int(3 * fs)) * dt  # the floor's record lags the table's by this
            x = np.interp(t, tf - tf[0] - lag, af, left=0.0, right=0.0)
        sign = np.sign(np.dot(_band(ground, fs, 0.5, 4.0), _band(x, fs, 0.5, 4.0)))
        floors.append(sign * x)
        notes.append(f"floor{k}: lag {lag * 1e3:+.0f} ms, sign {'+' if sign > 0 else '-'}")
    return dict(t=t, dt=dt, ground=ground, floors=np.array(floors), notes=notes)


def real_scene(name: str, folder: Path):
    """One 3-story frame (the source's lumped floor mass 0.142 kg; story stiffness from a 7.7 Hz first mode),
    its twin 1 m away, driven by the table's acceleration; the floors' acceleration as the experiment."""
    import pandas as pd

    d = imu_test(name)
    rec = folder / f"{name}_table.csv"
    np.savetxt(rec, np.column_stack([d["t"], d["ground"]]), delimiter=",", header="t_s,acc_m_s2", comments="")
    table = folder / f"{name}_floors.csv"
    pd.DataFrame({"t_s": d["t"], **{f"floor{k}_acc": d["floors"][k - 1] for k in (1, 2, 3)}}).to_csv(table, index=False)
    m, f1 = 0.142, 7.7
    k = (2 * np.pi * f1) ** 2 * m / 0.19806  # uniform 3-story chain: omega_1^2 = 0.19806 k / m
    dt = d["dt"] / 10.0
    text = f"""
name = "imu_{name}"
description = "real IMU shake-table test {name} (../shared): one 3-story frame, its twin 1 m away"
[building1]
masses_kg = [{m}, {m}, {m}]
story_stiffness_N_per_m = {k:.3f}
story_height_m = 0.2
damping_ratio = 0.01
[building2]
masses_kg = [{m}, {m}, {m}]
story_stiffness_N_per_m = {k:.3f}
story_height_m = 0.2
damping_ratio = 0.01
[contact]
gap_m = 1.0
k_ref_N_per_m = {k:.3f}
ks_ratio = 1.0
r = 0.5
[excitation]
type = "record"
name = "table {name}"
record = "{rec}"
format = "csv"
units = "m/s2"
[integration]
dt_s = {dt!r}
[output]
path = "{folder / name}.parquet"
[experiment]
table = "{table}"
channels = {{ floor1_acc = "abs_acc_b1f1", floor2_acc = "abs_acc_b1f2", floor3_acc = "abs_acc_b1f3" }}
acc_units = "m/s2"
use = "acceleration"
noise_window_s = [0.0, 1.5]             # before the shaking: each sensor's own noise
"""
    path = folder / f"{name}.toml"
    path.write_text(text)
    return load_scene(path), d


# ----------------------------------------------------------------------------- cases


def softening_truth():
    s = load_scene(SWEEPS / "paper_duzce_separated.toml")
    s = dataclasses.replace(s, sweep=(), excitation=dataclasses.replace(s.excitation, duration_s=12.0))
    df, prov = make_ivp_experiment(s, {}, drift_scale_m=0.01, noise_mm=0.0)
    channels = {f"model{b}_floor{f}_mm": f"b{b}f{f}" for b in (1, 2) for f in (1, 2, 3)}
    b1, b2 = s.building1.damping_ratio, s.building2.damping_ratio
    params = {
        "stiffness_scale_b1": [0.8, 1.2],
        "stiffness_scale_b2": [0.8, 1.2],
        "damping_ratio_b1": [0.2 * b1, 5 * b1],
        "damping_ratio_b2": [0.2 * b2, 5 * b2],
    }
    return s, df, prov, channels, params, [("strong motion", (1.0, 6.0)), ("free vibration", (7.0, 12.0))]


def per_story_truth():
    s = dataclasses.replace(load_scene(SWEEPS / "paper_6hz.toml"), sweep=())
    kf = ((1.08, 1.0, 0.92), (0.92, 1.0, 1.08))
    df, prov = make_ivp_experiment(s, {"ks_ratio": 3.0, "r": 0.6}, stiffness_factor=kf, noise_mm=0.0)
    channels = {"model1_floor3_mm": "b1f3", "model2_floor3_mm": "b2f3"}
    params = {
        "ks_ratio": [0.1, 20.0],
        "r": [0.05, 1.0],
        "stiffness_scale_b1": [0.8, 1.2],
        "stiffness_scale_b2": [0.8, 1.2],
    }
    return s, df, prov, channels, params, [("start-up", (0.0, 1.5)), ("steady state", (2.5, 5.0))]


def with_noise(truth, seed: int, folder: Path, noise_mm: float = 0.05):
    """The synthetic case's scene with its noise-free table plus white noise of `noise_mm` (seed)."""
    s, df, prov, channels, params, windows = truth
    rng = np.random.default_rng(seed)
    noisy = df.copy()
    for c in channels:
        noisy[c] = df[c] + rng.normal(0.0, noise_mm, len(df))
    path = folder / f"{s.name}_{seed}.parquet"
    write_experiment(noisy, {**prov, "noise_mm_rms": noise_mm, "seed": seed}, path)
    scene = dataclasses.replace(s, experiment=ExperimentConfig(table=str(path), channels=channels))
    return scene, params, noise_mm * 1e-3, windows


def real_case(name: str, folder: Path):
    scene, d = real_scene(name, folder)
    print(f"  {name}: {d['t'][-1]:.1f} s at {1 / d['dt']:.1f} samples/s; " + "; ".join(d["notes"]))
    params = {"stiffness_scale_b1": [0.5, 2.0], "damping_ratio_b1": [0.001, 0.1], "time_offset_s": [-0.05, 0.05]}
    return scene, params, None, None


def envelope_windows(prob, width_s: float = 5.0) -> list[tuple[str, tuple[float, float]]]:
    """The strong motion (the `width_s` window of the largest response, every channel's noise-normalised energy)
    and the small amplitude (the window of the least response among those above 5 % of it: still moving)."""
    t = np.concatenate(prob.target.time_exp) - prob.offset0
    e = np.concatenate([(v / s) ** 2 for v, s in zip(prob.target.values, prob.target.sigma)])
    lo, hi = prob.window
    starts = np.arange(lo, hi - width_s + 1e-9, 0.5)
    rms = np.array([np.sqrt(np.mean(e[(t >= a) & (t < a + width_s)])) for a in starts])
    strong = starts[np.argmax(rms)]
    moving = rms >= 0.05 * rms.max()
    small = starts[moving][np.argmin(rms[moving])]
    return [("strong motion", (strong, strong + width_s)), ("small amplitude", (small, small + width_s))]


def run_case(name: str, scene, params, noise_m, windows, threads: int) -> list[dict]:
    cal = CalibrateConfig(parameters=params, global_points=16, starts=2, profile_points=0, noise_m=noise_m)
    t0 = time.perf_counter()
    with collecting():
        fit = calibrate(dataclasses.replace(scene, calibrate=cal), threads)[0]
    whole_s = time.perf_counter() - t0
    windows = windows or envelope_windows(fit.problem)
    print(
        f"  whole record: misfit {fit.misfit_ratio:.2f} x the noise floor, quote '{fit.quote}', {fit.evaluations} runs, "
        f"{whole_s:.0f} s; split windows: "
        + ", ".join(
            f"[{w['start_s']:.1f}, {w['end_s']:.1f}] s misfit {w['misfit_over_noise']:.1f}" for w in fit.windows
        )
    )
    part = {}
    for label, (a, b) in windows:
        exp = dataclasses.replace(scene.experiment, window_s=(float(a), float(b)))
        with collecting():
            w = calibrate(dataclasses.replace(scene, experiment=exp, calibrate=cal), threads)[0]
        part[label] = better_window_fit(w, fit, (a, b))
        print(
            f"  window {label} [{a:.1f}, {b:.1f}] s: misfit {part[label]['misfit']:.2f}, {part[label]['estimate']}"
            + (
                " (refit from the whole record's optimum: the window's own calibration stopped higher)"
                if part[label]["refit"]
                else ""
            )
        )
    rows = []
    for n in fit.names:
        lo, hi = fit.ci95[n]
        mlo, mhi = fit.ci95_model.get(n, (np.nan, np.nan))
        # the windows that identify the parameter, by the split's rule (uncertainty.identifies, with the normal
        # 1.96 for the window calibration's own interval; these windows move: envelope_windows); the others'
        # values say nothing about it
        b0, b1 = fit.bounds[n]
        z = np.log if is_log(n) else (lambda x: x)
        ident = {
            label: bool(
                identifies(
                    1.96 * w["std_error"][n] / (w["estimate"][n] if is_log(n) else 1.0),
                    z(w["estimate"][n]),
                    z(b0),
                    z(b1),
                    moving=True,  # envelope_windows picks windows of motion (the strongest and a small amplitude)
                )
            )
            for label, w in part.items()
        }
        vals = {label: w["estimate"][n] for label, w in part.items() if ident[label]}
        # a window value's noise standard error: its Gauss-Newton one scaled from the residual to the noise floor
        se = [w["std_error"][n] / max(w["misfit"], 1.0) for label, w in part.items() if ident[label]]
        v = list(vals.values())
        row = dict(
            case=name,
            parameter=n,
            estimate=fit.estimate[n],
            noise_ci=(lo, hi),
            model_ci=(mlo, mhi),
            windows=vals,
            moved=len(v) == 2 and abs(v[0] - v[1]) > 4 * float(np.hypot(*se)),
            windows_identifying=len(v),
            noise_covers=all(lo <= x <= hi for x in v),
            model_covers=all(mlo <= x <= mhi for x in v),
            misfit=fit.misfit_ratio,
        )
        rows.append(row)
        print(
            f"    {n:20s} {fit.estimate[n]:.5g}  noise 95 % [{lo:.5g}, {hi:.5g}] ({100 * (hi - lo) / fit.estimate[n]:.2g} % "
            f"wide)  model error 95 % [{mlo:.5g}, {mhi:.5g}]  windows "
            + ", ".join(
                f"{k} {w['estimate'][n]:.5g}" + ("" if ident[k] else " (not identified by it)") for k, w in part.items()
            )
            + f"  covered: noise {row['noise_covers']}, model error {row['model_covers']}"
            + ("  (the model error moves it)" if row["moved"] else ""),
            flush=True,
        )
    return rows


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", default="softening,per-story," + ",".join(REAL))
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--seeds", type=int, default=1, help="noise draws of each synthetic case")
    args = ap.parse_args(argv)
    rows = []
    with tempfile.TemporaryDirectory() as d:
        folder = Path(d)
        for name in args.cases.split(","):
            if name in REAL and not IMU.is_dir():
                print(f"{name}: skipped ({IMU} not present)")
                continue
            t0 = time.perf_counter()
            if name in REAL:
                print(f"\n{name}:", flush=True)
                rows += run_case(name, *real_case(name, folder), args.threads)
                continue
            truth = {"softening": softening_truth, "per-story": per_story_truth}[name]()
            print(f"\n{name}: truth made in {time.perf_counter() - t0:.0f} s", flush=True)
            for seed in range(args.seeds):
                print(f" {name}, noise seed {seed}:", flush=True)
                rows += run_case(name, *with_noise(truth, seed, folder), args.threads)
    print(
        "\ncovered (every window fit that identifies the parameter inside the whole record's 95 % interval), over the"
        " noise draws:"
    )
    keys = list(dict.fromkeys((r["case"], r["parameter"]) for r in rows))
    for case, n in keys:
        got = [r for r in rows if (r["case"], r["parameter"]) == (case, n)]
        print(
            f"  {case:12s} {n:20s} misfit {np.median([r['misfit'] for r in got]):6.2f}  windows identifying it "
            f"{sum(r['windows_identifying'] for r in got)}/{2 * len(got)}  the model error moves it "
            f"{sum(r['moved'] for r in got)}/{len(got)}  covered: noise-based {sum(r['noise_covers'] for r in got)}/"
            f"{len(got)}, model error {sum(r['model_covers'] for r in got)}/{len(got)}"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
