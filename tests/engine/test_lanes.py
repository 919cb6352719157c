"""The lane kernel (engine/lanes: integrate_lanes) against the scalar kernel (engine/scalar.py: integrate_batch).

The two integrate the same scheme with different algebra (modal coordinates and fused multiply-adds
in the lanes, the floors' Newmark solve in the scalar kernel), so they agree to rounding, not bit for
bit. The contract tested here (assert_rows_agree), on every run the scalar kernel does not flag
`contact_underresolved` or `contact_unsettled`, with tolerances derived in tests/tolerances.py:
- counts (impacts, compression phases, steps, located events) and status codes equal, or at a
  near-tie between the scalar kernel's and its backward-error twins';
- every other value within tolerances.SAFETY times the larger difference the scalar kernel's two
  backward-error twins (the model's matrices as rounding may leave them) show for that run and column;
- plus, where the event scheme's own thresholds decide rather than rounding: the least force within
  k_s events.switch_tolerance, contact and compression times within one step per phase or impact,
  the median phase within one step (a phase ends where F = 0, and whether its last piece counts as
  compressive depends on the sign of a residue of that size).
Measured: at most 5.3x the twins' difference on three code-generation targets. Flagged runs (a contact
period of less than a step, or an active set that cycles) are not trustworthy in either kernel:
rounding changes their discrete contact decisions. For them the test checks that both kernels set
contact_underresolved (from the inputs) and that the lane kernel's rows are finite.
The grids span k_s/k 0.01..1e4, r 0/0.4/1, gaps 0/1/20 mm, harmonic and recorded excitation, both
contact laws, runs of unequal length in one group, a diverging run (rerun by the scalar kernel), and
other floor counts. Then: the result of a run does not depend on the lane, group or thread it lands
in (equal slot for slot), and run_chunk picks the scalar kernel whenever the lane kernel cannot compute the
same thing.
"""

from __future__ import annotations

import dataclasses
import functools

import numpy as np
import pytest
from conftest import SWEEPS
from tolerances import SEEDS, backward_error_twin, count_bounds, mca_twins, switch_residue_force, value_tolerance

from pounding_sweep import codes
from pounding_sweep.engine import driver, events, registry
from pounding_sweep.engine import lanes as kernel_lanes
from pounding_sweep.engine import layout as L
from pounding_sweep.engine.driver import HistorySpec, RunArrays, ScoreSpec
from pounding_sweep.model.contact import CONTACT_LAWS
from pounding_sweep.reference import newmark_reference
from pounding_sweep.scene import Axis, load_scene
from pounding_sweep.sweep.prepare import prepare

KS = (0.01, 0.1, 1.0, 10.0, 100.0, 1e4)
R = (0.0, 0.4, 1.0)
GAPS = (0.0, 1e-3, 0.02)


SCHEMES = ("implicit", "event")


def why(sysarr, hist, opts, score, law=codes.LAW_CLASSIC):
    """Why the lane kernel cannot run such a chunk of runs of `law` (the kernel registry's answer), or None."""
    lanes_kernel = next(k for k in registry.KERNELS if k.lanes)
    return lanes_kernel.why_not(registry.Chunk(sysarr, hist, opts, score, law))


def implicit(scene, law="classic", duration=None, scheme="implicit", dt=None):
    integ = dataclasses.replace(scene.integration, scheme=scheme)
    if dt is not None:
        integ = dataclasses.replace(integ, dt_s=dt)
    s = dataclasses.replace(scene, integration=integ, contact=dataclasses.replace(scene.contact, law=law))
    if duration is not None:
        s = dataclasses.replace(s, excitation=dataclasses.replace(s.excitation, duration_s=duration))
    return s


def chunk_inputs(prep, params=None):
    """RunArrays and record arrays for a chunk of the scene's grid (sweep.Prepared.kernel_inputs)."""
    runs, rec, _ = prep.kernel_inputs(params if params is not None else prep.grid.chunk(0, prep.grid.size))
    return runs, rec


# (ks_ratio, r, gap_m, law, scheme): tests/engine/test_scalar.py's pounding cases, both laws and both lane schemes
NUMPY_REFERENCE_CASES = [
    (1.0, 0.4, 0.0, "classic", "implicit"),
    (10.0, 0.0, 1e-3, "classic", "implicit"),
    (1.0, 0.0, 0.0, "no_tension", "implicit"),
    (1.0, 0.4, 0.0, "classic", "event"),
    (0.1, 1.0, 0.0, "classic", "event"),
    (10.0, 0.4, 0.0, "no_tension", "event"),
    (1.0, 1.0, 1e-3, "no_tension", "event"),
]


@pytest.mark.parametrize(
    "ks_ratio, r, gap_m, law, scheme",
    NUMPY_REFERENCE_CASES,
    ids=lambda v: f"{v}" if not isinstance(v, float) else f"{v:g}",
)
def test_lane_kernel_metrics_equal_the_numpy_reference(ks_ratio, r, gap_m, law, scheme):
    """The lane kernel against the plain NumPy Newmark loop of tests/reference.py directly (not only
    through the scalar kernel), 1 s of the 6 Hz scene: impacts and unsettled steps equal (or between the
    reference's and its Monte Carlo arithmetic twins' at a near-tie), peak displacements and peak forces
    within tolerances.SAFETY times the twins' difference, contact time within one step per impact (the
    lane kernel sums whole steps between switches in its vector steps; tests/tolerances.py)."""
    base = implicit(load_scene(SWEEPS / "paper_6hz.toml"), law=law, duration=1.0, scheme=scheme)
    s = dataclasses.replace(
        base, sweep=(), contact=dataclasses.replace(base.contact, ks_ratio=ks_ratio, r=r, gap_m=gap_m)
    )
    prep = prepare(s)
    assert why(prep.sysarr, HistorySpec.none(), prep.opts, ScoreSpec.none(), CONTACT_LAWS[law]) is None
    runs, rec = chunk_inputs(prep)
    assert runs.n == 1
    m, _ = driver.run_chunk_lanes(prep.sysarr, runs, rec, prep.opts)
    row = dict(zip(L.metric_columns(prep.model.floors, prep.model.n_pairs), m[0]))
    ref = newmark_reference(s)
    n_steps, n_dof = ref["u"].shape[0] - 1, ref["u"].shape[1]
    twins = mca_twins(lambda **kw: newmark_reference(s, **kw), n_dof)
    dt = ref["problem"].dt

    def agrees(got, values):
        tol = value_tolerance(
            np.array(values[0]), [np.array(v) for v in values[1:]], np.array(values[0]), n_steps, n_dof
        )
        return abs(got - values[0]) <= tol

    floors = [f"b{b}f{f}" for b, nf in zip((1, 2), prep.model.floors) for f in range(1, nf + 1)]
    for i, name in enumerate(floors):
        assert agrees(row[f"peak_disp_{name}_m"], [np.max(np.abs(x["u"][:, i])) for x in [ref] + twins]), name
    impacts = np.array([int(row[f"impacts_f{j + 1}"]) for j in range(prep.model.n_pairs)])
    assert impacts.any(), "the case is meant to pound"
    lo, hi = count_bounds(ref["impacts"], [t["impacts"] for t in twins])
    assert np.all((lo <= impacts) & (impacts <= hi))
    for j in range(prep.model.n_pairs):
        assert agrees(row[f"peak_force_f{j + 1}_N"], [x["peak_force"][j] for x in [ref] + twins]), j
        assert row[f"contact_time_f{j + 1}_s"] == pytest.approx(ref["contact_time"][j], abs=(impacts[j] + 1) * dt)
    lo, hi = count_bounds(ref["unsettled"], [t["unsettled"] for t in twins])
    assert lo <= int(row["unsettled_steps"]) <= hi


def both(prep, runs, rec, threads=1):
    lanes, _ = driver.run_chunk_lanes(prep.sysarr, runs, rec, prep.opts, threads)
    scalar, _, _, _ = driver.run_chunk_scalar(prep.sysarr, runs, rec, HistorySpec.none(), prep.opts, 1)
    return lanes, scalar


def assert_rows_identical(a, b, floors=(3, 3)):
    """Equality of every slot (0.0 == -0.0); on failure, name the first differing runs and columns."""
    assert a.shape == b.shape
    same = (a == b) | (np.isnan(a) & np.isnan(b))
    if not same.all():
        cols = L.metric_columns(floors, min(floors))
        bad = np.argwhere(~same)[:8]
        lines = [f"run {r}: {cols[c]} {a[r, c]!r} != {b[r, c]!r}" for r, c in bad]
        raise AssertionError(f"{(~same.all(axis=1)).sum()} of {len(a)} rows differ:\n" + "\n".join(lines))


FLAGGED = L.STATUS_UNSETTLED | L.STATUS_UNDERRESOLVED
COUNTS = ("impacts_", "compression_phases_", "steps", "status_code", "max_contact_iterations", "unsettled_steps")


def scalar_twins(prep, runs, rec):
    """The scalar kernel's rows on the backward-error twins of the model (tests/tolerances.py)."""
    return [
        driver.run_chunk_scalar(backward_error_twin(prep.sysarr, seed), runs, rec, HistorySpec.none(), prep.opts, 2)[0]
        for seed in SEEDS
    ]


def assert_rows_agree(prep, runs, rec, lanes, scalar, floors=(3, 3)):
    """The module docstring's contract; returns the mask of the runs it holds to the tolerances.

    Each value within tolerances.SAFETY times the larger difference the scalar kernel's backward-error
    twins show for that run and column (at least the floor of n_steps rounding steps on the column's
    scale); counts equal, or between the scalar kernel's and its twins' at a near-tie. Two quantities
    carry the event scheme's own thresholds, not rounding: the least force of a pair may be anywhere
    within +/- k_s times events.switch_tolerance (a force that small at a step's end is not a switch,
    in either kernel); and a compressive phase ends where F = 0, so whether its last piece counts as
    compressive depends on the sign of a force residue of that size: contact and compression times may
    differ by one step per phase or impact, the median phase by one step.
    """
    assert lanes.shape == scalar.shape
    twins = scalar_twins(prep, runs, rec)
    dt = prep.dt
    n_steps, n_dof = int(runs.nsteps.max()), prep.sysarr.m.size
    cols = L.metric_columns(floors, min(floors))
    col = {n: i for i, n in enumerate(cols)}
    status = scalar[:, col["status_code"]].astype(np.int64)
    lstatus = lanes[:, col["status_code"]].astype(np.int64)
    assert np.array_equal(status & L.STATUS_UNDERRESOLVED, lstatus & L.STATUS_UNDERRESOLVED)
    assert np.isfinite(lanes).all()
    good = (status & FLAGGED) == 0
    a, b, tw = lanes[good], scalar[good], [t[good] for t in twins]
    ks = runs.ks[good]
    problems = []
    for name, ci in col.items():
        x, y, ty = a[:, ci], b[:, ci], [t[:, ci] for t in tw]
        if name.startswith(COUNTS):
            if name == "status_code":
                lo = hi = y
            else:
                lo, hi = count_bounds(y, ty)
            err, tol = np.maximum(lo - x, x - hi), np.zeros_like(y)
        else:
            scale = np.abs(y).max()
            if name.endswith("_J"):
                scale = b[:, col["input_work_abs_J"]]
            tol = value_tolerance(y, ty, scale, n_steps, n_dof)
            err = np.abs(x - y)
            if name.startswith("min_force"):
                j = int(name.removeprefix("min_force_f").split("_")[0])
                tol = tol + 2 * switch_residue_force(
                    ks, b[:, col[f"peak_disp_b1f{j}_m"]], b[:, col[f"peak_disp_b2f{j}_m"]]
                )
            elif name.startswith(("contact_time", "compression_time")):
                j = name.split("_f")[1].split("_")[0]
                tol = tol + dt * (b[:, col[f"compression_phases_f{j}"]] + b[:, col[f"impacts_f{j}"]] + 1)
            elif name.startswith("median_compression"):
                tol = tol + dt * (1 + 1e-9)
        for r in np.flatnonzero(err > tol)[:3]:
            run = np.flatnonzero(good)[r]
            problems.append(
                f"run {run}: {name} lanes {x[r]!r} scalar {y[r]!r} twins {[t[r] for t in ty]} (tolerance {tol[r]:.3g})"
            )
    if problems:
        raise AssertionError(f"{len(problems)} disagreements:\n" + "\n".join(problems[:12]))
    return good


def col(metrics, name, floors=(3, 3)):
    return metrics[:, L.metric_columns(floors, min(floors)).index(name)]


@functools.cache
def harmonic_grid(law, scheme="implicit"):
    """k_s/k x r x gap, 0.5 s of the 6 Hz table motion at 2 mm and 5 mm."""
    s = implicit(load_scene(SWEEPS / "paper_6hz.toml"), law, duration=0.5, scheme=scheme)
    s = dataclasses.replace(
        s, sweep=(Axis("amplitude_m", (0.002, 0.005)), Axis("gap_m", GAPS), Axis("ks_ratio", KS), Axis("r", R))
    )
    prep = prepare(s)
    runs, rec = chunk_inputs(prep)
    return (prep, runs, rec) + both(prep, runs, rec)


@pytest.mark.parametrize("scheme", SCHEMES)
@pytest.mark.parametrize("law", ["classic", "no_tension"])
def test_harmonic_grid_rows_agree(law, scheme):
    prep, runs, rec, lanes, scalar = harmonic_grid(law, scheme)
    assert driver.kernel_for(prep.sysarr, prep.hist, prep.opts, prep.score) == "lanes"
    good = assert_rows_agree(prep, runs, rec, lanes, scalar)
    assert good.sum() >= 80  # the flagged runs are k_s/k = 1e4
    # the grid exercises what the lane kernel does differently: contact in some lanes and not in
    # others, impacts, long and short compressive phases, the active-set fallback (classic law)
    impacts = col(scalar, "impacts_f3")
    assert (impacts == 0).any() and (impacts > 5).any()
    assert (col(scalar, "compression_phases_f1") > 0).any()
    assert (col(scalar, "median_compression_phase_f3_s") > 0).any()
    assert (col(scalar, "status_code").astype(int) & L.STATUS_UNDERRESOLVED).any()
    assert (col(scalar, "max_contact_iterations") > 1).any()  # event scheme: several events in a step
    if law == "classic" and scheme == "implicit":
        # the steps whose active set cycles (this grid has them: they were flagged before the implicit
        # scheme handed them to the event step) settle in both kernels; the dashpot still pulls
        assert not (col(scalar, "unsettled_steps") > 0).any() and not (col(lanes, "unsettled_steps") > 0).any()
        assert (col(scalar, "min_force_f3_N") < 0).any()


@pytest.mark.parametrize("scheme", SCHEMES)
def test_record_grid_with_runs_of_unequal_length_rows_agree(tmp_path, scheme):
    """Duzce DZC180 (similitude 1/15) and a shortened copy in one sweep: groups mix records and
    lengths, so lanes end at different steps and read different ground motions."""
    from pounding_sweep.model.records import read_record

    rec = read_record(SWEEPS / "records" / "RSN1605_DUZCE_DZC180.AT2", units="g")
    short = tmp_path / "short.csv"
    n = rec.time_s.size // 3
    np.savetxt(
        short, np.column_stack([rec.time_s[:n], rec.acc_m_s2[:n]]), delimiter=",", header="t_s,acc_m_s2", comments=""
    )
    s = implicit(load_scene(SWEEPS / "paper_duzce.toml"), scheme=scheme)
    s = dataclasses.replace(
        s,
        excitation=dataclasses.replace(s.excitation, duration_s=None),
        sweep=(
            Axis("ks_ratio", (0.1, 1.0, 10.0)),
            Axis("r", (0.0, 0.4, 1.0)),
            Axis("record", (str(SWEEPS / "records" / "RSN1605_DUZCE_DZC180.AT2"), str(short))),
            Axis("scale", (0.5, 1.0)),
        ),
    )
    prep = prepare(s)
    runs, recarr = chunk_inputs(prep)
    assert len(set(runs.nsteps.tolist())) == 2
    lanes, scalar = both(prep, runs, recarr)
    assert assert_rows_agree(prep, runs, recarr, lanes, scalar).sum() >= 24  # of 36
    assert (col(scalar, "impacts_f3") > 0).any()


@pytest.mark.parametrize("scheme", SCHEMES)
def test_uneven_lengths_and_a_diverging_run_in_one_group(scheme):
    """Hand-made runs: lengths from 1 to 3000 steps (and 0) in one group; one run with a table
    motion of 100 km, which the divergence guard stops: the lane kernel hands it to the scalar kernel."""
    prep = prepare(implicit(load_scene(SWEEPS / "paper_6hz.toml"), duration=0.3, scheme=scheme))
    params = prep.grid.chunk(0, 1)
    base, rec = chunk_inputs(prep, params)
    n = 40
    rng = np.random.default_rng(7)
    pick = lambda a: np.repeat(a, n, axis=0).copy()  # noqa: E731
    runs = RunArrays(*(pick(a) for a in base))
    runs.ks[:] = 6830.0 * rng.choice([0.1, 1.0, 10.0], n)
    runs.cdash[:] = runs.cdash * np.sqrt(runs.ks / base.ks)[:, None] * rng.choice([0.0, 0.5, 1.0], n)[:, None]
    runs.gap[:] = rng.choice([0.0, 5e-4], n)
    runs.nsteps[:] = rng.integers(1, 3000, n)
    runs.nsteps[3] = 0
    runs.exc_amp[5] = 1e5
    lanes, scalar = both(prep, runs, rec)
    assert col(scalar, "status_code")[5] == L.STATUS_NONFINITE
    assert col(scalar, "steps")[3] == 0 and col(scalar, "steps")[7] == runs.nsteps[7]
    assert_rows_identical(lanes[5:6], scalar[5:6])  # the diverged run: the scalar kernel's own row
    assert assert_rows_agree(prep, runs, rec, lanes, scalar).all()


@pytest.mark.parametrize("scheme", SCHEMES)
def test_other_floor_counts(scheme):
    """A 4-story building beside a 2-story one (two contact pairs): the vector loops compiled for those sizes, the
    group driver not again (its types hold no floor count: engine/lanes/loops.py)."""
    from pounding_sweep.engine.lanes.groups import _integrate_groups

    s = implicit(load_scene(SWEEPS / "paper_6hz.toml"), duration=0.4, scheme=scheme)
    three = prepare(dataclasses.replace(s, sweep=(Axis("gap_m", (0.0,)),)))
    driver.run_chunk_lanes(three.sysarr, *chunk_inputs(three), three.opts, 1)
    drivers = set(_integrate_groups.signatures)
    s = dataclasses.replace(
        s,
        building1=dataclasses.replace(s.building1, masses_kg=(1.7, 1.7, 1.6, 1.5)),
        building2=dataclasses.replace(s.building2, masses_kg=(0.56, 0.45)),
        sweep=(Axis("gap_m", (0.0, 1e-3)), Axis("ks_ratio", (0.1, 1.0, 10.0)), Axis("r", (0.0, 0.4, 1.0))),
    )
    prep = prepare(s)
    assert prep.model.floors == (4, 2)
    runs, rec = chunk_inputs(prep)
    lanes, scalar = both(prep, runs, rec)
    assert set(_integrate_groups.signatures) == drivers
    assert assert_rows_agree(prep, runs, rec, lanes, scalar, floors=(4, 2)).sum() >= 12
    assert (col(scalar, "impacts_f2", (4, 2)) > 0).any()


@pytest.mark.parametrize("scheme", SCHEMES)
def test_a_run_does_not_depend_on_its_lane_group_or_thread(scheme):
    """Runs permuted (they land in other lanes and groups) and 2 threads: the same rows."""
    prep, runs, rec, lanes, _ = harmonic_grid("classic", scheme)
    perm = np.random.default_rng(3).permutation(runs.n)
    shuffled = runs.take(perm)
    again, _ = driver.run_chunk_lanes(prep.sysarr, shuffled, rec, prep.opts, threads=2)
    assert_rows_identical(again, lanes[perm])
    # a group of one: the run alone with 15 parked lanes
    one = runs.take(slice(7, 8))
    alone, _ = driver.run_chunk_lanes(prep.sysarr, one, rec, prep.opts)
    assert_rows_identical(alone, lanes[7:8])


def test_run_chunk_dispatch_and_the_eligibility_rules():
    prep = prepare(implicit(load_scene(SWEEPS / "paper_6hz.toml"), duration=0.05))
    sysarr, opts = prep.sysarr, prep.opts
    none_h, none_s = HistorySpec.none(), ScoreSpec.none()
    assert why(sysarr, none_h, opts, none_s) is None
    assert "histories" in why(sysarr, HistorySpec(np.array([codes.H_DISP]), np.array([2]), 1), opts, none_s)
    score = ScoreSpec(
        np.array([0.1]), np.zeros((1, 1)), np.array([2]), 0, 0.01, np.zeros(1, np.int64), np.zeros((0, 6))
    )
    assert "scoring" in why(sysarr, none_h, opts, score)
    assert "implicit" in why(sysarr, none_h, opts._replace(scheme=codes.SCHEMES["paper"]), none_s)
    for name, code in codes.SCHEMES.items():  # every scheme but implicit and event
        ok = why(sysarr, none_h, opts._replace(scheme=code), none_s) is None
        assert ok == (name in SCHEMES)
    assert why(sysarr, none_h, opts._replace(max_iter=0), none_s) is not None
    # the event scheme takes no active-set iteration
    assert why(sysarr, none_h, opts._replace(scheme=codes.SCHEMES["event"], max_iter=0), none_s) is None
    assert why(sysarr, none_h, opts, none_s, law=7) is not None
    assert "Hertz" in why(sysarr, none_h, opts, none_s, law=codes.LAW_HERTZ)
    coupled = dataclasses.replace(sysarr, K=sysarr.K + 1e-30)
    assert "coupled" in why(coupled, none_h, opts, none_s)
    C = sysarr.C.copy()
    C[0, 2] = C[2, 0] = 0.1 * C[0, 0]  # damping the building's modes do not diagonalise
    assert "classical" in why(dataclasses.replace(sysarr, C=C), none_h, opts, none_s)
    swapped = dataclasses.replace(sysarr, i1=sysarr.i1[::-1].copy())
    assert "facing" in why(swapped, none_h, opts, none_s)
    # a model whose scratch vectors (6 N + P) would not fit the lane kernel's buffer runs on the scalar kernel
    tall = implicit(load_scene(SWEEPS / "paper_6hz.toml"), duration=0.05)
    tall = dataclasses.replace(
        tall,
        building1=dataclasses.replace(tall.building1, masses_kg=(1.0,) * 14),
        building2=dataclasses.replace(tall.building2, masses_kg=(0.5,) * 13),
    )
    ptall = prepare(tall)
    assert "scratch" in why(ptall.sysarr, none_h, opts, none_s)
    assert driver.kernel_for(ptall.sysarr, none_h, opts, none_s) == "scalar"

    # run_chunk: lanes when eligible (same rows as the scalar kernel), scalar with histories
    runs, rec = chunk_inputs(prep)
    calls = []
    real = driver.run_chunk_lanes

    def spy(*a, **k):
        calls.append(1)
        return real(*a, **k)

    driver.run_chunk_lanes, saved = spy, driver.run_chunk_lanes
    try:
        m1, t1, h1, s1 = driver.run_chunk(sysarr, runs, rec, none_h, opts)
        assert calls and h1 is None and s1 is None and t1.shape == (runs.n,) and (t1 > 0).all()
        hist = HistorySpec(np.array([codes.H_DISP]), np.array([2]), 10)
        m2, _, h2, _ = driver.run_chunk(sysarr, runs, rec, hist, opts)
        assert len(calls) == 1 and h2 is not None
    finally:
        driver.run_chunk_lanes = saved
    assert_rows_agree(prep, runs, rec, m1, m2)


def test_excitation_profiles_equal_the_scalar_kernels_ground_acceleration():
    prep = prepare(implicit(load_scene(SWEEPS / "paper_6hz.toml"), duration=0.2))
    params = prep.grid.chunk(0, 1)
    runs, rec = chunk_inputs(prep, params)
    coef, pid, prof = kernel_lanes.excitation_profiles(runs, rec, prep.dt)
    steps = np.arange(int(runs.nsteps[0]) + 1)
    ref = np.array(
        [
            events.ground_acceleration(runs.exc_kind[0], runs.exc_amp[0], runs.exc_omega[0], rec[0], 0, 0, s, prep.dt)
            for s in steps
        ]
    )
    assert np.array_equal((coef[0] * prof[pid[0], steps]).view(np.int64), ref.view(np.int64))


@pytest.mark.parametrize("law", ["classic", "no_tension"])
def test_event_scheme_stiff_coarse_steps(law):
    """Event scheme at dt = 1 ms with k_s/k up to 1e4: contact events every few steps, several in one
    step, and under the no-tension law with r = 0 chattering switches that reach events.MAX_EVENTS
    (the step taken as it is and counted unsettled): most steps of many lanes go through the scalar
    fix-up, next to lanes that stay in the vector path. Most of these runs are flagged (a contact
    period under one step): the contract holds on the others, the flags on all."""
    s = implicit(load_scene(SWEEPS / "paper_6hz.toml"), law, duration=0.5, scheme="event", dt=1e-3)
    s = dataclasses.replace(
        s,
        sweep=(
            Axis("amplitude_m", (0.002, 0.005)),
            Axis("gap_m", GAPS),
            Axis("ks_ratio", (0.1, 1.0, 1e3, 3e3, 1e4)),
            Axis("r", R),
        ),
    )
    prep = prepare(s)
    runs, rec = chunk_inputs(prep)
    lanes, scalar = both(prep, runs, rec)
    assert (
        assert_rows_agree(prep, runs, rec, lanes, scalar).sum() >= 30
    )  # of 90: the rest have a contact period under a step
    located = col(scalar, "max_contact_iterations")
    assert (located == 0).any() and (located >= 3).any()
    assert (col(scalar, "impacts_f3") > 10).any()
    if law == "no_tension":
        assert (located == events.MAX_EVENTS).any() and (col(scalar, "unsettled_steps") > 0).any()
        assert (col(lanes, "max_contact_iterations") == events.MAX_EVENTS).any()
    again, _ = driver.run_chunk_lanes(prep.sysarr, runs, rec, prep.opts, threads=2)
    assert_rows_identical(again, lanes)


@pytest.mark.parametrize("scheme", SCHEMES)
@pytest.mark.parametrize("law", ["classic", "no_tension"])
def test_metric_groups_left_out_change_no_other_column(law, scheme):
    """A metric group left out (KernelOptions.groups) is NaN in the rows, and every other column is bit for bit
    what the lane kernel computes with every group: the groups' work in the vector steps feeds nothing else.
    The scalar kernel's rows are its all-groups rows with the same columns NaN (layout.leave_out), so a row is
    the same whichever kernel computes it. The divergence guard without the energy group (vector._nonfinite)
    hands the diverging run of test_uneven_lengths_... to the scalar kernel too (its row checked here)."""
    prep, runs, rec, lanes_all, scalar_all = harmonic_grid(law, scheme)
    n_dof, n_pairs = sum(prep.model.floors), prep.model.n_pairs
    for groups in (0, *L.GROUPS.values(), L.GROUPS_ALL ^ L.GROUP_ENERGY, L.GROUPS_ALL ^ L.GROUP_ACCEL):
        opts = prep.opts._replace(groups=groups)
        got, _ = driver.run_chunk_lanes(prep.sysarr, runs, rec, opts, 2)
        want = lanes_all.copy()
        L.leave_out(want, n_dof, n_pairs, groups)
        np.testing.assert_array_equal(got, want)
        out = L.left_out_slots(n_dof, n_pairs, groups)
        assert np.isnan(got[:, out]).all() and not np.isnan(np.delete(got, out, axis=1)).any()
        scalar, _, _, _ = driver.run_chunk_scalar(prep.sysarr, runs, rec, HistorySpec.none(), opts, 1)
        want = scalar_all.copy()
        L.leave_out(want, n_dof, n_pairs, groups)
        np.testing.assert_array_equal(scalar, want)


@pytest.mark.parametrize("scheme", SCHEMES)
def test_diverging_run_without_the_energy_group(scheme):
    """Without the energy group the lane kernel's divergence guard is the floors' own (vector._nonfinite):
    a run with a table motion of 100 km still goes to the scalar kernel, its row flagged diverged, and the
    other runs of its group are unchanged."""
    prep = prepare(implicit(load_scene(SWEEPS / "paper_6hz.toml"), duration=0.05, scheme=scheme))
    params = prep.grid.chunk(0, 1)
    base, rec = chunk_inputs(prep, params)
    runs = base.take(np.zeros(8, np.int64))
    amp = runs.exc_amp.copy()
    amp[3] = 1e5
    runs = runs._replace(exc_amp=amp)
    opts = prep.opts._replace(groups=0)
    got, _ = driver.run_chunk_lanes(prep.sysarr, runs, rec, opts)
    assert int(col(got, "status_code")[3]) & L.STATUS_NONFINITE
    want, _, _, _ = driver.run_chunk_scalar(prep.sysarr, runs, rec, HistorySpec.none(), opts, 1)
    np.testing.assert_array_equal(got[3], want[3])
    assert not (col(got, "status_code")[[0, 1, 2, 4, 5, 6, 7]].astype(int) & L.STATUS_NONFINITE).any()
