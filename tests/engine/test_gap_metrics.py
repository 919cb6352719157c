"""Closest approach (per floor pair) and peak interstory drift (per story): the kernels' metrics against
the run's own histories (the same numbers: exact) and, without contact, against the closed-form modal
solution (Newmark's error bound)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from conftest import SWEEPS

from pounding_sweep.model.coupled import CoupledModel
from pounding_sweep.reference import modal_harmonic_response
from pounding_sweep.scene import load_scene
from pounding_sweep.sweep import simulate


def scene(duration=1.0):
    s = load_scene(SWEEPS / "paper_6hz.toml")
    return dataclasses.replace(s, excitation=dataclasses.replace(s.excitation, duration_s=duration))


def channels(floors=(3, 3)):
    return [f"disp_b{b}f{f}" for b, nf in zip((1, 2), floors) for f in range(1, nf + 1)]


@pytest.mark.parametrize("gap_m, scheme", [(1.0, "event"), (5e-3, "implicit"), (5e-3, "paper")])
def test_metrics_equal_the_histories_at_the_step_ends(gap_m, scheme):
    """Without events inside steps (no contact, or the implicit and paper schemes, which switch at step
    ends only) the closest approach and the drifts are extremes over the step ends: the very values the
    histories hold, so equal bit for bit, time included."""
    h, m = simulate(scene(), channels=channels(), ks_ratio=1.0, r=0.4, gap_m=gap_m, scheme=scheme)
    t = h.t_s.to_numpy()
    for j in (1, 2, 3):
        near = gap_m - (h[f"disp_b1f{j}_m"] - h[f"disp_b2f{j}_m"]).to_numpy()
        k = int(np.argmin(near))
        assert m[f"closest_approach_f{j}_m"] == near[k]
        # the kernel's piece end is (k - 1) dt + dt, the history's stamp k dt: equal to two roundings
        assert m[f"closest_approach_time_f{j}_s"] == pytest.approx(t[k], rel=4 * np.finfo(float).eps)
    for b in (1, 2):
        u = np.column_stack([np.zeros(len(h))] + [h[f"disp_b{b}f{f}_m"].to_numpy() for f in (1, 2, 3)])
        for s in (1, 2, 3):
            assert m[f"peak_drift_b{b}s{s}_m"] == np.abs(u[:, s] - u[:, s - 1]).max()
    if gap_m < 0.01:
        assert m["closest_approach_f3_m"] < 0 < m["impacts_f3"]  # it pounds: the floors overlapped


def test_closest_approach_with_events_inside_steps_includes_the_switches():
    """The event scheme also checks the ends of sub-steps (at contact switches), so the closest approach is
    at most the step ends' least value, and equal to minus the largest penetration once they overlap."""
    h, m = simulate(scene(), channels=channels(), ks_ratio=1.0, r=0.4, gap_m=5e-3, scheme="event")
    for j in (1, 2, 3):
        near = 5e-3 - (h[f"disp_b1f{j}_m"] - h[f"disp_b2f{j}_m"]).to_numpy()
        assert m[f"closest_approach_f{j}_m"] <= near.min()
        if m[f"impacts_f{j}"] > 0:
            assert m[f"closest_approach_f{j}_m"] == -m[f"max_penetration_f{j}_m"]


def test_closest_approach_without_contact_is_the_modal_solutions():
    """Gap 1 m, 6 Hz table motion: gap - max (u1 - u2) against the exact modal solution (Chopra sec. 3.2
    per mode), evaluated densely. Bound: Newmark average acceleration's error on this run, 5e-5 of the
    peak displacement at dt = 1e-4 s (tests/engine/test_scalar.py measures 2.6e-5), plus the sampling of
    a maximum at the step ends, (w dt)^2 / 8 of the relative displacement's amplitude for its highest mode."""
    s = scene(1.5)
    h, m = simulate(s, channels=channels(), gap_m=1.0)
    M, C, K = CoupledModel.from_scene(s).matrices()
    t = np.linspace(0.0, 1.5, 150001)
    exact = modal_harmonic_response(M, C, K, 0.002, 2 * math.pi * 6.0, t)
    peak = np.abs(exact).max()
    w_max = math.sqrt(np.max(np.linalg.eigvals(np.linalg.solve(M, K)).real))
    for j in (1, 2, 3):
        rel = exact[:, j - 1] - exact[:, 3 + j - 1]
        bound = 5e-5 * peak + (w_max * 1e-4) ** 2 / 8 * np.abs(rel).max()
        assert abs(m[f"closest_approach_f{j}_m"] - (1.0 - rel.max())) <= bound
