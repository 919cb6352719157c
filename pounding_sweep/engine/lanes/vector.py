"""The lane kernel's vector steps: a group's LANES runs advanced side by side, VW lanes per SIMD value
(engine/simd.py), in modal coordinates, for the steps that need no scalar code.

Per step, for a group (chunks of VW lanes):
- quiet (no lane in contact at the step start, _quiet): modes, floors, energy increments, per-floor
  peaks. A floor peak is written only in the rare steps where it grows in some lane (no store otherwise);
- contact (some lane in contact, _contact): the free step, the contact forces of each lane's set, the end
  state, the per-pair contact metrics and energies;
- events: a lane whose end state contradicts its contact set (by the event scheme's test,
  events.switch_tolerance; under the implicit scheme, the active set the end state asks for differs)
  keeps its start state (q, r are double-buffered; other rows are written only for the other lanes)
  and is marked for its scalar step (engine/lanes/lane_step.py). A quiet chunk first tests only "some
  pair penetrates" and recomputes with the exact test when one does.
Each loop returns at the first step with an event, a divergence or (contact) the end of a compressive
phase; the group driver (engine/lanes/groups.py) then does the scalar work and calls again.
"""

from __future__ import annotations

from llvmlite import ir
from numba import types
from numba.extending import intrinsic

from pounding_sweep.codes import LAW_NO_TENSION, SCHEME_EVENT
from pounding_sweep.engine import layout as ML
from pounding_sweep.engine.jit import inline, njit_step
from pounding_sweep.engine.lanes.rows import (
    C_CQ,
    C_CR,
    C_DH,
    C_EK,
    C_GAM,
    C_NCF,
    C_NDA,
    C_NW2,
    LANES,
    S_AGE,
    S_AGS,
    S_BAD,
    S_COEF,
    S_DST,
    S_EABS,
    S_EIN,
    S_EVT,
    S_GAP,
    S_KS,
    S_WDA,
    S_WSP,
    row_offsets,
    scratch_entries,
    table_offsets,
)
from pounding_sweep.engine.simd import (
    VW,
    elem_ptr,
    f64v,
    fence,
    many,
    mconst,
    mcount,
    mfloat,
    scratch,
    select_bits,
    sget,
    splat,
    sset,
    vfma,
    vsel,
    vsplat,
)


def _vec_ptr(context, builder, sig, args):
    """Pointer to W[r * LANES + c] (args W, r, c) as a vector pointer."""
    idx = builder.mul(context.cast(builder, args[1], sig.args[1], types.int64), ir.Constant(ir.IntType(64), LANES))
    idx = builder.add(idx, context.cast(builder, args[2], sig.args[2], types.int64))
    return elem_ptr(context, builder, sig.args[0], args[0], idx)


@intrinsic
def _row(typingctx, W, r, c):
    """W[r * LANES + c : ... + VW] as a vector (row r, lanes c..c+VW-1)."""

    def codegen(context, builder, sig, args):
        return builder.load(_vec_ptr(context, builder, sig, args), align=8)

    return f64v(W, r, c), codegen


@intrinsic
def _put(typingctx, W, r, c, v):
    """Row r, lanes c..c+VW-1 := v."""

    def codegen(context, builder, sig, args):
        builder.store(args[3], _vec_ptr(context, builder, sig, args), align=8)
        return context.get_dummy_value()

    return types.none(W, r, c, v), codegen


@intrinsic
def _cv(typingctx, Cv, r):
    """Coefficient r of the table in every lane (one broadcast load: on AMD Zen 1 a full-width
    coefficient row would cost as many load slots as the data it multiplies)."""

    def codegen(context, builder, sig, args):
        a = context.make_array(sig.args[0])(context, builder, args[0])
        idx = context.cast(builder, args[1], sig.args[1], types.intp)
        return splat(builder, builder.load(builder.gep(a.data, [idx], inbounds=True)))

    return f64v(Cv, r), codegen


@intrinsic
def _keep(typingctx, W, r, c, cond, new):
    """Row r := new where cond, else unchanged (the old value through an arithmetic fence, so that
    LLVM does not turn the select and store into a masked store: microcoded and slow on AMD Zen)."""

    def codegen(context, builder, sig, args):
        ptr = _vec_ptr(context, builder, sig, args)
        old = fence(builder, builder.load(ptr, align=8))
        builder.store(select_bits(builder, args[3], args[4], old), ptr, align=8)
        return context.get_dummy_value()

    return types.none(W, r, c, cond, new), codegen


@inline
def _floors(T, N, N1, t_u, t_q, Cv, c_phi):
    """Floor values Phi x of the modal values x = T[t_q:t_q + N] into T[t_u:t_u + N]."""
    for i in range(N):
        lo = 0 if i < N1 else N1
        hi = N1 if i < N1 else N
        u = _cv(Cv, c_phi + i * N + lo) * sget(T, t_q + lo)
        for k in range(lo + 1, hi):
            u = vfma(_cv(Cv, c_phi + i * N + k), sget(T, t_q + k), u)
        sset(T, t_u + i, u)


@inline
def _floor_acc(T, i, N, N1, t_qa, Cv, c_phi):
    """Absolute acceleration of floor i: Phi applied to the modal accelerations T[t_qa:]."""
    lo = 0 if i < N1 else N1
    hi = N1 if i < N1 else N
    a = _cv(Cv, c_phi + i * N + lo) * sget(T, t_qa + lo)
    for k in range(lo + 1, hi):
        a = vfma(_cv(Cv, c_phi + i * N + k), sget(T, t_qa + k), a)
    return a


@inline
def _floor_peaks(W, c, T, N, N1, P, t_u, t_qa, r_met, Cv, c_phi, vt, gap, ok_mask, groups):
    """Per-floor peaks of |u| (and its time), (metric group accel) of |absolute acceleration|, (group drift)
    of |interstory drift| (the story below the floor), and (group closest) each pair's closest approach
    gap - (u1 - u2) (and its time). One test for all floors and pairs; rows are written only in the rare
    steps where some extreme grows in some lane of `ok_mask`. Returns the lanes that diverged (|u| >=
    DIVERGED_M or, with accel, |a| >= 1e300; a NaN never grows a peak and is caught by the energy rows, or without the
    energy group by _nonfinite, instead)."""
    pbase = r_met + ML.PER_DOF * N
    drifts = (groups & ML.GROUP_DRIFT) != 0
    closest = (groups & ML.GROUP_CLOSEST) != 0
    accel = (groups & ML.GROUP_ACCEL) != 0
    grow = mconst(False)
    for i in range(N):
        base = r_met + ML.PER_DOF * i
        u = sget(T, t_u + i)
        grow = grow | (abs(u) > _row(W, base + ML.DOF_PEAK_DISP, c))
        if drifts:
            drift = u if i == 0 or i == N1 else u - sget(T, t_u + i - 1)
            grow = grow | (abs(drift) > _row(W, base + ML.DOF_PEAK_DRIFT, c))
        if accel:
            grow = grow | (abs(_floor_acc(T, i, N, N1, t_qa, Cv, c_phi)) > _row(W, base + ML.DOF_PEAK_ABS_ACC, c))
    if closest:
        for j in range(P):
            near = gap - (sget(T, t_u + j) - sget(T, t_u + N1 + j))
            grow = grow | (near < _row(W, pbase + ML.PER_PAIR * j + ML.PAIR_CLOSEST, c))
    bad = mconst(False)
    if many(grow & ok_mask):
        for i in range(N):
            base = r_met + ML.PER_DOF * i
            u = sget(T, t_u + i)
            ad = abs(u)
            up = (ad > _row(W, base + ML.DOF_PEAK_DISP, c)) & ok_mask
            _keep(W, base + ML.DOF_PEAK_DISP, c, up, ad)
            _keep(W, base + ML.DOF_PEAK_DISP_TIME, c, up, vt)
            bad = bad | (up & (ad >= ML.DIVERGED_M))
            if drifts:
                dr = abs(u if i == 0 or i == N1 else u - sget(T, t_u + i - 1))
                up = (dr > _row(W, base + ML.DOF_PEAK_DRIFT, c)) & ok_mask
                _keep(W, base + ML.DOF_PEAK_DRIFT, c, up, dr)
            if accel:
                aa = abs(_floor_acc(T, i, N, N1, t_qa, Cv, c_phi))
                up = (aa > _row(W, base + ML.DOF_PEAK_ABS_ACC, c)) & ok_mask
                _keep(W, base + ML.DOF_PEAK_ABS_ACC, c, up, aa)
                bad = bad | (up & (aa >= 1e300))
        for j in range(P):
            if not closest:
                break
            base = pbase + ML.PER_PAIR * j
            near = gap - (sget(T, t_u + j) - sget(T, t_u + N1 + j))
            up = (near < _row(W, base + ML.PAIR_CLOSEST, c)) & ok_mask
            _keep(W, base + ML.PAIR_CLOSEST, c, up, near)
            _keep(W, base + ML.PAIR_CLOSEST_TIME, c, up, vt)
    return bad


@inline
def _nonfinite(T, N, N1, t_u, keep):
    """Without the energy group: the lanes of `keep` whose floors are not finite or beyond DIVERGED_M (each
    building's top floor: a NaN or inf in any of its modes reaches every floor through Phi)."""
    top1 = abs(sget(T, t_u + N1 - 1))
    top2 = abs(sget(T, t_u + N - 1))
    return keep & (~(top1 < ML.DIVERGED_M) | ~(top2 < ML.DIVERGED_M))


@inline
def _exact_events(W, c, T, N, N1, P, t_u, r_act, r_cd, dst, Cv, c_psv, law, scheme, ks, gap):
    """The lanes whose end state contradicts their contact set, by the scheme's own test (event:
    events.switch_tolerance, the no-tension indicator min(pen, pen + c/k_s v_rel); implicit: the set
    the end state asks for)."""
    evt = mconst(False)
    zero = vsplat(0.0)
    for j in range(P):
        up = sget(T, t_u + j)
        uq = sget(T, t_u + N1 + j)
        pe = (up - uq) - gap
        act = _row(W, r_act + j, c) > 0.5
        alt = pe
        if law == LAW_NO_TENSION:
            vr = zero
            for k in range(N):
                vr = vfma(_cv(Cv, c_psv + k * P + j), _row(W, dst + N + k, c), vr)
            alt = pe + (_row(W, r_cd + j, c) / ks) * vr
        if scheme == SCHEME_EVENT:
            if law == LAW_NO_TENSION:
                pe = vsel(pe > 0.0, vsel(alt < pe, alt, pe), pe)
            tol = 1e-15 + 1e-12 * (abs(up) + abs(uq))
            evt = evt | (act & (zero - tol > pe)) | (~act & (pe > tol))
        else:
            want = pe > 0.0
            if law == LAW_NO_TENSION:
                want = want & (alt > 0.0)  # k_s pen + c v_rel > 0, divided by k_s > 0
            evt = evt | (want != act)
    return evt


@inline
def _energy(W, c, r_s, s, pin, dsum, keep):
    """Input work (trapezoid), its absolute sum and structural damping; returns the lanes whose
    accumulators are no longer finite (a NaN or inf anywhere in the state reaches dsum)."""
    de = -0.5 * s * pin
    ein = _row(W, r_s + S_EIN, c) + de
    eab = _row(W, r_s + S_EABS, c) + abs(de)
    dst_ = _row(W, r_s + S_DST, c) + dsum
    _keep(W, r_s + S_EIN, c, keep, ein)
    _keep(W, r_s + S_EABS, c, keep, eab)
    _keep(W, r_s + S_DST, c, keep, dst_)
    return keep & (~(abs(dst_) < 1e300) | ~(abs(eab) < 1e300))


@inline
def _events_energy_peaks(W, c, T, dst, quiet, s, pin, dsum, vt, law, scheme, N, N1, P, Cv, lay, groups):
    """The end of a vector step, the floors of the new state in T: the lanes with an event (EVT row),
    then energy increments and per-floor peaks of the others. The exact event test runs only where a
    pair out of contact penetrates or one in contact does not: every event of either scheme under the
    classic law is one of these (under the no-tension law a pair in contact can also switch off while
    penetrating: with contact the exact test always runs). Returns (lanes without an event, events,
    divergences)."""
    r_q0, r_q1, r_g, r_f, r_pen, r_act, r_inc, r_cac, r_end, r_cd, r_R, r_s, r_met = lay
    c_phi, c_psi, c_psv = table_offsets(N, P)
    t_qa, t_u, t_dq, t_f, t_g, t_qf, t_rf = scratch_entries(N, P)
    gap = _row(W, r_s + S_GAP, c)
    maybe = mconst(law == LAW_NO_TENSION and not quiet)
    for j in range(P):
        pe = (sget(T, t_u + j) - sget(T, t_u + N1 + j)) - gap
        if quiet:
            maybe = maybe | (pe > 0.0)
        else:
            act = _row(W, r_act + j, c) > 0.5
            maybe = maybe | (act != (pe > 0.0))
    evt = mconst(False)
    nevt = 0
    if many(maybe):
        evt = _exact_events(
            W, c, T, N, N1, P, t_u, r_act, r_cd, dst, Cv, c_psv, law, scheme, _row(W, r_s + S_KS, c), gap
        )
        if many(evt):
            _put(W, r_s + S_EVT, c, mfloat(evt))
            nevt = mcount(evt)
    ok = ~evt
    if groups & ML.GROUP_ENERGY:
        bad = _energy(W, c, r_s, s, pin, dsum, ok)
    else:
        bad = _nonfinite(T, N, N1, t_u, ok)
    bad = bad | _floor_peaks(W, c, T, N, N1, P, t_u, t_qa, r_met, Cv, c_phi, vt, gap, ok, groups)
    nbad = 0
    if many(bad):
        _keep(W, r_s + S_BAD, c, bad, vsplat(1.0))
        nbad = mcount(bad)
    return ok, nevt, nbad


@inline
def _fill_ag(W, r_s, prof, pid_lane, step, uniform, pid0):
    """Ground acceleration rows: AGS at the step start, AGE at its end (coef * prof[pid, step])."""
    if uniform:
        p0 = prof[pid0, step - 1]
        p1 = prof[pid0, step]
        for c in range(0, LANES, VW):
            cf = _row(W, r_s + S_COEF, c)
            _put(W, r_s + S_AGS, c, cf * p0)
            _put(W, r_s + S_AGE, c, cf * p1)
    else:
        for l in range(LANES):
            cf = W[(r_s + S_COEF) * LANES + l]
            W[(r_s + S_AGS) * LANES + l] = cf * prof[pid_lane[l], step - 1]
            W[(r_s + S_AGE) * LANES + l] = cf * prof[pid_lane[l], step]


@inline
def _groups(mg):
    """The metric groups of mg = (LaneModel.gt, KernelOptions.groups): every group as a compile-time constant
    when gt is (0,) (its tests fold away), else the run-time mask."""
    gt, rt = mg
    return ML.GROUPS_ALL if len(gt) > 0 else rt


@njit_step
def _quiet(W, step0, step1, dt, scheme, law, nt, n1t, Cv, prof, pid_lane, uniform, pid0, mg):
    """Steps step0..step1 with no lane in contact at their start: the free step of every lane. Returns
    at the first step with an event or a divergence: (that step, lanes with an event, lanes diverged);
    event lanes are left for their scalar step (only their dst rows were written). mg = (LaneModel.gt,
    KernelOptions.groups): the metric groups (_groups)."""
    groups = _groups(mg)
    N = len(nt)
    N1 = len(n1t)
    P = min(N1, N - N1)
    lay = row_offsets(N, P)
    T = scratch()
    for step in range(step0, step1 + 1):
        src = lay[0] if (step - 1) % 2 == 0 else lay[1]
        dst = lay[1] if (step - 1) % 2 == 0 else lay[0]
        _fill_ag(W, lay[11], prof, pid_lane, step, uniform, pid0)
        nevt, nbad = _quiet_step(W, T, src, dst, step, dt, scheme, law, N, N1, P, Cv, lay, groups)
        if nevt > 0 or nbad > 0:
            return step, nevt, nbad
    return step1, 0, 0


@inline
def _quiet_step(W, T, src, dst, step, dt, scheme, law, N, N1, P, Cv, lay, groups):
    """One quiet step of every chunk of lanes: modes (Newmark, modal.py), floors, the cheap test
    "some pair penetrates" (then the exact event test), energy increments, peaks."""
    r_q0, r_q1, r_g, r_f, r_pen, r_act, r_inc, r_cac, r_end, r_cd, r_R, r_s, r_met = lay
    c_phi, c_psi, c_psv = table_offsets(N, P)
    t_qa, t_u, t_dq, t_f, t_g, t_qf, t_rf = scratch_entries(N, P)
    vt = vsplat(step * dt)
    nevt = 0
    nbad = 0
    for c in range(0, LANES, VW):
        s = _row(W, r_s + S_AGS, c) + _row(W, r_s + S_AGE, c)
        pin = vsplat(0.0)
        dsum = vsplat(0.0)
        for k in range(N):
            q = _row(W, src + k, c)
            r = _row(W, src + N + k, c)
            dq = vfma(_cv(Cv, C_CQ * N + k), q, vfma(_cv(Cv, C_CR * N + k), r, _cv(Cv, C_EK * N + k) * s))
            qn = q + dq
            rn = dq - r
            _put(W, dst + k, c, qn)
            _put(W, dst + N + k, c, rn)
            sset(T, t_dq + k, qn)
            pin = vfma(_cv(Cv, C_GAM * N + k), dq, pin)
            dsum = vfma(_cv(Cv, C_DH * N + k) * dq, dq, dsum)
            if groups & ML.GROUP_ACCEL:
                sset(T, t_qa + k, vfma(_cv(Cv, C_NDA * N + k), rn, _cv(Cv, C_NW2 * N + k) * qn))
        _floors(T, N, N1, t_u, t_dq, Cv, c_phi)
        ok, ne, nb = _events_energy_peaks(W, c, T, dst, True, s, pin, dsum, vt, law, scheme, N, N1, P, Cv, lay, groups)
        nevt += ne
        nbad += nb
    return nevt, nbad


@njit_step
def _contact(W, step0, step1, dt, scheme, law, nt, n1t, Cv, pon, prof, pid_lane, uniform, pid0, mg):
    """Steps step0..step1 with some lane in contact: the step with each lane's contact set (forces from
    its R), contact metrics and energies. Pairs in contact in no lane (bit j of pon clear) have zero
    force in every lane. Returns at the first step with an event, a divergence or the end of a
    compressive phase: (that step, lanes with an event, lanes diverged, lanes whose phase ended).
    Its loop is _quiet's: one function for both cost the quiet step 6-14 %."""
    groups = _groups(mg)
    N = len(nt)
    N1 = len(n1t)
    P = min(N1, N - N1)
    lay = row_offsets(N, P)
    T = scratch()
    for step in range(step0, step1 + 1):
        src = lay[0] if (step - 1) % 2 == 0 else lay[1]
        dst = lay[1] if (step - 1) % 2 == 0 else lay[0]
        _fill_ag(W, lay[11], prof, pid_lane, step, uniform, pid0)
        nevt, nbad, nend = _contact_step(W, T, src, dst, step, dt, scheme, law, N, N1, P, Cv, pon, lay, groups)
        if nevt > 0 or nbad > 0 or nend > 0:
            return step, nevt, nbad, nend
    return step1, 0, 0, 0


@inline
def _contact_step(W, T, src, dst, step, dt, scheme, law, N, N1, P, Cv, pon, lay, groups):
    """One step of every chunk of lanes, some lane in contact (the energy and phases groups' work only
    where `groups` asks for them)."""
    energy = (groups & ML.GROUP_ENERGY) != 0
    phases = (groups & ML.GROUP_PHASES) != 0
    r_q0, r_q1, r_g, r_f, r_pen, r_act, r_inc, r_cac, r_end, r_cd, r_R, r_s, r_met = lay
    c_phi, c_psi, c_psv = table_offsets(N, P)
    t_qa, t_u, t_dq, t_f, t_g, t_qf, t_rf = scratch_entries(N, P)
    vt = vsplat(step * dt)
    te = vsplat((step - 1) * dt + dt)
    vdt = vsplat(dt)
    zero = vsplat(0.0)
    half = vsplat(0.5)
    pbase = r_met + ML.PER_DOF * N
    nevt = 0
    nbad = 0
    nend = 0
    for c in range(0, LANES, VW):
        s = _row(W, r_s + S_AGS, c) + _row(W, r_s + S_AGE, c)
        ks = _row(W, r_s + S_KS, c)
        gap = _row(W, r_s + S_GAP, c)
        # the free step (start forces in the load): its end q, r and its increment, in the scratch
        for k in range(N):
            q = _row(W, src + k, c)
            r = _row(W, src + N + k, c)
            dq = vfma(
                _cv(Cv, C_CQ * N + k),
                q,
                vfma(
                    _cv(Cv, C_CR * N + k),
                    r,
                    vfma(_cv(Cv, C_EK * N + k), s, _cv(Cv, C_NCF * N + k) * _row(W, r_g + k, c)),
                ),
            )
            sset(T, t_qf + k, q + dq)
            sset(T, t_rf + k, dq - r)
            sset(T, t_dq + k, dq)
        # each lane's forces: F = R (k_s delta_free + c delta'_free), R zero outside its contact set
        for i in range(P):
            sset(T, t_f + i, zero)
        for j in range(P):
            if (pon >> j) & 1 == 0:
                continue
            d = zero
            v = zero
            for k in range(N):
                d = vfma(_cv(Cv, c_psi + k * P + j), sget(T, t_qf + k), d)
                v = vfma(_cv(Cv, c_psv + k * P + j), sget(T, t_rf + k), v)
            y = vfma(ks, d - gap, _row(W, r_cd + j, c) * v)
            for i in range(P):
                if (pon >> i) & 1:
                    sset(T, t_f + i, vfma(_row(W, r_R + i * P + j, c), y, sget(T, t_f + i)))
        # the end state: dq = dq_free - cf Psi F
        pin = zero
        dsum = zero
        for k in range(N):
            g = zero
            for j in range(P):
                if (pon >> j) & 1:
                    g = vfma(_cv(Cv, c_psi + k * P + j), sget(T, t_f + j), g)
            sset(T, t_g + k, g)
            corr = _cv(Cv, C_NCF * N + k) * g
            dq = sget(T, t_dq + k) + corr
            qn = sget(T, t_qf + k) + corr
            rn = sget(T, t_rf + k) + corr
            _put(W, dst + k, c, qn)
            _put(W, dst + N + k, c, rn)
            sset(T, t_dq + k, qn)
            pin = vfma(_cv(Cv, C_GAM * N + k), dq, pin)
            dsum = vfma(_cv(Cv, C_DH * N + k) * dq, dq, dsum)
            if groups & ML.GROUP_ACCEL:
                sset(T, t_qa + k, vfma(_cv(Cv, C_NDA * N + k), rn, _cv(Cv, C_NW2 * N + k) * qn) - g)
        _floors(T, N, N1, t_u, t_dq, Cv, c_phi)
        ok, ne, nb = _events_energy_peaks(W, c, T, dst, False, s, pin, dsum, vt, law, scheme, N, N1, P, Cv, lay, groups)
        nevt += ne
        nbad += nb
        # contact spring and dashpot work on each pair's penetration, contact metrics (kernel.py's order)
        wsp = _row(W, r_s + S_WSP, c)
        wda = _row(W, r_s + S_WDA, c)
        ended = mconst(False)
        for j in range(P):
            if (pon >> j) & 1 == 0:
                continue
            f = sget(T, t_f + j)
            pen = (sget(T, t_u + j) - sget(T, t_u + N1 + j)) - gap
            act = _row(W, r_act + j, c) > 0.5
            if energy:
                pen0 = _row(W, r_pen + j, c)
                sp0 = vsel(act, ks * pen0, zero)
                dp0 = vsel(act, _row(W, r_f + j, c) - sp0, zero)
                sp = vsel(act, ks * pen, zero)
                dp = vsel(act, f - sp, zero)
                dpen = pen - pen0
                wsp = vsel(ok, wsp + half * (sp0 + sp) * dpen, wsp)
                wda = vsel(ok, wda + half * (dp0 + dp) * dpen, wda)
            _keep(W, r_pen + j, c, ok, pen)
            _keep(W, r_f + j, c, ok, f)
            base = pbase + ML.PER_PAIR * j
            ak = act & ok
            x = _row(W, base + ML.PAIR_CONTACT_TIME, c)
            _keep(W, base + ML.PAIR_CONTACT_TIME, c, ak, x + vdt)
            # extremes: written only in the steps where some lane improves them
            up = ak & (pen > _row(W, base + ML.PAIR_MAX_PENETRATION, c))
            if many(up):
                _keep(W, base + ML.PAIR_MAX_PENETRATION, c, up, pen)
            up = ak & (f > _row(W, base + ML.PAIR_PEAK_FORCE, c))
            if many(up):
                _keep(W, base + ML.PAIR_PEAK_FORCE, c, up, f)
                _keep(W, base + ML.PAIR_PEAK_FORCE_TIME, c, up, te)
            up = ak & (f < _row(W, base + ML.PAIR_MIN_FORCE, c))
            if many(up):
                _keep(W, base + ML.PAIR_MIN_FORCE, c, up, f)
            if phases:
                comp = ak & (f > 0.0)
                x = _row(W, base + ML.PAIR_COMPRESSION_TIME, c)
                _keep(W, base + ML.PAIR_COMPRESSION_TIME, c, comp, x + vdt)
                inc = _row(W, r_inc + j, c) > 0.5
                x = _row(W, r_cac + j, c)
                _keep(W, r_cac + j, c, comp, vsel(inc, x + vdt, vdt))
                end = inc & ~comp & ok
                if many(end):
                    _put(W, r_end + j, c, mfloat(end))
                    ended = ended | end
                _keep(W, r_inc + j, c, ok, mfloat(comp))
        if energy:
            _put(W, r_s + S_WSP, c, wsp)
            _put(W, r_s + S_WDA, c, wda)
        nend += mcount(ended)
        for k in range(N):
            _keep(W, r_g + k, c, ok, sget(T, t_g + k))
    return nevt, nbad, nend
