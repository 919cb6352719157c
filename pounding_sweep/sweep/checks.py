"""Checks of a whole sweep that find a probable mistake in its scene (each a pounding_sweep.warn warning):
before the runs, a time step too coarse for every run's contact; after them, a grid in which no run made
contact although the scene is there to study pounding (a gap in mm in a metre field)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from pounding_sweep.warn import warn

#: sweep axes that are contact parameters: sweeping one says the scene studies pounding
CONTACT_AXES = ("gap_m", "ks_ratio", "ks_N_per_m", "r")


def round_down_125(x: float) -> float:
    """The largest of 1, 2, 5 x 10^k not above x (a time step to suggest)."""
    e = math.floor(math.log10(x))
    for m in (5.0, 2.0, 1.0):
        if m * 10.0**e <= x * (1 + 1e-12):
            return float(f"{m * 10.0**e:.0e}")
    return float(f"{10.0 ** (e - 1) * 5:.0e}")


#: the sweep axes that set a run's contact stiffness (and so its contact period)
STIFFNESS_AXES = ("law", "ks_ratio", "ks_N_per_m", "kh_N_per_m1_5")


def contact_stiffness_grid(grid):
    """The grid's distinct contact stiffnesses as run parameters (Grid.chunk's form): its law and stiffness axes
    crossed, every other parameter at the scene's value or its axis' first value (they do not set k)."""
    from pounding_sweep.model.grid import Grid

    axes = tuple((n, v) for n, v in grid.axes if n in STIFFNESS_AXES)
    fixed = dict(grid.fixed)
    fixed.update({n: v[0] for n, v in grid.axes if n not in STIFFNESS_AXES})
    sub = Grid(axes, fixed)
    return sub.chunk(0, sub.size)


def check_time_step(prep) -> None:
    """Warn when the time step leaves every run's contact under-resolved (each run would be flagged
    contact_underresolved): the softest contact of the grid has the longest contact period, so the
    grid's stiffness values decide it before any run (k_s, or for the Hertz-type laws their tangent stiffness
    at the reference penetration: sweep/prepare.py contact_arrays, whose steps per period this reads). With
    dt_s = 'auto' the step is chosen per run: no check."""
    from pounding_sweep.sweep.prepare import contact_arrays

    scene = prep.scene
    if scene.integration.auto or prep.model.n_pairs == 0:
        return
    params = contact_stiffness_grid(prep.grid)
    k, _, derived, _ = contact_arrays(prep.model, scene, params, prep.dt)
    steps = derived["steps_per_contact_period"]
    dt = prep.dt
    want = scene.integration.min_steps_per_contact_period
    softest = int(np.argmax(steps))
    if steps[softest] >= want:
        return
    soft, stiff = float(steps.max()) * dt, float(steps.min()) * dt  # contact periods [s]
    every = round_down_125(stiff / want)
    some = round_down_125(soft / want)
    hint = f"dt_s = {every:g}" if every == some else f"dt_s = {some:g} (the softest contact) or {every:g} (every run)"
    hertz = "kh_N_per_m1_5" in derived and np.isfinite(derived["kh_N_per_m1_5"][softest])
    what = (
        f"the softest k_h = {float(k[softest]):.4g} N/m^1.5 (tangent stiffness 1.5 k_h sqrt(reference_penetration_m))"
        if hertz
        else f"the softest k_s = {float(k[softest]):.4g} N/m"
    )
    warn(
        "contact_underresolved",
        f"[integration] dt_s = {dt:g} s under-resolves every run's contact: {steps[softest]:.3g} steps per contact "
        f"period 2 pi sqrt(m_eff / k) at {what}, fewer than "
        f"min_steps_per_contact_period = {want:g} (every run is flagged contact_underresolved): "
        f"use {hint}, or dt_s = 'auto'",
    )


class ContactTally:
    """Whether any run made contact, and how close the facing floors can have come, over result tables."""

    def __init__(self):
        self.runs = 0
        self.contact = False
        self.reach = 0.0  # largest |u1j| + |u2j| of a facing pair in a run: a bound on how far they closed in
        self.min_gap = math.inf

    def add(self, table, numpy_column) -> None:
        names = table.column_names
        self.runs += table.num_rows
        pairs = [n.removeprefix("impacts_f") for n in names if n.startswith("impacts_f")]
        for j in pairs:
            if np.nansum(numpy_column(table, f"impacts_f{j}")) > 0:
                self.contact = True
            a, b = f"peak_disp_b1f{j}_m", f"peak_disp_b2f{j}_m"
            if a in names and b in names:
                reach = np.abs(numpy_column(table, a)) + np.abs(numpy_column(table, b))
                self.reach = max(self.reach, float(np.nanmax(reach, initial=0.0)))
        if "gap_m" in names and table.num_rows:
            self.min_gap = min(self.min_gap, float(np.nanmin(numpy_column(table, "gap_m"))))


def check_contact(tally: ContactTally, scene) -> None:
    """Warn when no run of the grid made contact: the contact parameters then change nothing. A gap
    of a metre or more is named as the likely cause (millimetres written in gap_m, which is in metres)."""
    if tally.contact or tally.runs == 0:
        return
    swept = [a.name for a in scene.sweep if a.name in CONTACT_AXES and len(a.values) > 1]
    gap = tally.min_gap
    parts = [
        f"no run made contact ({tally.runs:,} run(s), largest pounding force 0 N): the facing floors moved "
        f"at most {tally.reach * 1e3:.3g} mm toward each other, against a gap of {gap * 1e3:.4g} mm"
    ]
    if gap >= 0.5:
        parts.append(f"gap_m is in metres: gap_m = {gap:g} is {gap:g} m (for {gap:g} mm write {gap / 1e3:g})")
    if swept:
        parts.append(f"the swept {', '.join(swept)} change nothing here")
    warn("no_contact", "; ".join(parts))


#: the most memory the calibration's global stage may keep in histories: its Sobol points run as one batch
GLOBAL_STAGE_BYTES = 2**30


def check_calibration(prep) -> None:
    """Before the grid, what would make the calibration after it fail or mislead, each one ConfigError naming
    the key: a time offset (a [sweep] value, or a [calibrate] bound) that moves the scored window off the
    experiment's table; a channel whose noise floor cannot be estimated (too few samples in the window: NaN; or
    none at all: 0) when [calibrate] gives no noise_m for it; a global stage whose histories would not fit in
    GLOBAL_STAGE_BYTES."""
    from pounding_sweep.errors import ConfigError, ExperimentError
    from pounding_sweep.model.experiment import NOISE_MIN_DIFFERENCES, noise_floor
    from pounding_sweep.scene.channels import ACC_PREFIX
    from pounding_sweep.sweep.scoring import score_spec

    scene, exp = prep.scene, prep.experiment
    if exp is None:
        return
    cal = scene.calibrate
    offsets = [("[sweep] time_offset_s", v) for v in scene.axis_values("time_offset_s")]
    if cal is not None and "time_offset_s" in cal.parameters:
        bounds = cal.parameters["time_offset_s"]
        offsets += [
            (f"[calibrate] parameters.time_offset_s = [{bounds[0]:g}, {bounds[1]:g}]", float(b)) for b in bounds
        ]
    for key, offset in offsets:
        moved = dataclasses.replace(scene.experiment, time_offset_s=offset)
        try:
            score_spec(exp, moved, prep.model.floors, prep.excitation.max_duration_s, prep.dt)
        except ExperimentError as e:
            raise ConfigError(f"{key}: at {offset:g} s, {e}") from None
    if cal is None:
        return
    duration = prep.excitation.max_duration_s
    lo, hi = scene.experiment.window_s or (0.0, duration)
    t_sim = exp.time_s - scene.experiment.time_offset_s
    inside = (t_sim >= lo) & (t_sim <= hi)
    weights = prep.combination.weights if prep.combination is not None else None
    rows = 0
    for i, code in enumerate(prep.score_codes):
        if weights is not None and weights[i] == 0:
            continue
        acc = code.startswith(ACC_PREFIX)
        rows += 1 if acc else 2
        if cal.noise_m is not None and not acc:
            continue
        y = exp.channels[code][inside]
        sigma, _ = noise_floor(y)
        if not sigma > 0:
            why = (
                f"{y.size} sample(s) in the scored window, fewer than the {NOISE_MIN_DIFFERENCES + 1} its noise floor "
                "is estimated from"
                if not np.isfinite(sigma)
                else "no noise at all (its differences are all 0: quantised or noise-free data)"
            )
            fix = "widen [experiment] window_s" if not np.isfinite(sigma) else "give the tracking noise"
            raise ConfigError(
                f"[calibrate]: the experiment's channel {code} has {why}; the residuals are weighed by it: {fix}, or "
                "give [calibrate] noise_m (the tracking noise in m)"
                + (" (acceleration channels need samples for their own)" if acc else "")
            )
    per_run = rows * (prep.excitation.max_steps // scene.output.history_decimate + 1) * 8
    if cal.global_points * per_run > GLOBAL_STAGE_BYTES:
        most = max(0, GLOBAL_STAGE_BYTES // per_run)
        raise ConfigError(
            f"[calibrate] global_points = {cal.global_points:,}: its runs are made as one batch and keep "
            f"{cal.global_points * per_run / 2**30:.3g} GiB of histories ({per_run / 2**20:.3g} MiB a run), more than "
            f"{GLOBAL_STAGE_BYTES / 2**30:g} GiB: use at most {most:,} points"
        )
