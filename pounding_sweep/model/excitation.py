"""Table motion for every run: harmonic parameters, or recorded ground acceleration resampled
to the integration step and flattened for the kernel.

Harmonic: table displacement x_g = A sin(2 pi f t), so the ground acceleration that drives the
relative-coordinate equations (1)-(2) is -A (2 pi f)^2 sin(2 pi f t), structure at rest at t = 0.
Records: read (PEER AT2 or CSV), similitude-scaled (eqs. 17-19: time / sqrt(lambda_L),
acceleration kept), linearly interpolated at t = n dt, times `scale`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pounding_sweep.codes import EXC_HARMONIC, EXC_RECORD
from pounding_sweep.model.records import GroundRecord, implausible_timing, read_record, resample, similitude_scale
from pounding_sweep.scene import Scene
from pounding_sweep.warn import warn


@dataclass(frozen=True)
class Excitation:
    """The scene's excitation at one dt: which kind, and every record it may use, resampled."""

    kind: str
    dt: float
    duration_s: float | None  # harmonic (or record override)
    records: tuple[GroundRecord, ...]  # after similitude scaling
    paths: tuple[str, ...]
    rec_flat: np.ndarray
    rec_off: np.ndarray
    rec_len: np.ndarray

    @classmethod
    def from_scene(cls, scene: Scene, dt: float) -> Excitation:
        e = scene.excitation
        if e.type == "harmonic":
            return cls("harmonic", dt, e.duration_s, (), (), np.zeros(1), np.zeros(1, np.int64), np.zeros(1, np.int64))
        paths = []
        for a in scene.sweep:
            if a.name == "record":
                paths = list(a.values)
        if not paths:
            paths = [e.record]
        recs, arrays = [], []
        for p in paths:
            rec = read_record(p, format=e.format, units=e.units)
            odd = implausible_timing(rec)
            if e.length_scale != 1.0:
                rec = similitude_scale(rec, e.length_scale)
            recs.append(rec)
            arrays.append(resample(rec, dt, e.duration_s))
            if odd is not None:
                steps = "" if scene.integration.auto else f" A run takes {arrays[-1].size - 1:,} steps of {dt:g} s."
                warn("record_timing", odd + steps)
            from pounding_sweep.model.sensors.checks import record_problem  # SciPy: only where a record is read

            if (offset := record_problem(recs[-1])) is not None:
                warn("record_offset", offset)
        lens = np.array([a.size for a in arrays], dtype=np.int64)
        if lens.min() < 2:
            from pounding_sweep.scene import ConfigError

            k = int(lens.argmin())
            key = "dt_max_s" if scene.integration.auto else "dt_s"
            run = (
                f"[excitation] duration_s = {e.duration_s!r}"
                if e.duration_s is not None
                else f"record {paths[k]}, {recs[k].duration_s:.6g} s long"
                + (f" at length_scale = {e.length_scale:g}" if e.length_scale != 1.0 else "")
            )
            raise ConfigError(f"[integration] {key} = {dt!r}: must be shorter than the run ({run})")
        offs = np.concatenate([[0], np.cumsum(lens)[:-1]]).astype(np.int64)
        flat = np.ascontiguousarray(np.concatenate(arrays))
        return cls("record", dt, e.duration_s, tuple(recs), tuple(paths), flat, offs, lens)

    def run_arrays(self, params: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        """Kernel excitation arrays for a chunk of runs: kind, amplitude, omega, record id, steps."""
        n = params["run_id"].size
        scale = params["scale"]
        if self.kind == "harmonic":
            nsteps = int(round(self.duration_s / self.dt))
            return dict(
                exc_kind=np.full(n, EXC_HARMONIC, np.int64),
                exc_amp=params["amplitude_m"] * scale,
                exc_omega=2.0 * np.pi * params["frequency_Hz"],
                rec_id=np.zeros(n, np.int64),
                nsteps=np.full(n, nsteps, np.int64),
            )
        index = {p: i for i, p in enumerate(self.paths)}
        rec_id = np.array([index[p] for p in params["record"]], dtype=np.int64)
        return dict(
            exc_kind=np.full(n, EXC_RECORD, np.int64),
            exc_amp=np.asarray(scale, dtype=float),
            exc_omega=np.zeros(n),
            rec_id=rec_id,
            nsteps=self.rec_len[rec_id] - 1,
        )

    @property
    def max_steps(self) -> int:
        """Steps of the longest run this excitation can make."""
        if self.kind == "harmonic":
            return int(round(self.duration_s / self.dt))
        return int(self.rec_len.max()) - 1

    @property
    def max_duration_s(self) -> float:
        return self.max_steps * self.dt

    def record_name(self, path: str) -> str:
        return self.records[self.paths.index(path)].name
