"""A monotonic wall clock callable from compiled code without the GIL (each run's run_time_s).

libc's clock_gettime is declared to LLVM by name and called from an intrinsic: objmode would take the
GIL, and a ctypes function pointer would stop Numba from caching the kernels."""

from __future__ import annotations

import ctypes

from llvmlite import binding as llvm_binding
from llvmlite import ir
from numba.core import cgutils, types
from numba.extending import intrinsic

from pounding_sweep.engine.jit import njit_kernel

llvm_binding.add_symbol("clock_gettime", ctypes.cast(ctypes.CDLL(None).clock_gettime, ctypes.c_void_p).value)


@intrinsic
def _monotonic_ns(typingctx):
    """CLOCK_MONOTONIC in nanoseconds (int64)."""

    def codegen(context, builder, signature, args):
        i32, i64 = ir.IntType(32), ir.IntType(64)
        ts_type = ir.LiteralStructType([i64, i64])
        fn = cgutils.get_or_insert_function(
            builder.module, ir.FunctionType(i32, [i32, ts_type.as_pointer()]), "clock_gettime"
        )
        ts = cgutils.alloca_once(builder, ts_type)
        builder.call(fn, [ir.Constant(i32, 1), ts])
        sec = builder.load(cgutils.gep_inbounds(builder, ts, 0, 0))
        nsec = builder.load(cgutils.gep_inbounds(builder, ts, 0, 1))
        return builder.add(builder.mul(sec, ir.Constant(i64, 1_000_000_000)), nsec)

    return types.int64(), codegen


@njit_kernel
def _clock():
    """Monotonic wall clock [s]."""
    return _monotonic_ns() * 1e-9
