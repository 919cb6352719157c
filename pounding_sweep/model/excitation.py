"""Table motion for every run: harmonic parameters, or recorded ground acceleration resampled
to the integration step and flattened for the kernel, or stochastic ground motion generated per chunk.

Harmonic: table displacement x_g = A sin(2 pi f t), so the ground acceleration that drives the
relative-coordinate equations (1)-(2) is -A (2 pi f)^2 sin(2 pi f t), structure at rest at t = 0.
Records: read (PEER AT2 or CSV), similitude-scaled (eqs. 17-19: time / sqrt(lambda_L),
acceleration kept), linearly interpolated at t = n dt, times `scale`.
Stochastic (model/stochastic.py): the realisations of a chunk's seeds, generated when the chunk is run
(deterministic from the seed: any chunk recomputes them exactly, on resume or on another worker), then
resampled like a record.
Intensity ([excitation] intensity, model/intensity.py): each motion's PGA or Sa(T) as given (after
similitude), computed on its own samples up to [excitation] duration_s where that cuts it (the motion a run
sees; the cut is warned where it loses the record's strong part); with scaling = 'intensity' the motion is
multiplied by scale g / intensity, so a run's `scale` is its intensity in g.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from pounding_sweep.codes import EXC_HARMONIC, EXC_RECORD
from pounding_sweep.model.records import (
    G_STANDARD,
    GroundRecord,
    RecordError,
    implausible_timing,
    read_record,
    resample,
    similitude_scale,
)
from pounding_sweep.scene import Scene
from pounding_sweep.warn import warn


def _similitude(rec: GroundRecord, scene: Scene) -> GroundRecord:
    """A record as the scene's runs see it: time scaled by [excitation] length_scale (eqs. 17-19)."""
    scale = scene.excitation.length_scale
    return similitude_scale(rec, scale) if scale != 1.0 else rec


def record_paths(scene: Scene) -> list[str]:
    """The records a scene's runs may use: its [sweep] record axis, else [excitation] record."""
    paths: list[str] = []
    for a in scene.sweep:
        if a.name == "record":
            paths = list(a.values)
    return paths or [scene.excitation.record]


def scene_record(scene: Scene, path: str | None = None) -> GroundRecord:
    """The record at `path` (default: [excitation] record) read as the scene reads it and similitude-scaled."""
    return _similitude(_read(scene, path or scene.excitation.record), scene)


def _read(scene: Scene, path: str) -> GroundRecord:
    """read_record with the scene's format and units; a RecordError names the key that gave the file too."""
    e = scene.excitation
    try:
        return read_record(path, format=e.format, units=e.units)
    except RecordError as err:
        key = "[sweep] record" if any(a.name == "record" for a in scene.sweep) else "[excitation] record"
        raise RecordError(f"{key}: {err}") from None


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
    intensity: str = "none"  # [excitation] intensity: 'none', 'pga' or 'sa'
    scaling: str = "factor"  # [excitation] scaling: 'factor' or 'intensity'
    period_s: float | None = None  # the Sa period
    rec_intensity: np.ndarray | None = None  # records: the intensity of each one as run (cut at duration_s) [m/s^2]
    motion: object | None = None  # stochastic: model.stochastic.StochasticMotion

    @classmethod
    def from_scene(cls, scene: Scene, dt: float) -> Excitation:
        e = scene.excitation
        if e.type == "harmonic":
            return cls("harmonic", dt, e.duration_s, (), (), np.zeros(1), np.zeros(1, np.int64), np.zeros(1, np.int64))
        period = intensity_period(scene)
        if e.type == "stochastic":
            from pounding_sweep.model.stochastic import from_config

            sdt = scene.stochastic.sample_dt_s or dt
            motion = from_config(scene.stochastic, sdt, e.duration_s)
            n = math.floor(e.duration_s / dt + 1e-9) + 1
            empty = np.zeros(0)
            return cls(
                "stochastic", dt, e.duration_s, (), (), empty, np.zeros(0, np.int64), np.array([n], np.int64),
                e.intensity, e.scaling, period, None, motion,
            )  # fmt: skip
        paths = record_paths(scene)
        recs, arrays = [], []
        for p in paths:
            rec = _read(scene, p)
            odd = implausible_timing(rec)
            rec = _similitude(rec, scene)
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
        im = None
        if e.intensity != "none":
            im = np.array([_run_intensity(r, p, e, period) for r, p in zip(recs, paths, strict=True)])
            if e.scaling == "intensity" and not (im > 0).all():
                from pounding_sweep.scene import ConfigError

                k = int(np.argmin(im))
                raise ConfigError(f"[excitation] scaling = 'intensity': record {paths[k]} has zero {e.intensity}")
        return cls(
            "record", dt, e.duration_s, tuple(recs), tuple(paths), flat, offs, lens, e.intensity, e.scaling, period, im
        )

    def chunk_inputs(self, params: dict[str, np.ndarray], threads: int = 1) -> tuple[dict[str, np.ndarray], tuple]:
        """run_arrays(params) (with 'intensity_g', each run's intensity in g, when the scene names one) and the
        records the chunk uses, (flat, off, len): the stored ones, or a stochastic chunk's realisations
        (generated on `threads` threads)."""
        if self.kind != "stochastic":
            ex = self.run_arrays(params)
            if self.rec_intensity is not None:
                im = self.rec_intensity[ex["rec_id"]]
                ex["intensity_g"] = params["scale"] * (1.0 if self.scaling == "intensity" else im / G_STANDARD)
                if self.scaling == "intensity":
                    ex["exc_amp"] = params["scale"] * G_STANDARD / im
            return ex, (self.rec_flat, self.rec_off, self.rec_len)
        seeds, rec_id = np.unique(np.asarray(params["seed"], dtype=np.int64), return_inverse=True)
        acc = self.motion.generate(seeds, threads)  # (distinct seeds, samples) at the motion's own step
        scale = np.asarray(params["scale"], dtype=float)
        ex = {}
        if self.intensity != "none":
            from pounding_sweep.model.intensity import intensity

            im = intensity(acc, self.motion.dt_s, self.intensity, self.period_s)[rec_id]
            if self.scaling == "intensity":
                ex["intensity_g"] = scale.copy()
                scale = scale * G_STANDARD / im
            else:
                ex["intensity_g"] = scale * im / G_STANDARD
        n = int(self.rec_len[0])
        if self.motion.dt_s == self.dt and self.motion.n_samples == n:
            flat = acc.reshape(-1)
        else:
            t = np.arange(n) * self.dt
            tm = self.motion.times
            flat = np.concatenate([np.where(t <= tm[-1] * (1 + 1e-12), np.interp(t, tm, a), 0.0) for a in acc])
        lens = np.full(seeds.size, n, np.int64)
        offs = np.arange(seeds.size, dtype=np.int64) * n
        ex.update(
            exc_kind=np.full(scale.size, EXC_RECORD, np.int64),
            exc_amp=scale,
            exc_omega=np.zeros(scale.size),
            rec_id=rec_id.astype(np.int64),
            nsteps=np.full(scale.size, n - 1, np.int64),
        )
        return ex, (np.ascontiguousarray(flat), offs, lens)

    def facts(self) -> dict:
        """What the result metadata says about the intensity measure and a stochastic motion."""
        out = {}
        if self.intensity != "none":
            out["intensity"] = {
                "measure": self.intensity,
                "period_s": self.period_s if self.intensity == "sa" else None,
                "damping": 0.05 if self.intensity == "sa" else None,
                "scaling": self.scaling,
                "column": "intensity_g",
                "method": "Nigam & Jennings 1969, exact for piecewise-linear input; peak over the samples",
            }
        if self.motion is not None:
            m = self.motion
            out["stochastic"] = {
                "filter": m.ground.kind,
                "omega_g_rad_s": m.ground.omega_g,
                "zeta_g": m.ground.zeta_g,
                "s0_m2_per_s3": m.ground.s0,
                "omega_f_rad_s": m.ground.omega_f,
                "zeta_f": m.ground.zeta_f,
                "envelope": m.envelope.kind,
                "sample_dt_s": m.dt_s,
                "samples": m.n_samples,
                "start": m.start,
                "generator": "numpy PCG64(SeedSequence(seed)); exact sampled state recursion (model/stochastic.py)",
            }
        return out

    def run_arrays(self, params: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        """Kernel excitation arrays for a chunk of runs: kind, amplitude, omega, record id, steps (harmonic and
        recorded motions: a stochastic chunk's come from chunk_inputs)."""
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


#: a cut record's intensity below this share of the whole record's is said (the cut dropped its strong part)
CUT_SHARE = 0.99


def _run_intensity(rec: GroundRecord, path: str, e, period: float | None) -> float:
    """The intensity [m/s^2] of the motion a run applies: the record up to [excitation] duration_s where that cuts
    it (the runs never see the rest; their intensity, and the factor scaling them to a level, are of what they
    see), with a warning where the cut leaves less than CUT_SHARE of the whole record's intensity."""
    from pounding_sweep.model.intensity import intensity

    whole = float(intensity(rec.acc_m_s2, rec.dt_s, e.intensity, period))
    if e.duration_s is None or e.duration_s >= rec.duration_s:
        return whole
    kept = rec.time_s <= e.duration_s + 1e-9 * rec.dt_s
    if kept.sum() < 2:
        from pounding_sweep.scene import ConfigError

        raise ConfigError(
            f"[excitation] duration_s = {e.duration_s!r}: keeps {int(kept.sum())} sample of record {path} (one every "
            f"{rec.dt_s:.4g} s): the motion run has no {e.intensity} to speak of; run at least two of its samples"
        )
    cut = float(intensity(rec.acc_m_s2[kept], rec.dt_s, e.intensity, period))
    if cut < CUT_SHARE * whole:
        what = f"Sa({period:.3g} s, 5 %)" if e.intensity == "sa" else "PGA"
        peak = float(rec.time_s[int(np.argmax(np.abs(rec.acc_m_s2)))])
        warn(
            "record_cut",
            f"[excitation] duration_s = {e.duration_s!r} cuts record {path} ({rec.duration_s:.4g} s long, its peak "
            f"acceleration at {peak:.4g} s): the motion run has {what} {cut / G_STANDARD:.4g} g against the whole "
            f"record's {whole / G_STANDARD:.4g} g; the runs' intensity (and scaling to it) is the motion run's: "
            "leave duration_s out to run the whole record",
        )
    return cut


def intensity_period(scene: Scene) -> float | None:
    """The Sa period of a scene: [excitation] intensity_period_s, else the geometric mean of the two buildings'
    first periods; None unless intensity = 'sa'."""
    e = scene.excitation
    if e.intensity != "sa":
        return None
    if e.intensity_period_s is not None:
        return float(e.intensity_period_s)
    from pounding_sweep.model.coupled import CoupledModel
    from pounding_sweep.model.intensity import geometric_mean_period

    model = CoupledModel.from_scene(scene)
    return geometric_mean_period([2.0 * math.pi / float(b.modes().omega_rad_s[0]) for b in model.buildings])
