"""Lane-parallel Numba kernel: LANES runs of a grid advanced side by side in SIMD lanes.

The arithmetic of every run is the scalar kernel's (kernel.integrate_batch, scheme "implicit" or "event"),
operation for operation; only the order in which runs are visited changes. The lane loops work on
explicit SIMD values (F64Vec: LLVM <VW x double>, below), whose operations are LLVM's plain IEEE
instructions lane by lane (no fast-math flags, no fused multiply-add), so every lane performs the
scalar kernel's sequence of roundings. The metric rows are therefore equal to the scalar
kernel's (tests/test_kernel_lanes.py asserts equality, not closeness), whichever lane, group,
batch or thread a run lands in.

What the vector code leaves out is only arithmetic whose operand is an exact zero: the off-block
entries of Keff^-1 and C (the two buildings are uncoupled without contact; the eligibility check
verifies these entries are exactly 0.0), the off-band entries of C (tridiagonal shear frames),
and H F when no lane of the group is in contact. Adding +-0.0 to a finite number does not change
it, so leaving it out changes no result.

Per step and group of LANES runs:

1. predict (vector): ag, Newmark effective load, u0 = Keff^-1 rhs0 for every lane; when a lane
   of the group is in contact, the contact forces of each lane's current active set (the scalar
   kernel's first active-set iteration; the elimination factors of the lane's active set are kept
   per lane, since they depend only on the set and the run's constants) and whether the end
   state agrees with that set. Without contact, only whether a pair penetrates.
2. settle (scalar, rare): a lane whose set does not agree (an impact starts or ends) redoes the
   scalar kernel's whole active-set iteration for this step, cycle fallback included.
3. finish (vector): u, v, a at the end of the step, divergence check, energy increments, metrics.
Scheme "event": a step in which no pair's end state contradicts the lane's contact set (by the event
scheme's own test, kernel._switch_tolerance and the no-tension indicator: _event_check) is the same
arithmetic as the implicit scheme's first solve with the unchanged set, so steps 1 and 3 compute it;
a lane whose end state contradicts its set is put back to the step start (a copy of its column of W)
and takes the step in scalar code (_event_lane: kernel._step_pieces locates, switches and integrates
the pieces between events). kernel._step_pieces is a jitted function of another file: a change to it
does not invalidate this module's on-disk cache (clear __pycache__/*.nbi after editing it);
tests/test_kernel_lanes.py would show the drift.

4. events (scalar, rare): compressive phases that end (their durations feed the median), runs
   that end (their metric row is written and the lane parked), runs that diverge (handed back to
   the driver, which reruns them with the scalar kernel).

Layout: every per-lane quantity is one row of LANES float64 in a single work array `W`; the floor
counts are compile-time constants (lengths of the tuples nt, n1t in the signature), so the row
offsets are too. Why explicit vectors rather than LLVM's loop vectoriser on scalar lane loops (the
first version): with 8 lanes the vectoriser did not vectorise at all (it unrolled the lane loop;
the issue's "lane counts under 16" pitfall, seen here too), with 16 it did, but on this Zen 3 it
turned every kept-or-updated metric into masked loads and stores (microcoded and slow on AMD) and
left whole loops scalar after innocuous edits; the kernel ran at 20-30 ns per lane-step. Explicit
vectors take no heuristic's permission.

No factory functions: the flags below are literal, so a change to them changes this file and
invalidates the on-disk cache (a flag passed into a factory would not: issue 9's pitfall).
"""

from __future__ import annotations

import operator

import numba
import numpy as np
from llvmlite import ir
from numba import types
from numba.core import cgutils
from numba.extending import intrinsic, models, overload, register_model

from . import kernel as _kernel
from . import metrics_layout as ML

#: runs per group, fixed at compile time: two SIMD values of VW = 8 lanes.
LANES = 16

#: strict IEEE (no fastmath: NaN checks and bit-for-bit agreement with the scalar kernel need it),
#: no GIL, cached on disk. Literal here on purpose (see the module docstring).
LANES_JIT = dict(nogil=True, cache=True, fastmath=False, error_model="numpy", boundscheck=False)


def njit_lanes(fn):
    """Decorate a lane kernel function with the flags above."""
    return numba.njit(**LANES_JIT)(fn)


# scheme / law / excitation codes, as in kernel.py (repeated, not imported, so that this module
# compiles without the scalar kernel; test_kernel_lanes checks they agree)
SCHEME_IMPLICIT = 0
SCHEME_EVENT = 2
LAW_NO_TENSION = 1
EXC_HARMONIC = 0
EXC_RECORD = 1

# ------------------------------------------------------------------------------------------ eligibility


def lanes_ineligible_reason(sys, hist, opts, score) -> str | None:
    """Why this chunk must run on the scalar kernel, or None when the lane kernel computes the same rows.

    The lane kernel computes metric rows only (no histories, no scoring against an experiment), for
    the implicit scheme (with at least one active-set iteration per step) and the event scheme (the
    paper's scheme and any other go to the scalar kernel), and for the coupled shear-frame structure it exploits:
    facing floor pairs j <-> n1 + j, Keff^-1 and C block-diagonal (exact zeros between the
    buildings) and C tridiagonal within each building.
    """
    if hist is not None and hist.active:
        return "histories requested"
    if score is not None and score.active:
        return "scoring against an experiment"
    if opts.scheme not in (SCHEME_IMPLICIT, SCHEME_EVENT):
        return "scheme is neither 'implicit' nor 'event'"
    if opts.law not in (0, LAW_NO_TENSION):
        return "unknown contact law"
    if opts.scheme == SCHEME_IMPLICIT and opts.max_iter < 1:
        return "max_contact_iterations < 1"
    n = sys.m.size
    p = sys.i1.size
    if p < 1 or n < 2:
        return "no contact pair"
    n1 = int(sys.i2[0]) if p else 0
    if not (np.array_equal(sys.i1, np.arange(p)) and np.array_equal(sys.i2, n1 + np.arange(p))):
        return "contact pairs are not floor j of building 1 facing floor j of building 2"
    if not (1 <= n1 < n and p == min(n1, n - n1)):
        return "pair count is not min(floors)"
    band = np.zeros((n, n), dtype=bool)
    block = np.zeros((n, n), dtype=bool)
    for lo, hi in ((0, n1), (n1, n)):
        block[lo:hi, lo:hi] = True
        for i in range(lo, hi):
            band[i, max(lo, i - 1):min(hi, i + 2)] = True
    if np.any(sys.Kinv[~block] != 0.0):
        return "Keff^-1 couples the buildings"
    if np.any(sys.C[~band] != 0.0):
        return "C is not tridiagonal per building"
    for name in ("m", "C", "K", "Kinv", "H", "S"):
        if not np.all(np.isfinite(getattr(sys, name))):
            return f"non-finite {name}"
    return None


def lanes_eligible(sys, hist, opts, score) -> bool:
    return lanes_ineligible_reason(sys, hist, opts, score) is None


# ------------------------------------------------------------------------------------------ excitation


@njit_lanes
def _sin_profile(omega, nsteps, dt, out):
    """out[step] = sin(omega * step * dt), the very expression kernel.ground_acceleration evaluates."""
    for step in range(nsteps + 1):
        out[step] = np.sin(omega * step * dt)


def excitation_profiles(runs, rec, dt):
    """Ground acceleration as coef[run] * prof[pid[run], step], equal to kernel.ground_acceleration.

    Harmonic: prof = sin(omega step dt) per distinct omega (computed by compiled code, as the kernel
    does), coef = -amp * omega * omega (left to right: NumPy's float64 products are the same IEEE
    operations). Record: prof = the resampled record (zero past its end), coef = the run's scale.
    Returns (coef, pid, prof).
    """
    rec_flat, rec_off, rec_len = rec
    n = runs.n
    nmax = int(runs.nsteps.max()) if n else 0
    harmonic = runs.exc_kind == EXC_HARMONIC
    coef = np.where(harmonic, -runs.exc_amp * runs.exc_omega * runs.exc_omega, runs.exc_amp)
    keys = [(EXC_HARMONIC, float(w)) if h else (EXC_RECORD, int(r))
            for h, w, r in zip(harmonic.tolist(), runs.exc_omega.tolist(), runs.rec_id.tolist())]
    index: dict = {}
    pid = np.array([index.setdefault(k, len(index)) for k in keys], dtype=np.int64)
    prof = np.zeros((max(1, len(index)), nmax + 1))
    for (kind, val), k in index.items():
        if kind == EXC_HARMONIC:
            _sin_profile(val, nmax, dt, prof[k])
        else:
            off, ln = int(rec_off[val]), int(rec_len[val])
            m = min(ln, nmax + 1)
            prof[k, :m] = rec_flat[off:off + m]
    return coef, pid, prof


def size_tuples(sys):
    """(nt, n1t): tuples whose lengths are the floor counts N and N1, fixed at compile time."""
    n1 = int(sys.i2[0])
    return (0,) * sys.m.size, (0,) * n1


# ------------------------------------------------------------------------------------------ SIMD values
# A float64 vector of VW lanes (LLVM <VW x double>) and a lane mask (<VW x i1>), with the arithmetic
# the kernel needs. Every operation is LLVM's plain IEEE instruction on each lane (no fast-math
# flags, no fused multiply-add), so a lane computes exactly what scalar code computes; writing the
# vectors out, instead of relying on LLVM's loop vectoriser, keeps the code vectorised whatever the
# vectoriser's heuristics decide (on this Zen 3 it turned selected stores into slow masked stores,
# or left whole loops scalar after innocuous edits). VW = 8: two AVX2 registers per vector (two
# independent instruction streams), one AVX-512 register.

VW = 8
_VT = ir.VectorType(ir.DoubleType(), VW)
_MT = ir.VectorType(ir.IntType(64), VW)  # all ones / all zeros per lane, as AVX compares give


class F64Vec(types.Type):
    def __init__(self):
        super().__init__(name=f"f64x{VW}")


class MaskVec(types.Type):
    def __init__(self):
        super().__init__(name=f"maskx{VW}")


f64v = F64Vec()
maskv = MaskVec()


@register_model(F64Vec)
class _F64VecModel(models.PrimitiveModel):
    def __init__(self, dmm, fe_type):
        super().__init__(dmm, fe_type, _VT)


@register_model(MaskVec)
class _MaskVecModel(models.PrimitiveModel):
    def __init__(self, dmm, fe_type):
        super().__init__(dmm, fe_type, _MT)


def _elem_ptr(context, builder, aryty, ary, idx):
    a = context.make_array(aryty)(context, builder, ary)
    return builder.bitcast(builder.gep(a.data, [idx], inbounds=True), _VT.as_pointer())


@intrinsic
def vload(typingctx, arr, idx):
    """arr[idx:idx + VW] as a vector (no bounds check)."""
    def codegen(context, builder, sig, args):
        return builder.load(_elem_ptr(context, builder, sig.args[0], args[0], args[1]), align=8)
    return f64v(arr, idx), codegen


@intrinsic
def vstore(typingctx, arr, idx, v):
    """arr[idx:idx + VW] = v (no bounds check)."""
    def codegen(context, builder, sig, args):
        builder.store(args[2], _elem_ptr(context, builder, sig.args[0], args[0], args[1]), align=8)
        return context.get_dummy_value()
    return types.none(arr, idx, v), codegen


@intrinsic
def vsplat(typingctx, x):
    """A vector with x in every lane."""
    def codegen(context, builder, sig, args):
        v = builder.insert_element(ir.Constant(_VT, ir.Undefined), args[0], ir.Constant(ir.IntType(32), 0))
        return builder.shuffle_vector(v, v, ir.Constant(ir.VectorType(ir.IntType(32), VW), [0] * VW))
    return f64v(types.float64), codegen


def _vv_intrinsic(build, restype):
    @intrinsic
    def fn(typingctx, a, b):
        def codegen(context, builder, sig, args):
            return build(builder, args[0], args[1])
        return restype(a, b), codegen
    return fn


_vadd = _vv_intrinsic(lambda b, x, y: b.fadd(x, y), f64v)
_vsub = _vv_intrinsic(lambda b, x, y: b.fsub(x, y), f64v)
_vmul = _vv_intrinsic(lambda b, x, y: b.fmul(x, y), f64v)
_vdiv = _vv_intrinsic(lambda b, x, y: b.fdiv(x, y), f64v)
_vgt = _vv_intrinsic(lambda b, x, y: b.sext(b.fcmp_ordered(">", x, y), _MT), maskv)
_vlt = _vv_intrinsic(lambda b, x, y: b.sext(b.fcmp_ordered("<", x, y), _MT), maskv)
_mand = _vv_intrinsic(lambda b, x, y: b.and_(x, y), maskv)
_mor = _vv_intrinsic(lambda b, x, y: b.or_(x, y), maskv)
_mne = _vv_intrinsic(lambda b, x, y: b.xor(x, y), maskv)


@intrinsic
def mnot(typingctx, m):
    def codegen(context, builder, sig, args):
        return builder.xor(args[0], ir.Constant(_MT, [-1] * VW))
    return maskv(m), codegen


@intrinsic
def mconst(typingctx, value):
    """Every lane true (value True) or false."""
    def codegen(context, builder, sig, args):
        return builder.select(args[0], ir.Constant(_MT, [-1] * VW), ir.Constant(_MT, [0] * VW))
    return maskv(types.boolean), codegen


def _truth(builder, m):
    return builder.icmp_signed("<", m, ir.Constant(_MT, [0] * VW))


@intrinsic
def vsel(typingctx, m, a, b):
    """a where m, else b (lane by lane)."""
    def codegen(context, builder, sig, args):
        return builder.select(_truth(builder, args[0]), args[1], args[2])
    return f64v(m, a, b), codegen


@intrinsic
def vabs(typingctx, a):
    def codegen(context, builder, sig, args):
        fn = cgutils.get_or_insert_function(builder.module, ir.FunctionType(_VT, [_VT]), f"llvm.fabs.v{VW}f64")
        return builder.call(fn, [args[0]])
    return f64v(a), codegen


@intrinsic
def mcount(typingctx, m):
    """Number of true lanes."""
    def codegen(context, builder, sig, args):
        it = ir.IntType(VW)
        fn = cgutils.get_or_insert_function(builder.module, ir.FunctionType(it, [it]), f"llvm.ctpop.i{VW}")
        return builder.zext(builder.call(fn, [builder.bitcast(_truth(builder, args[0]), it)]), ir.IntType(64))
    return types.int64(m), codegen


@intrinsic
def mfloat(typingctx, m):
    """1.0 where m, else 0.0."""
    def codegen(context, builder, sig, args):
        return builder.uitofp(_truth(builder, args[0]), _VT)
    return f64v(m), codegen


@intrinsic
def vfence(typingctx, a):
    """a, through llvm.arithmetic.fence: no code, but LLVM no longer sees where the value came from.
    Used on the kept operand of vkeep: given store(select(c, x, load p), p), LLVM would otherwise
    emit a masked store, which is microcoded and slow on AMD Zen."""
    def codegen(context, builder, sig, args):
        fn = cgutils.get_or_insert_function(builder.module, ir.FunctionType(_VT, [_VT]),
                                            f"llvm.arithmetic.fence.v{VW}f64")
        return builder.call(fn, [args[0]])
    return f64v(a), codegen


def _is_vec(t):
    return isinstance(t, F64Vec)


def _is_num(t):
    return isinstance(t, (types.Float, types.Integer))


def _overload_vector_op(op, fn):
    def typer(a, b):
        if _is_vec(a) and _is_vec(b):
            return lambda a, b: fn(a, b)
        if _is_num(a) and _is_vec(b):
            return lambda a, b: fn(vsplat(float(a)), b)
        if _is_vec(a) and _is_num(b):
            return lambda a, b: fn(a, vsplat(float(b)))
        return None
    overload(op, inline="always")(typer)


def _overload_mask_op(op, fn):
    def typer(a, b):
        if isinstance(a, MaskVec) and isinstance(b, MaskVec):
            return lambda a, b: fn(a, b)
        return None
    overload(op, inline="always")(typer)


for _op, _fn in ((operator.add, _vadd), (operator.sub, _vsub), (operator.mul, _vmul), (operator.truediv, _vdiv),
                 (operator.gt, _vgt), (operator.lt, _vlt)):
    _overload_vector_op(_op, _fn)
for _op, _fn in ((operator.and_, _mand), (operator.or_, _mor), (operator.ne, _mne)):
    _overload_mask_op(_op, _fn)


@overload(operator.invert, inline="always")
def _ov_invert(m):
    if isinstance(m, MaskVec):
        return lambda m: mnot(m)
    return None


@overload(abs, inline="always")
def _ov_abs(a):
    if _is_vec(a):
        return lambda a: vabs(a)
    return None


# ------------------------------------------------------------------------------------------ row layout

_inline = numba.njit(inline="always", **LANES_JIT)

# per-lane scalar rows, after r_s
(S_KS, S_D, S_KSD, S_COEF, S_AG, S_AGP, S_EIN, S_EINA, S_DST, S_WSP, S_WDA, S_WREL, S_UNS, S_MIT, S_EVT,
 S_BAD) = range(16)
N_SCALARS = 16


@_inline
def _layout(N, P):
    """Row offsets in W (compile-time constants once N and P are)."""
    r_u = 0
    r_v = r_u + N
    r_a = r_v + N
    r_w = r_a + N  # b1 u + v, then du (scratch)
    r_rh = r_w + N  # effective load, then the new u (scratch)
    r_u0 = r_rh + N  # end state without contact (scratch)
    r_f = r_u0 + N  # contact forces of the step
    r_act = r_f + P  # active set (1.0 / 0.0)
    r_was = r_act + P  # active set at the step start
    r_inc = r_was + P  # in a compressive phase
    r_cac = r_inc + P  # duration of the compressive phase in progress (a sum of dt, as kernel.py)
    r_end = r_cac + P  # a compressive phase ended in this step (event)
    r_sp = r_end + P  # spring and dashpot parts of F at the step start (energy)
    r_dp = r_sp + P
    r_ke = r_dp + P  # k_s + 2 c_j / dt
    r_cd = r_ke + P  # dashpot c_j
    r_z0 = r_cd + P  # g_j . u0 (scratch)
    r_bb = r_z0 + P  # k_s d + c_j g_j . w (scratch)
    r_x = r_bb + P  # contact solve / penetration at the step start (scratch)
    r_ff = r_x + P  # elimination multipliers of the lane's active set, f[i, k] at i * P + k
    r_fu = r_ff + P * P  # eliminated matrix, U[i, j] at i * P + j (identity rows for inactive pairs)
    r_s = r_fu + P * P  # per-lane scalars (S_*)
    r_met = r_s + N_SCALARS  # the metric row, in metrics_layout order
    return (r_u, r_v, r_a, r_w, r_rh, r_u0, r_f, r_act, r_was, r_inc, r_cac, r_end, r_sp, r_dp, r_ke, r_cd,
            r_z0, r_bb, r_x, r_ff, r_fu, r_s, r_met)


def n_rows(n: int, p: int) -> int:
    return 6 * n + 13 * p + 2 * p * p + N_SCALARS + ML.n_metrics(n, p)


# ------------------------------------------------------------------------------------------ vector loops
# Each runs over the group in chunks of VW lanes; row r of lane chunk c is W[r * LANES + c:... + VW].
# nt and n1t are tuples of length N (all floors) and N1 (building 1's floors): their lengths are
# compile-time constants, so the row offsets are too and LLVM unrolls the short loops over floors.


@_inline
def vkeep(cond, new, old):
    """new where cond, else old (old fenced: see vfence)."""
    return vsel(cond, new, vfence(old))


@njit_lanes
def _fill_ag(W, r_ag, r_coef, prof, pid_lane, step, uniform, pid0):
    """AG row = coef * prof[pid, step]."""
    if uniform:
        p = prof[pid0, step]
        for c in range(0, LANES, VW):
            vstore(W, r_ag * LANES + c, vload(W, r_coef * LANES + c) * p)
    else:
        for l in range(LANES):
            W[r_ag * LANES + l] = W[r_coef * LANES + l] * prof[pid_lane[l], step]


@_inline
def _effective_load(W, c, ag, a1, a2, b1, m, C, Kinv, N, N1, r_u, r_v, r_a, r_w, r_rh, r_u0):
    """w = b1 u + v; rhs0 = -M ag + M (a1 u + a2 v + a) + C w; u0 = Keff^-1 rhs0 (kernel.py's order;
    terms with an exact zero of C or Keff^-1 left out: they add +-0)."""
    for i in range(N):
        vstore(W, (r_w + i) * LANES + c, b1 * vload(W, (r_u + i) * LANES + c) + vload(W, (r_v + i) * LANES + c))
    for i in range(N):
        lo = 0 if i < N1 else N1
        hi = N1 if i < N1 else N
        mi = m[i]
        s = -mi * ag + mi * (a1 * vload(W, (r_u + i) * LANES + c) + a2 * vload(W, (r_v + i) * LANES + c)
                              + vload(W, (r_a + i) * LANES + c))
        if i - 1 >= lo:
            s = s + C[i, i - 1] * vload(W, (r_w + i - 1) * LANES + c)
        s = s + C[i, i] * vload(W, (r_w + i) * LANES + c)
        if i + 1 < hi:
            s = s + C[i, i + 1] * vload(W, (r_w + i + 1) * LANES + c)
        vstore(W, (r_rh + i) * LANES + c, s)
    for i in range(N):
        lo = 0 if i < N1 else N1
        hi = N1 if i < N1 else N
        s = vsplat(0.0)
        for k in range(lo, hi):
            s = s + Kinv[i, k] * vload(W, (r_rh + k) * LANES + c)
        vstore(W, (r_u0 + i) * LANES + c, s)


@njit_lanes
def _predict_quiet(W, dt, nt, n1t, m, C, Kinv):
    """No lane in contact at the step start: the end state without contact; EVT = 1 where a pair
    penetrates it (the lane then needs the active-set iteration). Returns the number of such lanes."""
    N = len(nt)
    N1 = len(n1t)
    P = min(N1, N - N1)
    (r_u, r_v, r_a, r_w, r_rh, r_u0, r_f, r_act, r_was, r_inc, r_cac, r_end, r_sp, r_dp, r_ke, r_cd,
     r_z0, r_bb, r_x, r_ff, r_fu, r_s, r_met) = _layout(N, P)
    a1 = 4.0 / (dt * dt)
    a2 = 4.0 / dt
    b1 = 2.0 / dt
    nevt = 0
    for c in range(0, LANES, VW):
        ag = vload(W, (r_s + S_AG) * LANES + c)
        _effective_load(W, c, ag, a1, a2, b1, m, C, Kinv, N, N1, r_u, r_v, r_a, r_w, r_rh, r_u0)
        d = vload(W, (r_s + S_D) * LANES + c)
        e = mconst(False)
        for j in range(P):
            pen = (vload(W, (r_u0 + j) * LANES + c) - vload(W, (r_u0 + N1 + j) * LANES + c)) - d
            e = e | (pen > 0.0)
        vstore(W, (r_s + S_EVT) * LANES + c, mfloat(e))
        nevt += mcount(e)
    return nevt


@njit_lanes
def _predict_contact(W, dt, law, nt, n1t, m, C, Kinv, S, pon):
    """Some lane in contact: the end state without contact, then for every lane the forces of its
    current active set (the scalar kernel's first active-set iteration, through the lane's stored
    elimination factors) and EVT = 1 where the end state asks for another set. Pairs no lane has
    in contact (pon[j] == 0) have zero force in every lane: their rows of the solve are skipped."""
    N = len(nt)
    N1 = len(n1t)
    P = min(N1, N - N1)
    (r_u, r_v, r_a, r_w, r_rh, r_u0, r_f, r_act, r_was, r_inc, r_cac, r_end, r_sp, r_dp, r_ke, r_cd,
     r_z0, r_bb, r_x, r_ff, r_fu, r_s, r_met) = _layout(N, P)
    a1 = 4.0 / (dt * dt)
    a2 = 4.0 / dt
    b1 = 2.0 / dt
    pull_ok = mconst(law != LAW_NO_TENSION)
    zero = vsplat(0.0)
    nevt = 0
    for c in range(0, LANES, VW):
        ag = vload(W, (r_s + S_AG) * LANES + c)
        _effective_load(W, c, ag, a1, a2, b1, m, C, Kinv, N, N1, r_u, r_v, r_a, r_w, r_rh, r_u0)
        d = vload(W, (r_s + S_D) * LANES + c)
        ksd = vload(W, (r_s + S_KSD) * LANES + c)
        for j in range(P):
            z0 = vload(W, (r_u0 + j) * LANES + c) - vload(W, (r_u0 + N1 + j) * LANES + c)
            wrel = vload(W, (r_w + j) * LANES + c) - vload(W, (r_w + N1 + j) * LANES + c)
            bb = ksd + vload(W, (r_cd + j) * LANES + c) * wrel
            vstore(W, (r_z0 + j) * LANES + c, z0)
            vstore(W, (r_bb + j) * LANES + c, bb)
            if pon[j] > 0:
                act = vload(W, (r_act + j) * LANES + c) > 0.5
                vstore(W, (r_x + j) * LANES + c, vsel(act, z0 - bb / vload(W, (r_ke + j) * LANES + c), zero))
            else:
                vstore(W, (r_x + j) * LANES + c, zero)
        # forward elimination, then back substitution (kernel._solve_spd's order on the active pairs;
        # inactive pairs are identity rows with zero multipliers, which change nothing)
        for k in range(P):
            if pon[k] > 0:
                for i in range(k + 1, P):
                    if pon[i] > 0:
                        vstore(W, (r_x + i) * LANES + c, vload(W, (r_x + i) * LANES + c)
                               - vload(W, (r_ff + i * P + k) * LANES + c) * vload(W, (r_x + k) * LANES + c))
        for ii in range(P):
            i = P - 1 - ii
            if pon[i] > 0:
                s = vload(W, (r_x + i) * LANES + c)
                for j in range(i + 1, P):
                    if pon[j] > 0:
                        s = s - vload(W, (r_fu + i * P + j) * LANES + c) * vload(W, (r_x + j) * LANES + c)
                vstore(W, (r_x + i) * LANES + c, s / vload(W, (r_fu + i * P + i) * LANES + c))
        e = mconst(False)
        for j in range(P):
            vstore(W, (r_f + j) * LANES + c, vload(W, (r_x + j) * LANES + c))
        for j in range(P):
            z = vload(W, (r_z0 + j) * LANES + c)
            for q in range(P):
                if pon[q] > 0:
                    z = z - S[j, q] * vload(W, (r_x + q) * LANES + c)
            pen = z - d
            want = (pen > 0.0) & (pull_ok | ((vload(W, (r_ke + j) * LANES + c) * z - vload(W, (r_bb + j) * LANES + c)) > 0.0))
            act = vload(W, (r_act + j) * LANES + c) > 0.5
            e = e | (want != act)
        vstore(W, (r_s + S_EVT) * LANES + c, mfloat(e))
        nevt += mcount(e)
    return nevt


@njit_lanes
def _event_check(W, dt, law, nt, n1t, H, pon):
    """Event scheme: EVT = 1 where the end state of the step taken with the lane's start set (u0 - H F,
    F from _predict_contact, or u0 when no lane is in contact) contradicts that set, by the scalar
    kernel's test (kernel._step_pieces, operation for operation): penetration beyond
    kernel._switch_tolerance for a pair out of contact, below minus it for a pair in contact, the
    no-tension law's indicator min(pen, pen + c/k_s v_rel) in place of a positive penetration. Those
    lanes take the step in scalar code (_event_lane); the others' step is the scalar kernel's step
    without an event, which the vector finish computes. Returns the number of EVT lanes."""
    N = len(nt)
    N1 = len(n1t)
    P = min(N1, N - N1)
    (r_u, r_v, r_a, r_w, r_rh, r_u0, r_f, r_act, r_was, r_inc, r_cac, r_end, r_sp, r_dp, r_ke, r_cd,
     r_z0, r_bb, r_x, r_ff, r_fu, r_s, r_met) = _layout(N, P)
    b1 = 2.0 / dt
    nevt = 0
    for c in range(0, LANES, VW):
        d = vload(W, (r_s + S_D) * LANES + c)
        ks = vload(W, (r_s + S_KS) * LANES + c)
        e = mconst(False)
        for j in range(P):
            p = j
            q = N1 + j
            unp = vload(W, (r_u0 + p) * LANES + c)
            unq = vload(W, (r_u0 + q) * LANES + c)
            for k in range(P):
                if pon[k] > 0:
                    fk = vload(W, (r_f + k) * LANES + c)
                    unp = unp - H[p, k] * fk
            for k in range(P):
                if pon[k] > 0:
                    fk = vload(W, (r_f + k) * LANES + c)
                    unq = unq - H[q, k] * fk
            pe = (unp - unq) - d
            if law == LAW_NO_TENSION:
                vnp = b1 * (unp - vload(W, (r_u + p) * LANES + c)) - vload(W, (r_v + p) * LANES + c)
                vnq = b1 * (unq - vload(W, (r_u + q) * LANES + c)) - vload(W, (r_v + q) * LANES + c)
                alt = pe + (vload(W, (r_cd + j) * LANES + c) / ks) * (vnp - vnq)
                pe = vsel(pe > 0.0, vsel(alt < pe, alt, pe), pe)  # min(pe, alt) where pe > 0
            tol = 1e-15 + 1e-12 * (abs(unp) + abs(unq))
            act = vload(W, (r_act + j) * LANES + c) > 0.5
            e = e | (act & (pe < 0.0 - tol)) | (~act & (pe > tol))
        vstore(W, (r_s + S_EVT) * LANES + c, mfloat(e))
        nevt += mcount(e)
    return nevt


@_inline
def _finish_dofs(W, c, ag, t, a1, a2, b1, dt, m, C, N, N1, r_u, r_v, r_a, r_w, r_rh, r_s, r_met):
    """End state (the new u is in the rh rows): velocity, acceleration, divergence check, input and
    structural-damping work, per-floor metrics. Returns the mask of lanes finite and bounded."""
    ok = mconst(True)
    s_in = vsplat(0.0)
    vt = vsplat(t)
    for i in range(N):
        un = vload(W, (r_rh + i) * LANES + c)
        uo = vload(W, (r_u + i) * LANES + c)
        vo = vload(W, (r_v + i) * LANES + c)
        du = un - uo
        vn = b1 * du - vo
        an = a1 * du - a2 * vo - vload(W, (r_a + i) * LANES + c)
        ok = ok & (abs(un) < ML.DIVERGED_M) & (abs(an) < 1e300)
        s_in = s_in + m[i] * du
        vstore(W, (r_w + i) * LANES + c, du)
        vstore(W, (r_u + i) * LANES + c, un)
        vstore(W, (r_v + i) * LANES + c, vn)
        vstore(W, (r_a + i) * LANES + c, an)
        base = r_met + ML.PER_DOF * i
        ad = abs(un)
        pk = vload(W, (base + ML.DOF_PEAK_DISP) * LANES + c)
        better = ad > pk
        vstore(W, (base + ML.DOF_PEAK_DISP) * LANES + c, vkeep(better, ad, pk))
        vstore(W, (base + ML.DOF_PEAK_DISP_TIME) * LANES + c,
               vkeep(better, vt, vload(W, (base + ML.DOF_PEAK_DISP_TIME) * LANES + c)))
        aa = abs(an + ag)
        pa = vload(W, (base + ML.DOF_PEAK_ABS_ACC) * LANES + c)
        vstore(W, (base + ML.DOF_PEAK_ABS_ACC) * LANES + c, vkeep(aa > pa, aa, pa))
    ds = vsplat(0.0)
    for i in range(N):
        lo = 0 if i < N1 else N1
        hi = N1 if i < N1 else N
        s = vsplat(0.0)
        if i - 1 >= lo:
            s = s + C[i, i - 1] * vload(W, (r_w + i - 1) * LANES + c)
        s = s + C[i, i] * vload(W, (r_w + i) * LANES + c)
        if i + 1 < hi:
            s = s + C[i, i + 1] * vload(W, (r_w + i + 1) * LANES + c)
        ds = ds + vload(W, (r_w + i) * LANES + c) * s
    de = -0.5 * (vload(W, (r_s + S_AGP) * LANES + c) + ag) * s_in
    vstore(W, (r_s + S_EIN) * LANES + c, vload(W, (r_s + S_EIN) * LANES + c) + de)
    vstore(W, (r_s + S_EINA) * LANES + c, vload(W, (r_s + S_EINA) * LANES + c) + abs(de))
    vstore(W, (r_s + S_DST) * LANES + c, vload(W, (r_s + S_DST) * LANES + c) + ds / dt)
    vstore(W, (r_s + S_AGP) * LANES + c, ag)
    return ok


@njit_lanes
def _finish_quiet(W, dt, step, nt, n1t, m, C):
    """No lane in contact at the step start or end: u = u0, then _finish_dofs. Returns the number
    of lanes whose state is not finite (BAD = 1)."""
    N = len(nt)
    N1 = len(n1t)
    P = min(N1, N - N1)
    (r_u, r_v, r_a, r_w, r_rh, r_u0, r_f, r_act, r_was, r_inc, r_cac, r_end, r_sp, r_dp, r_ke, r_cd,
     r_z0, r_bb, r_x, r_ff, r_fu, r_s, r_met) = _layout(N, P)
    a1 = 4.0 / (dt * dt)
    a2 = 4.0 / dt
    b1 = 2.0 / dt
    t = step * dt
    nbad = 0
    for c in range(0, LANES, VW):
        ag = vload(W, (r_s + S_AG) * LANES + c)
        ok = _finish_dofs(W, c, ag, t, a1, a2, b1, dt, m, C, N, N1, r_u, r_v, r_a, r_w, r_u0, r_s, r_met)
        bad = ~ok
        vstore(W, (r_s + S_BAD) * LANES + c, mfloat(bad))
        nbad += mcount(bad)
    return nbad


@njit_lanes
def _finish_contact(W, dt, step, nt, n1t, m, C, H, pon_now, pon_any):
    """Some lane in contact: u = u0 - H F, _finish_dofs, the work of the contact's spring and
    dashpot parts and the per-pair metrics (kernel.py's order of comparisons; times as kernel.py
    takes them: step * dt for floors, (step - 1) * dt + dt for the force peak). Returns (lanes not
    finite, lanes where a compressive phase ended: END rows). Pairs in contact in no lane now
    (pon_now[j] == 0) have F = 0: H F leaves them out; pairs in contact in no lane now nor at the step
    start (pon_any[j] == 0) change no energy term or metric: skipped."""
    N = len(nt)
    N1 = len(n1t)
    P = min(N1, N - N1)
    (r_u, r_v, r_a, r_w, r_rh, r_u0, r_f, r_act, r_was, r_inc, r_cac, r_end, r_sp, r_dp, r_ke, r_cd,
     r_z0, r_bb, r_x, r_ff, r_fu, r_s, r_met) = _layout(N, P)
    a1 = 4.0 / (dt * dt)
    a2 = 4.0 / dt
    b1 = 2.0 / dt
    t = step * dt
    te = vsplat((step - 1) * dt + dt)
    vdt = vsplat(dt)
    zero = vsplat(0.0)
    pbase = r_met + ML.PER_DOF * N
    nbad = 0
    nend = 0
    for c in range(0, LANES, VW):
        ag = vload(W, (r_s + S_AG) * LANES + c)
        d = vload(W, (r_s + S_D) * LANES + c)
        ks = vload(W, (r_s + S_KS) * LANES + c)
        for j in range(P):  # penetration at the step start (the scalar kernel's pen_prev)
            if pon_any[j] > 0:
                vstore(W, (r_x + j) * LANES + c, (vload(W, (r_u + j) * LANES + c) - vload(W, (r_u + N1 + j) * LANES + c)) - d)
        for i in range(N):
            s = vload(W, (r_u0 + i) * LANES + c)
            for j in range(P):
                if pon_now[j] > 0:
                    s = s - H[i, j] * vload(W, (r_f + j) * LANES + c)
            vstore(W, (r_rh + i) * LANES + c, s)
        ok = _finish_dofs(W, c, ag, t, a1, a2, b1, dt, m, C, N, N1, r_u, r_v, r_a, r_w, r_rh, r_s, r_met)
        bad = ~ok
        vstore(W, (r_s + S_BAD) * LANES + c, mfloat(bad))
        nbad += mcount(bad)
        wsp = vload(W, (r_s + S_WSP) * LANES + c)
        wda = vload(W, (r_s + S_WDA) * LANES + c)
        wrel = vload(W, (r_s + S_WREL) * LANES + c)
        ended = mconst(False)
        for j in range(P):
            if pon_any[j] == 0:
                continue
            pen = (vload(W, (r_u + j) * LANES + c) - vload(W, (r_u + N1 + j) * LANES + c)) - d
            act = vload(W, (r_act + j) * LANES + c) > 0.5
            was = vload(W, (r_was + j) * LANES + c) > 0.5
            f = vload(W, (r_f + j) * LANES + c)
            sp = vsel(act, ks * pen, zero)
            dp = vsel(act, f - sp, zero)
            dpen = pen - vload(W, (r_x + j) * LANES + c)
            wsp = wsp + 0.5 * (vload(W, (r_sp + j) * LANES + c) + sp) * dpen
            wda = wda + 0.5 * (vload(W, (r_dp + j) * LANES + c) + dp) * dpen
            wrel = vkeep(was & ~act & (pen > 0.0), wrel + 0.5 * ks * pen * pen, wrel)
            vstore(W, (r_sp + j) * LANES + c, sp)
            vstore(W, (r_dp + j) * LANES + c, dp)
            base = pbase + ML.PER_PAIR * j
            q = vload(W, (base + ML.PAIR_IMPACTS) * LANES + c)
            vstore(W, (base + ML.PAIR_IMPACTS) * LANES + c, vkeep(act & ~was, q + 1.0, q))
            q = vload(W, (base + ML.PAIR_CONTACT_TIME) * LANES + c)
            vstore(W, (base + ML.PAIR_CONTACT_TIME) * LANES + c, vkeep(act, q + vdt, q))
            q = vload(W, (base + ML.PAIR_MAX_PENETRATION) * LANES + c)
            vstore(W, (base + ML.PAIR_MAX_PENETRATION) * LANES + c, vkeep(act & (pen > q), pen, q))
            q = vload(W, (base + ML.PAIR_PEAK_FORCE) * LANES + c)
            up = act & (f > q)
            vstore(W, (base + ML.PAIR_PEAK_FORCE) * LANES + c, vkeep(up, f, q))
            vstore(W, (base + ML.PAIR_PEAK_FORCE_TIME) * LANES + c,
                   vkeep(up, te, vload(W, (base + ML.PAIR_PEAK_FORCE_TIME) * LANES + c)))
            q = vload(W, (base + ML.PAIR_MIN_FORCE) * LANES + c)
            vstore(W, (base + ML.PAIR_MIN_FORCE) * LANES + c, vkeep(act & (f < q), f, q))
            comp = act & (f > 0.0)
            q = vload(W, (base + ML.PAIR_COMPRESSION_TIME) * LANES + c)
            vstore(W, (base + ML.PAIR_COMPRESSION_TIME) * LANES + c, vkeep(comp, q + vdt, q))
            inc = vload(W, (r_inc + j) * LANES + c) > 0.5
            q = vload(W, (r_cac + j) * LANES + c)
            vstore(W, (r_cac + j) * LANES + c, vkeep(comp, vsel(inc, q + vdt, vdt), q))
            end = inc & ~comp
            vstore(W, (r_end + j) * LANES + c, mfloat(end))
            ended = ended | end
            vstore(W, (r_inc + j) * LANES + c, mfloat(comp))
            vstore(W, (r_was + j) * LANES + c, mfloat(act))
        vstore(W, (r_s + S_WSP) * LANES + c, wsp)
        vstore(W, (r_s + S_WDA) * LANES + c, wda)
        vstore(W, (r_s + S_WREL) * LANES + c, wrel)
        nend += mcount(ended)
    return nbad, nend


# ------------------------------------------------------------------------------------------ scalar parts
# (copies of kernel.py's helpers, operation for operation: a cached caller does not see changes to a
# jitted callee in another file, so the lane kernel does not call into kernel.py; the equality tests
# catch any drift between the two)


@njit_lanes
def _solve_spd(A, b, n):
    """kernel._solve_spd: Gaussian elimination of A[:n, :n] x = b[:n] in place."""
    for k in range(n):
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


@njit_lanes
def _contact_forces(S, z0, bb, ke, active, n_pairs, idx, Asmall, rhs, F):
    """kernel._contact_forces: forces of the pairs in `active` (others 0)."""
    na = 0
    for j in range(n_pairs):
        F[j] = 0.0
        if active[j]:
            idx[na] = j
            na += 1
    if na == 0:
        return
    for p in range(na):
        jp = idx[p]
        for q in range(na):
            Asmall[p, q] = S[jp, idx[q]]
        Asmall[p, p] += 1.0 / ke[jp]
        rhs[p] = z0[jp] - bb[jp] / ke[jp]
    _solve_spd(Asmall, rhs, na)
    for p in range(na):
        F[idx[p]] = rhs[p]


@njit_lanes
def _mask(active, npair):
    """kernel._mask."""
    mk = 0
    for j in range(min(npair, 62)):
        if active[j]:
            mk |= 1 << j
    return mk


@njit_lanes
def _lane_factors(W, l, S, P, r_ke, r_act, r_ff, r_fu, idx, Asmall):
    """Store the elimination of lane l's active set (kernel._solve_spd's multipliers and eliminated
    matrix on the active pairs) in full P x P positions: identity rows for inactive pairs."""
    na = 0
    for j in range(P):
        if W[(r_act + j) * LANES + l] > 0.5:
            idx[na] = j
            na += 1
    for q in range(P * P):
        W[(r_ff + q) * LANES + l] = 0.0
        W[(r_fu + q) * LANES + l] = 0.0
    for j in range(P):
        W[(r_fu + j * P + j) * LANES + l] = 1.0
    for p in range(na):
        jp = idx[p]
        for q in range(na):
            Asmall[p, q] = S[jp, idx[q]]
        Asmall[p, p] += 1.0 / W[(r_ke + jp) * LANES + l]
    for k in range(na):
        piv = Asmall[k, k]
        for i in range(k + 1, na):
            f = Asmall[i, k] / piv
            W[(r_ff + idx[i] * P + idx[k]) * LANES + l] = f
            for j in range(k, na):
                Asmall[i, j] -= f * Asmall[k, j]
    for i in range(na):
        for j in range(i, na):
            W[(r_fu + idx[i] * P + idx[j]) * LANES + l] = Asmall[i, j]


@njit_lanes
def _settle_lane(W, l, law, max_iter, S, N1, P, r_w, r_u0, r_f, r_act, r_ke, r_cd, r_s,
                 z0, bb, ke, active, trial, prev, seen, idx, Asmall, rsmall, F):
    """The scalar kernel's active-set iteration for lane l in this step, from the set the lane had at
    the step start (kernel.integrate_batch, scheme implicit, operation for operation). Writes the
    forces and the set; returns (iterations, 1 if the set cycled else 0, 1 if the set changed else 0)."""
    d = W[(r_s + S_D) * LANES + l]
    ksd = W[(r_s + S_KSD) * LANES + l]
    for j in range(P):
        z0[j] = W[(r_u0 + j) * LANES + l] - W[(r_u0 + N1 + j) * LANES + l]
        wrel = W[(r_w + j) * LANES + l] - W[(r_w + N1 + j) * LANES + l]
        bb[j] = ksd + W[(r_cd + j) * LANES + l] * wrel
        ke[j] = W[(r_ke + j) * LANES + l]
        active[j] = W[(r_act + j) * LANES + l] > 0.5
        prev[j] = active[j]
    start = _mask(active, P)
    it = 0
    settled = False
    cycled = False
    while it < max_iter and not cycled:
        seen[it] = _mask(active, P)
        it += 1
        _contact_forces(S, z0, bb, ke, active, P, idx, Asmall, rsmall, F)
        changed = False
        for j in range(P):
            z = z0[j]
            for q in range(P):
                z -= S[j, q] * F[q]
            pen = z - d
            want = pen > 0.0
            if want and law == LAW_NO_TENSION:
                want = (ke[j] * z - bb[j]) > 0.0
            trial[j] = want
            if want != active[j]:
                changed = True
        if not changed:
            settled = True
            break
        for j in range(P):
            prev[j] = active[j]
            active[j] = trial[j]
        mk = _mask(active, P)
        for q in range(it):
            if seen[q] == mk and P <= 62:
                cycled = True
    unsettled = 0
    if not settled:
        unsettled = 1
        for j in range(P):
            active[j] = prev[j] or trial[j]
        _contact_forces(S, z0, bb, ke, active, P, idx, Asmall, rsmall, F)
    for j in range(P):
        W[(r_f + j) * LANES + l] = F[j]
        W[(r_act + j) * LANES + l] = 1.0 if active[j] else 0.0
    return it, unsettled, (1 if _mask(active, P) != start else 0)


@njit_lanes
def _event_lane(W, l, step, dt, law, harmonic, amp, om, m, C, K, H, S, i1, i2, c, N1, r_u, r_v, r_a, r_w, r_u0,
                r_f, r_act, r_was, r_inc, r_cac, r_sp, r_dp, r_ke, r_s, r_met, dur_l, nph_l, u, v, a, u0, un, vn, an,
                F, z0, bb, ke, active, was_active, just, trial, thetas, in_comp, comp_acc, Sprev, Dprev, pen_prev,
                Cdu, Amat, rvec, en, orow, idx, Asmall, rsmall):
    """Event scheme, lane l (whose end state contradicts its contact set): the scalar kernel's step,
    operation for operation (kernel.integrate_batch: the forces of the start set, the trial end state,
    then kernel._step_pieces, which locates and handles the events, and the per-floor peaks), on the
    lane's state gathered from W and written back to it. Returns True when the state stays finite
    (else the lane goes back to the driver, which reruns the run with the scalar kernel)."""
    N = m.shape[0]
    P = i1.shape[0]
    a1 = 4.0 / (dt * dt)
    a2 = 4.0 / dt
    b1 = 2.0 / dt
    k_s = W[(r_s + S_KS) * LANES + l]
    d = W[(r_s + S_D) * LANES + l]
    ksd = W[(r_s + S_KSD) * LANES + l]
    ag = W[(r_s + S_AG) * LANES + l]
    ag_prev = W[(r_s + S_AGP) * LANES + l]
    for i in range(N):
        u[i] = W[(r_u + i) * LANES + l]
        v[i] = W[(r_v + i) * LANES + l]
        a[i] = W[(r_a + i) * LANES + l]
        u0[i] = W[(r_u0 + i) * LANES + l]
    for j in range(P):
        z0[j] = u0[i1[j]] - u0[i2[j]]
        wrel = W[(r_w + i1[j]) * LANES + l] - W[(r_w + i2[j]) * LANES + l]
        bb[j] = ksd + c[j] * wrel
        ke[j] = W[(r_ke + j) * LANES + l]
        active[j] = W[(r_act + j) * LANES + l] > 0.5
        was_active[j] = W[(r_was + j) * LANES + l] > 0.5
        in_comp[j] = W[(r_inc + j) * LANES + l] > 0.5
        comp_acc[j] = W[(r_cac + j) * LANES + l]
        Sprev[j] = W[(r_sp + j) * LANES + l]
        Dprev[j] = W[(r_dp + j) * LANES + l]
        pen_prev[j] = u[i1[j]] - u[i2[j]] - d  # the scalar kernel's pen_prev: set from u at every accepted piece
    en[_kernel.EN_W_RELEASE] = W[(r_s + S_WREL) * LANES + l]
    en[_kernel.EN_E_IN] = W[(r_s + S_EIN) * LANES + l]
    en[_kernel.EN_E_IN_ABS] = W[(r_s + S_EINA) * LANES + l]
    en[_kernel.EN_D_STRUCT] = W[(r_s + S_DST) * LANES + l]
    en[_kernel.EN_W_SPRING] = W[(r_s + S_WSP) * LANES + l]
    en[_kernel.EN_W_DASH] = W[(r_s + S_WDA) * LANES + l]
    pbase = ML.PER_DOF * N
    rbase = pbase + ML.PER_PAIR * P
    for q in range(rbase):
        orow[q] = W[(r_met + q) * LANES + l]
    # kernel.integrate_batch, event scheme: the step with the start set, then its pieces
    _contact_forces(S, z0, bb, ke, active, P, idx, Asmall, rsmall, F)
    for i in range(N):
        s = u0[i]
        for j in range(P):
            s -= H[i, j] * F[j]
        un[i] = s
    for i in range(N):
        du = un[i] - u[i]
        vn[i] = b1 * du - v[i]
        an[i] = a1 * du - a2 * v[i] - a[i]
    finite, n_ev, uns = _kernel._step_pieces(SCHEME_EVENT, law, step, dt, ag, ag_prev, harmonic, amp, om,
                                             (m, C, K, i1, i2), k_s, c, d, (u, v, a, un, vn, an, F),
                                             (active, was_active, just, trial), thetas,
                                             (in_comp, comp_acc, dur_l, nph_l), (Sprev, Dprev, pen_prev),
                                             (Cdu, Amat, rvec), en, orow, pbase)
    if n_ev > W[(r_s + S_MIT) * LANES + l]:
        W[(r_s + S_MIT) * LANES + l] = n_ev
    W[(r_s + S_UNS) * LANES + l] += uns
    if not finite:
        W[(r_s + S_BAD) * LANES + l] = 1.0
        return False
    W[(r_s + S_BAD) * LANES + l] = 0.0
    W[(r_s + S_AGP) * LANES + l] = ag
    t = step * dt
    for i in range(N):  # per-floor metrics at the step end (kernel.integrate_batch)
        base = ML.PER_DOF * i
        ad = abs(u[i])
        if ad > orow[base + ML.DOF_PEAK_DISP]:
            orow[base + ML.DOF_PEAK_DISP] = ad
            orow[base + ML.DOF_PEAK_DISP_TIME] = t
        aa = abs(a[i] + ag)
        if aa > orow[base + ML.DOF_PEAK_ABS_ACC]:
            orow[base + ML.DOF_PEAK_ABS_ACC] = aa
    for i in range(N):
        W[(r_u + i) * LANES + l] = u[i]
        W[(r_v + i) * LANES + l] = v[i]
        W[(r_a + i) * LANES + l] = a[i]
    for j in range(P):
        W[(r_f + j) * LANES + l] = F[j]
        W[(r_act + j) * LANES + l] = 1.0 if active[j] else 0.0
        W[(r_was + j) * LANES + l] = 1.0 if was_active[j] else 0.0
        W[(r_inc + j) * LANES + l] = 1.0 if in_comp[j] else 0.0
        W[(r_cac + j) * LANES + l] = comp_acc[j]
        W[(r_sp + j) * LANES + l] = Sprev[j]
        W[(r_dp + j) * LANES + l] = Dprev[j]
    W[(r_s + S_WREL) * LANES + l] = en[_kernel.EN_W_RELEASE]
    W[(r_s + S_EIN) * LANES + l] = en[_kernel.EN_E_IN]
    W[(r_s + S_EINA) * LANES + l] = en[_kernel.EN_E_IN_ABS]
    W[(r_s + S_DST) * LANES + l] = en[_kernel.EN_D_STRUCT]
    W[(r_s + S_WSP) * LANES + l] = en[_kernel.EN_W_SPRING]
    W[(r_s + S_WDA) * LANES + l] = en[_kernel.EN_W_DASH]
    for q in range(rbase):
        W[(r_met + q) * LANES + l] = orow[q]
    return True


@njit_lanes
def _end_phase(dur, nph, l, j, duration):
    """kernel._end_phase for lane l."""
    k = nph[l, j]
    if k < dur.shape[2]:
        dur[l, j, k] = duration
    nph[l, j] = k + 1


@njit_lanes
def _park(W, l, N, P, nrows, r_u, r_v, r_a, r_f, r_fu, r_s):
    """Put lane l at rest, out of contact, with no excitation, far from its neighbour: it computes
    zeros until the group ends and never asks for the active-set iteration."""
    for q in range(nrows):
        W[q * LANES + l] = 0.0
    for j in range(P):
        W[(r_fu + j * P + j) * LANES + l] = 1.0
    W[(r_s + S_D) * LANES + l] = 1.0


@njit_lanes
def _finalize_lane(W, l, out, status, steps_done, dt, m, K, N, N1, P, dur, nph,
                   r_u, r_v, r_act, r_inc, r_cac, r_s, r_met):
    """Write lane l's metric row (kernel.integrate_batch's end-of-run code)."""
    nm = out.size
    pbase = ML.PER_DOF * N
    rbase = pbase + ML.PER_PAIR * P
    for q in range(rbase):
        out[q] = W[(r_met + q) * LANES + l]
    for q in range(rbase, nm):
        out[q] = 0.0
    for j in range(P):
        if W[(r_inc + j) * LANES + l] > 0.5:
            _end_phase(dur, nph, l, j, W[(r_cac + j) * LANES + l])
        base = pbase + ML.PER_PAIR * j
        k = nph[l, j]
        out[base + ML.PAIR_COMPRESSION_PHASES] = k
        if k > ML.MEDIAN_BUFFER:
            status |= ML.STATUS_MEDIAN_TRUNCATED
            k = ML.MEDIAN_BUFFER
        out[base + ML.PAIR_MEDIAN_COMPRESSION] = np.median(dur[l, j, :k]) if k > 0 else 0.0
    unsettled = W[(r_s + S_UNS) * LANES + l]
    if unsettled > 0:
        status |= ML.STATUS_UNSETTLED
    ke_end = 0.0
    se_end = 0.0
    for i in range(N):
        vi = W[(r_v + i) * LANES + l]
        ke_end += 0.5 * m[i] * vi * vi
        s = 0.0
        for k in range(N):
            s += K[i, k] * W[(r_u + k) * LANES + l]
        se_end += 0.5 * W[(r_u + i) * LANES + l] * s
    d = W[(r_s + S_D) * LANES + l]
    ks = W[(r_s + S_KS) * LANES + l]
    e_spring = 0.0
    for j in range(P):
        if W[(r_act + j) * LANES + l] > 0.5:
            pp = (W[(r_u + j) * LANES + l] - W[(r_u + N1 + j) * LANES + l]) - d
            e_spring += 0.5 * ks * pp * pp
    w_release = W[(r_s + S_WREL) * LANES + l]
    residual = W[(r_s + S_WSP) * LANES + l] - e_spring - w_release
    e_in_abs = W[(r_s + S_EINA) * LANES + l]
    out[rbase + ML.RUN_E_IN] = W[(r_s + S_EIN) * LANES + l]
    out[rbase + ML.RUN_E_IN_ABS] = e_in_abs
    out[rbase + ML.RUN_KE] = ke_end
    out[rbase + ML.RUN_SE] = se_end
    out[rbase + ML.RUN_D_STRUCT] = W[(r_s + S_DST) * LANES + l]
    out[rbase + ML.RUN_D_CONTACT] = W[(r_s + S_WDA) * LANES + l] + w_release
    out[rbase + ML.RUN_E_SPRING] = e_spring
    out[rbase + ML.RUN_E_RESIDUAL] = residual
    if not (abs(residual) <= ML.ENERGY_TOL * e_in_abs):
        status |= ML.STATUS_ENERGY
    out[rbase + ML.RUN_UNSETTLED] = unsettled
    out[rbase + ML.RUN_MAX_ITER] = W[(r_s + S_MIT) * LANES + l]
    out[rbase + ML.RUN_STEPS] = steps_done
    out[rbase + ML.RUN_STATUS] = status


# ------------------------------------------------------------------------------------------ entry point


@njit_lanes
def integrate_lanes(
    order,  # run indices, grouped LANES at a time: group g is order[g * LANES:(g + 1) * LANES]
    g_start,
    g_stop,
    dt,
    scheme,
    law,
    max_iter,
    # structure: nt, n1t are tuples of length N and N1 (floor counts fixed at compile time)
    nt,
    n1t,
    m,
    C,
    K,
    Kinv,
    H,
    S,
    # per run
    ks,
    cdash,
    gap,
    status_in,
    nsteps,
    exc_kind,
    exc_amp,
    exc_omega,
    coef,
    pid,
    prof,
    # outputs
    metrics,
    redo,
):
    """Integrate groups g_start..g_stop-1 of `order`; fill metrics[run] (metrics_layout), or set
    redo[run] = 1 for a run that diverged (the caller reruns it with the scalar kernel, which
    decides where it stops and what its row holds)."""
    N = len(nt)
    N1 = len(n1t)
    P = min(N1, N - N1)
    (r_u, r_v, r_a, r_w, r_rh, r_u0, r_f, r_act, r_was, r_inc, r_cac, r_end, r_sp, r_dp, r_ke, r_cd,
     r_z0, r_bb, r_x, r_ff, r_fu, r_s, r_met) = _layout(N, P)
    nrows = r_met + ML.PER_DOF * N + ML.PER_PAIR * P + ML.PER_RUN
    b1 = 2.0 / dt
    W = np.zeros(nrows * LANES)
    dur = np.empty((LANES, P, ML.MEDIAN_BUFFER))
    nph = np.zeros((LANES, P), dtype=np.int64)
    lane_run = np.empty(LANES, dtype=np.int64)
    lane_nst = np.empty(LANES, dtype=np.int64)
    lane_status = np.empty(LANES, dtype=np.int64)
    live = np.zeros(LANES, dtype=np.bool_)
    act_pair = np.zeros(P, dtype=np.int64)
    pon_start = np.zeros(P, dtype=np.int64)  # pairs some lane has in contact at the step start
    pon_now = np.zeros(P, dtype=np.int64)  # ... at the step end
    pon_any = np.zeros(P, dtype=np.int64)  # either
    pid_lane = np.zeros(LANES, dtype=np.int64)
    # scalar work arrays of the active-set iteration
    z0 = np.empty(P)
    bb = np.empty(P)
    ke = np.empty(P)
    Fw = np.empty(P)
    active = np.zeros(P, dtype=np.bool_)
    trial = np.zeros(P, dtype=np.bool_)
    prev = np.zeros(P, dtype=np.bool_)
    seen = np.zeros(max_iter + 1, dtype=np.int64)
    idx = np.empty(P, dtype=np.int64)
    Asmall = np.empty((P, P))
    rsmall = np.empty(P)
    n_runs = order.size
    # event scheme: the lanes whose step has an event (state at the step start kept in snap), and the
    # scalar work arrays of their step (kernel.integrate_batch's)
    event = scheme == SCHEME_EVENT
    snap = np.empty((LANES, nrows))
    fix = np.zeros(LANES, dtype=np.bool_)
    i1 = np.arange(P)
    i2 = N1 + np.arange(P)
    eu = np.empty(N)
    ev = np.empty(N)
    ea = np.empty(N)
    eu0 = np.empty(N)
    eun = np.empty(N)
    evn = np.empty(N)
    ean = np.empty(N)
    ecdu = np.empty(N)
    was_e = np.zeros(P, dtype=np.bool_)
    just = np.zeros(P, dtype=np.bool_)
    thetas = np.empty(P)
    inc_e = np.zeros(P, dtype=np.bool_)
    cac_e = np.zeros(P)
    sp_e = np.zeros(P)
    dp_e = np.zeros(P)
    penp = np.zeros(P)
    Amat = np.empty((N, N))
    rvec = np.empty(N)
    en = np.zeros(_kernel.EN_N)
    orow = np.zeros(ML.PER_DOF * N + ML.PER_PAIR * P + ML.PER_RUN)

    for g in range(g_start, g_stop):
        base = g * LANES
        nl = min(LANES, n_runs - base)
        max_nst = 0
        uniform = True
        for l in range(LANES):
            _park(W, l, N, P, nrows, r_u, r_v, r_a, r_f, r_fu, r_s)
            live[l] = False
            nph[l, :] = 0
            if l >= nl:
                continue
            run = order[base + l]
            lane_run[l] = run
            lane_nst[l] = nsteps[run]
            lane_status[l] = status_in[run]
            live[l] = True
            pid_lane[l] = pid[run]
            if pid[run] != pid[order[base]]:
                uniform = False
            max_nst = max(max_nst, nsteps[run])
            k_s = ks[run]
            d = gap[run]
            W[(r_s + S_KS) * LANES + l] = k_s
            W[(r_s + S_D) * LANES + l] = d
            W[(r_s + S_KSD) * LANES + l] = k_s * d
            W[(r_s + S_COEF) * LANES + l] = coef[run]
            for j in range(P):
                W[(r_cd + j) * LANES + l] = cdash[run, j]
                W[(r_ke + j) * LANES + l] = k_s + b1 * cdash[run, j]
            # at rest relative to the table; a0 = -ag(0) (kernel.py, eq. 11)
            ag0 = coef[run] * prof[pid[run], 0]
            for i in range(N):
                W[(r_a + i) * LANES + l] = -ag0
            W[(r_s + S_AGP) * LANES + l] = ag0
            W[(r_s + S_MIT) * LANES + l] = 1.0 if (nsteps[run] >= 1 and not event) else 0.0
        for l in range(nl):
            if lane_nst[l] == 0:
                _finalize_lane(W, l, metrics[lane_run[l]], lane_status[l], 0, dt, m, K, N, N1, P, dur, nph,
                               r_u, r_v, r_act, r_inc, r_cac, r_s, r_met)
                _park(W, l, N, P, nrows, r_u, r_v, r_a, r_f, r_fu, r_s)
                live[l] = False
        next_end = max_nst + 1
        for l in range(nl):
            if live[l] and lane_nst[l] < next_end:
                next_end = lane_nst[l]
        n_act = 0  # active (lane, pair) entries
        act_pair[:] = 0  # lanes with pair j active
        pid0 = pid[order[base]] if nl > 0 else 0
        for step in range(1, max_nst + 1):
            _fill_ag(W, r_s + S_AG, r_s + S_COEF, prof, pid_lane, step, uniform, pid0)
            had_contact = n_act > 0
            if had_contact:
                for j in range(P):
                    pon_start[j] = 1 if act_pair[j] > 0 else 0
                nevt = _predict_contact(W, dt, law, nt, n1t, m, C, Kinv, S, pon_start)
            else:
                nevt = _predict_quiet(W, dt, nt, n1t, m, C, Kinv)
                pon_start[:] = 0
            if event:
                # the step with each lane's start set; lanes where it ends contradicting the set are
                # redone below in scalar code, from the state kept here
                for j in range(P):
                    pon_start[j] = 1 if act_pair[j] > 0 else 0
                nevt = _event_check(W, dt, law, nt, n1t, H, pon_start)
                nfix = 0
                if nevt > 0:
                    for l in range(LANES):
                        fix[l] = live[l] and W[(r_s + S_EVT) * LANES + l] > 0.5
                        if fix[l]:
                            nfix += 1
                            for q in range(nrows):
                                snap[l, q] = W[q * LANES + l]
                if had_contact:
                    nbad, nend = _finish_contact(W, dt, step, nt, n1t, m, C, H, pon_start, pon_start)
                else:
                    nbad = _finish_quiet(W, dt, step, nt, n1t, m, C)
                    nend = 0
                if nfix > 0:
                    for l in range(LANES):
                        if not fix[l]:
                            continue
                        for q in range(nrows):
                            W[q * LANES + l] = snap[l, q]
                        for j in range(P):
                            if W[(r_act + j) * LANES + l] > 0.5:
                                act_pair[j] -= 1
                                n_act -= 1
                        run = lane_run[l]
                        _event_lane(W, l, step, dt, law, exc_kind[run] == EXC_HARMONIC, exc_amp[run], exc_omega[run],
                                    m, C, K, H, S, i1, i2, cdash[run], N1, r_u, r_v, r_a, r_w, r_u0, r_f, r_act,
                                    r_was, r_inc, r_cac, r_sp, r_dp, r_ke, r_s, r_met, dur[l], nph[l], eu, ev, ea,
                                    eu0, eun, evn, ean, Fw, z0, bb, ke, active, was_e, just, trial, thetas, inc_e,
                                    cac_e, sp_e, dp_e, penp, ecdu, Amat, rvec, en, orow, idx, Asmall, rsmall)
                        for j in range(P):
                            if W[(r_act + j) * LANES + l] > 0.5:
                                act_pair[j] += 1
                                n_act += 1
                        _lane_factors(W, l, S, P, r_ke, r_act, r_ff, r_fu, idx, Asmall)  # the set may have changed
                    nbad = 0
                    for l in range(LANES):
                        if live[l] and W[(r_s + S_BAD) * LANES + l] > 0.5:
                            nbad += 1
            elif nevt > 0:
                for l in range(LANES):
                    if live[l] and W[(r_s + S_EVT) * LANES + l] > 0.5:
                        for j in range(P):
                            if W[(r_act + j) * LANES + l] > 0.5:
                                act_pair[j] -= 1
                                n_act -= 1
                        it, uns, changed = _settle_lane(W, l, law, max_iter, S, N1, P, r_w, r_u0, r_f, r_act, r_ke,
                                                        r_cd, r_s, z0, bb, ke, active, trial, prev, seen, idx,
                                                        Asmall, rsmall, Fw)
                        if it > W[(r_s + S_MIT) * LANES + l]:
                            W[(r_s + S_MIT) * LANES + l] = it
                        W[(r_s + S_UNS) * LANES + l] += uns
                        for j in range(P):
                            if W[(r_act + j) * LANES + l] > 0.5:
                                act_pair[j] += 1
                                n_act += 1
                        if changed:
                            _lane_factors(W, l, S, P, r_ke, r_act, r_ff, r_fu, idx, Asmall)
            if event:
                pass  # finished above
            elif had_contact or n_act > 0:
                for j in range(P):
                    pon_now[j] = 1 if act_pair[j] > 0 else 0
                    pon_any[j] = 1 if (pon_start[j] > 0 or act_pair[j] > 0) else 0
                nbad, nend = _finish_contact(W, dt, step, nt, n1t, m, C, H, pon_now, pon_any)
            else:
                nbad = _finish_quiet(W, dt, step, nt, n1t, m, C)
                nend = 0
            if nend > 0:
                for l in range(LANES):
                    for j in range(P):
                        if W[(r_end + j) * LANES + l] > 0.5:
                            W[(r_end + j) * LANES + l] = 0.0
                            if live[l]:
                                _end_phase(dur, nph, l, j, W[(r_cac + j) * LANES + l])
            if nbad > 0:
                for l in range(LANES):
                    if live[l] and W[(r_s + S_BAD) * LANES + l] > 0.5:
                        redo[lane_run[l]] = 1
                        for j in range(P):
                            if W[(r_act + j) * LANES + l] > 0.5:
                                act_pair[j] -= 1
                                n_act -= 1
                        _park(W, l, N, P, nrows, r_u, r_v, r_a, r_f, r_fu, r_s)
                        live[l] = False
            if step == next_end:
                next_end = max_nst + 1
                for l in range(LANES):
                    if live[l] and lane_nst[l] == step:
                        _finalize_lane(W, l, metrics[lane_run[l]], lane_status[l], step, dt, m, K, N, N1, P, dur,
                                       nph, r_u, r_v, r_act, r_inc, r_cac, r_s, r_met)
                        for j in range(P):
                            if W[(r_act + j) * LANES + l] > 0.5:
                                act_pair[j] -= 1
                                n_act -= 1
                        _park(W, l, N, P, nrows, r_u, r_v, r_a, r_f, r_fu, r_s)
                        live[l] = False
                    elif live[l] and lane_nst[l] < next_end:
                        next_end = lane_nst[l]
