"""Explicit SIMD values for Numba kernels: a float64 vector of VW lanes and a lane mask.

F64Vec is LLVM's <VW x double>, MaskVec a <VW x i64> of all-ones / all-zeros lanes (what AVX compares
give). Arithmetic is LLVM's plain IEEE instruction lane by lane (no fast-math flags), and `vfma` is
llvm.fma (one rounding; a vfmadd instruction on FMA hardware). Writing the vectors out, rather than
relying on LLVM's loop vectoriser over scalar lane loops, keeps the kernel vectorised whatever the
vectoriser's heuristics decide: earlier versions of the lane kernel saw it leave whole loops scalar
after innocuous edits, and turn kept-or-updated values into masked stores, which are microcoded and
slow on AMD Zen.

VW, float64 lanes per value, follows the CPU Numba compiles for: 8 (one register) where it has AVX-512, 4 (one
AVX2 register) elsewhere. On a Zen 3 (AVX2) the lane kernel took 0.82-0.94 of the time with 4 lanes that it took
with 8, two registers per value, whose state does not fit the 16 registers (docs/explanation/performance.md).
A lane's arithmetic is the same instructions at either width, so the results are the same bit for bit
(benchmarks/check_identity.py).
"""

from __future__ import annotations

import operator

from llvmlite import ir
from numba import types
from numba.core import cgutils
from numba.core.imputils import lower_builtin
from numba.core.typing.templates import AbstractTemplate, infer_global, signature
from numba.extending import intrinsic, models, register_model


def target_width(features: str | None = None) -> int:
    """float64 lanes per vector value for a CPU feature string (LLVM's "+avx2,-avx512f,..."; default: the one
    Numba compiles for, as numba/core/codegen.py reads it: NUMBA_CPU_FEATURES, "" under NUMBA_CPU_NAME=generic,
    else the host's): 8 with AVX-512 (one register), else 4."""
    if features is None:
        from numba.core import config
        from numba.core.codegen import get_host_cpu_features

        features = config.CPU_FEATURES if config.CPU_FEATURES is not None else get_host_cpu_features()
    said = [f for f in features.split(",") if f in ("+avx512f", "-avx512f")]
    return 8 if said and said[-1] == "+avx512f" else 4  # LLVM takes a feature's last mention


#: float64 lanes per vector value (one register of the target: AVX-512 or AVX2)
VW = target_width()
_VT = ir.VectorType(ir.DoubleType(), VW)
_MT = ir.VectorType(ir.IntType(64), VW)
_I32 = ir.IntType(32)


class F64Vec(types.Type):
    def __init__(self):
        super().__init__(name=f"simd_f64x{VW}")


class MaskVec(types.Type):
    def __init__(self):
        super().__init__(name=f"simd_maskx{VW}")


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


def elem_ptr(context, builder, aryty, ary, idx):
    """IR: pointer to ary[idx] as a vector pointer (no bounds check)."""
    a = context.make_array(aryty)(context, builder, ary)
    return builder.bitcast(builder.gep(a.data, [idx], inbounds=True), _VT.as_pointer())


def _intrinsic_fn(builder, name, ret, args):
    return cgutils.get_or_insert_function(builder.module, ir.FunctionType(ret, args), name)


def splat(builder, x):
    """IR: the float64 x in every lane (insertelement + shufflevector: one broadcast)."""
    v = builder.insert_element(ir.Constant(_VT, ir.Undefined), x, ir.Constant(_I32, 0))
    return builder.shuffle_vector(v, v, ir.Constant(ir.VectorType(_I32, VW), [0] * VW))


def fence(builder, v):
    """IR: v through llvm.arithmetic.fence: no code, but LLVM no longer sees where the value came from.
    Used on the kept operand of a select that is stored back where it was loaded from: given
    store(select(c, x, load p), p), LLVM would otherwise emit a masked store (slow on AMD Zen)."""
    return builder.call(_intrinsic_fn(builder, f"llvm.arithmetic.fence.v{VW}f64", _VT, [_VT]), [v])


@intrinsic
def vload(typingctx, arr, idx):
    """arr[idx:idx + VW] as a vector (no bounds check)."""

    def codegen(context, builder, sig, args):
        return builder.load(elem_ptr(context, builder, sig.args[0], args[0], args[1]), align=8)

    return f64v(arr, idx), codegen


@intrinsic
def vstore(typingctx, arr, idx, v):
    """arr[idx:idx + VW] = v (no bounds check)."""

    def codegen(context, builder, sig, args):
        builder.store(args[2], elem_ptr(context, builder, sig.args[0], args[0], args[1]), align=8)
        return context.get_dummy_value()

    return types.none(arr, idx, v), codegen


@intrinsic
def vsplat(typingctx, x):
    """A vector with x in every lane."""

    def codegen(context, builder, sig, args):
        return splat(builder, args[0])

    return f64v(types.float64), codegen


@intrinsic
def vfma(typingctx, a, b, c):
    """a * b + c with one rounding (llvm.fma)."""

    def codegen(context, builder, sig, args):
        fn = _intrinsic_fn(builder, f"llvm.fma.v{VW}f64", _VT, [_VT, _VT, _VT])
        return builder.call(fn, list(args))

    return f64v(f64v, f64v, f64v), codegen


# Operators on vectors and masks: typed by templates and lowered straight to one LLVM instruction.
# (An @overload(..., inline="always") per operator made Numba inline IR at every use: most of the
# kernel's compile time went there.)


def _is_vec(t):
    return isinstance(t, F64Vec)


def _is_num(t):
    return isinstance(t, (types.Float, types.Integer))


def _as_vec(context, builder, ty, val):
    """A vector operand: the vector itself, or a scalar cast to float64 and splatted."""
    if _is_vec(ty):
        return val
    return splat(builder, context.cast(builder, val, ty, types.float64))


def _binary(op, build, restype):
    @infer_global(op)
    class _Typer(AbstractTemplate):
        def generic(self, args, kws):
            if (
                len(args) == 2
                and not kws
                and any(_is_vec(a) for a in args)
                and all(_is_vec(a) or _is_num(a) for a in args)
            ):
                return signature(restype, *args)

    def lower(context, builder, sig, args):
        a = _as_vec(context, builder, sig.args[0], args[0])
        b = _as_vec(context, builder, sig.args[1], args[1])
        return build(builder, a, b)

    for ta in (F64Vec, types.Number):
        for tb in (F64Vec, types.Number):
            if ta is F64Vec or tb is F64Vec:
                lower_builtin(op, ta, tb)(lower)


def _mask_binary(op, build):
    @infer_global(op)
    class _Typer(AbstractTemplate):
        def generic(self, args, kws):
            if len(args) == 2 and not kws and all(isinstance(a, MaskVec) for a in args):
                return signature(maskv, *args)

    lower_builtin(op, MaskVec, MaskVec)(lambda context, builder, sig, args: build(builder, args[0], args[1]))


def _unary(op, check, restype, build):
    @infer_global(op)
    class _Typer(AbstractTemplate):
        def generic(self, args, kws):
            if len(args) == 1 and not kws and check(args[0]):
                return signature(restype, *args)

    lower_builtin(op, F64Vec if restype is f64v else MaskVec)(
        lambda context, builder, sig, args: build(builder, args[0])
    )


_binary(operator.add, lambda b, x, y: b.fadd(x, y), f64v)
_binary(operator.sub, lambda b, x, y: b.fsub(x, y), f64v)
_binary(operator.mul, lambda b, x, y: b.fmul(x, y), f64v)
_binary(operator.truediv, lambda b, x, y: b.fdiv(x, y), f64v)


def _compare(op):
    """A lane mask of x op y, compared four lanes at a time: an 8-lane comparison gives an <8 x i1>,
    which AVX2 legalises through 16-bit lanes (a pack per comparison, an unpack per use)."""

    def build(b, x, y):
        if VW <= 4:
            return b.sext(b.fcmp_ordered(op, x, y), _MT)
        half = ir.VectorType(ir.IntType(64), 4)
        parts = []
        for lo in range(0, VW, 4):
            idx = ir.Constant(ir.VectorType(_I32, 4), list(range(lo, lo + 4)))
            xs = b.shuffle_vector(x, x, idx)
            ys = b.shuffle_vector(y, y, idx)
            parts.append(b.sext(b.fcmp_ordered(op, xs, ys), half))
        while len(parts) > 1:
            a, c = parts[0], parts[1]
            n = a.type.count + c.type.count
            parts = [b.shuffle_vector(a, c, ir.Constant(ir.VectorType(_I32, n), list(range(n))))] + parts[2:]
        return parts[0]

    return build


_binary(operator.gt, _compare(">"), maskv)
_binary(operator.lt, _compare("<"), maskv)
_binary(operator.ge, _compare(">="), maskv)
_mask_binary(operator.and_, lambda b, x, y: b.and_(x, y))
_mask_binary(operator.or_, lambda b, x, y: b.or_(x, y))
_mask_binary(operator.ne, lambda b, x, y: b.xor(x, y))
_unary(operator.neg, _is_vec, f64v, lambda b, x: b.fneg(x))
_unary(abs, _is_vec, f64v, lambda b, x: b.call(_intrinsic_fn(b, f"llvm.fabs.v{VW}f64", _VT, [_VT]), [x]))
_unary(operator.invert, lambda t: isinstance(t, MaskVec), maskv, lambda b, x: b.xor(x, ir.Constant(_MT, [-1] * VW)))


@intrinsic
def mconst(typingctx, value):
    """Every lane true (value True) or false."""

    def codegen(context, builder, sig, args):
        return builder.select(args[0], ir.Constant(_MT, [-1] * VW), ir.Constant(_MT, [0] * VW))

    return maskv(types.boolean), codegen


def _truth(builder, m):
    return builder.icmp_signed("<", m, ir.Constant(_MT, [0] * VW))


def select_bits(builder, m, a, b):
    """a where the 64-bit lane mask m is set (all ones), b where it is clear (for intrinsics that
    build their own selects)."""
    return builder.select(_truth(builder, m), a, b)


@intrinsic
def vsel(typingctx, m, a, b):
    """a where m, else b (lane by lane)."""

    def codegen(context, builder, sig, args):
        return select_bits(builder, args[0], args[1], args[2])

    return f64v(m, a, b), codegen


@intrinsic
def many(typingctx, m):
    """True when any lane of the mask is true: an OR reduction of the lanes (vpor and vptest; a
    bitcast of the lanes' truth to an integer made LLVM pack the two AVX2 halves first)."""

    def codegen(context, builder, sig, args):
        fn = _intrinsic_fn(builder, f"llvm.vector.reduce.or.v{VW}i64", ir.IntType(64), [_MT])
        return builder.icmp_unsigned("!=", builder.call(fn, [args[0]]), ir.Constant(ir.IntType(64), 0))

    return types.boolean(m), codegen


@intrinsic
def mcount(typingctx, m):
    """Number of true lanes (each true lane is -1: minus the sum of the lanes)."""

    def codegen(context, builder, sig, args):
        fn = _intrinsic_fn(builder, f"llvm.vector.reduce.add.v{VW}i64", ir.IntType(64), [_MT])
        return builder.neg(builder.call(fn, [args[0]]))

    return types.int64(m), codegen


@intrinsic
def mfloat(typingctx, m):
    """1.0 where m, else 0.0 (the bits of 1.0 kept where the mask is set)."""

    def codegen(context, builder, sig, args):
        one = ir.Constant(_MT, [0x3FF0000000000000] * VW)
        return builder.bitcast(builder.and_(args[0], one), _VT)

    return f64v(m), codegen


#: vectors in a stack scratch buffer (see `scratch`)
SCRATCH = 160
vecptr = types.CPointer(f64v)


@intrinsic
def scratch(typingctx):
    """A function-local buffer of SCRATCH vectors (an alloca in the entry block, not zero-filled: every
    entry is written before it is read). The loops over modes do not fully unroll, so it stays on
    the stack, in L1 with store-to-load forwarding; forcing full unrolling (LLVM -unroll-threshold=2000)
    let SROA promote it to registers but measured 4-9 % slower (more spills) on this Zen 1."""

    def codegen(context, builder, sig, args):
        # not cgutils.alloca_once: it zero-fills the buffer (a memset of the whole buffer at every call)
        with builder.goto_entry_block():
            arr = builder.alloca(ir.ArrayType(_VT, SCRATCH))
        return builder.bitcast(arr, _VT.as_pointer())

    return vecptr(), codegen


@intrinsic
def sget(typingctx, T, i):
    """Entry i of a scratch buffer."""

    def codegen(context, builder, sig, args):
        idx = context.cast(builder, args[1], sig.args[1], types.intp)
        return builder.load(builder.gep(args[0], [idx], inbounds=True))

    return f64v(T, i), codegen


@intrinsic
def sset(typingctx, T, i, v):
    """Entry i of a scratch buffer := v."""

    def codegen(context, builder, sig, args):
        idx = context.cast(builder, args[1], sig.args[1], types.intp)
        builder.store(args[2], builder.gep(args[0], [idx], inbounds=True))
        return context.get_dummy_value()

    return types.none(T, i, v), codegen
