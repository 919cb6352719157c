"""Tolerances of the suite's "equal up to rounding" comparisons, each derived from an error bound.

Two computations that are equal in exact arithmetic (the kernel and the NumPy reference; the lane
kernel and the scalar kernel) differ by their rounding, propagated through the run. How much a run
amplifies rounding depends on the run: a quiet linear stretch adds it up step by step, a contact
event can multiply it (the impact instant moves with the state). A fixed tolerance tuned on one CPU
is either too loose for the quiet runs or too tight for the sensitive ones on another CPU (vector
width, fused multiply-adds and the libm differ between code-generation targets). So each
comparison measures the run's own sensitivity with a *twin*, a computation that rounds differently
on purpose, and allows SAFETY times what the twin shows:

- against the NumPy reference: Monte Carlo arithmetic twins (tests/reference.py `noise`): every
  solve result, velocity and acceleration of the reference multiplied by (1 + n u xi), xi uniform in
  [-1, 1], n the degrees of freedom: one random rounding of the size of Higham's bound on a length-n
  dot product's relative error (gamma_n ~ n u: Higham, Accuracy and Stability of Numerical
  Algorithms, 2nd ed. 2002, eq. 3.4), applied where a program rounds, before eqs. 15-16 amplify it by
  2/dt and 4/dt^2 (Parker, Pierce & Eggert, "Monte Carlo arithmetic: how to gamble with floating
  point and win", Comput. Sci. Eng. 2(4), 2000);
- against the scalar kernel (the lane kernel's grids, too many runs for the reference): backward-error
  twins: the scalar kernel on the same model with every entry of its stored matrices (C, K, Keff^-1,
  H, S) multiplied by (1 +/- n u), fixed random signs: the matrices as rounding leaves them when they
  are formed (Higham ch. 3, the backward error of a matrix product or inverse is n u per entry to first
  order). The lane kernel's own difference from the scalar kernel is of this kind: its modal
  coordinates carry the eigenvectors' rounding into every step, the same error in every step.

SAFETY: measured over the 23 kernel-vs-reference cases and the lane kernel's harmonic grids on three
code-generation targets (the host's AVX-512 `znver4`, AVX2 with FMA `haswell`, and `generic`
x86-64 without either), the largest ratio of the actual difference to the larger of two twins'
differences was 8.7 (MCA, event scheme) and 5.3 (backward-error twins); one twin's difference varies
by up to 2.6x between seeds (8 seeds). 8.7 x 2.6 = 23, rounded up to a power of two: 32.

Floors: where both twins agree with the base exactly (a quantity that is identically zero, say),
FLOOR_STEPS (the linear accumulation of one rounding per step over N steps of a non-expanding
recurrence: Newmark average acceleration has spectral radius 1, Chopra sec. 5.5; Higham Lemma 3.1)
still allows N n u of the quantity's scale.

Near-ties: counts (impacts, compression phases) are equal unless a twin's count differs from the
base's: then the run sits at a near-tie (an impact decided by a rounding-level difference) and any
count between the base's and the twins' is accepted. Quantities that the event scheme sets at its
own thresholds rather than by rounding carry those thresholds (`switch_residue_force`, phases).
"""

from __future__ import annotations

import numpy as np

#: unit roundoff of IEEE 754 binary64 (half the spacing of doubles at 1)
U = 2.0**-53
#: the largest difference / twin-difference ratio measured (8.7) times the twins' seed variation (2.6),
#: rounded up to a power of two (module docstring)
SAFETY = 32.0
#: seeds of the two twins of every comparison
SEEDS = (1, 2)


def rel_to_peak(x, ref) -> float:
    """max |x - ref| / max |ref| (the absolute difference when ref is identically 0)."""
    peak = np.max(np.abs(ref)) if np.size(ref) else 0.0
    diff = np.max(np.abs(np.asarray(x) - np.asarray(ref))) if np.size(ref) else 0.0
    return float(diff / peak) if peak > 0 else float(diff)


def mca_noise(n_dof: int) -> float:
    """Relative size of one random rounding in the Monte Carlo arithmetic twins: n u (Higham's gamma_n to
    first order: the relative error of a length-n dot product, the core of every solve)."""
    return n_dof * U


def floor_steps(n_steps: int, n_dof: int) -> float:
    """Relative rounding accumulated by n_steps of a non-expanding recurrence that rounds each of n_dof
    components once per step: n_steps n u (Higham Lemma 3.1, errors adding linearly)."""
    return float(n_steps) * n_dof * U


def history_tolerance(ref: dict, twins: list[dict], key: str, n_steps: int, n_dof: int, sl=slice(None)) -> float:
    """Tolerance on rel_to_peak(kernel[key], ref[key]): SAFETY times the larger twin difference, at least
    the linear accumulation floor."""
    spread = max(rel_to_peak(t[key][sl], ref[key][sl]) for t in twins)
    return SAFETY * max(spread, floor_steps(n_steps, n_dof))


def value_tolerance(
    base: np.ndarray, twins: list[np.ndarray], scale: np.ndarray, n_steps: int, n_dof: int
) -> np.ndarray:
    """Per-element tolerance on |other - base| for a per-run value: SAFETY times the larger twin
    difference, at least the linear accumulation floor of the value's `scale` (the column's largest
    magnitude: a peak is computed from states whose rounding is relative to the run's peaks, not to
    the value itself, which may be near zero)."""
    spread = np.max([np.abs(t - base) for t in twins], axis=0)
    return SAFETY * np.maximum(spread, floor_steps(n_steps, n_dof) * np.abs(scale))


def count_bounds(base, twins) -> tuple[np.ndarray, np.ndarray]:
    """Counts accepted for another computation: the base's, or, where a twin's differs (a near-tie), any
    value between the base's and the twins'."""
    stack = np.stack([np.asarray(base)] + [np.asarray(t) for t in twins])
    return stack.min(axis=0), stack.max(axis=0)


def switch_residue_force(ks, up, uq):
    """Largest |force| [N] the event scheme leaves on a pair without calling it a switch: a penetration
    (or, under no tension, F / k_s) inside events.switch_tolerance of zero at a step's end does not
    contradict the contact set, so a phase's least force may sit anywhere in +/- k_s times it. The
    tolerance is the kernel's own rule (one home), evaluated on the floors' peak displacements."""
    from pounding_sweep.engine.events import switch_tolerance

    return np.asarray(ks) * np.vectorize(switch_tolerance)(np.asarray(up, float), np.asarray(uq, float))


def summation_tolerance(n_terms: int, abs_sum) -> float:
    """|error| of a floating-point sum of n_terms terms: (n_terms - 1) u sum |terms| (Higham eq. 4.4,
    recursive summation), for identities whose two sides are sums over the run's steps."""
    return max(n_terms - 1, 1) * U * abs_sum


def energy_balance_tolerance(m: dict, n_dof: int) -> float:
    """|E_in - (KE + SE + D_struct + D_contact + E_spring + residual)| for a run's metrics `m`: both sides
    are sums over the run's steps of increments that are each n_dof-term dot products (relative error
    n u of their absolute terms) and are summed recursively (error (N - 1) u sum |increments|: Higham
    eq. 4.4): N (n + 1) u times the energies' absolute scale. (The identity itself, trapezoidal work
    against Newmark average acceleration, is exact in exact arithmetic.)"""
    scale = (
        m["input_work_abs_J"]
        + abs(m["structural_damping_energy_J"])
        + abs(m["contact_damping_energy_J"])
        + abs(m["kinetic_energy_end_J"])
        + abs(m["strain_energy_end_J"])
        + abs(m["contact_spring_energy_end_J"])
    )
    return summation_tolerance(int(m["steps"]) * (n_dof + 1), scale)


def mca_twins(run, n_dof: int) -> list:
    """The Monte Carlo arithmetic twins of a reference run: run(noise=..., seed=...) for each of SEEDS."""
    return [run(noise=mca_noise(n_dof), seed=s) for s in SEEDS]


def backward_error_twin(sysarr, seed: int):
    """The scalar kernel's SystemArrays with every entry of C, K, Keff^-1, H and S multiplied by
    (1 +/- n u), random signs from `seed`: the same model as rounding may leave it (module docstring)."""
    import dataclasses

    rng = np.random.default_rng(seed)
    n = sysarr.m.size

    def rounded(A):
        return np.ascontiguousarray(A * (1.0 + n * U * rng.choice([-1.0, 1.0], A.shape)))

    return dataclasses.replace(
        sysarr,
        C=rounded(sysarr.C),
        K=rounded(sysarr.K),
        Kinv=rounded(sysarr.Kinv),
        H=rounded(sysarr.H),
        S=rounded(sysarr.S),
    )


def interpolation_bound(values, t_end: float, dt: float) -> float:
    """|difference| of two linear interpolations of the same step values `values` (one per step of dt) at the
    same instants, computed two ways (the kernel's theta = (t_k - (t - dt)) / dt, np.interp's slope): each theta
    is off by the rounding of t - dt or of the step's length, (t_end / dt + 3) u relative, times the step's
    change |values[n + 1] - values[n]|, and each result rounds a product and two sums, 3 u |value|; for the two
    computations twice that (Higham, Accuracy and Stability of Numerical Algorithms, 2nd ed. 2002, ch. 2:
    every operation exact times (1 + delta), |delta| <= u)."""
    v = np.asarray(values, float)
    return 2.0 * (3.0 * U * np.abs(v).max() + (t_end / dt + 3.0) * U * np.abs(np.diff(v)).max())


def sos_rounding_bound(sos, x) -> float:
    """Largest |error| that filtering x through the second-order sections `sos` in the transposed direct form II
    (scipy.signal.sosfilt; engine/score.py sos_filter) can commit, to first order in u. Per sample, section s
    commits at most u (|b0| X + Y) in its output y (a product and a sum), u (2 |b1| X + 2 |a1| Y + Z) in its first
    state (two products, a difference and a sum) and u (2 |b2| X + 2 |a2| Y) in its second (X, Y, Z: the largest
    |input|, |output| and |first state| of the section on x; Higham ch. 2). An error committed in a section's
    state or output enters that section's output as an input to its poles 1 / A_s(z) and then passes the later
    sections, so the cascade's output is off by at most sum_s E_s ||g_s||_1, g_s the impulse response of
    1 / A_s followed by sections s + 1.. over the record's length (an error at sample n reaches n..N-1 only)."""
    from scipy.signal import sosfilt

    x = np.asarray(x, float)
    n = x.size
    impulse = np.zeros(n)
    impulse[0] = 1.0
    total = 0.0
    xin = x
    for s in range(sos.shape[0]):
        b0, b1, b2, _, a1, a2 = sos[s]
        y = sosfilt(sos[s : s + 1], xin)
        z = y[1:] - b0 * xin[1:]  # y[n + 1] = b0 x[n + 1] + z[n]
        X, Y, Z = np.abs(xin).max(), np.abs(y).max(), (np.abs(z).max() if z.size else 0.0)
        per_sample = U * (
            (abs(b0) * X + Y) + (2 * abs(b1) * X + 2 * abs(a1) * Y + Z) + (2 * abs(b2) * X + 2 * abs(a2) * Y)
        )
        poles = np.array([[1.0, 0.0, 0.0, 1.0, a1, a2]])
        g = sosfilt(np.vstack([poles, sos[s + 1 :]]), impulse)
        total += per_sample * np.abs(g).sum()
        xin = y
    return float(total)


def filtered_samples_bound(sos, samples, input_bound: float) -> float:
    """|difference| of two filterings (scipy's and the kernel's) of two sample sequences that differ by at most
    `input_bound` each: the filter's gain ||h||_1 on the input difference (a linear filter's output moves at most
    that much) plus both filterings' own rounding (sos_rounding_bound). Without sections: input_bound."""
    if sos.shape[0] == 0:
        return float(input_bound)
    from scipy.signal import sosfilt

    impulse = np.zeros(len(samples))
    impulse[0] = 1.0
    gain = np.abs(sosfilt(sos, impulse)).sum()
    return float(gain * input_bound + 2.0 * sos_rounding_bound(sos, samples))


def rel_rms_bound(sample_bound: float, xe, value_pct: float) -> float:
    """|difference| [%] of two eq. 20 errors of numerical samples that differ by at most `sample_bound` each,
    against the same experiment xe: 100 sample_bound / rms(xe) (the numerator is a 2-norm: it moves at most by
    the 2-norm of the difference, sqrt(N) sample_bound), plus the relative rounding of each computation's two
    N-term sums and square root, 2 (N + 2) u of the value."""
    xe = np.asarray(xe, float)
    return float(100.0 * sample_bound / np.sqrt(np.mean(xe**2)) + 2.0 * (xe.size + 2) * U * value_pct)
