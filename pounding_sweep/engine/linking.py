"""The kernels' LLVM optimisation once per kernel, not once per level of calls: the same code, a shorter compile.

Numba compiles every function into a library of its own and finalises it at once: it links in the modules of
the functions it calls, runs LLVM's full module pipeline (O3) over the whole and emits machine code
(numba/core/codegen.py CPUCodeLibrary.finalize). A caller then links that optimised module into its own and
optimises everything again, so code called from deep inside a kernel (the event step's pieces, four levels
down) is optimised once per level. The scalar kernels' pieces that only compiled code calls (engine/jit.py
njit_inner and njit_generic, the time loop and the event step: no Python or C entry) never run from their own
library: only a caller's copy of their code runs, and that caller (in the end a kernel's entry, called from
Python) optimises the whole module, their code included, with the same pipeline. Those decorators register
their functions here (`optimised_by_callers`), and `install` makes a registered function's library skip its
own module pipeline and its machine code; it still runs Numba's function passes (the cleanup before
linking), and the disk cache keeps its module for the next caller to link. Not registered: the lane kernel's
own pieces (jit.njit_step), of which LLVM makes faster code in two passes (optimised once, its event case
took 1.18x as long and its quiet loop 1.14x).
Arithmetic is the same either way: without fast-math flags LLVM may not reorder or fuse floating-point
operations, so where the optimiser inlines, unrolls or vectorises differently the results are bit-identical
(benchmarks/check_identity.py). Only registered functions are touched: a user's own Numba functions, Numba's
overloads and @cfunc callbacks keep Numba's pipeline. It relies on how Numba builds and finalises a library,
so it is installed only where the methods read for it are unchanged (KNOWN_SOURCES); elsewhere nothing changes
but the compile time. Figures: docs/explanation/performance.md.
"""

from __future__ import annotations

import functools
import hashlib
import inspect

from llvmlite import binding as ll
from numba.core import codegen, typed_passes

#: SHA-256 (16 hex digits) of the source of BaseNativeLowering.run_pass, CPUCodeLibrary.finalize and
#: CPUCodeLibrary._optimize_final_module as this module was written against (numba 0.68.1)
KNOWN_SOURCES = frozenset({"d781a62cdbc44676"})
#: the attribute that marks a library whose code only its callers' libraries optimise
MARK = "_optimised_by_callers"
#: the Python functions whose compiled code only their callers' libraries optimise (optimised_by_callers)
_REGISTERED: set = set()


def source_digest() -> str:
    """The digest KNOWN_SOURCES holds, of this Numba's methods (their own source, not the installed wrappers)."""
    h = hashlib.sha256()
    for owner, name in (
        (typed_passes.BaseNativeLowering, "run_pass"),
        (codegen.CPUCodeLibrary, "finalize"),
        (codegen.CPUCodeLibrary, "_optimize_final_module"),
    ):
        h.update(inspect.getsource(inspect.unwrap(getattr(owner, name))).encode())
    return h.hexdigest()[:16]


def optimised_by_callers(fn):
    """Register fn, a function compiled without a Python or C entry, as one whose code its callers optimise."""
    _REGISTERED.add(fn)
    return fn


def _marked(state) -> bool:
    """Whether the function being lowered is registered, and has neither a Python nor a C entry to run from."""
    flags = state.flags
    return bool(flags.no_cpython_wrapper and flags.no_cfunc_wrapper and state.func_id.func in _REGISTERED)


def _for_linking_only(library) -> None:
    """Keep a marked library's module for its callers to link (its definitions linkonce_odr, as Numba's
    _get_module_for_linking makes them), and make its own definitions available_externally: LLVM emits no
    machine code for those, and nothing would run it. Emitted, it slowed the kernels compiled in the same
    process: the scalar kernel's event case took 0.86 s a call in the process that compiled it, against 0.22 s
    for the same object code loaded from the disk cache into a fresh process (and 0.63 s for that object
    reloaded into the compiling process), whether this code was left linkonce_odr (where Numba's JIT may bind
    a caller's call to it) or made internal. Without it, 0.23 s in both."""
    shared = library._final_module.clone()
    for fn in shared.functions:
        if not fn.is_declaration and fn.linkage == ll.Linkage.external:
            fn.linkage = "linkonce_odr"
    library._shared_module = shared
    for fn in library._final_module.functions:
        if not fn.is_declaration:
            fn.linkage = "available_externally"


def _known() -> bool:
    try:
        return source_digest() in KNOWN_SOURCES
    except (OSError, TypeError, AttributeError):  # no source to read: not the Numba this was written for
        return False


def install() -> bool:
    """Mark the libraries of the registered functions, and skip their own module pipeline; True when installed
    now or before."""
    lowering = typed_passes.BaseNativeLowering
    if getattr(lowering.run_pass, "marks_libraries", False):
        return True
    if not _known():
        return False
    run_pass = lowering.run_pass
    optimize = codegen.CPUCodeLibrary._optimize_final_module

    @functools.wraps(run_pass)
    def marking_run_pass(self, state):
        if state.library is None and _marked(state):
            # the library Numba would create here (run_pass's first lines), marked before lowering finalises it
            state.library = state.targetctx.codegen().create_library(state.func_id.func_qualname)
            state.library.enable_object_caching()
            setattr(state.library, MARK, True)
        return run_pass(self, state)

    @functools.wraps(optimize)
    def optimize_final_module(self):
        if getattr(self, MARK, False):
            _for_linking_only(self)  # its callers' libraries optimise this code with theirs
            return None
        return optimize(self)

    marking_run_pass.marks_libraries = True  # type: ignore[attr-defined]
    lowering.run_pass = marking_run_pass  # type: ignore[method-assign]
    codegen.CPUCodeLibrary._optimize_final_module = optimize_final_module  # type: ignore[method-assign]
    return True
