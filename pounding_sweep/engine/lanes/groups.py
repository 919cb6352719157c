"""The lane kernel's group driver: LANES runs of a chunk at a time, the vector loops (engine/lanes/vector.py)
run until a step needs scalar work, then that work: the scalar steps of the lanes with an event
(engine/lanes/lane_step.py), compressive phases that ended, lanes that diverged (handed back: the driver
reruns them on the scalar kernel), lanes that reached their last step (their metric row written).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from pounding_sweep.codes import EXC_HARMONIC, SCHEME_EVENT
from pounding_sweep.engine import layout as ML
from pounding_sweep.engine.bookkeeping import median_inplace
from pounding_sweep.engine.clock import _monotonic_ns
from pounding_sweep.engine.inputs import LaneWork, RunArrays
from pounding_sweep.engine.jit import inline, njit_lanes, njit_step
from pounding_sweep.engine.lanes.lane_step import end_phase, lane_step
from pounding_sweep.engine.lanes.loops import call_contact, call_quiet, contact_loop, floor_loops, loop_signatures
from pounding_sweep.engine.lanes.model import lane_model
from pounding_sweep.engine.lanes.rows import (
    BR,
    LANES,
    S_BAD,
    S_COEF,
    S_DST,
    S_EABS,
    S_EIN,
    S_EVT,
    S_GAP,
    S_KS,
    S_MIT,
    S_UNS,
    S_WDA,
    S_WREL,
    S_WSP,
    ST_CALLS,
    ST_FIX_NS,
    ST_FIXUPS,
    ST_TIMED,
    ST_VSTEPS,
    Z_DMP,
    Z_GAM,
    Z_OM2,
    Z_PHI,
    ZR,
    row_offsets,
)


class Group(NamedTuple):
    """A group's state: the lane-major rows W and the lanes' book-keeping beside them."""

    W: np.ndarray  # (rows * LANES,) row r, lane l at r * LANES + l (rows.row_offsets)
    run: np.ndarray  # (LANES,) each lane's run
    nst: np.ndarray  # (LANES,) its steps
    status: np.ndarray  # (LANES,) its status bits known before the run
    pid: np.ndarray  # (LANES,) its excitation profile
    live: np.ndarray  # (LANES,) bool: integrating (not parked)
    stale: np.ndarray  # (LANES,) bool: a compressive phase open on a pair out of contact ...
    stale_at: np.ndarray  # (LANES,) ... since the end of this step
    act_pair: np.ndarray  # (P,) lanes in contact, per pair
    lane: LaneWork  # one lane's scalar step's arrays
    sizes: tuple  # (N, N1, P, rows)


def _aligned_zeros(n: int, align: int = 64) -> np.ndarray:
    """n float64 zeros starting at a multiple of `align` bytes (a vector of VW lanes is 32 or 64 bytes, inside
    one 64-byte cache line: NumPy's 16-byte alignment would split vector loads across two lines)."""
    buf = np.zeros(n + align // 8)
    start = (-buf.ctypes.data % align) // 8
    return buf[start : start + n]


def group_work(model, max_iter: int) -> Group:
    """The arrays integrate_lanes works in, for a model (engine/inputs.py LaneModel)."""
    n, n1 = model.n, model.n1
    p = min(n1, n - n1)
    rows = row_offsets.py_func(n, p)[12] + ML.PER_DOF * n + ML.PER_PAIR * p
    lane = LaneWork(
        np.zeros((ZR, max(n, p, 6))),
        np.zeros((BR, p), dtype=np.bool_),
        np.zeros((2, max(p, max_iter + 1)), dtype=np.int64),
        np.zeros((p, 2 * p)),
        np.zeros(ML.PER_DOF * n + ML.PER_PAIR * p),
        np.empty((LANES, p, ML.MEDIAN_BUFFER)),
        np.zeros((LANES, p), dtype=np.int64),
    )
    ints = [np.zeros(LANES, dtype=np.int64) for _ in range(4)]
    flags = [np.zeros(LANES, dtype=np.bool_) for _ in range(2)]
    return Group(
        _aligned_zeros(rows * LANES),
        *ints,
        *flags,
        np.zeros(LANES, np.int64),
        np.zeros(p, np.int64),
        lane,
        (n, n1, p, rows),
    )


@njit_step
def _park(W, l, nrows, r_s):
    """Lane l at rest, out of contact, with no excitation, far from its neighbour: it computes zeros
    until the group ends and never has an event."""
    for z in range(nrows):
        W[z * LANES + l] = 0.0
    W[(r_s + S_GAP) * LANES + l] = 1.0
    W[(r_s + S_KS) * LANES + l] = 1.0


@njit_step
def _finalize_lane(gw, l, metrics, steps_done, dt, modal):
    """Write lane l's metric row (the scalar kernel's end-of-run code, scalar._batch_kernel) after its last step;
    modal = (om2, psi) (engine/inputs.py LaneModel)."""
    W, run, status = gw.W, gw.run[l], gw.status[l]
    dur, nph = gw.lane.dur, gw.lane.nph
    om2, psi = modal
    N, _n1, P, _rows = gw.sizes
    r_q0, r_q1, r_g, r_f, r_pen, r_act, r_inc, r_cac, r_end, r_cd, r_R, r_s, r_met = row_offsets(N, P)
    buf = r_q1 if steps_done % 2 == 1 else r_q0  # step s writes buffer q1 when s is odd
    nm = metrics.shape[1]
    pbase = ML.PER_DOF * N
    rbase = pbase + ML.PER_PAIR * P
    for z in range(rbase):
        metrics[run, z] = W[(r_met + z) * LANES + l]
    for z in range(rbase, nm):
        metrics[run, z] = 0.0
    for j in range(P):
        if W[(r_inc + j) * LANES + l] > 0.5:
            end_phase(dur, nph, l, j, W[(r_cac + j) * LANES + l])
        base = pbase + ML.PER_PAIR * j
        k = nph[l, j]
        metrics[run, base + ML.PAIR_COMPRESSION_PHASES] = k
        if k > ML.MEDIAN_BUFFER:
            status |= ML.STATUS_MEDIAN_TRUNCATED
            k = ML.MEDIAN_BUFFER
        metrics[run, base + ML.PAIR_MEDIAN_COMPRESSION] = median_inplace(dur[l, j], k)
    unsettled = W[(r_s + S_UNS) * LANES + l]
    if unsettled > 0:
        status |= ML.STATUS_UNSETTLED
    # kinetic and strain energy at the end: modes are mass-normalised (1/2 q'^2, 1/2 w^2 q^2)
    ke_end = 0.0
    se_end = 0.0
    for k in range(N):
        qk = W[(buf + k) * LANES + l]
        vk = (2.0 / dt) * W[(buf + N + k) * LANES + l]
        ke_end += 0.5 * vk * vk
        se_end += 0.5 * om2[k] * qk * qk
    ks = W[(r_s + S_KS) * LANES + l]
    gap = W[(r_s + S_GAP) * LANES + l]
    e_spring = 0.0
    for j in range(P):
        if W[(r_act + j) * LANES + l] > 0.5:
            pp = -gap
            for k in range(N):
                pp += psi[k, j] * W[(buf + k) * LANES + l]
            e_spring += 0.5 * ks * pp * pp
    w_release = W[(r_s + S_WREL) * LANES + l]
    residual = W[(r_s + S_WSP) * LANES + l] - e_spring - w_release
    e_in_abs = W[(r_s + S_EABS) * LANES + l]
    metrics[run, rbase + ML.RUN_E_IN] = W[(r_s + S_EIN) * LANES + l]
    metrics[run, rbase + ML.RUN_E_IN_ABS] = e_in_abs
    metrics[run, rbase + ML.RUN_KE] = ke_end
    metrics[run, rbase + ML.RUN_SE] = se_end
    metrics[run, rbase + ML.RUN_D_STRUCT] = W[(r_s + S_DST) * LANES + l]
    metrics[run, rbase + ML.RUN_D_CONTACT] = W[(r_s + S_WDA) * LANES + l] + w_release
    metrics[run, rbase + ML.RUN_E_SPRING] = e_spring
    metrics[run, rbase + ML.RUN_E_RESIDUAL] = residual
    if not (abs(residual) <= ML.ENERGY_TOL * e_in_abs):
        status |= ML.STATUS_ENERGY
    metrics[run, rbase + ML.RUN_UNSETTLED] = unsettled
    metrics[run, rbase + ML.RUN_MAX_ITER] = W[(r_s + S_MIT) * LANES + l]
    metrics[run, rbase + ML.RUN_STEPS] = steps_done
    metrics[run, rbase + ML.RUN_STATUS] = status


@njit_step
def _count_act(W, l, act_pair, sizes, sign):
    """Add (sign 1) or remove (-1) lane l's contact set from the per-pair counts act_pair; returns the change
    of the total. sizes = (N, N1, P, rows): Group.sizes."""
    N, _n1, P, _rows = sizes
    r_act = row_offsets(N, P)[5]
    n = 0
    for j in range(P):
        if W[(r_act + j) * LANES + l] > 0.5:
            act_pair[j] += sign
            n += sign
    return n


@njit_step
def _start_group(gw, lanes, model, opts, runs, excitation):
    """Load the runs lanes = order[base:base + nl] into the group's lanes, park the others; returns
    (max steps, whether every lane shares the first one's excitation profile, that profile)."""
    W = gw.W
    N, _n1, P, nrows = gw.sizes
    r_q0, r_q1, r_g, r_f, r_pen, r_act, r_inc, r_cac, r_end, r_cd, r_R, r_s, r_met = row_offsets(N, P)
    pid = excitation.pid
    nl = lanes.size
    max_nst = 0
    uniform = nl > 0  # computed, not the literal True: a literal argument compiles its callee twice
    pid0 = pid[lanes[0]] if nl > 0 else 0
    for l in range(LANES):
        _park(W, l, nrows, r_s)
        gw.live[l] = False
        for j in range(P):
            gw.lane.nph[l, j] = 0
        if l >= nl:
            continue
        run = lanes[l]
        gw.run[l] = run
        gw.nst[l] = runs.nsteps[run]
        gw.status[l] = runs.status_in[run]
        gw.live[l] = True
        gw.pid[l] = pid[run]
        if pid[run] != pid0:
            uniform = False
        max_nst = max(max_nst, runs.nsteps[run])
        W[(r_s + S_KS) * LANES + l] = runs.ks[run]
        W[(r_s + S_GAP) * LANES + l] = runs.gap[run]
        W[(r_s + S_COEF) * LANES + l] = excitation.coef[run]
        for j in range(P):
            W[(r_cd + j) * LANES + l] = runs.cdash[run, j]
            W[(r_pen + j) * LANES + l] = -runs.gap[run]
            W[(r_met + ML.PER_DOF * N + ML.PER_PAIR * j + ML.PAIR_CLOSEST) * LANES + l] = runs.gap[run]
        W[(r_s + S_MIT) * LANES + l] = 1.0 if (runs.nsteps[run] >= 1 and opts.scheme != SCHEME_EVENT) else 0.0
    for j in range(P):
        gw.act_pair[j] = 0
    for l in range(LANES):
        gw.stale[l] = False
    return max_nst, uniform, pid0


@inline
def _stale_phases(gw, step):
    """A compressive phase left open by a switch-off at a step's very end (see _scalar_steps) closes in
    the lane's next step, as in the scalar kernel: here, if that step was a vector step; if it is
    this step's scalar step, lane_step closes it as the scalar kernel does."""
    W = gw.W
    N, _n1, P, _rows = gw.sizes
    r_q0, r_q1, r_g, r_f, r_pen, r_act, r_inc, r_cac, r_end, r_cd, r_R, r_s, r_met = row_offsets(N, P)
    for l in range(LANES):
        if gw.stale[l]:
            gw.stale[l] = False
            if step > gw.stale_at[l] + 1 or W[(r_s + S_EVT) * LANES + l] < 0.5:
                for j in range(P):
                    if W[(r_inc + j) * LANES + l] > 0.5 and W[(r_act + j) * LANES + l] < 0.5:
                        if gw.live[l]:
                            end_phase(gw.lane.dur, gw.lane.nph, l, j, W[(r_cac + j) * LANES + l])
                        W[(r_inc + j) * LANES + l] = 0.0


@inline
def _scalar_steps(gw, bufs, model, opts, runs, stats):
    """The step bufs = (src, dst, step) of every lane the vector loop marked (an event) in scalar code
    (lane_step). Returns (change of the lanes in contact, lanes diverged, a phase left open)."""
    W = gw.W
    N, N1, P, _rows = gw.sizes
    r_q0, r_q1, r_g, r_f, r_pen, r_act, r_inc, r_cac, r_end, r_cd, r_R, r_s, r_met = row_offsets(N, P)
    d_act = 0
    nbad = 0
    any_stale = False
    for l in range(LANES):
        if W[(r_s + S_EVT) * LANES + l] > 0.5:
            W[(r_s + S_EVT) * LANES + l] = 0.0
            if not gw.live[l]:
                continue
            run = gw.run[l]
            d_act += _count_act(gw.W, l, gw.act_pair, gw.sizes, np.int64(-1))
            timed = stats[ST_TIMED] > 0
            t0_ = _monotonic_ns() if timed else 0
            ctx = (
                model.dt,
                opts.scheme,
                runs.law[run],
                opts.max_iter,
                runs.exc_kind[run] == EXC_HARMONIC,
                runs.exc_amp[run],
                runs.exc_omega[run],
                N,
                N1,
                P,
            )
            ok = lane_step(W, l, bufs, run, ctx, (model.phi, model.psi, model.W), runs.cdash, gw.lane)
            if timed:
                stats[ST_FIX_NS] += _monotonic_ns() - t0_
            stats[ST_FIXUPS] += 1
            d_act += _count_act(gw.W, l, gw.act_pair, gw.sizes, np.int64(1))
            if not ok:
                nbad += 1
            for j in range(P):  # a phase still open on a pair that switched off at the step end
                if W[(r_inc + j) * LANES + l] > 0.5 and W[(r_act + j) * LANES + l] < 0.5:
                    gw.stale[l] = True
                    gw.stale_at[l] = bufs[2]
                    any_stale = True
    return d_act, nbad, any_stale


@inline
def _ended_phases(gw):
    """The compressive phases the contact loop saw end (END rows), closed."""
    W = gw.W
    N, _n1, P, _rows = gw.sizes
    r_q0, r_q1, r_g, r_f, r_pen, r_act, r_inc, r_cac, r_end, r_cd, r_R, r_s, r_met = row_offsets(N, P)
    for l in range(LANES):
        for j in range(P):
            if W[(r_end + j) * LANES + l] > 0.5:
                W[(r_end + j) * LANES + l] = 0.0
                if gw.live[l]:
                    end_phase(gw.lane.dur, gw.lane.nph, l, j, W[(r_cac + j) * LANES + l])


@inline
def _drop_diverged(gw, redo):
    """Lanes that diverged: handed back (redo) and parked. Returns the change of the lanes in contact."""
    N, _n1, P, nrows = gw.sizes
    r_s = row_offsets(N, P)[11]
    d_act = 0
    for l in range(LANES):
        if gw.W[(r_s + S_BAD) * LANES + l] > 0.5:
            if gw.live[l]:
                redo[gw.run[l]] = 1
                d_act += _count_act(gw.W, l, gw.act_pair, gw.sizes, np.int64(-1))
                gw.live[l] = False
            _park(gw.W, l, nrows, r_s)
    return d_act


@inline
def _finish_lanes(gw, step, metrics, model, max_nst):
    """The lanes whose last step this was: their rows written, parked. Returns (the next lane end, the
    change of the lanes in contact)."""
    N, _n1, P, nrows = gw.sizes
    r_s = row_offsets(N, P)[11]
    next_end = max_nst + 1
    d_act = 0
    for l in range(LANES):
        if gw.live[l] and gw.nst[l] == step:
            _finalize_lane(gw, l, metrics, step, model.dt, (model.om2, model.psi))
            d_act += _count_act(gw.W, l, gw.act_pair, gw.sizes, np.int64(-1))
            _park(gw.W, l, nrows, r_s)
            gw.live[l] = False
        elif gw.live[l] and gw.nst[l] < next_end:
            next_end = gw.nst[l]
    return next_end, d_act


@njit_lanes
def _integrate_groups(order, groups, model, opts, runs, excitation, out, gw, loops):
    """integrate_lanes' loop over groups (g_start, g_stop) and steps; loops: the addresses of the vector loops
    for the model's floor counts (loops.floor_loops), so that no type here holds a floor count."""
    N, N1, P, nrows = gw.sizes
    r_q0, r_q1, r_g, r_f, r_pen, r_act, r_inc, r_cac, r_end, r_cd, r_R, r_s, r_met = row_offsets(N, P)
    W, stats, Z = gw.W, out.stats, gw.lane.Z
    for k in range(N):
        Z[Z_OM2, k] = model.om2[k]
        Z[Z_DMP, k] = model.dmp[k]
        Z[Z_GAM, k] = model.gam[k]
        Z[Z_PHI, k] = 0.0
        for i in range(N):
            Z[Z_PHI, k] = max(Z[Z_PHI, k], abs(model.phi[i, k]))
    for g in range(groups[0], groups[1]):
        base = g * LANES
        nl = min(LANES, order.size - base)
        lanes = order[base : base + nl]
        # the group's law: the runs of one call share it (run_chunk_lanes)
        law = runs.law[lanes[0]]
        max_nst, uniform, pid0 = _start_group(gw, lanes, model, opts, runs, excitation)
        dt, scheme, Cv, prof, pid = (
            model.dt,
            opts.scheme,
            model.Cv,
            excitation.prof,
            gw.pid,
        )
        for l in range(nl):
            if gw.nst[l] == 0:
                _finalize_lane(gw, l, out.metrics, np.int64(0), model.dt, (model.om2, model.psi))
                _park(W, l, nrows, r_s)
                gw.live[l] = False
        next_end = max_nst + 1
        for l in range(nl):
            if gw.live[l] and gw.nst[l] < next_end:
                next_end = gw.nst[l]
        n_act = 0
        any_stale = False
        step = 0
        while step < max_nst:
            # the vector code runs until a step that needs the scalar side (or a lane's last step)
            step_before = step
            last = next_end if next_end <= max_nst else max_nst
            if n_act == 0:
                step, nevt, nbad = call_quiet(
                    loops[0], W, step + 1, last, dt, scheme, law, Cv, prof, pid, uniform, pid0, (model.gt, opts.groups)
                )
                nend = 0
            else:
                pon = gw.act_pair[0] * 0  # int64, not a literal (see uniform)
                for j in range(P):
                    if gw.act_pair[j] > 0:
                        pon |= 1 << j
                step, nevt, nbad, nend = call_contact(
                    loops[1],
                    W,
                    step + 1,
                    last,
                    dt,
                    scheme,
                    law,
                    Cv,
                    pon,
                    prof,
                    pid,
                    uniform,
                    pid0,
                    (model.gt, opts.groups),
                )
            stats[ST_CALLS] += 1
            stats[ST_VSTEPS] += step - step_before
            src = r_q0 if (step - 1) % 2 == 0 else r_q1
            dst = r_q1 if (step - 1) % 2 == 0 else r_q0
            if any_stale:
                any_stale = False
                _stale_phases(gw, step)
            if nevt > 0:
                d_act, n_bad, any_stale = _scalar_steps(gw, (src, dst, step), model, opts, runs, stats)
                n_act += d_act
                nbad += n_bad
            if nend > 0:
                _ended_phases(gw)
            if nbad > 0:
                n_act += _drop_diverged(gw, out.redo)
            if step == next_end:
                next_end, d_act = _finish_lanes(gw, step, out.metrics, model, max_nst)
                n_act += d_act


def integrate_lanes(order, g_start, g_stop, model, opts, runs, excitation, out, work=None):
    """Integrate groups g_start..g_stop-1 of `order` (run indices, LANES at a time: group g is
    order[g * LANES:(g + 1) * LANES]); fill out.metrics[run] (engine/layout.py), or set out.redo[run] = 1
    for a run that diverged (the driver reruns it with the scalar kernel, which decides where it stops
    and what its row holds); add the work counters (rows.ST_*) to out.stats. The runs share one contact
    law (runs.law: codes.LAW_CLASSIC or LAW_NO_TENSION).

    Records (engine/inputs.py): model LaneModel, opts KernelOptions, runs RunArrays, excitation LaneExcitation
    (ground acceleration coef[run] * prof[pid[run], step]), out LaneOutputs; work: group_work(model,
    opts.max_iter), made here when not given. The compiled loop allocates nothing, so it runs without
    Numba's reference counts (on the records' arrays they cost the scalar steps a fifth of their time)."""
    gw = work if work is not None else group_work(model, opts.max_iter)
    loops = floor_loops(model, opts, runs, gw, excitation.prof)
    _integrate_groups(order, (g_start, g_stop), model, opts, runs, excitation, out, gw, loops)


def step_pieces(sys, opts, law) -> tuple:
    """What a compile of the lane kernel for this system (model.coupled.SystemArrays), options and contact law
    can leave to a second process (engine/aside.py), in the order it takes them (the first not cached): the
    scalar step, lane_step (17 s of its 30 s compile), whose types do not depend on the floor counts; once that
    is cached, for a new pair of floor counts, that pair's contact loop (loops.py contact_loop_N_N1), which this
    process compiles after the quiet loop."""
    model = lane_model(sys, opts)
    runs = RunArrays.one_at_rest(sys.i1.size, law)
    gw = group_work(model, opts.max_iter)
    _quiet_sig, contact_sig = loop_signatures(model, opts, runs, gw)
    return (
        (lane_step, _lane_step_signature(model, opts, runs, gw)),
        (contact_loop(model.n, model.n1), contact_sig),
    )


def _lane_step_signature(model, opts, runs, gw) -> tuple:
    """The argument types _scalar_steps calls lane_step with for this model (LaneModel), options,
    runs (RunArrays) and work arrays (group_work): W, the lane, bufs = (src, dst, step), the run, ctx,
    modal, cdash and work. So a second process can compile it for them (engine/aside.py;
    tests/engine/test_aside.py checks that the kernel finds it)."""
    from numba import typeof, types

    N, N1, P, _rows = gw.sizes
    harmonic = runs.exc_kind[0] == EXC_HARMONIC
    ctx = (model.dt, opts.scheme, runs.law[0], opts.max_iter, harmonic, runs.exc_amp[0], runs.exc_omega[0], N, N1, P)
    i64 = types.int64
    modal = (model.phi, model.psi, model.W)
    return (
        typeof(gw.W),
        i64,
        types.UniTuple(i64, 3),
        i64,
        typeof(ctx),
        typeof(modal),
        typeof(runs.cdash),
        typeof(gw.lane),
    )
