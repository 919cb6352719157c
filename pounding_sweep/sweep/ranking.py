"""Which runs fit the experiment best: running minima over the streamed chunks, the channels'
combined error, and an optional continuous refinement of (k_s/k, r) with scipy.optimize."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import pyarrow as pa

from pounding_sweep.engine.score import ACC_SCORE_NAMES, S_REL_RMS_PCT, SCORE_NAMES
from pounding_sweep.scene.channels import is_acceleration
from pounding_sweep.scene.parameters import BEST, is_log, names

if TYPE_CHECKING:  # pandas costs 0.3 s to import: only where a table is built
    import pandas as pd

    from pounding_sweep.sweep.scoring import Combination

#: the columns of a best-runs row: the run, its law and the parameters that describe it (scene/parameters.py)
PARAM_COLUMNS = ("run_id", "contact_law", *names(BEST))


def score_names(code: str) -> tuple[tuple[str, str], ...]:
    """The score columns' name templates and meanings of one channel: a displacement's ('b1f3') or an
    absolute acceleration's ('abs_acc_b1f3', its peak in m/s^2)."""
    return ACC_SCORE_NAMES if is_acceleration(code) else SCORE_NAMES


def score_columns(codes: list[str]) -> list[tuple[str, str]]:
    """(column name, meaning) of every per-channel score, channel-major."""
    return [(name.format(c=c), doc) for c in codes for name, doc in score_names(c)]


def combined_meaning(comb: Combination) -> str:
    """What rel_rms_combined_pct holds for this combination (the result file's column description)."""
    which = "the channels weighted > 0, by their weights" if comb.weights is not None else "every scored channel"
    return f"the channels' eq. 20 errors made one per run: their {comb.how} over {which} ([experiment] combine) [%]"


def combine_errors(rel_rms: np.ndarray, how: str, weights: np.ndarray | None = None) -> np.ndarray:
    """Channels' eq. 20 errors (runs x channels) -> one error per run: mean, max or rms; with `weights`
    (per channel, summing to 1; sweep/scoring.py combination) over the channels weighted > 0: the weighted
    mean sum w_c e_c, the largest e_c, or the weighted rms sqrt(sum w_c e_c^2)."""
    if weights is not None:
        sel = weights > 0
        e, w = rel_rms[:, sel], weights[sel]
        if how == "mean":
            return (e * w).sum(axis=1) / w.sum()
        if how == "max":
            return e.max(axis=1)
        return np.sqrt((e**2 * w).sum(axis=1) / w.sum())
    if how == "mean":
        return rel_rms.mean(axis=1)
    if how == "max":
        return rel_rms.max(axis=1)
    return np.sqrt((rel_rms**2).mean(axis=1))


def score_table_columns(scores: np.ndarray, codes: list[str], comb: Combination) -> dict[str, np.ndarray]:
    """Per-run score columns from the kernel's (runs, channels, scores) array, plus the combined error."""
    cols = {}
    for ci, c in enumerate(codes):
        for si, (name, _) in enumerate(score_names(c)):
            cols[name.format(c=c)] = scores[:, ci, si]
    cols["rel_rms_combined_pct"] = combine_errors(scores[:, :, S_REL_RMS_PCT], comb.how, comb.weights)
    return cols


class Ranking:
    """Best (lowest-error) run per criterion, kept across chunks without keeping the chunks."""

    def __init__(self, criteria: list[str]):
        self.criteria = criteria
        self.best: dict[str, dict] = {}

    def update(self, table: pa.Table) -> None:
        for crit in self.criteria:
            v = table.column(crit).to_numpy(zero_copy_only=False)
            if np.all(np.isnan(v)):
                continue
            i = int(np.nanargmin(v))
            if crit not in self.best or v[i] < self.best[crit][crit]:
                row = {k: table.column(k)[i].as_py() for k in table.column_names if k in PARAM_COLUMNS or k == crit}
                row["status"] = table.column("status")[i].as_py()
                self.best[crit] = row

    def frame(self) -> pd.DataFrame:
        rows = []
        for crit in self.criteria:
            if crit in self.best:
                r = dict(self.best[crit])
                rows.append({"criterion": crit, "error_pct": r.pop(crit), **r})
        import pandas as pd

        return pd.DataFrame(rows)


@dataclass
class Refinement:
    """Result of the continuous search started from the best grid cell."""

    start: dict
    start_error_pct: float
    optimum: dict
    error_pct: float
    evaluations: int
    message: str


def refine(
    objective: Callable[[dict], float],
    start: dict,
    start_error: float,
    bounds: dict[str, tuple[float, float]],
    max_evals: int,
) -> Refinement:
    """Minimise objective({ks_ratio, r}) by bounded Nelder-Mead from the best grid cell.

    k_s/k is searched on a log scale (the grid spans decades); the objective is not smooth
    (impacts come and go), so a derivative-free method is used.
    """
    from scipy.optimize import minimize

    names = list(bounds)
    log = {n: is_log(n) for n in names}

    def to_x(p):
        return np.array([np.log10(p[n]) if log[n] else p[n] for n in names])

    def from_x(x):
        return {n: float(10**xi if log[n] else xi) for n, xi in zip(names, x)}

    lo = np.array([np.log10(bounds[n][0]) if log[n] else bounds[n][0] for n in names])
    hi = np.array([np.log10(bounds[n][1]) if log[n] else bounds[n][1] for n in names])
    x0 = np.clip(to_x(start), lo, hi)
    cache: dict[tuple, float] = {}

    def f(x):
        key = tuple(np.round(x, 12))
        if key not in cache:
            cache[key] = objective(from_x(np.clip(x, lo, hi)))
        return cache[key]

    # the start is the grid cell itself: its error is the grid's (no log10 round trip of k_s)
    cache[tuple(np.round(x0, 12))] = e0 = float(start_error)
    # initial simplex: a quarter of each parameter's range, pointed into the box
    span = hi - lo
    simplex = [x0]
    for i in range(len(names)):
        xi = x0.copy()
        step = 0.25 * span[i] if span[i] > 0 else 0.0
        xi[i] = x0[i] + step if x0[i] + step <= hi[i] else x0[i] - step
        simplex.append(xi)
    res = minimize(
        f,
        x0,
        method="Nelder-Mead",
        bounds=list(zip(lo, hi)),
        options={"initial_simplex": np.array(simplex), "maxfev": max_evals, "xatol": 1e-3, "fatol": 1e-4},
    )
    xbest = np.clip(res.x, lo, hi)
    ebest = f(xbest)
    if not ebest < e0:  # never report worse than the start; report the start exactly
        return Refinement(dict(start), e0, dict(start), e0, len(cache), str(res.message))
    return Refinement(dict(start), e0, from_x(xbest), float(ebest), len(cache), str(res.message))
