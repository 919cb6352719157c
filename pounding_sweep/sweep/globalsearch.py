"""The calibration's global stage: find the basin of the best fit, not a local minimum near the first guess.

Why: pounding responses are sensitive to their parameters, more so the longer the record: an error in the
contact stiffness or a building's frequency shifts the impacts, the shift grows impact after impact, and the
misfit over a whole record is a landscape of narrow basins (on a 6 Hz test with k_s/k = 10 and r = 0.8 the
misfit along k_s/k over 4 s has a dozen local minima, over the first second one). A design over the bounds
and least squares from its best points then stop in a wrong basin (9 of 30 in benchmarks/bench_calibration.py's
family, 8 of its 10 stiff, high-r, low-noise tests; 11-19 times the noise floor on that test). A population
method on the whole record gets there at many times the cost (benchmarks/bench_global_de.py: scipy's
differential_evolution, 70 members x 30 generations run as batches, 3969 runs and 213 s to a member 12.6 times
the noise floor, from which least squares reached the basin; this stage: 289 runs, 5 s).

Method: incremental single shooting (Michalik, Hannemann & Marquardt 2009, "Incremental single shooting - a
robust method for the estimation of parameters in dynamical systems", Comput. Chem. Eng. 33:1298): fit the
leading part of the record, where the landscape is smooth, then lengthen the fitted horizon step by step,
each fit starting from the last one's optimum, until the whole record is fitted.
* Horizons: the first spans at least 4 periods of the slowest building's first mode (4 forcing periods for a
  harmonic test) and at least the time by which 1/8 of the measured signal's energy (noise-normalised) has
  arrived; each next one is twice as long, the last the whole scored window (a horizon past 0.8 of it is
  the whole window). Simulations stop at each horizon's end, so the short ones cost less.
* Design on the first horizon: a scrambled Sobol design (scipy.stats.qmc) of max(global_points, 16 p) points,
  rounded up to a power of 2 (its size grows with the number of parameters p), run as one batch, plus the
  sweep's best cell when there is one (global_points = 0: no design, and no restart; the local fits start
  from the best cell, else the scene's values).
* Starts: the `starts` best design points that lie apart (each at least 0.1 of the bounds' diagonal, in the
  fit's coordinates, from those taken): local least squares from each on the first horizon, best first, until
  one fits it to within misfit_factor times the noise floor (the data then have no better basin to offer on
  that horizon). Of the distinct optima, up to BEAM whose misfit is below misfit_factor or within COMPARABLE
  times the best's are carried to the next horizon, refitted there (the same rules), and so on.
* Restart: when the best optimum on the whole record misfits more than misfit_factor times the noise floor,
  the search runs once more from a fresh design (another scramble, twice the points); the better answer
  is kept. A model that cannot explain the data pays this twice; the warning says so either way.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from pounding_sweep.sweep.fitstats import local_fit, misfit_of

BEAM = 2  # optima carried from one horizon to the next
COMPARABLE = 2.0  # ... when their misfit is within this factor of the best's (or below misfit_factor)
FIRST_PERIODS = 4  # the first horizon spans at least this many periods (slowest mode, forcing)
FIRST_ENERGY = 1.0 / 8.0  # ... and at least this share of the measured signal's (noise-normalised) energy
WHOLE = 0.8  # a horizon past this share of the scored window is the whole window
DESIGN_PER_PARAMETER = 16  # design points per fitted parameter (at least)
APART = 0.1  # starts at least this share of the bounds' diagonal apart (fit coordinates)


@dataclass
class Search:
    """The global stage's answer: the optimum on the whole record (fit coordinates), the local fit there (its
    residuals .fun and Jacobian .jac) and what each stage did."""

    z: np.ndarray
    result: object  # scipy OptimizeResult of the last local fit
    stages: list[dict] = field(default_factory=list)
    restarted: bool = False


def horizons(prob) -> list[float]:
    """The ladder of horizon ends [s, simulation time] (module docstring), the last the scored window's end."""
    lo, hi = prob.window
    periods = [float(b.modes().period_s.max()) for b in prob.prep.model.buildings]
    first = FIRST_PERIODS * max(periods)
    exc = prob.scene.excitation
    if exc.type == "harmonic":
        first = max(first, FIRST_PERIODS / exc.frequency_Hz)
    t = prob.times() - prob.offset0
    e = np.concatenate([(v / s) ** 2 for v, s in zip(prob.target.values, prob.target.sigma)])
    order = np.argsort(t, kind="stable")
    cum = np.cumsum(e[order])
    if cum[-1] > 0:
        first = max(first, float(t[order][np.searchsorted(cum, FIRST_ENERGY * cum[-1])]) - lo)
    out, length = [], first
    while lo + length < lo + WHOLE * (hi - lo):
        out.append(lo + length)
        length *= 2.0
    return out + [hi]


def design_size(global_points: int, p: int) -> int:
    """Sobol points of the design: max(global_points, 16 p), rounded up to a power of 2; none for
    global_points = 0 (no global stage: local fits from the sweep's best cell, else the scene's values)."""
    if global_points <= 0:
        return 0
    return 2 ** max(1, math.ceil(math.log2(max(global_points, DESIGN_PER_PARAMETER * p, 2))))


def find_basin(prob, cal, best_cell: dict | None = None, progress=None) -> Search:
    """The global stage (module docstring) for calibrate.Problem `prob` and [calibrate] `cal`."""

    ladder = horizons(prob)
    first = _search(prob, cal, ladder, best_cell, 12345, design_size(cal.global_points, len(prob.names)))
    if progress is not None:
        progress(f"calibration: global stage over {len(ladder)} horizons, {prob.evaluations} runs")
    if cal.global_points <= 0 or misfit_of(first.result.fun, prob.sizes()) <= cal.misfit_factor:
        return first
    again = _search(prob, cal, ladder, None, 54321, 2 * design_size(cal.global_points, len(prob.names)))
    if progress is not None:
        progress(f"calibration: restarted from fresh points, {prob.evaluations} runs")
    best = again if again.result.cost < first.result.cost else first
    best.stages = first.stages + again.stages
    best.restarted = True
    return best


def _search(prob, cal, ladder, best_cell, seed, n_design) -> Search:
    from scipy.stats import qmc

    lo, hi = prob.z_bounds
    p = len(prob.names)
    sub = prob.restricted((prob.window[0], ladder[0])) if len(ladder) > 1 else prob
    z = np.zeros((0, p))
    if n_design:
        z = qmc.scale(qmc.Sobol(p, scramble=True, seed=seed).random_base2(int(round(math.log2(n_design)))), lo, hi)
    if best_cell is not None and all(n in best_cell and np.isfinite(best_cell[n]) for n in prob.names):
        z = np.vstack([np.clip(prob.to_z(np.array([best_cell[n] for n in prob.names])), lo, hi), z])
    if not z.shape[0]:  # no design, no best cell: the scene's own values
        z = np.clip(prob.to_z(np.array([float(prob.base[n][0]) for n in prob.names])), lo, hi)[None, :]
    r = sub.residuals(np.array([prob.to_theta(zz) for zz in z]))
    rss = np.sum(r * r, axis=1)
    starts = _apart(z[np.argsort(rss)], (hi - lo), max(cal.starts, 1))
    stages = [
        {
            "horizon_s": ladder[0],
            "design": int(z.shape[0]),
            "best_design_misfit": misfit_of(r[np.argmin(rss)], sub.sizes()),
        }
    ]
    carried = starts
    result = None
    for k, end in enumerate(ladder):
        here = sub if k == 0 else (prob if end >= ladder[-1] else prob.restricted((prob.window[0], end)))
        fits = []
        for z0 in carried:  # best first; an optimum at the noise floor here ends the horizon's starts
            fits.append(local_fit(here, z0, cal.max_evals))
            if misfit_of(fits[-1].fun, here.sizes()) <= cal.misfit_factor:
                break
        fits.sort(key=lambda f: f.cost)
        best = misfit_of(fits[0].fun, here.sizes())
        kept = []
        for f in fits:  # distinct optima, comparable with the best (module docstring)
            if all(np.max(np.abs(f.z - g.z) / (hi - lo)) > 1e-3 for g in kept):
                if misfit_of(f.fun, here.sizes()) <= max(cal.misfit_factor, COMPARABLE * best):
                    kept.append(f)
        result = kept[0]
        carried = [f.z for f in kept[:BEAM]]
        stages.append({"horizon_s": end, "starts": len(fits), "misfit": best})
        if here is not prob:  # the runs of a shorter horizon count as runs of the calibration
            prob.evaluations += here.evaluations
            here.evaluations = 0
    return Search(result.z, result, stages)


def _apart(z_sorted: np.ndarray, width: np.ndarray, k: int) -> list[np.ndarray]:
    """Up to k of the points (best first) each at least APART of the bounds' diagonal from those taken."""
    taken: list[np.ndarray] = []
    diag = math.sqrt(len(width))
    for zz in z_sorted:
        if all(np.linalg.norm((zz - t) / width) >= APART * diag for t in taken):
            taken.append(zz)
        if len(taken) == k:
            break
    return taken
