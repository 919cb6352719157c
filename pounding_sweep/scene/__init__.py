"""The scene layer: a scene file (TOML) -> validated, frozen dataclasses; `--describe`; the config hash.

Holds what a user writes and nothing computed from it. May import only the standard library, NumPy
(axis ranges) and the shared bottom modules (pounding_sweep.errors, pounding_sweep.codes): never Numba,
SciPy, pandas, pyarrow or OpenCV, so a scene is read and refused in a fraction of a second.
Modules: schema (the dataclasses), parse (TOML -> Scene), validate, axes (sweepable parameters, the
k_s rule), channels (history and floor names), video ([experiment.video]), keys, hashing, describe.
"""

from pounding_sweep.errors import ConfigError
from pounding_sweep.scene.axes import SWEEPABLE, contact_stiffness, ks_counterpart, setting_ks
from pounding_sweep.scene.describe import describe
from pounding_sweep.scene.parse import load_scene, scene_from_dict
from pounding_sweep.scene.schema import (
    EXECUTORS,
    MAX_GRID,
    MAX_STEPS,
    SECTIONS,
    Axis,
    BuildingConfig,
    ContactConfig,
    ExcitationConfig,
    ExecutionConfig,
    ExperimentConfig,
    IntegrationConfig,
    OutputConfig,
    Scene,
)
from pounding_sweep.scene.validate import validate

__all__ = [
    "ConfigError",
    "SWEEPABLE",
    "contact_stiffness",
    "ks_counterpart",
    "setting_ks",
    "describe",
    "load_scene",
    "scene_from_dict",
    "EXECUTORS",
    "MAX_GRID",
    "MAX_STEPS",
    "SECTIONS",
    "Axis",
    "BuildingConfig",
    "ContactConfig",
    "ExcitationConfig",
    "ExecutionConfig",
    "ExperimentConfig",
    "IntegrationConfig",
    "OutputConfig",
    "Scene",
    "validate",
]
