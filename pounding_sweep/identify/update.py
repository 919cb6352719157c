"""Model update: scale a building's story stiffness (or its columns' EI) so that its first
frequency matches the identified one, as the paper did (Sekerci & Damci, sec. 3 and Table 1:
column EI 5.4 -> 4.6 N m^2 for Model-1 and 5.4 -> 4.1 N m^2 for Model-2, from f1 measured by FFT
of the tracked video).

Scaling every story stiffness by the same factor c scales the stiffness matrix, so every
eigenvalue of K phi = w^2 M phi scales by c: the factor that moves f1 to the target is exactly
c = (f1_target / f1_model)^2 (with k = n 12 EI / h^3, the same factor applies to EI). The
eigen-analysis is `pounding_sweep.structure.modal_analysis`; the result is written as a
`[buildingN]` TOML section a scene can use.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from pounding_sweep.model.coupled import building_from_config
from pounding_sweep.model.structure import modal_analysis, shear_frame_stiffness
from pounding_sweep.scene import BuildingConfig, Scene


def frequencies_Hz(masses_kg, story_stiffness_N_per_m) -> np.ndarray:
    """Undamped natural frequencies of a shear frame [Hz], ascending."""
    m = np.asarray(masses_kg, dtype=float)
    k = np.atleast_1d(np.asarray(story_stiffness_N_per_m, dtype=float))
    if k.size == 1:
        k = np.full(m.size, k[0])
    return modal_analysis(np.diag(m), shear_frame_stiffness(k)).frequency_Hz


def stiffness_factor_for_f1(masses_kg, story_stiffness_N_per_m, f1_target_Hz: float) -> float:
    """The factor on every story stiffness that gives the first frequency f1_target_Hz (exact)."""
    if not (np.isfinite(f1_target_Hz) and f1_target_Hz > 0):
        raise ValueError(f"target first frequency must be > 0 Hz, got {f1_target_Hz!r}")
    f1 = frequencies_Hz(masses_kg, story_stiffness_N_per_m)[0]
    return float((f1_target_Hz / f1) ** 2)


def column_EI_for_story_stiffness(k_N_per_m: float, n_columns: int, height_m: float) -> float:
    """Inverse of structure.column_story_stiffness: EI = k h^3 / (12 n)."""
    return float(k_N_per_m) * float(height_m) ** 3 / (12.0 * n_columns)


@dataclass(frozen=True)
class StiffnessUpdate:
    """One building's update: before and after, and the section a scene can use."""

    section: str  # 'building1' or 'building2'
    config: BuildingConfig  # before
    updated: BuildingConfig  # after
    f1_model_Hz: float
    f1_target_Hz: float
    factor: float  # on every story stiffness (and column EI)

    @property
    def story_stiffness_N_per_m(self) -> tuple[float, ...]:
        return tuple(building_from_config(self.updated, self.section).story_stiffness_N_per_m)

    @property
    def f1_updated_Hz(self) -> float:
        return float(building_from_config(self.updated, self.section).modes().frequency_Hz[0])

    def toml(self) -> str:
        """The updated `[buildingN]` section, every key set, with a comment on where it came from."""
        how = "column_EI_Nm2" if self.config.column_EI_Nm2 is not None else "story_stiffness_N_per_m"
        lines = [
            f"[{self.section}]",
            f"# model update: f1 {self.f1_model_Hz:.4f} Hz -> {self.f1_target_Hz:.4f} Hz identified; "
            f"{how} x {self.factor:.4f} (was {_fmt(getattr(self.config, how))})",
        ]
        for f in dataclasses.fields(BuildingConfig):
            v = getattr(self.updated, f.name)
            if v is None or (f.name == "name" and not v) or (f.name == "damping_modes" and v == (1, 2)):
                continue
            lines.append(f"{f.name} = {_fmt(v)}")
        return "\n".join(lines) + "\n"


def _fmt(v) -> str:
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(v, (tuple, list)):
        return "[" + ", ".join(_fmt(x) for x in v) + "]"
    if isinstance(v, float):
        return f"{v:.6g}" if "e" not in f"{v:.6g}" else repr(v)
    return str(v)


def update_building(
    cfg: BuildingConfig, f1_target_Hz: float, section: str = "building1", damping_ratio: float | None = None
) -> StiffnessUpdate:
    """Scale the story stiffness (or, for a building given by columns, their EI) so that f1 equals
    the target; optionally set an identified damping ratio too."""
    frame = building_from_config(cfg, section)
    f1 = float(frame.modes().frequency_Hz[0])
    c = stiffness_factor_for_f1(frame.masses_kg, frame.story_stiffness_N_per_m, f1_target_Hz)
    if cfg.story_stiffness_N_per_m is not None:
        new = dataclasses.replace(cfg, story_stiffness_N_per_m=tuple(k * c for k in cfg.story_stiffness_N_per_m))
    else:
        new = dataclasses.replace(cfg, column_EI_Nm2=tuple(e * c for e in cfg.column_EI_Nm2))
    if damping_ratio is not None:
        if cfg.rayleigh_a0_per_s is not None or cfg.rayleigh_a1_s is not None:
            new = dataclasses.replace(new, rayleigh_a0_per_s=None, rayleigh_a1_s=None)
        new = dataclasses.replace(new, damping_ratio=float(damping_ratio), modal_damping_ratios=None)
    return StiffnessUpdate(section, cfg, new, f1, float(f1_target_Hz), c)


def update_scene(
    scene: Scene, f1_targets_Hz: dict[int, float], damping: dict[int, float] | None = None
) -> list[StiffnessUpdate]:
    """Update the buildings named in f1_targets_Hz ({1: 4.28, 2: 7.22}); the sections to paste."""
    out = []
    for b, f in sorted(f1_targets_Hz.items()):
        if b not in (1, 2):
            raise ValueError(f"building must be 1 or 2, got {b!r}")
        out.append(update_building(getattr(scene, f"building{b}"), f, f"building{b}", (damping or {}).get(b)))
    return out
