"""The solve_ivp synthetic generator (synthetic.make_ivp_experiment) and what it rests on: the softening-story
reference (reference/softening.py) and the MEMS accelerometer model (synthetic.mems_samples).

* With linear stories the softening reference solves the same equations as reference/ivp.py's continuous
  reference (a nonlinear right-hand side against the linear systems): the same histories to their tolerance.
* story_chains reads per-story stiffnesses back from the assembled matrix.
* Softening stories lower the response's frequency: the fitted (linear) stiffness scale falls below 1
  (tests/sweep/test_uncertainty.py fits it).
* The accelerometer's moving average of a sinusoid has the closed form of a Dirichlet kernel.
* The generator's table holds the reference's displacement at the sample instants and the accelerometer's
  output of the reference's absolute acceleration, whose integral is the absolute velocity's change.
"""

from __future__ import annotations

import dataclasses
import functools
import math

import numpy as np
import pytest
from conftest import SWEEPS

from pounding_sweep.reference.ivp import continuous_reference, law_ivp_reference
from pounding_sweep.reference.newmark import resolve
from pounding_sweep.reference.softening import softening_reference, story_chains
from pounding_sweep.scene import load_scene
from pounding_sweep.synthetic import make_ivp_experiment, mems_samples, perturbed


@functools.cache
def scene_6hz(duration_s: float):
    s = load_scene(SWEEPS / "paper_6hz.toml")
    return dataclasses.replace(s, sweep=(), excitation=dataclasses.replace(s.excitation, duration_s=duration_s))


def test_linear_stories_give_the_continuous_reference():
    """k_s/k = 3, r = 0.5, 1 s of the 6 Hz test: the top floors' displacement on the 5 ms grid agree within 1e-8 of
    their peak. Both are DOP853 at rtol 1e-10 on the same pieces (the events located alike); each one's global
    error is at most about rtol x the ~100 pieces x the response's growth between events (of order 1), so
    1e-8 is their error bound, not a tuned figure; the impact counts are equal."""
    s = scene_6hz(1.0)
    a = continuous_reference(s, ks_ratio=3.0, r=0.5)
    b = softening_reference(s, None, dt_out=5e-3, ks_ratio=3.0, r=0.5)
    top = b["u"][:, [2, 5]]
    assert np.max(np.abs(top - a.top)) <= 1e-8 * np.max(np.abs(a.top))
    np.testing.assert_array_equal(a.impacts, b["impacts"])


def test_story_chains_read_per_story_stiffness_back():
    s = perturbed(scene_6hz(0.1), ((1.08, 1.0, 0.92), (0.9, 1.1, 1.0)), (1.0, 1.0))
    P = resolve(s)
    (d1, k1), (d2, k2) = story_chains(P.K, (3, 3))
    np.testing.assert_array_equal(d1, [0, 1, 2])
    np.testing.assert_array_equal(d2, [3, 4, 5])
    # K's entries are sums and differences of the k's: recovered to a few ulps of the largest
    np.testing.assert_allclose(k1, 5920.0 * np.array([1.08, 1.0, 0.92]), rtol=1e-13)
    np.testing.assert_allclose(k2, 5140.0 * np.array([0.9, 1.1, 1.0]), rtol=1e-13)


def test_softening_stories_tend_to_the_linear_frame_and_depart_from_it_with_amplitude():
    """The separated 6 Hz test (no contact), 1 s: with a drift scale of 1 m against drifts of a few mm the
    response is the linear one up to the cubic term, relative size X^2 / (4 s^2) ~ 1e-5 (bounded here by 1e-4
    of the peak); with 5 mm it departs by more than 5 % of the peak."""
    s = dataclasses.replace(scene_6hz(1.0), contact=dataclasses.replace(scene_6hz(1.0).contact, gap_m=0.05))
    lin = softening_reference(s, None, dt_out=1e-3)
    near = softening_reference(s, 1.0, dt_out=1e-3)
    soft = softening_reference(s, 0.005, dt_out=1e-3)
    assert lin["impacts"].sum() == near["impacts"].sum() == soft["impacts"].sum() == 0
    peak = np.max(np.abs(lin["u"][:, 2]))
    assert np.max(np.abs(near["u"][:, 2] - lin["u"][:, 2])) <= 1e-4 * peak
    assert np.max(np.abs(soft["u"][:, 2] - lin["u"][:, 2])) > 0.05 * peak


def test_the_accelerometer_average_of_a_sinusoid_is_a_dirichlet_kernel():
    """sin(w t) sampled at 1 kHz and averaged over its 10 most recent samples, output at 100 samples/s: the
    output is G sin(w (t - 4.5 ms)) with G = sin(10 w D / 2) / (10 sin(w D / 2)), D = 1 ms (the sum of a
    geometric series of phasors); equal to rounding (1e-12 of the amplitude) once the 10 samples lie after 0."""
    f = 37.0
    w = 2 * math.pi * f
    t = np.arange(0, 2001) * 1e-3
    tout, aout = mems_samples(t, np.sin(w * t), 100.0, 1000.0)
    np.testing.assert_array_equal(tout, t[::10])
    gain = math.sin(10 * w * 1e-3 / 2) / (10 * math.sin(w * 1e-3 / 2))
    expect = gain * np.sin(w * (tout - 4.5e-3))
    np.testing.assert_allclose(aout[1:], expect[1:], rtol=0, atol=1e-12)


def test_mems_samples_refuses_rates_that_do_not_divide():
    t = np.arange(0, 100) * 1e-3
    with pytest.raises(ValueError, match="not a multiple"):
        mems_samples(t, np.zeros(t.size), 300.0, 1000.0)


def test_a_hertz_damp_table_is_the_reference_seen_by_tracker_and_accelerometer():
    """1 s of the 6 Hz test with the Hertz-damp law, no noise: the displacement columns are the reference's at the
    100 samples/s instants (exactly: the same numbers, in mm), the accelerometer columns are mems_samples of its
    absolute acceleration, and that acceleration integrates to the absolute velocity's change: over each 10 ms
    the trapezoid rule on the 1 ms grid agrees with v(t1) - v(t0) + v_table(t1) - v_table(t0) within
    (10 ms) (1 ms)^2 / 12 max|a''|, a'' bounded by the second differences of a on that grid (x 4 for safety)."""
    s = scene_6hz(1.0)
    df, prov = make_ivp_experiment(
        s, {"law": "hertzdamp", "ks_ratio": 3.0, "r": 0.6}, noise_mm=0.0, acc_noise_m_s2=0.0, seed=1
    )
    ref = law_ivp_reference(s, dt_out=1e-3, law="hertzdamp", ks_ratio=3.0, r=0.6)
    assert prov["reference"] == "law_ivp_reference" and prov["law"] == "hertzdamp"
    np.testing.assert_array_equal(df.model1_floor3_mm.to_numpy(), ref["u"][::10, 2] * 1e3)
    P = ref["problem"].base
    a_abs = -(ref["v"] @ P.C.T + ref["u"] @ P.K.T + ref["F"] @ P.G.T) / np.diag(P.M)
    np.testing.assert_array_equal(df.b2f3_acc.to_numpy(), mems_samples(ref["t"], a_abs[:, 5], 100.0, 1000.0)[1])
    # the absolute acceleration integrates to the absolute velocity's change (table velocity A w cos(w t))
    e = s.excitation
    om = 2 * math.pi * e.frequency_Hz
    v_abs = ref["v"][:, 5] + e.amplitude_m * om * np.cos(om * ref["t"])
    a = a_abs[:, 5]
    trap = np.array([np.trapezoid(a[k : k + 11], dx=1e-3) for k in range(0, a.size - 10, 10)])
    dv = v_abs[10::10] - v_abs[:-10:10]
    a2 = np.abs(np.diff(a, 2)) / 1e-6
    bound = np.array([4 * 1e-2 * 1e-6 / 12 * a2[max(k - 1, 0) : k + 11].max() for k in range(0, a.size - 10, 10)])
    assert np.all(np.abs(trap - dv) <= bound + 1e-12)
