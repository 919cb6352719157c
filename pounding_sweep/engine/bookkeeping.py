"""The per-run book-keeping the two floor-coordinate kernels share (engine/scalar.py for the linear laws,
engine/nonlinear.py for the Hertz-type laws): the metric row's reset, per-floor peaks, per-pair contact
metrics of an accepted piece, the experiment samples, history columns, and the run's closing rows
(compression phases, scores, energy balance). One home, so both kernels report a run the same way; the
phases' median (median_inplace) is the lane kernel's too.
"""

from __future__ import annotations

import numpy as np

from pounding_sweep import codes
from pounding_sweep.engine import layout as L
from pounding_sweep.engine.events import ground_acceleration
from pounding_sweep.engine.jit import inline_kernel, njit_inner, njit_piece_once
from pounding_sweep.engine.score import N_SCORES, _score_channel, _sos_filter


@njit_inner
def start_row(out, npair, pbase, gap):
    """Zero the run's metric row; each pair's closest approach starts at the gap (at rest, time 0)."""
    for q in range(out.shape[0]):
        out[q] = 0.0
    for j in range(npair):
        out[pbase + L.PER_PAIR * j + L.PAIR_CLOSEST] = gap


@njit_inner
def start_at_rest(run, runs, records, dt, u, v, a):
    """The run at rest relative to the table: u = v = 0 and, by eq. (11) a0 = M^-1 (p0 - C v0 - K u0) with
    p0 = -M 1 ag(0), a = -ag(0). Returns (roff, rlen, ag(0)): the run's record in records.flat (offset,
    length; 0, 0 for a harmonic run) and the table's acceleration at t = 0 [m/s^2]."""
    kind = runs.exc_kind[run]
    roff = 0
    rlen = 0
    if kind == codes.EXC_RECORD:
        roff = records.off[runs.rec_id[run]]
        rlen = records.len[runs.rec_id[run]]
    ag = ground_acceleration(kind, runs.exc_amp[run], runs.exc_omega[run], records.flat, roff, rlen, np.int64(0), dt)
    for i in range(u.size):
        u[i] = 0.0
        v[i] = 0.0
        a[i] = -ag
    return roff, rlen, ag


@njit_inner
def start_pairs(active, F, bufs, phases, gap):
    """Every pair at rest at the run's start: out of contact, no force, `gap` apart, no phase open.
    bufs = (was_active, spring part, dashpot part, penetration) of the energy book-keeping; phases as
    pair_pieces takes them."""
    was_active, sprev, dprev, pen_prev = bufs
    in_comp, comp_acc, _durations, nphase = phases
    for j in range(active.size):
        active[j] = False
        was_active[j] = False
        F[j] = 0.0
        sprev[j] = 0.0
        dprev[j] = 0.0
        pen_prev[j] = -gap  # at rest the pair is `gap` apart
        in_comp[j] = False
        comp_acc[j] = 0.0
        nphase[j] = 0


@njit_inner
def force_extremes(out, base, f, t):
    """A pair's peak force (and its time) and least force, at slot `base` of a metric row."""
    if f > out[base + L.PAIR_PEAK_FORCE]:
        out[base + L.PAIR_PEAK_FORCE] = f
        out[base + L.PAIR_PEAK_FORCE_TIME] = t
    if f < out[base + L.PAIR_MIN_FORCE]:
        out[base + L.PAIR_MIN_FORCE] = f


@njit_inner
def samples_at_rest(exp_t, xs):
    """Experiment samples at t <= 0 see the structure at rest; returns the next sample to fill."""
    k = 0
    while k < exp_t.size and exp_t[k] <= 0.0:
        for c in range(xs.shape[0]):
            xs[c, k] = 0.0
        k += 1
    return k


@njit_inner
def any_acceleration(exp_kind):
    """Whether an experiment channel is an absolute acceleration (codes.H_ABS_ACC)."""
    for c in range(exp_kind.size):
        if exp_kind[c] == codes.H_ABS_ACC:
            return True
    return False


@njit_inner
def sample_experiment(k, channels, xs, start, end, t, dt):
    """Fill the experiment samples inside (t - dt, t] by linear interpolation between the step's ends
    (channels = (times, DOFs, kinds) as engine/inputs.py ScoreSpec's t, dof, kind),
    start = (u, a, ag) and end = (u, a, ag) (displacement and acceleration relative to the table, the
    table's acceleration): a displacement channel between the two u, an absolute-acceleration channel
    between a + ag at either end (the abs_acc history channel's values there); returns the next sample
    to fill."""
    exp_t, exp_dof, exp_kind = channels
    ustep, astep, agstep = start
    u, a, ag = end
    while k < exp_t.size and exp_t[k] <= t + 1e-12 * dt:
        theta = (exp_t[k] - (t - dt)) / dt
        for c in range(exp_dof.size):
            q = exp_dof[c]
            if exp_kind[c] == codes.H_ABS_ACC:
                a0 = astep[q] + agstep
                xs[c, k] = a0 + theta * ((a[q] + ag) - a0)
            else:
                xs[c, k] = ustep[q] + theta * (u[q] - ustep[q])
        k += 1
    return k


@njit_inner
def floor_peaks(out, u, a, ag, t, n1):
    """Per floor, at a step's end: peak |u| (and its time), peak |absolute acceleration|, peak |drift|
    of the story below (building 1's ground story is DOF 0, building 2's DOF n1)."""
    for i in range(u.shape[0]):
        base = L.PER_DOF * i
        ad = abs(u[i])
        if ad > out[base + L.DOF_PEAK_DISP]:
            out[base + L.DOF_PEAK_DISP] = ad
            out[base + L.DOF_PEAK_DISP_TIME] = t
        aa = abs(a[i] + ag)
        if aa > out[base + L.DOF_PEAK_ABS_ACC]:
            out[base + L.DOF_PEAK_ABS_ACC] = aa
        dr = abs(u[i] - u[i - 1]) if i != 0 and i != n1 else abs(u[i])
        if dr > out[base + L.DOF_PEAK_DRIFT]:
            out[base + L.DOF_PEAK_DRIFT] = dr


@njit_inner
def channel(kind, index, u, v, a, F, ag):
    """Value of one history channel (see pounding_sweep.codes.H_*)."""
    if kind == codes.H_DISP:
        return u[index]
    if kind == codes.H_VEL:
        return v[index]
    if kind == codes.H_ABS_ACC:
        return a[index] + ag
    if kind == codes.H_FORCE:
        return F[index]
    return ag


@njit_inner
def keep_history(hist, run, col, kinds, index, u, v, a, F, ag):
    """Store every history channel's value in column `col` (dropped past the array's end)."""
    if col < hist.shape[2]:
        for c in range(kinds.shape[0]):
            hist[run, c, col] = channel(kinds[c], index[c], u, v, a, F, ag)


@inline_kernel
def structure_work(u, un, m, C, Cdu, ag_s, ag_e, hs):
    """(input work, structural damping work) of an accepted Newmark piece of length hs from u to un:
    -du.M 1 (ag_s + ag_e) / 2 and du.C du / hs, exact for average acceleration (du = hs (v + vn) / 2)."""
    n = u.shape[0]
    s_in = 0.0
    for i in range(n):
        s_in += m[i] * (un[i] - u[i])
        s = 0.0
        for k in range(n):
            s += C[i, k] * (un[k] - u[k])
        Cdu[i] = s
    de = -0.5 * (ag_s + ag_e) * s_in
    s = 0.0
    for i in range(n):
        s += (un[i] - u[i]) * Cdu[i]
    return de, s / hs


@njit_inner
def end_phase(durations, nphase, j, duration):
    """Close a compressive phase of pair j (its duration kept for the median while the buffer lasts)."""
    k = nphase[j]
    if k < durations.shape[1]:
        durations[j, k] = duration
    nphase[j] = k + 1


@njit_inner
def pair_pieces(out, pbase, pen, F, active, was_active, hs, t_e, phases):
    """Contact metrics of every pair over an accepted piece of length hs ending at t_e, with penetration
    pen[j] and force F[j] there: closest approach, impacts (a pair that entered contact), contact time,
    penetration and force extremes, compressive time and phases (F > 0; phases = (in_comp, comp_acc,
    durations, nphase): a phase in progress, its duration so far, the phases' durations and count);
    then was_active = active."""
    in_comp, comp_acc, durations, nphase = phases
    for j in range(pen.shape[0]):
        base = pbase + L.PER_PAIR * j
        p = pen[j]
        f = F[j]
        act = active[j]
        if -p < out[base + L.PAIR_CLOSEST]:  # closest approach, at every accepted piece's end
            out[base + L.PAIR_CLOSEST] = -p
            out[base + L.PAIR_CLOSEST_TIME] = t_e
        if act:
            if not was_active[j]:
                out[base + L.PAIR_IMPACTS] += 1.0
            out[base + L.PAIR_CONTACT_TIME] += hs
            if p > out[base + L.PAIR_MAX_PENETRATION]:
                out[base + L.PAIR_MAX_PENETRATION] = p
            if f > out[base + L.PAIR_PEAK_FORCE]:
                out[base + L.PAIR_PEAK_FORCE] = f
                out[base + L.PAIR_PEAK_FORCE_TIME] = t_e
            if f < out[base + L.PAIR_MIN_FORCE]:
                out[base + L.PAIR_MIN_FORCE] = f
        comp = act and f > 0.0
        if comp:
            out[base + L.PAIR_COMPRESSION_TIME] += hs
            comp_acc[j] = comp_acc[j] + hs if in_comp[j] else hs
        elif in_comp[j]:
            end_phase(durations, nphase, j, comp_acc[j])
        in_comp[j] = comp
        was_active[j] = act


@njit_inner
def median_inplace(x, k):
    """Median of x[:k] (the mean of the two middle values for even k, as np.median: the same value, bit for
    bit), sorting x[:k] in place (heapsort: no allocation, and far less to compile than np.median's
    quickselect, which cost a first run 1.6 s); 0.0 when k = 0. The phases' median, in every kernel."""
    if k == 0:
        return 0.0
    for start in range(k // 2 - 1, -1, -1):  # heapify, then pop the largest to the end
        _sift_down(x, start, k)
    for end in range(k - 1, 0, -1):
        y = x[0]
        x[0] = x[end]
        x[end] = y
        _sift_down(x, np.int64(0), end)
    if k % 2 == 1:
        return x[k // 2]
    return (x[k // 2 - 1] + x[k // 2]) / 2.0


@njit_inner
def _sift_down(x, i, n):
    """Move x[i] down the max-heap x[:n] to its place."""
    while True:
        c = 2 * i + 1
        if c >= n:
            return
        if c + 1 < n and x[c + 1] > x[c]:
            c += 1
        if x[c] <= x[i]:
            return
        y = x[c]
        x[c] = x[i]
        x[i] = y
        i = c


@njit_inner
def close_row(out, pbase, npair, phases, status):
    """Close the phases still open at the run's end; per pair the phase count and median duration.
    Returns the status with STATUS_MEDIAN_TRUNCATED where the buffer overflowed."""
    in_comp, comp_acc, durations, nphase = phases
    for j in range(npair):
        if in_comp[j]:
            end_phase(durations, nphase, j, comp_acc[j])
        base = pbase + L.PER_PAIR * j
        k = nphase[j]
        out[base + L.PAIR_COMPRESSION_PHASES] = k
        if k > L.MEDIAN_BUFFER:
            status |= L.STATUS_MEDIAN_TRUNCATED
            k = L.MEDIAN_BUFFER
        out[base + L.PAIR_MEDIAN_COMPRESSION] = median_inplace(durations[j], k)
    return status


@njit_piece_once
def score_run(scores, run, xs, experiment, k_filled, status):
    """Score the run's samples against every experiment channel (engine/score.py), the acceleration
    channels after the experiment's low-pass filter (experiment.sos, as the experiment's samples were
    filtered); a run that stopped before the experiment's window ended is unscored (NaN,
    STATUS_UNSCORED). Returns the status."""
    exp_t, exp_x = experiment.t, experiment.x
    for c in range(exp_x.shape[0]):
        if k_filled < exp_t.size:
            status |= L.STATUS_UNSCORED
            for q in range(N_SCORES):
                scores[run, c, q] = np.nan
        else:
            if experiment.kind[c] == codes.H_ABS_ACC and experiment.sos.shape[0] > 0:
                _sos_filter(experiment.sos, xs[c])
            _score_channel(xs[c], exp_x[c], exp_t, experiment.max_lag, experiment.dt_sample, scores[run, c])
    return status


def score_run_signature(score) -> tuple:
    """The argument types the scalar kernels call score_run with for this experiment (engine/scalar.py,
    engine/nonlinear.py: out.scores, the run's index, the run's samples xs = np.empty((channels, samples)),
    the experiment, k_filled and the status), so a second process can compile it for them (engine/aside.py;
    tests/engine/test_aside.py checks that the kernels find it)."""
    from numba import typeof, types

    return (
        typeof(np.empty((0, 0, N_SCORES))),
        types.int64,
        typeof(np.empty((0, 0))),
        typeof(score),
        types.int64,
        types.int64,
    )


def empty_phases() -> tuple:
    """An empty phases tuple of the kernels' types (in_comp, comp_acc, durations, nphase: bool, float64, 2-d float64,
    int64 arrays), for the signatures a second process compiles pieces with (engine/aside.py)."""
    return (np.empty(0, dtype=np.bool_), np.empty(0), np.empty((0, 0)), np.empty(0, dtype=np.int64))


def pair_pieces_signature() -> tuple:
    """The argument types both scalar kernels' event steps call pair_pieces with (through their _accept): the run's
    metric row, its int64 offset, pen_prev and F, the contact set and the last piece's (bool), the piece's length
    and end time, the phases tuple; a second process compiles it with them (scalar.event_pieces,
    nonlinear.event_pieces)."""
    from numba import typeof, types

    f1, b1 = typeof(np.empty(0)), typeof(np.empty(0, dtype=np.bool_))
    return (f1, types.int64, f1, f1, b1, b1, types.float64, types.float64, typeof(empty_phases()))


def row_end_pieces() -> tuple:
    """The run's end book-keeping both scalar kernels call with the same types (close_row, energy_row, run_counts),
    which a second process can compile for them (engine/aside.py): about 0.5 s of a first compile. The argument
    types: the run's metric row (out.metrics[run]), int64 offsets, counts and status, the phases tuple
    (bool, float64, 2-d float64 and int64 arrays), the model's m and K, the end state's u and v, the six energies
    (tests/engine/test_aside.py checks that the kernels find them)."""
    from numba import typeof, types

    f1, f2 = typeof(np.empty(0)), typeof(np.empty((0, 0)))
    phases = typeof(empty_phases())
    i64 = types.int64
    return (
        (close_row, (f1, i64, i64, phases, i64)),
        (energy_row, (f1, i64, f1, f2, f1, f1, types.UniTuple(types.float64, 6), i64)),
        (run_counts, (f1, i64, i64, i64, i64, i64)),
    )


def score_pieces(score) -> tuple:
    """What a scalar kernel's compile can leave to a second process (engine/aside.py): score_run, when it scores."""
    return ((score_run, score_run_signature(score)),) if score is not None and score.active else ()


@njit_inner
def energy_row(out, rbase, m, K, u, v, energies, status):
    """The energy balance E_in = KE + SE + D_struct + D_contact + E_spring + residual at the run's end
    (kinetic and strain energy from the end state; energies = (E_in, the input work's absolute sum,
    D_struct, D_contact, E_spring, residual)); STATUS_ENERGY when |residual| > ENERGY_TOL of the input
    work. Returns the status."""
    e_in, e_in_abs, d_struct, d_contact, e_spring, residual = energies
    n = u.shape[0]
    ke_end = 0.0
    se_end = 0.0
    for i in range(n):
        ke_end += 0.5 * m[i] * v[i] * v[i]
        s = 0.0
        for k in range(n):
            s += K[i, k] * u[k]
        se_end += 0.5 * u[i] * s
    out[rbase + L.RUN_E_IN] = e_in
    out[rbase + L.RUN_E_IN_ABS] = e_in_abs
    out[rbase + L.RUN_KE] = ke_end
    out[rbase + L.RUN_SE] = se_end
    out[rbase + L.RUN_D_STRUCT] = d_struct
    out[rbase + L.RUN_D_CONTACT] = d_contact
    out[rbase + L.RUN_E_SPRING] = e_spring
    out[rbase + L.RUN_E_RESIDUAL] = residual
    if not (abs(residual) <= L.ENERGY_TOL * e_in_abs):
        status |= L.STATUS_ENERGY
    return status


@njit_inner
def run_counts(out, rbase, unsettled, max_it, steps, status):
    """The run's solver counts and status at the end of its row."""
    if unsettled > 0:
        status |= L.STATUS_UNSETTLED
    out[rbase + L.RUN_UNSETTLED] = unsettled
    out[rbase + L.RUN_MAX_ITER] = max_it
    out[rbase + L.RUN_STEPS] = steps
    out[rbase + L.RUN_STATUS] = status
