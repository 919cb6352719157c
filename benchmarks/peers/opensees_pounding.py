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
  own samples), Newmark gamma = 1/2, beta = 1/4, Newton iterations to a displacement-increment norm
  of 1e-12 m, one analyze() call for the whole record (the per-step loop runs in C++).

So both programs solve the same discrete equations; the difference between their results is the
Newton tolerance plus the rare steps where the engine's active set cycles (it keeps the union of the
last two sets, OpenSees whatever Newton converges to). Measured (6 Hz scene, k_s = k, r = 0.4, gap 0,
5 s at dt = 1e-4 s): top-floor displacement 3e-9 (building 1) and 1e-8 (building 2) relative RMS
apart, peak floor-3 force 30.4941386 N in both (5e-9 apart).

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
    with _quiet_stderr(quiet):
        return _run(model, ks, c, gap, ag, dt, tol, max_iter)


def _run(model, ks, c, gap, ag, dt, tol, max_iter):
    import openseespy.opensees as ops

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
    contact_eles = []
    for j in range(model.n_pairs):
        # ViscoelasticGap wants a negative gap; a zero gap it turns into -0.0 (and says so on stderr)
        ops.uniaxialMaterial("ViscoelasticGap", mat, float(ks), float(c[j]), -float(gap) if gap > 0 else -0.0)
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
        ok = ops.analyze(nsteps, float(dt))
        wall = time.perf_counter() - t0
        ops.wipe()  # flushes and closes the recorders
        U = np.loadtxt(fu, ndmin=2)
        Fb = np.loadtxt(ff, ndmin=2)
    if ok != 0:
        raise RuntimeError(f"OpenSees analyze returned {ok}")
    t = np.concatenate([[0.0], U[:, 0]])
    u = np.vstack([np.zeros(len(all_nodes)), U[:, 1:]])
    F = np.vstack([np.zeros(len(contact_eles)), -Fb])  # basic force < 0 in compression
    return dict(t=t, u=u, F=F, wall_s=wall, steps=nsteps)
