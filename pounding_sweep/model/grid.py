"""Sweep grid: the Cartesian product of the scene's axes, generated chunk by chunk.

Run i's parameters come from unravelling i over the axis lengths (last axis fastest), so a
grid of any size costs memory only for the chunk being run.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pounding_sweep.scene import SWEEPABLE, Scene
from pounding_sweep.scene.axes import KS_FORMS, ks_counterpart

#: axes whose values are names, not numbers
CATEGORICAL = ("record", "law")


@dataclass(frozen=True)
class Grid:
    """Axes (name, values) and the scene's fixed values for the parameters that are not swept."""

    axes: tuple[tuple[str, tuple], ...]
    fixed: dict

    @classmethod
    def from_scene(cls, scene: Scene) -> Grid:
        fixed = {}
        for name, (section, key) in SWEEPABLE.items():
            part = getattr(scene, section)  # [experiment] may be absent: its keys are then None
            fixed[name] = None if part is None else getattr(part, key)
        swept = {a.name for a in scene.sweep}
        # a swept ks in one form makes the other form derived, not fixed
        for form in KS_FORMS:
            if form in swept:
                fixed[ks_counterpart(form)] = None
        for a in scene.sweep:
            fixed.pop(a.name)
        return cls(tuple((a.name, a.values) for a in scene.sweep), fixed)

    @property
    def shape(self) -> tuple[int, ...]:
        return tuple(len(v) for _, v in self.axes)

    @property
    def size(self) -> int:
        return int(np.prod(self.shape, dtype=np.int64)) if self.axes else 1

    def chunk(self, start: int, stop: int) -> dict[str, np.ndarray]:
        """Parameters of runs start..stop-1: one array per sweepable name (fixed ones broadcast)."""
        ids = np.arange(start, stop, dtype=np.int64)
        out: dict[str, np.ndarray] = {"run_id": ids}
        if self.axes:
            idx = np.unravel_index(ids, self.shape)
            for (name, values), ix in zip(self.axes, idx):
                out[name] = np.asarray(values, dtype=object if name in CATEGORICAL else float)[ix]
        n = ids.size
        for name, value in self.fixed.items():
            if name in CATEGORICAL:
                out[name] = np.full(n, value, dtype=object)
            else:
                out[name] = np.full(n, np.nan if value is None else value, dtype=float)
        return out

    def chunks(self, chunk_runs: int):
        for s in range(0, self.size, chunk_runs):
            yield s, min(self.size, s + chunk_runs)
