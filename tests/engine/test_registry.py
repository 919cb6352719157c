"""The kernel registry (engine/registry.py) and the engine without contact pairs.

The registry: which kernel each chunk gets (by law, histories, scoring and the caller's choice), why a
kernel refuses one, and that a chunk mixing laws gives each law's runs the rows they get alone.

No pairs (P = 0, a building on its own: the single-building scenes' model): the engine runs it (the
scalar kernel; the lane kernel refuses it) and building 1's rows equal those it gets beside a neighbour
too far away to touch, within the rounding tolerance tests/tolerances.py derives (backward-error twins
of the coupled model).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from conftest import SWEEPS
from tolerances import SEEDS, backward_error_twin, energy_balance_tolerance, value_tolerance

from pounding_sweep import codes
from pounding_sweep.engine import driver, registry
from pounding_sweep.engine import layout as L
from pounding_sweep.engine.inputs import HistorySpec, ScoreSpec
from pounding_sweep.engine.registry import Chunk
from pounding_sweep.model.coupled import SystemArrays
from pounding_sweep.scene import Axis, load_scene
from pounding_sweep.sweep.prepare import prepare


def scene(law="classic", scheme="event", duration=0.3, **contact):
    s = load_scene(SWEEPS / "paper_6hz.toml")
    return dataclasses.replace(
        s,
        integration=dataclasses.replace(s.integration, scheme=scheme),
        contact=dataclasses.replace(s.contact, law=law, **contact),
        excitation=dataclasses.replace(s.excitation, duration_s=duration),
        sweep=(),
    )


def test_the_registry_chooses_by_law_outputs_and_choice():
    prep = prepare(scene())
    sysarr, opts = prep.sysarr, prep.opts
    none_h, none_s = HistorySpec.none(), ScoreSpec.none()
    hist = HistorySpec(np.array([codes.H_DISP]), np.array([2]), 1)
    for name, law in codes.CONTACT_LAWS.items():
        chunk = Chunk(sysarr, none_h, opts, none_s, law)
        auto = registry.choose(chunk)
        assert auto.name == ("nonlinear" if codes.is_nonlinear(law) else "lanes"), name
        assert law in auto.laws
        assert registry.choose(chunk, "scalar").name == ("nonlinear" if codes.is_nonlinear(law) else "scalar")
        assert registry.choose(chunk._replace(hist=hist)).name == auto.name.replace("lanes", "scalar")
        if codes.is_nonlinear(law):
            with pytest.raises(ValueError, match="lane kernel cannot run this chunk.*Hertz"):
                registry.choose(chunk, "lanes")
    with pytest.raises(ValueError, match="no kernel can run this chunk"):
        registry.choose(Chunk(sysarr, none_h, opts, none_s, 7))
    with pytest.raises(ValueError, match="expected one of"):
        registry.choose(Chunk(sysarr, none_h, opts, none_s, codes.LAW_CLASSIC), "gpu")
    # every law has exactly one one-run-at-a-time kernel, and the compile records' keys are the registry's
    for law in codes.CONTACT_LAWS.values():
        assert sum(law in k.laws for k in registry.KERNELS if not k.lanes) == 1
    score = ScoreSpec(
        np.array([0.1]), np.zeros((1, 1)), np.array([2]), 0, 0.01, np.zeros(1, np.int64), np.zeros((0, 6))
    )
    assert registry.KERNELS[1].compile_key(score) == ("scalar_scored", "the scalar kernel with scoring")
    assert registry.KERNELS[0].compile_key(None) == ("lanes", "the lane kernel")


def test_a_chunk_mixing_laws_gives_each_law_its_own_rows():
    """Runs of four laws interleaved in one chunk: each run's row equals the one it gets in a chunk of its
    law alone, slot for slot (the driver splits by runs.law and puts the rows back in order)."""
    s = scene(duration=0.2)
    s = dataclasses.replace(
        s,
        sweep=(Axis("law", ("classic", "hertz", "no_tension", "jankowski")), Axis("ks_ratio", (0.3, 3.0))),
    )
    prep = prepare(s)
    params = prep.grid.chunk(0, prep.grid.size)
    runs, rec, _ = prep.kernel_inputs(params)
    assert np.unique(runs.law).size == 4
    mixed, _, _, _ = driver.run_chunk(prep.sysarr, runs, rec, prep.hist, prep.opts)
    for code in np.unique(runs.law):
        idx = np.flatnonzero(runs.law == code)
        alone, _, _, _ = driver.run_chunk(prep.sysarr, runs.take(idx), rec, prep.hist, prep.opts)
        assert np.array_equal(mixed[idx], alone, equal_nan=True)


def building_one_alone(sysarr: SystemArrays) -> SystemArrays:
    """Building 1 of a coupled model on its own: its floors, no contact pairs (P = 0)."""
    n1 = int(sysarr.i2[0])
    dt = sysarr.dt
    C = np.ascontiguousarray(sysarr.C[:n1, :n1])
    K = np.ascontiguousarray(sysarr.K[:n1, :n1])
    m = np.ascontiguousarray(sysarr.m[:n1])
    Kinv = np.linalg.inv(K + (2.0 / dt) * C + (4.0 / dt**2) * np.diag(m))
    none = np.zeros(0, np.int64)
    return SystemArrays(dt, m, C, K, np.ascontiguousarray(Kinv), np.zeros((n1, 0)), np.zeros((0, 0)), none, none)


@pytest.mark.parametrize("scheme", ["event", "implicit", "paper"])
def test_a_model_without_contact_pairs_runs(scheme):
    """P = 0: the scalar kernel runs it (the lane kernel says why not), with histories too, and building 1's
    per-floor metrics equal those it has beside building 2 at a 1 m gap (never touching) within SAFETY
    times the coupled model's backward-error twins' difference; the energy balance closes to rounding."""
    prep = prepare(scene(scheme=scheme, gap_m=1.0, duration=1.0))
    params = prep.grid.chunk(0, prep.grid.size)
    coupled_runs, rec, _ = prep.kernel_inputs(params)
    alone = building_one_alone(prep.sysarr)
    n1 = alone.m.size
    runs = coupled_runs._replace(cdash=np.zeros((coupled_runs.n, 0)))
    why = registry.KERNELS[0].why_not(Chunk(alone, prep.hist, prep.opts, prep.score, codes.LAW_CLASSIC))
    assert "no contact pair" in why if scheme != "paper" else "scheme" in why
    assert driver.kernel_for(alone, prep.hist, prep.opts, prep.score) == "scalar"
    m, t, h, s = driver.run_chunk(alone, runs, rec, prep.hist, prep.opts)
    assert m.shape == (runs.n, L.n_metrics(n1, 0)) and h is None and s is None
    cols = L.metric_columns((n1, 0), 0)
    row = dict(zip(cols, m[0]))
    assert row["status_code"] == 0 and row["steps"] == runs.nsteps[0]
    balance = row["input_energy_J"] - sum(
        row[c]
        for c in (
            "kinetic_energy_end_J",
            "strain_energy_end_J",
            "structural_damping_energy_J",
            "contact_damping_energy_J",
            "contact_spring_energy_end_J",
            "energy_residual_J",
        )
    )
    assert abs(balance) <= energy_balance_tolerance(row, n1)
    assert row["contact_damping_energy_J"] == 0.0 and row["energy_residual_J"] == 0.0

    def coupled(sysarr):
        return driver.run_chunk_scalar(sysarr, coupled_runs, rec, prep.hist, prep.opts)[0]

    base = coupled(prep.sysarr)
    twins = [coupled(backward_error_twin(prep.sysarr, seed)) for seed in SEEDS]
    b1 = slice(0, L.PER_DOF * n1)
    tol = value_tolerance(
        base[:, b1], [tw[:, b1] for tw in twins], np.abs(base[:, b1]).max(axis=0), runs.nsteps.max(), prep.sysarr.m.size
    )
    assert np.all(np.abs(m[:, b1] - base[:, b1]) <= tol)
    # histories of a model without pairs: a floor's displacement, the ground acceleration
    hist = HistorySpec(np.array([codes.H_DISP, codes.H_GROUND_ACC]), np.array([n1 - 1, 0]), 5)
    m2, _, h2, _ = driver.run_chunk(alone, runs, rec, hist, prep.opts)
    assert np.array_equal(m2, m) and h2.shape == (runs.n, 2, int(runs.nsteps.max()) // 5 + 1)
    # every 5th step's displacement, of which the peak is the largest over every step
    assert 0.0 < np.abs(h2[0, 0]).max() <= row[f"peak_disp_b1f{n1}_m"]
