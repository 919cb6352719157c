"""The same two-building pounding model in OpenSeesPy, for the throughput comparison.

Needs `pip install openseespy` (3.7.1 used here) and Debian's libblas3 and liblapack3.

Model (one horizontal DOF per floor, ndm = ndf = 1, displacements relative to the table):
- each story a zeroLength element with an Elastic material of the story stiffness, between the floor
  below (the fixed ground node for the first story) and the floor above; lumped nodal masses;
- Rayleigh damping C = a0 M + a1 K of each building, set per building with `region` (mass part on
  its nodes, initial-stiffness part on its story elements only, so the contact elements add none);
- Kelvin-Voigt contact at each facing floor pair: a zeroLength element with
  `uniaxialMaterial ViscoelasticGap K=k_s C=c_j gap=-d` between floor j of building 1 (node i) and
  floor j of building 2 (node j). Its deformation u2 - u1 closes the gap when u1 - u2 > d; its force
  is K (e - gap) + C de/dt while e < gap, else 0: eq. 8 with the dashpot allowed to pull, i.e. the
  engine's `law = "classic"`; the contact state follows the converged end-of-step state, as the
  engine's implicit scheme does;
- UniformExcitation with the ground acceleration sampled at t = n dt (a Path series of the engine's
  own samples), the floors starting at rest with the acceleration -ag(0) as the engine's do (setNodeAccel;
  OpenSees would start from 0, which matters for a record whose first sample is not 0: the Duzce record's is
  -0.105 m/s^2, and without it the classic law's top floors differ by 1.6e-4 relative RMS over the first
  second, 4e-8 with it), Newmark gamma = 1/2, beta = 1/4, Newton iterations to a displacement-increment norm
  of 1e-12 m, one analyze() call for the whole record (the per-step loop runs in C++).

So both programs solve the same discrete equations; the difference between their results is the
Newton tolerance plus the rare steps where the engine's active set cycles (it keeps the union of the
last two sets, OpenSees whatever Newton converges to). Measured (6 Hz scene, k_s = k, r = 0.4, gap 0,
5 s at dt = 1e-4 s): top-floor displacement 3e-9 (building 1) and 1e-8 (building 2) relative RMS
apart, peak floor-3 force 30.4941386 N in both (5e-9 apart).

run_model builds this model with any uniaxial contact material (a callback defines it per pair) and takes an
optional analyze() that redoes failed steps; run_opensees is run_model with ViscoelasticGap, and
opensees_laws.py (the Hertz-type laws' peer) reuses run_model.

Two OpenSees details that matter: zeroLength elements take Rayleigh damping only with
`-doRayleigh 1`, and `region -ele` also claims the elements' nodes (resetting their alphaM), hence
`-nodeOnly` / `-eleOnly`. Without them the frames are undamped and the results 10 % apart.
"""

from __future__ import annotations

import contextlib
import os
import sys
import tempfile
import time

import numpy as np


@contextlib.contextmanager
def _quiet_stderr(quiet: bool):
    """OpenSees writes a line to the C stderr at every impact (ViscoelasticGap): silence fd 2."""
    if not quiet:
        yield
        return
    sys.stderr.flush()
    saved = os.dup(2)
    devnull = os.open(os.devnull, os.O_WRONLY)
    os.dup2(devnull, 2)
    try:
        yield
    finally:
        os.dup2(saved, 2)
        os.close(saved)
        os.close(devnull)


def run_opensees(
    model,
    ks: float,
    c: np.ndarray,
    gap: float,
    ag: np.ndarray,
    dt: float,
    tol: float = 1e-12,
    max_iter: int = 50,
    quiet: bool = True,
) -> dict:
    """Integrate len(ag) - 1 steps. model: pounding_sweep.model.CoupledModel; c: dashpot per pair.

    Returns t, u (steps + 1, n_dof; building 1 floors then building 2 floors), F (steps + 1, pairs;
    > 0 in compression) and the wall time of the analysis alone (model building excluded).
    """

    def viscoelastic_gap(ops, tag, j):
        # ViscoelasticGap wants a negative gap; a zero gap it turns into -0.0 (and says so on stderr)
        ops.uniaxialMaterial("ViscoelasticGap", tag, float(ks), float(c[j]), opensees_gap(gap))

    return run_model(model, viscoelastic_gap, ag, dt, tol, max_iter, quiet=quiet)


def opensees_gap(gap: float) -> float:
    """The gap materials' `gap` argument for a clear distance gap >= 0: -gap (-0.0 for touching floors)."""
    return -float(gap) if gap > 0 else -0.0


def run_model(model, contact_material, ag, dt, tol=1e-12, max_iter=50, analyze=None, quiet=True) -> dict:
    """The two-building model of the module docstring with the uniaxial material that
    contact_material(ops, tag, j) defines (tag: the material's tag, j: the pair, 0 = first floors) at each
    facing floor pair, integrated over len(ag) - 1 steps of dt.

    analyze(ops, nsteps, dt) -> (status, info) replaces the single ops.analyze(nsteps, dt) call (e.g. to
    redo failed steps in sub-steps no finer than dt / 1000; their rows off the dt grid are dropped from the
    histories).
    Returns t, u, F (as run_opensees), wall_s, steps and info.
    """
    with _quiet_stderr(quiet):
        return _run(model, contact_material, np.asarray(ag, float), dt, tol, max_iter, analyze)


def _frames(ops, model):
    """The ground node (tag 1), each building's floor nodes with their masses and its story elements
    (Elastic materials, -doRayleigh 1). Returns (floor node tags per building, story element tags per
    building, next free material tag, next free element tag)."""
    ops.wipe()
    ops.model("basic", "-ndm", 1, "-ndf", 1)
    ops.node(1, 0.0)
    ops.fix(1, 1)
    floors = []  # node tags per building
    tag = 2
    for b in (model.b1, model.b2):
        tags = []
        for mass in b.masses_kg:
            ops.node(tag, 0.0)
            ops.mass(tag, float(mass))
            tags.append(tag)
            tag += 1
        floors.append(tags)
    mat = 1
    ele = 1
    story_eles = []
    for b, tags in zip((model.b1, model.b2), floors):
        eles = []
        below = 1
        for k, n in zip(b.story_stiffness_N_per_m, tags):
            ops.uniaxialMaterial("Elastic", mat, float(k))
            ops.element("zeroLength", ele, below, n, "-mat", mat, "-dir", 1, "-doRayleigh", 1)
            eles.append(ele)
            mat += 1
            ele += 1
            below = n
        story_eles.append(eles)
    return floors, story_eles, mat, ele


def _run(model, contact_material, ag, dt, tol, max_iter, analyze):
    import openseespy.opensees as ops

    floors, story_eles, mat, ele = _frames(ops, model)
    contact_eles = []
    for j in range(model.n_pairs):
        contact_material(ops, mat, j)
        ops.element("zeroLength", ele, floors[0][j], floors[1][j], "-mat", mat, "-dir", 1)
        contact_eles.append(ele)
        mat += 1
        ele += 1
    for r, (b, tags, eles) in enumerate(zip((model.b1, model.b2), floors, story_eles)):
        ops.region(10 + r, "-nodeOnly", *tags, "-rayleigh", float(b.rayleigh_a0_per_s), 0.0, 0.0, 0.0)
        ops.region(20 + r, "-eleOnly", *eles, "-rayleigh", 0.0, 0.0, float(b.rayleigh_a1_s), 0.0)
    ops.timeSeries("Path", 1, "-dt", float(dt), "-values", *map(float, ag))
    ops.pattern("UniformExcitation", 1, 1, "-accel", 1)
    all_nodes = floors[0] + floors[1]
    for n in all_nodes:  # at rest: M a(0) = -M ag(0), as the engine starts (OpenSees would start from a = 0)
        ops.setNodeAccel(n, 1, -float(ag[0]), "-commit")
    info = None
    with tempfile.TemporaryDirectory() as d:
        fu = os.path.join(d, "u.txt")
        ff = os.path.join(d, "f.txt")
        ops.recorder("Node", "-file", fu, "-precision", 17, "-time", "-node", *all_nodes, "-dof", 1, "disp")
        ops.recorder("Element", "-file", ff, "-precision", 17, "-ele", *contact_eles, "basicForce")
        ops.constraints("Plain")
        ops.numberer("Plain")
        ops.system("FullGeneral")
        ops.test("NormDispIncr", tol, max_iter)
        ops.algorithm("Newton")
        ops.integrator("Newmark", 0.5, 0.25)
        ops.analysis("Transient")
        nsteps = ag.size - 1
        t0 = time.perf_counter()
        if analyze is None:
            ok = ops.analyze(nsteps, float(dt))
        else:
            ok, info = analyze(ops, nsteps, float(dt))
        wall = time.perf_counter() - t0
        ops.wipe()  # flushes and closes the recorders
        U = np.loadtxt(fu, ndmin=2)
        Fb = np.loadtxt(ff, ndmin=2)
    if ok != 0:
        raise RuntimeError(f"OpenSees analyze returned {ok}")
    if analyze is not None:  # sub-steps of a redone step are recorded too: keep the rows on the dt grid
        k = U[:, 0] / dt  # (the recorded time is a running sum: ~1e-5 dt off after 1e6 steps)
        on_grid = np.abs(k - np.round(k)) < 2.5e-4  # sub-steps no finer than dt / 1000
        U, Fb = U[on_grid], Fb[on_grid]
    if U.shape[0] != nsteps:
        raise RuntimeError(f"OpenSees recorded {U.shape[0]} steps on the dt grid, expected {nsteps}")
    t = np.concatenate([[0.0], U[:, 0]])
    u = np.vstack([np.zeros(len(all_nodes)), U[:, 1:]])
    F = np.vstack([np.zeros(len(contact_eles)), -Fb])  # basic force < 0 in compression
    return dict(t=t, u=u, F=F, wall_s=wall, steps=nsteps, info=info)
