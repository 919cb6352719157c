"""The experiment channels' noise floor (model/experiment.py noise_floor) against known noise, and what
acceleration scoring resolves at each sample rate.

Usage (from the repository root):

    python benchmarks/bench_noise_floor.py

Runs the paper's 6 Hz (k_s/k = 5, r = 0.4) and Duzce (k_s/k = 1, r = 0.6) points with simulate() at
dt = 1e-4 s, samples the third floors' displacement at 100 samples/s (the paper's video) and their
absolute acceleration at 100, 500 and 1000 samples/s, adds Gaussian noise (0.05 mm; 0.06 m/s^2, an
MPU-6050's 400 ug/sqrt(Hz) over 260 Hz), and prints the estimated noise floor over the noise added (the
figures noise_floor's docstring quotes), with the difference order that gave it. Then, for the 6 Hz
Model-2 acceleration, eq. 20 between the hidden run and runs 1-2 % away in k_s/k or r, unfiltered, at
each sample rate (and its displacement's at 100 samples/s): how steep the error is near the optimum. Last, the eq. 20 errors of
displacement and acceleration channels against a synthetic experiment (hidden k_s/k = 5, r = 0.4, no
model error, 1000 samples/s, 0.05 mm and 0.06 m/s^2 of noise, accelerations filtered at 50 Hz) for
runs away from the hidden one (the README's figures).
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from pounding_sweep.model.experiment import noise_floor  # noqa: E402
from pounding_sweep.scene import load_scene  # noqa: E402
from pounding_sweep.sweep.simulate import simulate  # noqa: E402

CHANNELS = ["disp_b1f3", "disp_b2f3", "abs_acc_b1f3", "abs_acc_b2f3"]
POINTS = {"paper_6hz": {"ks_ratio": 5.0, "r": 0.4}, "paper_duzce": {"ks_ratio": 1.0, "r": 0.6}}
NOISE = {"disp": 0.05e-3, "abs_acc": 0.06}


def sampled(hist, name: str, fs: float) -> np.ndarray:
    t = hist.t_s.to_numpy()
    ts = np.arange(0.0, t[-1], 1.0 / fs)
    unit = "_m" if name.startswith("disp") else "_m_s2"
    return np.interp(ts, t, hist[name + unit].to_numpy())


def main() -> None:
    rng = np.random.default_rng(2026)
    print("noise floor estimate / noise added (difference order):")
    runs = {}
    for scene_name, point in POINTS.items():
        scene = load_scene(REPO / "sweeps" / f"{scene_name}.toml")
        hist, _ = simulate(scene, channels=CHANNELS, **point)
        runs[scene_name] = (scene, hist)
        for name in CHANNELS:
            kind = "disp" if name.startswith("disp") else "abs_acc"
            rates = (100.0,) if kind == "disp" else (100.0, 500.0, 1000.0)
            for fs in rates:
                x = sampled(hist, name, fs)
                sigma = NOISE[kind]
                est, order = noise_floor(x + rng.normal(0.0, sigma, x.size))
                print(f"  {scene_name:12s} {name:13s} {fs:6.0f} samples/s: {est / sigma:6.2f} (order {order})")
    pure = [noise_floor(rng.normal(0.0, 1.0, 500))[0] for _ in range(200)]
    print(f"  pure white noise, 500 samples: mean {np.mean(pure):.3f}, spread {np.std(pure):.3f}")

    print("6 Hz, Model-2's unfiltered acceleration, eq. 20 [%] of runs near the hidden one against it:")
    scene, hist = runs["paper_6hz"]
    print("  (its displacement at 100 samples/s, for comparison:", end=" ")
    near = {
        "k_s/k x 1.01": {"ks_ratio": 5.05, "r": 0.4},
        "k_s/k x 1.02": {"ks_ratio": 5.1, "r": 0.4},
        "r x 1.01": {"ks_ratio": 5.0, "r": 0.404},
        "r x 1.02": {"ks_ratio": 5.0, "r": 0.408},
    }
    others = {label: simulate(scene, channels=["abs_acc_b2f3", "disp_b2f3"], **p)[0] for label, p in near.items()}
    xe = sampled(hist, "disp_b2f3", 100.0)
    rel = {
        k: 100 * np.sqrt(np.mean((sampled(h, "disp_b2f3", 100.0) - xe) ** 2) / np.mean(xe**2))
        for k, h in others.items()
    }
    print(", ".join(f"{k} {v:.2f}" for k, v in rel.items()) + ")")
    for fs in (100.0, 500.0, 1000.0):
        xe = sampled(hist, "abs_acc_b2f3", fs)
        cells = []
        for label, h in others.items():
            xd = sampled(h, "abs_acc_b2f3", fs)
            cells.append(f"{label} {100 * np.sqrt(np.mean((xd - xe) ** 2) / np.mean(xe**2)):6.2f}")
        print(f"  {fs:6.0f} samples/s: " + ", ".join(cells))

    import dataclasses
    import tempfile

    from pounding_sweep.synthetic import make_experiment

    df, _ = make_experiment(
        scene, POINTS["paper_6hz"], fps=1000.0, dt_s=1e-4, acc_noise_m_s2=0.06, stiffness_factor=(1, 1),
        damping_factor=(1, 1),
    )  # fmt: skip
    with tempfile.TemporaryDirectory() as tmp:
        df.to_csv(Path(tmp) / "exp.csv", index=False)
        scored = load_scene(REPO / "sweeps" / "scored_6hz.toml")
        chans = {"model1_floor3_mm": "b1f3", "model2_floor3_mm": "b2f3", "b1f3_acc": "abs_acc_b1f3"}
        chans["b2f3_acc"] = "abs_acc_b2f3"
        exp = dataclasses.replace(
            scored.experiment, table=str(Path(tmp) / "exp.csv"), channels=chans, lowpass_Hz=50.0, refine=False
        )
        scored = dataclasses.replace(scored, experiment=exp)
        print("eq. 20 [%] against a synthetic 6 Hz experiment (hidden k_s/k = 5, r = 0.4), 1000 samples/s:")
        for ks, r in ((5.0, 0.4), (1.0, 0.4), (10.0, 0.4), (5.0, 0.8)):
            _, m = simulate(scored, channels=["disp_b1f3"], ks_ratio=ks, r=r)
            cells = ", ".join(f"{c} {m[f'rel_rms_{c}_pct']:6.2f}" for c in chans.values())
            print(f"  k_s/k {ks:4g}, r {r}: {cells}")


if __name__ == "__main__":
    main()
