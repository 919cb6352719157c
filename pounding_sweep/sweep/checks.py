"""Checks of a whole sweep that find a probable mistake in its scene (each a pounding_sweep.warn warning):
before the runs, a time step too coarse for every run's contact; after them, a grid in which no run made
contact although the scene is there to study pounding (a gap in mm in a metre field)."""

from __future__ import annotations

import math

import numpy as np

from pounding_sweep.model.contact import contact_period
from pounding_sweep.scene.axes import contact_stiffness
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


def check_time_step(prep) -> None:
    """Warn when the time step leaves every run's contact under-resolved (each run would be flagged
    contact_underresolved): the softest contact of the grid has the longest contact period, so the
    grid's k_s values decide it before any run. With dt_s = 'auto' the step is chosen per run: no check."""
    scene = prep.scene
    if scene.integration.auto:
        return
    axes = dict(prep.grid.axes)
    ratios = axes.get("ks_ratio", (prep.grid.fixed.get("ks_ratio"),))
    newtons = axes.get("ks_N_per_m", (prep.grid.fixed.get("ks_N_per_m"),))
    k_ref = scene.contact.k_ref_N_per_m
    ks = np.array([contact_stiffness(r, n, k_ref) for r in ratios for n in newtons], dtype=float)
    m1, m2 = prep.model.pair_masses()
    if ks.size == 0 or m1.size == 0:
        return
    dt = prep.dt
    want = scene.integration.min_steps_per_contact_period
    period = contact_period(ks[:, None], m1[None, :], m2[None, :]).min(axis=1)  # per k_s: its shortest pair
    soft, stiff = float(period.max()), float(period.min())
    if soft / dt >= want:
        return
    every = round_down_125(stiff / want)
    some = round_down_125(soft / want)
    hint = f"dt_s = {every:g}" if every == some else f"dt_s = {some:g} (the softest contact) or {every:g} (every run)"
    warn(
        "contact_underresolved",
        f"[integration] dt_s = {dt:g} s under-resolves every run's contact: {soft / dt:.3g} steps per contact "
        f"period 2 pi sqrt(m_eff / k_s) at the softest k_s = {float(ks.min()):.4g} N/m, fewer than "
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
