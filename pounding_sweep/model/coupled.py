"""The coupled two-building model: both shear frames, their facing floor pairs, and the
Newmark matrices the kernel needs for a given dt (see kernel.py for the algebra). A single-building
scene's model is building 1 alone: no building 2, no pairs (P = 0: the engine runs it on the scalar kernel)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pounding_sweep.model.structure import ShearFrame, build_shear_frame, column_story_stiffness
from pounding_sweep.scene import BuildingConfig, Scene


def building_from_config(cfg: BuildingConfig, default_name: str) -> ShearFrame:
    """Resolve a [buildingN] table: story stiffness directly or from columns (k = n 12 EI / h^3), times the
    building's stiffness_scale and each story's own factor (story_stiffness_scales); masses times its mass_scale."""
    n = len(cfg.masses_kg)

    def per_story(vals):
        return [vals[0]] * n if len(vals) == 1 else list(vals)

    if cfg.story_stiffness_N_per_m is not None:
        k = per_story(cfg.story_stiffness_N_per_m)
    else:
        ei, h = per_story(cfg.column_EI_Nm2), per_story(cfg.story_height_m)
        k = [column_story_stiffness(e, cfg.n_columns, hh) for e, hh in zip(ei, h)]
    return build_shear_frame(
        cfg.name or default_name,
        [m * cfg.mass_scale for m in cfg.masses_kg],
        [x * cfg.stiffness_scale * s for x, s in zip(k, cfg.story_stiffness_scales or (1.0,) * n)],
        damping_ratio=cfg.damping_ratio,
        damping_modes=tuple(cfg.damping_modes[:2]) if n > 1 else (1, 1),
        rayleigh_a0_per_s=cfg.rayleigh_a0_per_s,
        rayleigh_a1_s=cfg.rayleigh_a1_s,
        modal_damping_ratios=cfg.modal_damping_ratios,
    )


@dataclass(frozen=True)
class SystemArrays:
    """Everything about the structure the kernel needs at one dt (all float64 / int64, C-contiguous)."""

    dt: float
    m: np.ndarray  # lumped masses, building 1 floors then building 2 floors
    C: np.ndarray
    K: np.ndarray
    Kinv: np.ndarray  # (K + 2/dt C + 4/dt^2 M)^-1
    H: np.ndarray  # Kinv G
    S: np.ndarray  # G^T Kinv G
    i1: np.ndarray  # DOF of building 1 in pair j
    i2: np.ndarray  # DOF of building 2 in pair j


@dataclass(frozen=True)
class CoupledModel:
    """Two shear frames side by side; floor j of one faces floor j of the other (same levels). b2 None: building
    1 on its own (a single-building scene)."""

    b1: ShearFrame
    b2: ShearFrame | None

    @classmethod
    def from_scene(cls, scene: Scene) -> CoupledModel:
        b2 = None if scene.building2 is None else building_from_config(scene.building2, "building 2")
        return cls(building_from_config(scene.building1, "building 1"), b2)

    @property
    def buildings(self) -> tuple[ShearFrame, ...]:
        """The model's buildings, building 1 first (one in a single-building scene)."""
        return (self.b1,) if self.b2 is None else (self.b1, self.b2)

    @property
    def floors(self) -> tuple[int, int]:
        return self.b1.n_floors, 0 if self.b2 is None else self.b2.n_floors

    @property
    def n_pairs(self) -> int:
        return min(self.floors)

    @property
    def n_dof(self) -> int:
        return sum(self.floors)

    def pair_masses(self) -> tuple[np.ndarray, np.ndarray]:
        """Masses of the two floors of each pair [kg] (for eq. 9; empty without building 2)."""
        p = self.n_pairs
        if self.b2 is None:
            return np.zeros(0), np.zeros(0)
        return np.asarray(self.b1.masses_kg[:p]), np.asarray(self.b2.masses_kg[:p])

    def matrices(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Block-diagonal M, C, K of the uncoupled 2N-DOF system (contact couples them)."""
        n1, n = self.b1.n_floors, self.n_dof
        M, C, K = np.zeros((n, n)), np.zeros((n, n)), np.zeros((n, n))
        for b, sl in zip(self.buildings, (slice(0, n1), slice(n1, n))):
            M[sl, sl], C[sl, sl], K[sl, sl] = b.M, b.C, b.K
        return M, C, K

    def contact_matrix(self) -> np.ndarray:
        """G: column j is e(building 1, floor j) - e(building 2, floor j)."""
        G = np.zeros((self.n_dof, self.n_pairs))
        for j in range(self.n_pairs):
            G[j, j] = 1.0
            G[self.b1.n_floors + j, j] = -1.0
        return G

    def system_arrays(self, dt: float) -> SystemArrays:
        M, C, K = self.matrices()
        Keff = K + (2.0 / dt) * C + (4.0 / dt**2) * M
        Kinv = np.linalg.inv(Keff)
        G = self.contact_matrix()
        H = Kinv @ G
        S = G.T @ H
        S = 0.5 * (S + S.T)
        p = self.n_pairs
        c = np.ascontiguousarray
        return SystemArrays(
            dt,
            c(np.diag(M)),
            c(C),
            c(K),
            c(Kinv),
            c(H),
            c(S),
            np.arange(p, dtype=np.int64),
            np.arange(p, dtype=np.int64) + self.b1.n_floors,
        )
