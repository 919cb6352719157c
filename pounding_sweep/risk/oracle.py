"""Closed-form oracles of the probability of pounding of the linear two-building system under Gaussian
filtered white noise: the covariance of the relative displacement of each facing floor pair and of its rate
(Lyapunov), the mean rate of up-crossings of a gap (Rice), and two approximations of the first-passage
probability (Poisson, Vanmarcke 1975). The Monte Carlo of the engine is checked against them (tests/risk).

The system: the two shear frames without contact, M u'' + C u' + K u = -M 1 a_g, and the ground filter
z' = A_f z + B_f w, a_g = e(t) C_f z (model/stochastic.py), one linear system X' = A(t) X + B w in
X = (u, u', z), driven by white noise of intensity q = 2 pi S0. Its covariance P(t) obeys

    P' = A P + P A' + q B B'    (Lyapunov; e.g. Lutes & Sarkani, Random Vibrations, 2004, sec. 9.5),

stationary where P' = 0 (scipy.linalg.solve_continuous_lyapunov). From rest (u = u' = 0) with the filter
started stationary and no envelope, P(t) is propagated exactly over a step h by P <- F P F' + Q, F = exp(A h),
Q = int_0^h exp(A s) q B B' exp(A' s) ds (Van Loan 1978); with an envelope, A varies and P' is integrated
(scipy.integrate.solve_ivp, rtol 1e-10).

Rice (1944-45, "Mathematical analysis of random noise", Bell Syst. Tech. J. 23:282-332, 24:46-156): the mean
rate of up-crossings of a level b by a zero-mean Gaussian process x with derivative v, at time t, is
nu+(b, t) = int_0^inf v p(b, v; t) dv; with var x = sx^2, var v = sv^2, cov(x, v) = c this is

    nu+ = phi(b / sx) / sx (s phi(m / s) + m Phi(m / s)),   m = c b / sx^2,   s^2 = sv^2 - c^2 / sx^2,

and for a stationary process (c = 0) the classical nu+ = sv / (2 pi sx) exp(-b^2 / (2 sx^2)). The expected
number of up-crossings in [0, T] is its integral, E N = int nu+ dt, and since a run from rest starts below any
gap b > 0, P(first passage in [0, T]) <= E N exactly (Markov's inequality on N).

Approximations of the first-passage probability P_f = P(max x > b over [0, T]):
- Poisson (crossings independent): P_f = 1 - exp(-E N); exact in the limit b -> inf (Cramer 1966).
- Vanmarcke (1975, "On the distribution of the first-passage time for normal stationary random processes",
  J. Appl. Mech. 42:215-220): crossings come in clumps for a narrow-band process; his two-state Markov
  model of the envelope gives the decay rate
      alpha = nu+ (1 - exp(-sqrt(pi / 2) delta_e r)) / (1 - exp(-r^2 / 2)),   r = b / sx,
  with the bandwidth delta = sqrt(1 - l1^2 / (l0 l2)) of the spectral moments l_k = int |w|^k S(w) dw and his
  empirical delta_e = delta^1.2; P_f = 1 - exp(-int alpha dt), applied here with the time-varying nu+ and r of
  a run from rest and the stationary delta (a stated approximation). The spectral moments come from the
  frequency-response integral (scipy.integrate.quad); l0 and l2 equal the Lyapunov variances (a check of both).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from pounding_sweep.model.coupled import CoupledModel


@dataclass(frozen=True)
class LinearSystem:
    """X' = A X + B w (the coupling of the ground acceleration into the structure in A's block `couple`,
    scaled by the envelope), q = 2 pi S0; rows of `out_d` / `out_v` pick each floor pair's relative
    displacement u1j - u2j and its rate."""

    A: np.ndarray
    B: np.ndarray
    q: float
    out_d: np.ndarray  # (pairs, states)
    out_v: np.ndarray  # (pairs, states)
    n_struct: int  # 2 N: the structure's states (u, u') come first
    couple: np.ndarray  # (N, filter states): -1 C_f, the ground acceleration's entry into u''

    def with_envelope(self, e: float) -> np.ndarray:
        """A with the ground acceleration multiplied by e."""
        A = self.A.copy()
        n = self.n_struct // 2
        A[n : 2 * n, self.n_struct :] = e * self.couple
        return A


def linear_system(model: CoupledModel, ground) -> LinearSystem:
    """The two frames (no contact) and the ground filter (model.stochastic.GroundFilter) as one system."""
    M, C, K = model.matrices()
    n = M.shape[0]
    Af, Bf, Cf = ground.state_space()
    s = Af.shape[0]
    minv = np.linalg.inv(M)
    A = np.zeros((2 * n + s, 2 * n + s))
    A[:n, n : 2 * n] = np.eye(n)
    A[n : 2 * n, :n] = -minv @ K
    A[n : 2 * n, n : 2 * n] = -minv @ C
    couple = -np.outer(np.ones(n), Cf)  # u'' = ... - 1 a_g, a_g = C_f z
    A[n : 2 * n, 2 * n :] = couple
    A[2 * n :, 2 * n :] = Af
    B = np.zeros(2 * n + s)
    B[2 * n :] = Bf
    G = model.contact_matrix()  # (N, pairs): u1j - u2j = G' u
    out_d = np.zeros((G.shape[1], 2 * n + s))
    out_v = np.zeros_like(out_d)
    out_d[:, :n] = G.T
    out_v[:, n : 2 * n] = G.T
    return LinearSystem(A, B, 2.0 * math.pi * ground.s0, out_d, out_v, 2 * n, couple)


def newmark_covariance_history(model: CoupledModel, motion, n_steps: int) -> np.ndarray:
    """The exact covariance of what the engine computes: Newmark average acceleration (h = the motion's sample
    step, the load linear between samples) driven by the exact sampled filter, from rest. The state is
    (u, u', u'', z); one step is the linear map of Newmark's two update equations and equilibrium at the step's
    end (Chopra, Dynamics of Structures, Table 5.4.2, in matrix form), and u''(0) = -1 a_g(0) from equilibrium
    at rest. Returns (n_steps + 1, pairs, 2): var d and var v of each pair at every step. Its difference from
    covariance_history is the discretisation error of the scheme and of the linear interpolation of the input."""
    phi, L, Cf, lp = motion.discrete()
    h = motion.dt_s
    M, C, K = model.matrices()
    n = M.shape[0]
    eye, zero = np.eye(n), np.zeros((n, n))
    lhs = np.block([[eye, zero, -h * h / 4 * eye], [zero, eye, -h / 2 * eye], [K, C, M]])
    rhs = np.block([[eye, h * eye, h * h / 4 * eye], [zero, eye, h / 2 * eye], [zero, zero, zero]])
    step = np.linalg.solve(lhs, rhs)
    load = np.linalg.solve(lhs, np.concatenate([np.zeros(2 * n), -M @ np.ones(n)]))  # per unit a_g(t + h)
    s = phi.shape[0]
    F = np.zeros((3 * n + s, 3 * n + s))
    F[: 3 * n, : 3 * n] = step
    F[: 3 * n, 3 * n :] = np.outer(load, Cf @ phi)  # a_g(t + h) = C (Phi z + L e)
    F[3 * n :, 3 * n :] = phi
    G = np.zeros((3 * n + s, s))
    G[: 3 * n] = np.outer(load, Cf @ L)
    G[3 * n :] = L
    T = np.zeros((3 * n + s, s))
    T[2 * n : 3 * n] = -np.outer(np.ones(n), Cf)
    T[3 * n :] = np.eye(s)
    S = T @ (lp @ lp.T) @ T.T
    Q = G @ G.T
    Gc = model.contact_matrix()
    out = np.empty((n_steps + 1, Gc.shape[1], 2))
    for k in range(n_steps + 1):
        if k:
            S = F @ S @ F.T + Q
        out[k, :, 0] = np.einsum("ip,ij,jp->p", Gc, S[:n, :n], Gc)
        out[k, :, 1] = np.einsum("ip,ij,jp->p", Gc, S[n : 2 * n, n : 2 * n], Gc)
    return out


def stationary_covariance(sys: LinearSystem) -> np.ndarray:
    """P with A P + P A' + q B B' = 0."""
    from scipy.linalg import solve_continuous_lyapunov

    P = solve_continuous_lyapunov(sys.A, -sys.q * np.outer(sys.B, sys.B))
    return 0.5 * (P + P.T)


def initial_covariance(sys: LinearSystem, ground, start: str = "stationary") -> np.ndarray:
    """P(0) of a run from rest: the structure at rest, the filter stationary (or at rest)."""
    P = np.zeros_like(sys.A)
    if start == "stationary":
        P[sys.n_struct :, sys.n_struct :] = ground.stationary_covariance()
    return P


def covariance_history(sys: LinearSystem, P0: np.ndarray, times, envelope=None) -> np.ndarray:
    """P(t) at `times` (uniform, from 0) from P(0) = P0: (len(times), states, states). Without an envelope by
    the exact step propagation, with one by integrating the Lyapunov equation (module docstring)."""
    t = np.asarray(times, dtype=float)
    out = np.empty((t.size,) + P0.shape)
    out[0] = P0
    qbb = sys.q * np.outer(sys.B, sys.B)
    if envelope is None or getattr(envelope, "kind", "none") == "none":
        from scipy.linalg import expm

        h = float(t[1] - t[0])
        n = sys.A.shape[0]
        m = np.zeros((2 * n, 2 * n))
        m[:n, :n] = -sys.A
        m[:n, n:] = qbb
        m[n:, n:] = sys.A.T
        e = expm(m * h)
        F = e[n:, n:].T
        Q = F @ e[:n, n:]
        Q = 0.5 * (Q + Q.T)
        P = P0
        for k in range(1, t.size):
            P = F @ P @ F.T + Q
            out[k] = P
        return out
    from scipy.integrate import solve_ivp

    n = sys.A.shape[0]

    def rhs(tt, y):
        A = sys.with_envelope(float(envelope(tt)))
        P = y.reshape(n, n)
        return (A @ P + P @ A.T + qbb).ravel()

    sol = solve_ivp(rhs, (t[0], t[-1]), P0.ravel(), t_eval=t, rtol=1e-10, atol=1e-30, method="DOP853")
    return sol.y.T.reshape((t.size, n, n))


def pair_moments(sys: LinearSystem, P) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(var d, var v, cov(d, v)) of each pair's relative displacement d and rate v, for P (..., states, states):
    arrays (..., pairs)."""
    d, v = sys.out_d, sys.out_v
    var_d = np.einsum("pi,...ij,pj->...p", d, P, d)
    var_v = np.einsum("pi,...ij,pj->...p", v, P, v)
    cov = np.einsum("pi,...ij,pj->...p", d, P, v)
    return var_d, var_v, cov


def upcrossing_rate(b, var_x, var_v, cov_xv=0.0) -> np.ndarray:
    """Rice's mean up-crossing rate of level b by a zero-mean Gaussian process [1/s] (module docstring)."""
    from scipy.special import ndtr

    sx = np.sqrt(np.asarray(var_x, dtype=float))
    c = np.asarray(cov_xv, dtype=float)
    with np.errstate(divide="ignore", invalid="ignore"):
        m = c * b / (sx * sx)
        s = np.sqrt(np.maximum(np.asarray(var_v, dtype=float) - c * c / (sx * sx), 0.0))
        phi_b = np.exp(-0.5 * (b / sx) ** 2) / (math.sqrt(2 * math.pi) * sx)
        ms = np.where(s > 0, m / np.where(s > 0, s, 1.0), np.sign(m) * np.inf)
        inner = s * np.exp(-0.5 * np.minimum(ms * ms, 1e300)) / math.sqrt(2 * math.pi) + m * ndtr(ms)
        out = phi_b * inner
    return np.where(sx > 0, out, 0.0)


def expected_upcrossings(times, rate) -> np.ndarray:
    """int nu+ dt by the trapezoid rule along the first axis of `rate` (times uniform)."""
    return np.trapezoid(np.asarray(rate), np.asarray(times, dtype=float), axis=0)


def poisson_first_passage(expected_crossings) -> np.ndarray:
    """1 - exp(-E N)."""
    return -np.expm1(-np.asarray(expected_crossings, dtype=float))


def vanmarcke_rate(b, var_x, var_v, delta, cov_xv=0.0) -> np.ndarray:
    """Vanmarcke's (1975) first-passage decay rate alpha for a one-sided barrier b (module docstring)."""
    nu = upcrossing_rate(b, var_x, var_v, cov_xv)
    with np.errstate(divide="ignore", invalid="ignore"):
        r = b / np.sqrt(np.asarray(var_x, dtype=float))
        factor = -np.expm1(-math.sqrt(2.0 * math.pi) * delta**1.2 * r) / -np.expm1(-0.5 * r * r)
    return np.where(np.isfinite(factor), nu * factor, 0.0)


def vanmarcke_first_passage(times, b, var_x, var_v, delta, cov_xv=0.0) -> np.ndarray:
    """1 - exp(-int alpha dt) with the time-varying moments of a run from rest and a fixed bandwidth delta."""
    alpha = vanmarcke_rate(b, var_x, var_v, delta, cov_xv)
    return -np.expm1(-expected_upcrossings(times, alpha))


def spectral_moments(model: CoupledModel, ground, pair: int, orders=(0, 1, 2)) -> dict[int, float]:
    """l_k = int_{-inf}^{inf} |w|^k |H_j(w)|^2 S_a(w) dw of pair j's stationary relative displacement
    (H_j: its frequency response to the ground acceleration), by adaptive quadrature split at the frames'
    modal frequencies and the filter's corner frequencies (scipy.integrate.quad, epsrel 1e-10)."""
    from scipy.integrate import quad

    M, C, K = model.matrices()
    G = model.contact_matrix()[:, pair]
    one = np.ones(M.shape[0])
    rhs = -M @ one

    def h2(w):
        Z = K - w * w * M + 1j * w * C
        u = np.linalg.solve(Z, rhs)
        return abs(G @ u) ** 2

    freqs = []
    for b in (model.b1, model.b2):
        freqs += list(b.modes().omega_rad_s)
    freqs += [ground.omega_g] + ([ground.omega_f] if ground.omega_f > 0 else [])
    edges = sorted({0.0, *[float(f) for f in freqs], *[2.0 * float(f) for f in freqs]})
    out = {}
    for k in orders:

        def f(w, k=k):
            return w**k * h2(w) * float(ground.psd(w))

        total = sum(quad(f, a, b, limit=500, epsabs=0.0, epsrel=1e-10)[0] for a, b in zip(edges[:-1], edges[1:]))
        total += quad(f, edges[-1], np.inf, limit=500, epsabs=0.0, epsrel=1e-10)[0]
        out[k] = 2.0 * total  # the spectrum is even: both halves of the frequency axis
    return out


def bandwidth(moments: dict[int, float]) -> float:
    """Vanmarcke's delta = sqrt(1 - l1^2 / (l0 l2))."""
    return math.sqrt(max(0.0, 1.0 - moments[1] ** 2 / (moments[0] * moments[2])))


__all__ = [
    "LinearSystem",
    "linear_system",
    "newmark_covariance_history",
    "stationary_covariance",
    "initial_covariance",
    "covariance_history",
    "pair_moments",
    "upcrossing_rate",
    "expected_upcrossings",
    "poisson_first_passage",
    "vanmarcke_rate",
    "vanmarcke_first_passage",
    "spectral_moments",
    "bandwidth",
]
