"""The real IMU shake-table tests (../shared/data/imu_shake_table, stiff 3-story), end to end: what the import
finds, the modes identify reads against an independent Welch estimate, damping with its intervals, and each check
on a deliberately damaged copy of the table (gravity kept, one channel reversed, one delayed 40 ms, time in us)
and on the clean one. Prints tables; about 10 s.

    python benchmarks/bench_real_imu.py [northridge bonus_event ...]
"""

from __future__ import annotations

import sys
import warnings
from pathlib import Path

import numpy as np
import pandas as pd
import scipy.signal

from pounding_sweep.errors import ExperimentError
from pounding_sweep.identify.table import identify_table
from pounding_sweep.model.experiment import experiment_from_table
from pounding_sweep.model.sensors.assemble import import_sensors
from pounding_sweep.scene.schema import ExperimentConfig

IMU = Path(__file__).resolve().parents[2] / "shared" / "data" / "imu_shake_table" / "stiff_3story"
CFG = ExperimentConfig(table="t", channels={f"b1f{k}_acc_m_s2": f"abs_acc_b1f{k}" for k in (1, 2, 3)})


def welch_peaks(x, y, fs, seconds):
    n = int(seconds * fs)
    f, pxy = scipy.signal.csd(x, y, fs=fs, nperseg=n)
    _, pxx = scipy.signal.welch(x, fs=fs, nperseg=n)
    h = np.abs(pxy / pxx)
    idx, props = scipy.signal.find_peaks(np.where(f > 2, h, 0), prominence=0)
    return f, h, sorted(float(f[i]) for i in idx[np.argsort(-props["prominences"])[:6]])


def half_power(f, h, f0):
    """Half-power damping on the Welch |H1| (bins of 1 / segment: an upper bound when the band spans few bins)."""
    i = int(np.argmin(np.abs(f - f0)))
    lvl = h[i] / np.sqrt(2)
    a, b = i, i
    while a > 0 and h[a] > lvl:
        a -= 1
    while b < h.size - 1 and h[b] > lvl:
        b += 1
    return (f[b] - f[a]) / (2 * f[i])


def messages(df):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            experiment_from_table(df, {}, "t", CFG, (3, 3))
        except ExperimentError as e:
            return [f"error: {e}"]
    return [str(w.message) for w in caught]


def main(tests):
    for test in tests:
        files = {"ground": IMU / test / "ground.csv", **{f"b1f{k}": IMU / test / f"floor{k}.csv" for k in (1, 2, 3)}}
        im = import_sensors({n: str(p) for n, p in files.items()}, "ground")
        print(f"\n== {test}")
        print("\n".join(im.summary()))
        for w in im.warnings:
            print(f"  warning: {w}")
        df = pd.DataFrame({"t_s": im.time_s, **im.columns})
        ident = identify_table(df, test, input_kind_given="acceleration")
        fs = 1 / float(np.median(np.diff(df["t_s"])))
        seg = min(16.0, float(df["t_s"].iloc[-1]) / 4)
        f, h, ref = welch_peaks(df["ground_acc_m_s2"].to_numpy(), df["b1f3_acc_m_s2"].to_numpy(), fs, seg)
        print(f"modes (identify: {ident.method.split(',')[0]}; Welch H1 table -> top floor, {seg:.1f} s segments)")
        print(
            "mode  identify Hz  merged        Welch Hz  half-power %  (+/- res)     fitted % (95 %)          Welch hp %"
        )
        for k, m in enumerate(ident.results[1].modes, 1):
            g = min(ref, key=lambda g: abs(g - m.frequency_Hz))
            lo, hi = m.damping_half_power_interval
            hp = f"{100 * m.damping_half_power:.3f}" if np.isfinite(m.damping_half_power) else "n/a"
            a, b = m.damping_fit_ci95
            print(
                f"{k:4d} {m.frequency_Hz:12.4f}  {','.join(f'{x:.3f}' for x in m.merged_Hz):12s} {g:9.3f}  "
                f"{hp:>11s}  ({100 * lo:.2f}-{100 * hi:.2f})  {100 * m.damping_fit:7.3f} ({100 * a:.3f} to {100 * b:.3f})"
                f"  {100 * half_power(f, h, g):8.3f}"
            )
        for note in ident.results[1].notes:
            print(f"  note: {note}")
        clean = df.drop(columns="ground_acc_m_s2")
        print("checks on the clean table:", messages(clean) or "none")
        k = int(round(0.040 * fs))
        for how, change in (
            ("gravity kept on b1f1", lambda d: d.assign(b1f1_acc_m_s2=d["b1f1_acc_m_s2"] + 9.80665)),
            ("b1f2 reversed", lambda d: d.assign(b1f2_acc_m_s2=-d["b1f2_acc_m_s2"])),
            (
                f"b1f3 delayed {1e3 * k / fs:.1f} ms",
                lambda d: d.assign(b1f3_acc_m_s2=np.r_[np.zeros(k), d["b1f3_acc_m_s2"].to_numpy()[:-k]]),
            ),
            ("time in us", lambda d: d.assign(t_s=d["t_s"] * 1e6)),
        ):
            print(f"checks, {how}:")
            for msg in messages(change(clean.copy())):
                print(f"  {msg}")


if __name__ == "__main__":
    main(sys.argv[1:] or ["northridge", "bonus_event"])
