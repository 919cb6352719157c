"""engine/simd.py's vector operators against NumPy, lane by lane: every arithmetic operator (vector with
vector, with a scalar on either side), fused multiply-add (one rounding: against the exactly rounded
a b + c from fractions), comparisons (ordered: NaN compares false), the mask operators and reductions,
select, splat and the scratch buffer. Equality is exact: each lane is one IEEE operation."""

from __future__ import annotations

from fractions import Fraction

import numba
import numpy as np
import pytest

from pounding_sweep.engine.simd import (
    VW,
    many,
    mconst,
    mcount,
    mfloat,
    scratch,
    sget,
    sset,
    vfma,
    vload,
    vsel,
    vsplat,
    vstore,
)

RNG = np.random.default_rng(5)
SPECIAL = np.array([0.0, -0.0, 1.0, -1.5, np.inf, -np.inf, np.nan, 5e-324, 1.7976931348623157e308, 3.0])


def lanes(n_vectors: int = 16) -> np.ndarray:
    """Random lanes with the special values mixed in, VW per vector."""
    x = RNG.normal(0.0, 10.0, n_vectors * VW) * 10.0 ** RNG.integers(-5, 5, n_vectors * VW)
    x[RNG.choice(x.size, SPECIAL.size, replace=False)] = SPECIAL
    return x


def same(a, b) -> bool:
    """Bit-for-bit equal, NaN equal to NaN."""
    return (
        np.array_equal(np.asarray(a).view(np.int64), np.asarray(b).view(np.int64))
        or np.array_equal(a, b, equal_nan=True)
        and np.array_equal(np.signbit(a), np.signbit(b))
    )


@numba.njit
def _binary(op, a, b, out):
    for i in range(0, a.size, VW):
        x, y = vload(a, i), vload(b, i)
        if op == 0:
            r = x + y
        elif op == 1:
            r = x - y
        elif op == 2:
            r = x * y
        else:
            r = x / y
        vstore(out, i, r)


@numba.njit
def _with_scalar(op, a, s, out, left):
    for i in range(0, a.size, VW):
        x = vload(a, i)
        if op == 0:
            r = s + x if left else x + s
        elif op == 1:
            r = s - x if left else x - s
        elif op == 2:
            r = s * x if left else x * s
        else:
            r = s / x if left else x / s
        vstore(out, i, r)


@numba.njit
def _unary(a, neg, absval):
    for i in range(0, a.size, VW):
        x = vload(a, i)
        vstore(neg, i, -x)
        vstore(absval, i, abs(x))


@numba.njit
def _fma(a, b, c, out):
    for i in range(0, a.size, VW):
        vstore(out, i, vfma(vload(a, i), vload(b, i), vload(c, i)))


@numba.njit
def _compare(op, a, b, out):
    for i in range(0, a.size, VW):
        x, y = vload(a, i), vload(b, i)
        if op == 0:
            m = x > y
        elif op == 1:
            m = x < y
        else:
            m = x >= y
        vstore(out, i, mfloat(m))


@numba.njit
def _masks(a, b, out_and, out_or, out_ne, out_not, any_out, count_out, sel):
    for i in range(0, a.size, VW):
        p, q = vload(a, i) > 0.0, vload(b, i) > 0.0
        vstore(out_and, i, mfloat(p & q))
        vstore(out_or, i, mfloat(p | q))
        vstore(out_ne, i, mfloat(p != q))
        vstore(out_not, i, mfloat(~p))
        any_out[i // VW] = many(p)
        count_out[i // VW] = mcount(p)
        vstore(sel, i, vsel(p, vload(a, i), vload(b, i)))


@numba.njit
def _constants(out_true, out_false, splat, x):
    vstore(out_true, 0, mfloat(mconst(True)))
    vstore(out_false, 0, mfloat(mconst(False)))
    vstore(splat, 0, vsplat(x))


@numba.njit
def _scratch(a, out):
    T = scratch()
    n = a.size // VW
    for k in range(n):
        sset(T, k, vload(a, k * VW))
    for k in range(n):
        vstore(out, k * VW, sget(T, n - 1 - k))


@pytest.mark.parametrize("op, f", [(0, np.add), (1, np.subtract), (2, np.multiply), (3, np.divide)])
def test_arithmetic_equals_numpy_lane_by_lane(op, f):
    a, b = lanes(), lanes()
    out = np.empty_like(a)
    _binary(op, a, b, out)
    with np.errstate(all="ignore"):
        assert same(out, f(a, b))
    for left in (False, True):
        s = 2.5
        _with_scalar(op, a, s, out, left)
        with np.errstate(all="ignore"):
            assert same(out, f(s, a) if left else f(a, s))


def test_negation_and_absolute_value():
    a = lanes()
    neg, ab = np.empty_like(a), np.empty_like(a)
    _unary(a, neg, ab)
    assert same(neg, -a) and same(ab, np.abs(a))


def test_fused_multiply_add_rounds_once():
    """vfma(a, b, c) is a b + c rounded once: the exact value from fractions, rounded to the nearest double
    (which differs from the twice-rounded a * b + c in some lanes: the test would see a plain multiply-add)."""
    a, b, c = (RNG.normal(size=64 * VW) for _ in range(3))
    out = np.empty_like(a)
    _fma(a, b, c, out)
    exact = np.array([float(Fraction(x) * Fraction(y) + Fraction(z)) for x, y, z in zip(a, b, c)])
    assert same(out, exact)
    assert not same(exact, a * b + c)  # the data do tell one rounding from two


@pytest.mark.parametrize("op, f", [(0, np.greater), (1, np.less), (2, np.greater_equal)])
def test_comparisons_are_ordered(op, f):
    a, b = lanes(), lanes()
    b[::7] = a[::7]  # ties
    out = np.empty_like(a)
    _compare(op, a, b, out)
    with np.errstate(invalid="ignore"):
        assert same(out, f(a, b).astype(float))


def test_mask_operators_reductions_and_select():
    a, b = lanes(), lanes()
    n = a.size // VW
    outs = [np.empty_like(a) for _ in range(4)]
    any_out, count_out, sel = np.zeros(n, np.bool_), np.zeros(n, np.int64), np.empty_like(a)
    _masks(a, b, *outs, any_out, count_out, sel)
    p, q = a > 0.0, b > 0.0
    assert same(outs[0], (p & q).astype(float)) and same(outs[1], (p | q).astype(float))
    assert same(outs[2], (p != q).astype(float)) and same(outs[3], (~p).astype(float))
    assert np.array_equal(any_out, p.reshape(n, VW).any(axis=1))
    assert np.array_equal(count_out, p.reshape(n, VW).sum(axis=1))
    assert same(sel, np.where(p, a, b))


def test_constants_splat_and_the_scratch_buffer():
    t, f, s = np.empty(VW), np.empty(VW), np.empty(VW)
    _constants(t, f, s, -3.25)
    assert same(t, np.ones(VW)) and same(f, np.zeros(VW)) and same(s, np.full(VW, -3.25))
    a = lanes(8)
    out = np.empty_like(a)
    _scratch(a, out)
    assert same(out, a.reshape(-1, VW)[::-1].ravel())


def test_the_width_follows_the_target():
    """8 lanes (one register) where the target has AVX-512, 4 (one AVX2 register) elsewhere, read from the feature
    string Numba compiles with; CI runs this file again for plain x86-64 (NUMBA_CPU_NAME=generic: 4 lanes), so both
    widths are tested on an AVX-512 machine."""
    from numba.core import config
    from numba.core.codegen import get_host_cpu_features

    from pounding_sweep.engine.simd import target_width

    assert target_width("+sse2,+avx,+avx2,+fma,-avx512f,-avx512fp16") == 4
    assert target_width("+avx2,+avx512f,+avx512dq") == 8
    assert target_width("") == 4  # NUMBA_CPU_NAME=generic: no features
    assert target_width("+avx512fp16,-avx512f") == 4  # a feature named like it is not it
    assert target_width("+avx512f,+avx2,-avx512f") == 4  # LLVM takes the last mention
    features = config.CPU_FEATURES if config.CPU_FEATURES is not None else get_host_cpu_features()
    assert VW == target_width(features)
