"""A per-channel clock offset ([calibrate] time_offset_s_<channel>) on the REAL shipped Northridge test
(sweeps/real_northridge.toml, sweeps/experiments/imu_northridge/): one floor's sensor delayed by a whole number of
samples (5 at 120.005 Hz: 41.66 ms, no interpolation), then fitted three ways: the clean table (the walkthrough's
calibration), the delayed table without the channel's offset, and with it. Prints each fit's values, 95 %
intervals (noise-based and with the model's error), relative RMS error and misfit over the sensors' noise.
About 2-4 min on 2 busy cores.

    python benchmarks/bench_channel_offsets.py [--floor 3] [--samples 5] [--threads 2]
"""

from __future__ import annotations

import argparse
import dataclasses
import tempfile
import time
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from pounding_sweep.scene import load_scene, validate
from pounding_sweep.sweep.calibrate import calibrate
from pounding_sweep.warn import collecting

SCENE = Path(__file__).resolve().parents[1] / "sweeps" / "real_northridge.toml"


def delayed_table(src: Path, column: str, k: int, out: Path) -> float:
    """The table with `column` delayed by k samples (its value at sample i the original's at i - k; the first k
    samples repeat the quiet lead-in's first), the metadata kept. Returns the delay [s]."""
    table = pq.read_table(src)
    cols = {n: table.column(n).to_numpy() for n in table.column_names}
    y = cols[column]
    cols[column] = np.r_[y[:k], y[:-k]]
    pq.write_table(pa.table(cols).replace_schema_metadata(table.schema.metadata), out)
    return k * float(np.median(np.diff(cols["t_s"])))


def fit(scene, parameters: dict, threads: int, label: str) -> None:
    cal = dataclasses.replace(scene.calibrate, parameters=parameters)
    s = dataclasses.replace(scene, calibrate=cal)
    validate(s)
    t0 = time.perf_counter()
    with collecting():
        f = calibrate(s, threads)[0]
    print(f"\n== {label}: {f.evaluations} runs, {time.perf_counter() - t0:.0f} s")
    print(f"relative RMS error {f.error_pct:.1f} %, misfit {f.misfit_ratio:.1f} x the sensors' noise")
    print(f"{'parameter':32s} {'fitted':>10s}  {'95 % (noise)':>22s}  {'95 % (with model error)':>24s}")
    for n in f.names:
        a, b = f.ci95[n]
        ma, mb = f.ci95_model.get(n, (np.nan, np.nan))
        print(f"{n:32s} {f.estimate[n]:10.5g}  {a:10.5g} .. {b:<10.5g}  {ma:10.5g} .. {mb:<10.5g}")
    print(
        "per channel RMS residual / noise [m/s^2]: "
        + ", ".join(f"{c} {f.rms_m[c]:.4g} / {f.noise_m[c]:.4g}" for c in f.rms_m)
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--floor", type=int, default=3)
    ap.add_argument("--samples", type=int, default=5)
    ap.add_argument("--threads", type=int, default=2)
    a = ap.parse_args()
    scene = load_scene(SCENE)
    scene = dataclasses.replace(scene, sweep=())
    base = dict(scene.calibrate.parameters)
    code = f"abs_acc_b1f{a.floor}"
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "delayed.parquet"
        lag = delayed_table(Path(scene.experiment.table), f"b1f{a.floor}_acc_m_s2", a.samples, out)
        print(f"floor {a.floor}'s sensor delayed by {a.samples} samples = {1e3 * lag:.2f} ms")
        late = dataclasses.replace(scene, experiment=dataclasses.replace(scene.experiment, table=str(out)))
        fit(scene, base, a.threads, "clean table, the walkthrough's fit")
        fit(late, base, a.threads, f"floor {a.floor} delayed, no channel offset")
        fit(
            late,
            {**base, f"time_offset_s_{code}": [-0.06, 0.06]},
            a.threads,
            f"floor {a.floor} delayed, its offset fitted",
        )
        fit(
            scene,
            {**base, f"time_offset_s_{code}": [-0.06, 0.06]},
            a.threads,
            "clean table, the channel's offset fitted",
        )


if __name__ == "__main__":
    main()
