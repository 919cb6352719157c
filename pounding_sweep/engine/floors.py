"""The floor-coordinate pieces the two one-run-at-a-time kernels share (engine/scalar.py for the linear
laws, engine/nonlinear.py for the Hertz-type ones): a dense solve, the acceleration from equilibrium,
and the event step's view of a pair (penetration, rate, switch tolerance) and of divergence.

A kernel's state record (scalar.LinearState, nonlinear.HertzState) holds, under the same names, the
model (m, C, K, i1, i2: engine/inputs.py Structure), the run's gap, the start state u, v, a and the
end state un, vn, an of the piece in progress [m, m/s, m/s^2, relative to the table]; these functions
read those fields and compile once per record type.

Equations of motion (SI, restoring sign): M a + C v + K u + G F = -M 1 ag (the paper's eqs. 1-2),
F_j > 0 in compression, G's column j = e(building 1, floor j) - e(building 2, floor j).
"""

from __future__ import annotations

import numpy as np

from pounding_sweep.engine import layout as L
from pounding_sweep.engine.events import switch_tolerance
from pounding_sweep.engine.jit import njit_inner, njit_kernel

#: gauss_solve's `pivot`, typed rather than literal, so it compiles once for every kernel (events.AT_END says why)
NO_PIVOT, PIVOT = np.bool_(False), np.bool_(True)


@njit_kernel
def gauss_solve(A, b, n, pivot):
    """Solve A[:n,:n] x = b[:n] in place by Gaussian elimination; with `pivot`, partial pivoting (the Hertz-type
    laws' Newton Jacobian I + D S is not symmetric); without, none (A symmetric positive definite)."""
    for k in range(n):
        if pivot:
            p = k
            for i in range(k + 1, n):
                if abs(A[i, k]) > abs(A[p, k]):
                    p = i
            if p != k:
                for j in range(n):
                    A[k, j], A[p, j] = A[p, j], A[k, j]
                b[k], b[p] = b[p], b[k]
        piv = A[k, k]
        for i in range(k + 1, n):
            f = A[i, k] / piv
            for j in range(k, n):
                A[i, j] -= f * A[k, j]
            b[i] -= f * b[k]
    for i in range(n - 1, -1, -1):
        s = b[i]
        for j in range(i + 1, n):
            s -= A[i, j] * b[j]
        b[i] = s / A[i, i]


@njit_inner
def equilibrium_acceleration(st, ag, u, v, F, a):
    """a = M^-1 (-M 1 ag - C v - K u - G F), the equations of motion (eqs. 1-2, restoring sign), with
    st's model (m, C, K, i1, i2)."""
    m, C, K, i1, i2 = st.m, st.C, st.K, st.i1, st.i2
    n = m.shape[0]
    for i in range(n):
        s = -m[i] * ag
        for k in range(n):
            s -= C[i, k] * v[k] + K[i, k] * u[k]
        a[i] = s
    for j in range(i1.shape[0]):
        a[i1[j]] -= F[j]
        a[i2[j]] += F[j]
    for i in range(n):
        a[i] /= m[i]


@njit_inner
def pair(st, end, j):
    """(penetration g.u - d [m], its rate g.v [m/s]) of pair j at the piece's end state or its start."""
    p, q = st.i1[j], st.i2[j]
    if end:
        return st.un[p] - st.un[q] - st.gap, st.vn[p] - st.vn[q]
    return st.u[p] - st.u[q] - st.gap, st.v[p] - st.v[q]


@njit_inner
def tolerance(st, j):
    """Pair j's switch tolerance at the end state (events.switch_tolerance of its two floors)."""
    return switch_tolerance(st.un[st.i1[j]], st.un[st.i2[j]])


@njit_inner
def finite(st):
    """The end state is finite: every floor within DIVERGED_M and every acceleration below 1e300."""
    ok = True
    for i in range(st.un.shape[0]):
        if not (abs(st.un[i]) < L.DIVERGED_M) or not (abs(st.an[i]) < 1e300):
            ok = False
    return ok


# The time loop's per-step pieces both kernels take alike (engine/scalar.py _time_loop_for and
# engine/nonlinear.py _time_loop): where a step starts, its end without contact, and its end with the contact forces.


@njit_inner
def step_start(st, ustep, astep, has_acc):
    """Keep the step's start displacement (and, where a channel records acceleration, its relative
    acceleration) for the experiment samples that fall inside the step."""
    for i in range(st.u.shape[0]):
        ustep[i] = st.u[i]
    if has_acc:
        for i in range(st.u.shape[0]):
            astep[i] = st.a[i]


@njit_inner
def free_end(st, Kinv, ag, dt, w, rhs0, u0):
    """The step's end without contact forces, Newmark average acceleration (Chopra Table 5.4.2 in total
    form; the paper's eqs. 12-13): w = 2/dt u + v, p_hat = -M 1 ag + M (4/dt^2 u + 4/dt v + a) + C w
    (ag at the step's end), u0 = Keff^-1 p_hat with Kinv = Keff^-1."""
    m, C, u, v, a = st.m, st.C, st.u, st.v, st.a
    n = m.shape[0]
    a1 = 4.0 / (dt * dt)
    a2 = 4.0 / dt
    b1 = 2.0 / dt
    for i in range(n):
        w[i] = b1 * u[i] + v[i]
    for i in range(n):
        s = -m[i] * ag + m[i] * (a1 * u[i] + a2 * v[i] + a[i])
        for k in range(n):
            s += C[i, k] * w[k]
        rhs0[i] = s
    for i in range(n):
        s = 0.0
        for k in range(n):
            s += Kinv[i, k] * rhs0[k]
        u0[i] = s


@njit_inner
def end_state(st, u0, H, dt):
    """The step's end with the contact forces st.F: u_n+1 = u0 - H F (H = Keff^-1 G), then Newmark's
    velocity and acceleration (the paper's eqs. 15-16) into st.un, st.vn, st.an."""
    u, v, a, un, vn, an, F = st.u, st.v, st.a, st.un, st.vn, st.an, st.F
    a1 = 4.0 / (dt * dt)
    a2 = 4.0 / dt
    b1 = 2.0 / dt
    for i in range(u.shape[0]):
        s = u0[i]
        for j in range(F.shape[0]):
            s -= H[i, j] * F[j]
        un[i] = s
    for i in range(u.shape[0]):
        du = un[i] - u[i]
        vn[i] = b1 * du - v[i]
        an[i] = a1 * du - a2 * v[i] - a[i]
