"""Xsens DOT exports of a known test, written here: a 3-story shear frame on a table shaken by band-limited noise,
its floors' absolute acceleration computed on a fine grid (scipy.signal.lsim of the state-space model, first-order
hold, at 1200 Hz), sampled by four "sensors" at 120 Hz on their own clocks, with gravity on Z, a tilt offset on X,
noise, and optionally one sensor reversed. What the import must find is known exactly."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import scipy.signal

FINE = 10  # fine-grid samples per sensor sample
RATE = 120.0  # sensor samples per second
TICK_US = 8333  # the DOT's SampleTimeFine step at 120 Hz (us)
G = 9.80665
HEADER = (
    "sep=,\nDeviceTag:,{tag}\nFirmwareVersion:,3.0.0\nAppVersion:,2023.6.0\n"
    "StartTime: ,2025-03-06_12:43:39_000 PST\n\u00a9 Movella Technologies B. V. 2005-2025\n\n"
    "PacketCounter,SampleTimeFine,Euler_X,Euler_Y,Euler_Z,Acc_X,Acc_Y,Acc_Z,Gyr_X,Gyr_Y,Gyr_Z\n"
)


@dataclass
class Truth:
    fine_t: np.ndarray  # s, the fine grid (the table's clock)
    acc: dict  # name -> absolute acceleration on the fine grid [m/s^2]
    frequencies_Hz: np.ndarray


def shear_frame_test(
    duration_s: float = 40.0, seed: int = 1, quiet_s: float = 3.0, stop_s: float | None = None
) -> Truth:
    """Masses 0.142 kg, story stiffness 1700 N/m (f1 about 7.7 Hz, as the stiff IMU model), 1 % Rayleigh
    damping; the table's acceleration white noise band-limited to 0.3-20 Hz after `quiet_s` of rest (until
    `stop_s`, after which the table is at rest and the floors vibrate freely)."""
    m, k = 0.142, 1700.0
    M = np.diag([m, m, m])
    K = k * np.array([[2, -1, 0], [-1, 2, -1], [0, -1, 1]], float)
    w2, _ = np.linalg.eigh(np.linalg.solve(M, K))
    w = np.sqrt(w2)
    zeta = 0.01
    a0, a1 = 2 * zeta * w[0] * w[1] / (w[0] + w[1]), 2 * zeta / (w[0] + w[1])
    C = a0 * M + a1 * K
    n = 3
    Minv = np.linalg.inv(M)
    A = np.block([[np.zeros((n, n)), np.eye(n)], [-Minv @ K, -Minv @ C]])
    B = np.concatenate([np.zeros(n), -np.ones(n)])[:, None]  # relative coordinates: -1 a_g on every floor
    Cout = np.hstack([-Minv @ K, -Minv @ C])  # relative acceleration
    D = -np.ones((n, 1))
    fs = RATE * FINE
    t = np.arange(int(duration_s * fs)) / fs
    rng = np.random.default_rng(seed)
    ag = rng.normal(0, 1, t.size)
    sos = scipy.signal.butter(4, [0.3, 20.0], btype="bandpass", fs=fs, output="sos")
    ag = scipy.signal.sosfilt(sos, ag)
    ag[t < quiet_s] = 0.0
    if stop_s is not None:
        ag[t >= stop_s] = 0.0
    ag *= 0.6 / np.std(ag[ag != 0])
    _, y, _ = scipy.signal.lsim((A, B, Cout, D), ag, t, interp=True)
    acc = {"ground": ag}
    for j in range(n):
        acc[f"b1f{j + 1}"] = y[:, j] + ag  # absolute = relative + table
    return Truth(t, acc, w / (2 * np.pi))


def write_sensor(
    path: Path,
    x: np.ndarray,
    start_tick: int,
    first_fine: int,
    tag: str = "Xsens DOT",
    sign: int = 1,
    tilt: float = 0.0,
    noise: float = 0.01,
    seed: int = 0,
    samples: int | None = None,
) -> None:
    """One DOT export: samples x[first_fine + FINE i] (i = 0..) times `sign` on Acc_X plus `tilt` plus noise,
    gravity on Acc_Z, SampleTimeFine from start_tick (mod 2^32) in steps of TICK_US; a leading all-zero row."""
    rng = np.random.default_rng(seed)
    idx = np.arange(first_fine, x.size, FINE)[:samples]
    ax = sign * x[idx] + tilt + rng.normal(0, noise, idx.size)
    ay = rng.normal(0, noise, idx.size)
    az = G + rng.normal(0, noise, idx.size)
    ticks = (start_tick + TICK_US * np.arange(idx.size + 1)) % 2**32
    rows = [f"0,{ticks[0]},1.0,2.0,3.0,0,0,0,0,0,0"]
    for i in range(idx.size):
        rows.append(f"{i + 1},{ticks[i + 1]},1.0,2.0,3.0,{ax[i]:.8f},{ay[i]:.8f},{az[i]:.8f},0.01,0.02,0.03")
    path.write_text(HEADER.format(tag=tag) + "\n".join(rows) + "\n", encoding="utf-8")
