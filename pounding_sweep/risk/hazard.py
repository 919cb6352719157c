"""The annual rate of pounding: a fragility integrated over a hazard curve given as a table.

lambda_P(g) = int P(pounding | g, x) |d lambda(x)|, lambda(x) the annual rate of intensities above x (the total
probability theorem in rates: Cornell & Krawinkler 2000, "Progress and challenges in seismic performance
assessment", PEER Center News 3(2); Cornell et al. 2002, J. Struct. Eng. 128(4):526-533). The table's curve is
interpolated log-log (a power law between its points) and the integral is a sum over a fine geometric grid of
its range; the intensities above the table's largest are counted with the fragility's value there (their rate
times P at the largest intensity: a lower bound of their share, P growing with x), the ones below its smallest
not at all (unknown rates; small probabilities). For one power law lambda = k0 x^-k and a lognormal fragility
the integral over all x has the closed form k0 theta^-k exp(k^2 beta^2 / 2) (Cornell et al. 2002), the
check of this module (tests/risk).

Table format: CSV with a header row; columns `intensity_g` (the study's intensity measure, in g, increasing) and
`annual_rate` (of exceedance, per year, decreasing, > 0); other columns are ignored.
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass

import numpy as np

from pounding_sweep.errors import InputError
from pounding_sweep.scene.files import MAX_TABLE_BYTES, read_regular, text_problem

#: grid points per decade of intensity in the integral (log-trapezoid: error far below a table's own)
POINTS_PER_DECADE = 400


@dataclass(frozen=True)
class Hazard:
    """A hazard curve: intensities [g] and annual rates of exceedance [1/yr], from a table."""

    intensity_g: np.ndarray
    annual_rate: np.ndarray
    source: str

    def rate(self, x) -> np.ndarray:
        """lambda(x) by log-log interpolation inside the table (NaN outside)."""
        lx = np.log(np.asarray(x, dtype=float))
        li, lr = np.log(self.intensity_g), np.log(self.annual_rate)
        out = np.exp(np.interp(lx, li, lr))
        return np.where((lx >= li[0]) & (lx <= li[-1]), out, np.nan)


def read_hazard(path: str) -> Hazard:
    """A hazard table (module docstring); InputError naming the file, line and value otherwise."""
    raw = read_regular(path, "hazard table", MAX_TABLE_BYTES, InputError)
    if (why := text_problem(path, "hazard table", raw)) is not None:
        raise InputError(why)
    lines = raw.decode("utf-8-sig", errors="replace").splitlines()
    rows = list(csv.reader(line for line in lines if line.strip() and not line.lstrip().startswith("#")))
    if not rows:
        raise InputError(f"{path}: empty hazard table (expected columns intensity_g, annual_rate)")
    header = [h.strip() for h in rows[0]]
    for col in ("intensity_g", "annual_rate"):
        if col not in header:
            raise InputError(f"{path}, line 1: no column '{col}' in the header {header!r}")
    ix, ir = header.index("intensity_g"), header.index("annual_rate")
    xs, rs = [], []
    for lineno, row in enumerate(rows[1:], start=2):
        try:
            x, r = float(row[ix]), float(row[ir])
        except (ValueError, IndexError):
            raise InputError(f"{path}, row {lineno}: not two numbers in intensity_g, annual_rate: {row!r}") from None
        if not (math.isfinite(x) and x > 0 and math.isfinite(r) and r > 0):
            raise InputError(f"{path}, row {lineno}: intensity_g = {x!r}, annual_rate = {r!r}: both must be > 0")
        xs.append(x)
        rs.append(r)
    x, r = np.array(xs), np.array(rs)
    if x.size < 2:
        raise InputError(f"{path}: {x.size} row(s); a hazard curve needs at least 2")
    if not (np.diff(x) > 0).all():
        raise InputError(f"{path}: intensity_g must increase from row to row")
    if not (np.diff(r) < 0).all():
        raise InputError(f"{path}: annual_rate must decrease as intensity_g increases (a rate of exceedance)")
    return Hazard(x, r, str(path))


def annual_rate(hazard: Hazard, probability) -> np.ndarray:
    """lambda_P = int P(x) |d lambda| over the table's range plus lambda(x_max) P(x_max) (module docstring).
    `probability(x)`: the fragility at intensities x [g], returning (..., len(x))."""
    lo, hi = math.log10(hazard.intensity_g[0]), math.log10(hazard.intensity_g[-1])
    x = np.logspace(lo, hi, max(2, int(math.ceil((hi - lo) * POINTS_PER_DECADE)) + 1))
    lam = hazard.rate(x)
    p = np.asarray(probability(x), dtype=float)
    mid = 0.5 * (p[..., 1:] + p[..., :-1])
    return (mid * (lam[:-1] - lam[1:])).sum(-1) + p[..., -1] * lam[-1]


def power_law_rate(k0: float, k: float, theta: float, beta: float) -> float:
    """k0 theta^-k exp(k^2 beta^2 / 2): the annual rate for lambda = k0 x^-k and a lognormal fragility."""
    return k0 * theta ** (-k) * math.exp(0.5 * k * k * beta * beta)


__all__ = ["POINTS_PER_DECADE", "Hazard", "read_hazard", "annual_rate", "power_law_rate"]
