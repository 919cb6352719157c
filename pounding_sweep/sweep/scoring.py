"""The experiment a sweep scores against: its table read (or its video tracked, once per process) and
turned into the kernel's ScoreSpec, the samples inside the scored window on the simulation clock."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from pounding_sweep.engine.inputs import ScoreSpec
from pounding_sweep.errors import ExperimentError, VideoError
from pounding_sweep.model.experiment import Experiment, experiment_from_table, read_table
from pounding_sweep.scene import ExperimentConfig
from pounding_sweep.scene.channels import floor_dof


def load_experiment(cfg: ExperimentConfig, floors: tuple[int, int]) -> Experiment:
    """Read and check the table of an [experiment] section, or track its [experiment.video] into one."""
    if cfg.video is not None:
        df, md, where = _tracked(cfg.video)
    else:
        df, md = read_table(cfg.table)
        where = cfg.table
    return experiment_from_table(df, md, where, cfg, floors)


_TRACKED: dict = {}  # (spec, file size, mtime) -> (table, provenance): a video is tracked once per process


def _tracked(spec) -> tuple:
    """Track the video of an [experiment.video] section (OpenCV, lazily imported) into the table
    format above; a video that cannot give one is an ExperimentError naming the file."""
    from pounding_sweep.video.tracker import tracked_table

    try:
        st = Path(spec.path).stat()
        key = (spec, st.st_size, st.st_mtime_ns)
        if key not in _TRACKED:
            from pounding_sweep.progress import Progress

            df, md = tracked_table(spec, progress=Progress(unit="frames"))
            _TRACKED.clear()
            _TRACKED[key] = (df, md)
        df, md = _TRACKED[key]
    except FileNotFoundError:
        raise ExperimentError(f"{spec.path}: video not found ([experiment.video] path)") from None
    except VideoError as e:
        raise ExperimentError(str(e)) from None
    return df, {"tracking": md}, spec.path


def score_spec(
    exp: Experiment, cfg: ExperimentConfig, floors: tuple[int, int], sim_duration_s: float, dt: float
) -> ScoreSpec:
    """The samples inside the scored window, on the simulation clock, as kernel arrays.

    Simulation time = experiment time - time_offset_s. The window defaults to all of the
    experiment that the simulation covers; a window outside that is an error.
    """
    ts = exp.time_s - cfg.time_offset_s
    lo, hi = (0.0, sim_duration_s) if cfg.window_s is None else cfg.window_s
    if cfg.window_s is not None and (lo < 0 or hi > sim_duration_s + 1e-9):
        raise ExperimentError(
            f"[experiment] window_s = [{lo}, {hi}]: outside the simulation, which covers 0 .. {sim_duration_s:.6g} s"
        )
    tol = 1e-12 * dt  # the kernel fills samples up to t_step + 1e-12 dt: the same tolerance here
    keep = (ts >= lo - tol) & (ts <= hi + tol) & (ts >= 0) & (ts <= sim_duration_s + tol)
    if keep.sum() < 2:
        raise ExperimentError(
            f"{exp.path}: its time range {exp.time_s[0]:.6g} .. {exp.time_s[-1]:.6g} s (offset {cfg.time_offset_s} s) "
            f"leaves {int(keep.sum())} sample(s) (at least 2 needed) in the simulation 0 .. {sim_duration_s:.6g} s "
            f"within the window [{lo}, {hi}]"
        )
    codes = list(exp.channels)
    x = np.ascontiguousarray(np.stack([exp.channels[c][keep] for c in codes]))
    dof = np.array([floor_dof(c, floors, "channel") for c in codes], dtype=np.int64)
    max_lag = int(min(round(cfg.max_lag_s / exp.dt_sample), keep.sum() - 2))  # at most the window
    return ScoreSpec(np.ascontiguousarray(ts[keep]), x, dof, max_lag, exp.dt_sample)
