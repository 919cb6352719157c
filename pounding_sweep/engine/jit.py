"""Numba flags in one place. No fastmath anywhere: NaN/inf guards and bit-identical results
across executors depend on strict IEEE arithmetic."""

from __future__ import annotations

import numba

#: serial kernels: released GIL so a thread pool can run them side by side; cached on disk.
KERNEL_JIT = dict(nogil=True, cache=True, fastmath=False, error_model="numpy")


def njit_kernel(fn):
    """Decorate a serial numerical kernel with the project's flags."""
    return numba.njit(**KERNEL_JIT)(fn)
