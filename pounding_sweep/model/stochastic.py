"""Stochastic ground motion: filtered white noise (Kanai-Tajimi, Clough-Penzien), stationary or modulated by
a time envelope, sampled exactly and generated deterministically from a seed.

Filters (the bedrock acceleration w(t) is Gaussian white noise with two-sided spectral density S0 in
circular frequency: E[w(t) w(t + tau)] = 2 pi S0 delta(tau), S0 in m^2/s^3):

- Kanai-Tajimi (Kanai 1957, Bull. Earthq. Res. Inst. 35:309-325; Tajimi 1960, Proc. 2nd WCEE 781-797): a soil
  layer as an oscillator x'' + 2 zg wg x' + wg^2 x = -w, whose absolute acceleration a = x'' + w =
  -(2 zg wg x' + wg^2 x) is the ground acceleration: S_a(w) = S0 (wg^4 + 4 zg^2 wg^2 w^2) /
  ((wg^2 - w^2)^2 + 4 zg^2 wg^2 w^2).
- Clough-Penzien (Clough & Penzien, Dynamics of Structures, 1975, sec. 25-4): the Kanai-Tajimi acceleration
  through a second oscillator y'' + 2 zf wf y' + wf^2 y = a_KT whose relative acceleration y'' is the ground
  acceleration: S_a times w^4 / ((wf^2 - w^2)^2 + 4 zf^2 wf^2 w^2), which removes the Kanai-Tajimi
  spectrum's finite value at w = 0 (unbounded ground displacement).

Either is a linear system z' = A z + B w, a = C z. Sampled at the step h it is exactly the autoregression
z[k+1] = Phi z[k] + L e[k], Phi = exp(A h), e standard normal, L L' = Q = int_0^h exp(A s) B 2 pi S0 B'
exp(A' s) ds (Van Loan 1978, IEEE Trans. Autom. Control 23:395-404, for Phi and Q from one exponential;
L is Q's Cholesky factor). So every sample is the continuous process's value at t = k h, with no
discretisation error; between samples the engine interpolates linearly, as for a record. "stationary": z[0]
is drawn from the stationary covariance P (A P + P A' + 2 pi S0 B B' = 0, scipy.linalg.
solve_continuous_lyapunov), so the ground motion is stationary from t = 0; "rest": z[0] = 0.

Envelope (uniformly modulated process, a(t) = e(t) C z(t)): Jennings, Housner & Tsai (1968, "Simulated
earthquake motions", Report EERL, California Institute of Technology): e = (t / t1)^2 before t1, 1 until t2,
exp(-c (t - t2)) after.

Determinism: realisation `seed` draws its normals from numpy's PCG64 seeded by SeedSequence(seed), first
z[0]'s (stationary start), then e[k] row by row; it depends on nothing but the seed, the model and the
sampling, so any chunk of a sweep regenerates it bit for bit on resume or on another worker (the same NumPy
version: numpy.random's stream policy, NEP 19).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

FILTERS = ("kanai_tajimi", "clough_penzien")
ENVELOPES = ("none", "jennings")
STARTS = ("stationary", "rest")


@dataclass(frozen=True)
class GroundFilter:
    """The filter of a filtered-white-noise ground acceleration (module docstring), SI units."""

    kind: str  # FILTERS
    omega_g: float  # soil frequency wg [rad/s]
    zeta_g: float  # soil damping ratio zg
    s0: float  # two-sided spectral density of the bedrock white noise [m^2/s^3]
    omega_f: float = 0.0  # Clough-Penzien high-pass frequency wf [rad/s]
    zeta_f: float = 0.0  # Clough-Penzien high-pass damping ratio zf

    def state_space(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(A, B, C): z' = A z + B w, a_g = C z (no feed-through)."""
        wg, zg = self.omega_g, self.zeta_g
        kt_out = np.array([-wg * wg, -2.0 * zg * wg])  # a_KT = -(wg^2 x + 2 zg wg x')
        if self.kind == "kanai_tajimi":
            A = np.array([[0.0, 1.0], [-wg * wg, -2.0 * zg * wg]])
            B = np.array([0.0, -1.0])
            return A, B, kt_out
        wf, zf = self.omega_f, self.zeta_f
        A = np.zeros((4, 4))
        A[0, 1] = 1.0
        A[1, :2] = [-wg * wg, -2.0 * zg * wg]
        A[2, 3] = 1.0
        A[3, :2] = kt_out  # y'' = a_KT - wf^2 y - 2 zf wf y'
        A[3, 2:] = [-wf * wf, -2.0 * zf * wf]
        B = np.array([0.0, -1.0, 0.0, 0.0])
        return A, B, A[3].copy()  # a_CP = y''

    def psd(self, omega) -> np.ndarray:
        """Two-sided spectral density of the ground acceleration [m^2/s^3] at circular frequencies omega."""
        w2 = np.asarray(omega, dtype=float) ** 2
        wg2, c = self.omega_g**2, 4.0 * self.zeta_g**2 * self.omega_g**2
        out = self.s0 * (wg2 * wg2 + c * w2) / ((wg2 - w2) ** 2 + c * w2)
        if self.kind == "clough_penzien":
            wf2, cf = self.omega_f**2, 4.0 * self.zeta_f**2 * self.omega_f**2
            out = out * w2 * w2 / ((wf2 - w2) ** 2 + cf * w2)
        return out

    def stationary_covariance(self) -> np.ndarray:
        """P: A P + P A' + 2 pi S0 B B' = 0 (the filter's stationary state covariance)."""
        from scipy.linalg import solve_continuous_lyapunov

        A, B, _ = self.state_space()
        P = solve_continuous_lyapunov(A, -2.0 * math.pi * self.s0 * np.outer(B, B))
        return 0.5 * (P + P.T)

    def variance(self) -> float:
        """Stationary variance of the ground acceleration [m^2/s^4]: C P C'."""
        _, _, C = self.state_space()
        return float(C @ self.stationary_covariance() @ C)


@dataclass(frozen=True)
class Envelope:
    """A time envelope e(t) of a uniformly modulated process (module docstring)."""

    kind: str = "none"  # ENVELOPES
    rise_s: float = 0.0  # t1
    strong_end_s: float = 0.0  # t2
    decay_per_s: float = 0.0  # c

    def __call__(self, t) -> np.ndarray:
        t = np.asarray(t, dtype=float)
        if self.kind == "none":
            return np.ones_like(t)
        t1, t2, c = self.rise_s, self.strong_end_s, self.decay_per_s
        rise = (t / t1) ** 2 if t1 > 0 else np.ones_like(t)
        return np.where(t < t1, rise, np.where(t <= t2, 1.0, np.exp(-c * np.maximum(t - t2, 0.0))))


@dataclass(frozen=True)
class StochasticMotion:
    """A family of ground motions: the filter, the envelope, the sampling; realisations by seed."""

    ground: GroundFilter
    envelope: Envelope
    dt_s: float  # sample step h [s]
    n_samples: int  # samples at t = k h, k = 0 .. n - 1
    start: str = "stationary"  # STARTS
    _cache: dict = field(default_factory=dict, compare=False, repr=False, hash=False)

    def discrete(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(Phi, L, C, Lp): the exact sampled recursion z[k+1] = Phi z[k] + L e[k], the output a = C z and
        the Cholesky factor of the stationary covariance (zero for a start at rest)."""
        if "discrete" not in self._cache:
            from scipy.linalg import expm

            A, B, C = self.ground.state_space()
            n = A.shape[0]
            # Van Loan: exp([[-A, B q B'], [0, A']] h) = [[., F12], [0, F22]]; Phi = F22', Q = Phi F12
            m = np.zeros((2 * n, 2 * n))
            m[:n, :n] = -A
            m[:n, n:] = 2.0 * math.pi * self.ground.s0 * np.outer(B, B)
            m[n:, n:] = A.T
            e = expm(m * self.dt_s)
            phi = e[n:, n:].T.copy()
            q = phi @ e[:n, n:]
            q = 0.5 * (q + q.T)
            L = np.linalg.cholesky(q)
            if self.start == "stationary":
                lp = np.linalg.cholesky(self.ground.stationary_covariance())
            else:
                lp = np.zeros((n, n))
            self._cache["discrete"] = (phi, L, C, lp)
        return self._cache["discrete"]

    @property
    def times(self) -> np.ndarray:
        return np.arange(self.n_samples) * self.dt_s

    @property
    def duration_s(self) -> float:
        return (self.n_samples - 1) * self.dt_s

    def generate(self, seeds, threads: int = 1) -> np.ndarray:
        """The realisations of `seeds` (non-negative integers): (len(seeds), n_samples) ground accelerations
        [m/s^2]. Each row depends only on its seed (module docstring), whatever the other rows and `threads`
        (the normals are drawn on that many threads: numpy.random releases the GIL while it fills an array)."""
        phi, L, C, lp = self.discrete()
        seeds = [int(s) for s in np.atleast_1d(seeds)]
        s, n, r = phi.shape[0], self.n_samples, len(seeds)
        z = np.empty((r, s))
        noise = np.empty((r, n, s))

        def draw(rows) -> None:
            for i in rows:
                rng = np.random.Generator(np.random.PCG64(np.random.SeedSequence(seeds[i])))
                z0 = rng.standard_normal(s)
                z[i] = [sum(lp[a, b] * z0[b] for b in range(s)) for a in range(s)]
                rng.standard_normal(out=noise[i])

        threads = max(1, min(int(threads), r))
        if threads == 1:
            draw(range(r))
        else:
            from concurrent.futures import ThreadPoolExecutor

            with ThreadPoolExecutor(max_workers=threads) as pool:
                list(pool.map(draw, [range(t, r, threads) for t in range(threads)]))
        out = np.empty((r, n))
        _recursion()(np.ascontiguousarray(phi), np.ascontiguousarray(L), np.ascontiguousarray(C), z, noise, out)
        if self.envelope.kind != "none":
            out *= self.envelope(self.times)
        return out


_RECURSION = []


def _recursion():
    """The sampled recursion a[k] = C z[k], z[k+1] = Phi z[k] + L e[k], compiled once (Numba, cached; serial
    and row by row, so a row's rounding never depends on the other rows of the chunk: a matrix product's
    blocking would, BLAS kernels differ with the row count)."""
    if not _RECURSION:
        import numba

        @numba.njit(cache=True, nogil=True)
        def run(phi, L, C, z0, noise, out):  # pragma: no cover - compiled
            r, n = out.shape
            s = phi.shape[0]
            z = np.empty(s)
            w = np.empty(s)
            for row in range(r):
                for i in range(s):
                    z[i] = z0[row, i]
                for k in range(n):
                    acc = 0.0
                    for i in range(s):
                        acc += C[i] * z[i]
                    out[row, k] = acc
                    if k + 1 < n:
                        for i in range(s):
                            v = 0.0
                            for j in range(s):
                                v += phi[i, j] * z[j]
                            for j in range(s):
                                v += L[i, j] * noise[row, k, j]
                            w[i] = v
                        for i in range(s):
                            z[i] = w[i]

        _RECURSION.append(run)
    return _RECURSION[0]


def from_config(cfg, dt_s: float, duration_s: float) -> StochasticMotion:
    """The family a scene's [stochastic] section describes, sampled every dt_s over duration_s."""
    two_pi = 2.0 * math.pi
    ground = GroundFilter(
        cfg.filter,
        two_pi * cfg.ground_frequency_Hz,
        cfg.ground_damping,
        cfg.s0_m2_per_s3,
        two_pi * (cfg.highpass_frequency_Hz or 0.0),
        cfg.highpass_damping or 0.0,
    )
    env = Envelope(cfg.envelope, cfg.rise_s or 0.0, cfg.strong_end_s or 0.0, cfg.decay_per_s or 0.0)
    n = math.floor(duration_s / dt_s + 1e-9) + 1
    return StochasticMotion(ground, env, dt_s, n, cfg.start)


__all__ = ["FILTERS", "ENVELOPES", "STARTS", "GroundFilter", "Envelope", "StochasticMotion", "from_config"]
