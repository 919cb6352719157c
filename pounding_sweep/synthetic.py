"""Synthetic "experiments": tracked-displacement (and accelerometer) tables made by the project itself
from stated hidden parameters, a perturbed structure and measurement noise, for demos and tests.

They stand in for the paper's measurements, which are not public. Each table's Parquet
metadata says that it is synthetic and exactly how it was made.
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq

from pounding_sweep import __version__
from pounding_sweep.scene import Scene
from pounding_sweep.scene.channels import building_floor
from pounding_sweep.sweep.simulate import simulate, with_overrides


def perturbed(scene: Scene, stiffness_factor: tuple, damping_factor: tuple[float, float]) -> Scene:
    """The scene with each building's story stiffnesses and damping ratio (or its modal damping ratios) scaled
    (model error). A building's stiffness factor is one number (every story) or one per story (floor 1 first): a
    frame whose stories differ where the model's are uniform; its damping factor one number, or with modal damping
    one per mode."""
    out = {}
    for name, kf, zf in zip(("building1", "building2"), stiffness_factor, damping_factor):
        b = getattr(scene, name)
        if b.story_stiffness_N_per_m is None or (b.damping_ratio is None and b.modal_damping_ratios is None):
            raise ValueError(f"[{name}]: perturbation needs story_stiffness_N_per_m and a damping ratio")
        n = len(b.masses_kg)
        ks = b.story_stiffness_N_per_m * (n if len(b.story_stiffness_N_per_m) == 1 else 1)
        kf = tuple(float(x) for x in np.broadcast_to(np.asarray(kf, float), (n,)))
        damping = {"damping_ratio": b.damping_ratio * zf} if b.modal_damping_ratios is None else {}
        if b.modal_damping_ratios is not None:
            zf = np.broadcast_to(np.asarray(zf, float), (n,))
            damping["modal_damping_ratios"] = tuple(float(z * f) for z, f in zip(b.modal_damping_ratios, zf))
        out[name] = dataclasses.replace(b, story_stiffness_N_per_m=tuple(k * f for k, f in zip(ks, kf)), **damping)
    return dataclasses.replace(scene, **out)


def make_experiment(
    scene: Scene,
    hidden: dict,
    *,
    stiffness_factor=(1.015, 0.985),
    damping_factor=(1.05, 0.95),
    noise_mm: float = 0.05,
    fps: float = 100.0,
    dt_s: float = 2e-5,
    seed: int = 0,
    time_offset_s: float = 0.0,
    noise_rho: float = 0.0,
    with_table: bool = False,
    acc_noise_m_s2: float | None = None,
):
    """Simulate the hidden parameters on the perturbed structure at a fine dt, sample every floor
    at `fps`, add Gaussian noise of `noise_mm` RMS (AR(1) with lag-1 correlation `noise_rho`: tracking
    errors that persist over frames), put the table's clock `time_offset_s` ahead of the simulation's;
    return (table in mm, provenance dict). With `with_table`, also the table's displacement `table_mm` (as a
    tracked table marker gives it, same noise): A sin(2 pi f t) for a harmonic excitation, the ground
    acceleration integrated twice from rest for a record.

    With `acc_noise_m_s2`, the table also holds every floor's absolute acceleration as an ideal
    accelerometer would sample it (the truth's at the same instants, interpolated linearly between its
    steps, no anti-alias filter) plus Gaussian noise of that RMS, in m/s^2, as columns `b<b>f<f>_acc`.
    The displacement columns are the same with or without them (their noise is drawn first)."""
    truth = perturbed(scene, stiffness_factor, damping_factor)
    floors = scene.floors
    chans = [f"disp_b{b}f{f}" for b, nf in zip((1, 2), floors) for f in range(1, nf + 1)]
    accs = [f"abs_acc_b{b}f{f}" for b, nf in zip((1, 2), floors) for f in range(1, nf + 1)]
    extra = (["ground_acc"] if with_table else []) + (accs if acc_noise_m_s2 is not None else [])
    hist, metrics = simulate(truth, channels=chans + extra, dt_s=dt_s, **hidden)
    t_end = hist.t_s.iloc[-1]
    t = np.arange(0.0, t_end + 1e-12, 1.0 / fps)
    rng = np.random.default_rng(seed)
    table = {"t_s": t + time_offset_s}
    for ch in chans:
        b, f = building_floor(ch)
        x_mm = np.interp(t, hist.t_s.to_numpy(), hist[f"{ch}_m"].to_numpy()) * 1e3
        table[f"model{b}_floor{f}_mm"] = x_mm + ar1_noise(rng, t.size, noise_mm, noise_rho)
    if with_table:
        table["table_mm"] = table_displacement_m(with_overrides(truth, **hidden), hist, t) * 1e3 + rng.normal(
            0.0, noise_mm, t.size
        )
    if acc_noise_m_s2 is not None:
        for ch in accs:
            acc = np.interp(t, hist.t_s.to_numpy(), hist[f"{ch}_m_s2"].to_numpy())
            table[f"{ch.removeprefix('abs_acc_')}_acc"] = acc + rng.normal(0.0, acc_noise_m_s2, t.size)
    provenance = {
        "synthetic": True,
        "what": "SYNTHETIC tracked displacement made by pounding_sweep, not a measurement",
        "scene": scene.name,
        "hidden_parameters": hidden,
        "structure_perturbation": {
            "story_stiffness_factor": [np.asarray(f, float).tolist() for f in stiffness_factor],
            "damping_ratio_factor": list(damping_factor),
        },
        "noise_mm_rms": noise_mm,
        "noise_lag1_correlation": noise_rho,
        "time_offset_s": time_offset_s,
        **({"acc_noise_m_s2_rms": acc_noise_m_s2} if acc_noise_m_s2 is not None else {}),
        "fps": fps,
        "simulation_dt_s": dt_s,
        "seed": seed,
        "status_of_truth_run": metrics["status"],
        "units": "displacement relative to the table in mm"
        + ("; table_mm: the table's displacement in mm" if with_table else "")
        + ("; absolute acceleration (b<b>f<f>_acc) in m/s^2" if acc_noise_m_s2 is not None else "")
        + "; t_s in seconds",
        "generator": "pounding_sweep.synthetic.make_experiment (sweeps/experiments/make_synthetic.py)",
        "pounding_sweep_version": __version__,
    }
    return pd.DataFrame(table), provenance


def mems_samples(
    t_fine: np.ndarray, a_fine: np.ndarray, fps: float, internal_hz: float
) -> tuple[np.ndarray, np.ndarray]:
    """An accelerometer with a built-in low-pass, as MEMS parts have: it samples at its internal rate
    `internal_hz`, averages the n = internal_hz / fps most recent internal samples (a moving average: its
    decimation filter) and outputs every n-th average, at `fps`. `t_fine`, `a_fine`: the acceleration on a
    grid of spacing 1 / internal_hz from 0 (before t = 0 the structure is at rest: 0). Returns (t_out, a_out):
    output m at t = m / fps averages the internal samples at t - j / internal_hz, j = 0..n-1."""
    n = int(round(internal_hz / fps))
    if n < 1 or abs(n * fps - internal_hz) > 1e-9 * internal_hz:
        raise ValueError(f"mems_samples: internal rate {internal_hz} Hz is not a multiple of {fps} samples/s")
    step = np.diff(t_fine)
    if t_fine[0] != 0.0 or np.any(np.abs(step - 1.0 / internal_hz) > 1e-9 / internal_hz):
        raise ValueError("mems_samples: the fine grid must start at 0 with spacing 1 / internal_hz")
    padded = np.concatenate([np.zeros(n - 1), a_fine])
    csum = np.concatenate([[0.0], np.cumsum(padded)])
    means = (csum[n:] - csum[:-n]) / n  # means[k]: internal samples k - n + 1 .. k
    idx = np.arange(0, a_fine.size, n)
    return t_fine[idx], means[idx]


def butter_samples(
    t_fine: np.ndarray, a_fine: np.ndarray, fps: float, internal_hz: float, order: int, cutoff_hz: float
) -> tuple[np.ndarray, np.ndarray]:
    """An accelerometer whose digital low-pass is a Butterworth of `order` poles and cut-off `cutoff_hz` run at its
    internal rate (scipy.signal.butter, second-order sections, causal from rest), output every internal_hz / fps-th
    filtered sample; `t_fine`, `a_fine` as mems_samples takes them."""
    from scipy.signal import butter, sosfilt

    n = int(round(internal_hz / fps))
    if n < 1 or abs(n * fps - internal_hz) > 1e-9 * internal_hz:
        raise ValueError(f"butter_samples: internal rate {internal_hz} Hz is not a multiple of {fps} samples/s")
    y = sosfilt(butter(order, cutoff_hz, btype="low", output="sos", fs=internal_hz), a_fine)
    return t_fine[::n], y[::n]


def make_ivp_experiment(
    scene: Scene,
    hidden: dict,
    *,
    stiffness_factor=(1.0, 1.0),
    damping_factor=(1.0, 1.0),
    drift_scale_m: float | None = None,
    noise_mm: float = 0.05,
    fps: float = 100.0,
    sensor_hz: float = 1000.0,
    sensor_butter: tuple[int, float] | None = None,
    acc_noise_m_s2: float | None = None,
    seed: int = 0,
    time_offset_s: float = 0.0,
    noise_rho: float = 0.0,
):
    """A synthetic experiment from the continuous-time references (solve_ivp with contact events), which share
    no discretisation with the kernels: the contact law of `hidden["law"]` (else the scene's), its Hertz-type
    laws by reference/ivp.py's law_ivp_reference (harmonic excitation), the Kelvin-Voigt laws by
    reference/softening.py (harmonic or record; with `drift_scale_m`, story springs that soften with the drift:
    amplitude-dependent stiffness, a model error the linear frame cannot fit). The structure perturbed as
    make_experiment's (`stiffness_factor`: per building one factor or one per story).

    Every floor's displacement relative to the table, sampled at `fps` (point samples, as a tracker gives
    them) plus AR(1) noise of `noise_mm` RMS, columns model<b>_floor<f>_mm; with `acc_noise_m_s2`, every floor's
    absolute acceleration as a MEMS accelerometer gives it (mems_samples: the truth sampled at `sensor_hz`,
    averaged over sensor_hz / fps samples, output at `fps`) plus Gaussian noise of that RMS, columns
    b<b>f<f>_acc [m/s^2]; with `sensor_butter` = (order, cut-off Hz), a Butterworth at `sensor_hz` in place of the
    average (butter_samples). The table's clock runs `time_offset_s` ahead of the simulation's. Returns (table,
    provenance)."""
    from pounding_sweep.reference.ivp import law_ivp_reference
    from pounding_sweep.reference.nonlinear import LAWS as HERTZ_LAWS
    from pounding_sweep.reference.softening import softening_reference

    hidden = dict(hidden)
    law = hidden.pop("law", scene.contact.law)
    truth = perturbed(scene, stiffness_factor, damping_factor)
    dt_fine = 1.0 / sensor_hz
    if law in HERTZ_LAWS:
        if drift_scale_m is not None:
            raise ValueError("make_ivp_experiment: softening stories with the Kelvin-Voigt laws only")
        out = law_ivp_reference(truth, dt_out=dt_fine, law=law, **hidden)
        P = out["problem"].base
        a_abs = -(out["v"] @ P.C.T + out["u"] @ P.K.T + out["F"] @ P.G.T) / np.diag(P.M)
    else:
        out = softening_reference(truth, drift_scale_m, dt_out=dt_fine, law=law, **hidden)
        a_abs = out["a_abs"]
    t_fine, u = out["t"], out["u"]
    n = int(round(sensor_hz / fps))
    t = t_fine[::n]
    rng = np.random.default_rng(seed)
    floors = scene.floors
    dofs = [(b, f, i) for i, (b, f) in enumerate((b, f) for b, nf in zip((1, 2), floors) for f in range(1, nf + 1))]
    table = {"t_s": t + time_offset_s}
    for b, f, i in dofs:
        table[f"model{b}_floor{f}_mm"] = u[::n, i] * 1e3 + ar1_noise(rng, t.size, noise_mm, noise_rho)
    if acc_noise_m_s2 is not None:
        for b, f, i in dofs:
            if sensor_butter is None:
                _, acc = mems_samples(t_fine, a_abs[:, i], fps, sensor_hz)
            else:
                _, acc = butter_samples(t_fine, a_abs[:, i], fps, sensor_hz, *sensor_butter)
            table[f"b{b}f{f}_acc"] = acc + rng.normal(0.0, acc_noise_m_s2, t.size)
    provenance = {
        "synthetic": True,
        "what": "SYNTHETIC tracked displacement (and accelerometer) made by pounding_sweep's solve_ivp references, "
        "not a measurement",
        "scene": scene.name,
        "law": law,
        "hidden_parameters": hidden,
        "structure_perturbation": {
            "story_stiffness_factor": [np.asarray(f, float).tolist() for f in stiffness_factor],
            "damping_ratio_factor": [np.asarray(f, float).tolist() for f in damping_factor],
            "softening_drift_scale_m": drift_scale_m,
        },
        "noise_mm_rms": noise_mm,
        "noise_lag1_correlation": noise_rho,
        "time_offset_s": time_offset_s,
        **(
            {
                "acc_noise_m_s2_rms": acc_noise_m_s2,
                "accelerometer": (
                    f"moving average of {n} samples"
                    if sensor_butter is None
                    else f"Butterworth low-pass, {sensor_butter[0]} poles, cut-off {sensor_butter[1]:g} Hz,"
                )
                + f" at {sensor_hz:g} Hz, output at {fps:g} samples/s",
            }
            if acc_noise_m_s2 is not None
            else {}
        ),
        "fps": fps,
        "reference": "law_ivp_reference" if law in HERTZ_LAWS else "softening_reference",
        "impacts_per_pair": np.asarray(out["impacts"]).tolist(),
        "seed": seed,
        "units": "displacement relative to the table in mm"
        + ("; absolute acceleration (b<b>f<f>_acc) in m/s^2" if acc_noise_m_s2 is not None else "")
        + "; t_s in seconds",
        "generator": "pounding_sweep.synthetic.make_ivp_experiment",
        "pounding_sweep_version": __version__,
    }
    return pd.DataFrame(table), provenance


def ar1_noise(rng: np.random.Generator, n: int, rms: float, rho: float) -> np.ndarray:
    """n samples of stationary AR(1) noise e_k = rho e_(k-1) + w_k of RMS `rms` (white for rho = 0)."""
    w = rng.normal(0.0, rms * np.sqrt(1.0 - rho * rho), n)
    if rho == 0.0:
        return w
    e = np.empty(n)
    e[0] = rng.normal(0.0, rms)
    for k in range(1, n):
        e[k] = rho * e[k - 1] + w[k]
    return e


def table_displacement_m(scene: Scene, hist: pd.DataFrame, t: np.ndarray) -> np.ndarray:
    """The table's displacement [m] at times t: the scene's A sin(2 pi f t) for a harmonic excitation,
    else `hist`'s ground acceleration integrated twice from rest (trapezoid rule)."""
    e = scene.excitation
    if e.type == "harmonic":
        return e.amplitude_m * np.sin(2 * np.pi * e.frequency_Hz * t)
    from scipy.integrate import cumulative_trapezoid

    ts = hist.t_s.to_numpy()
    v = cumulative_trapezoid(hist.ground_acc_m_s2.to_numpy(), ts, initial=0.0)
    return np.interp(t, ts, cumulative_trapezoid(v, ts, initial=0.0))


def write_experiment(df: pd.DataFrame, provenance: dict, path: str | Path) -> None:
    """Parquet with the provenance in the key-value metadata ('synthetic' and 'provenance')."""
    t = pa.Table.from_pandas(df, preserve_index=False)
    t = t.replace_schema_metadata({b"synthetic": b"true", b"provenance": json.dumps(provenance).encode()})
    pq.write_table(t, path)
