"""The scalar kernels' LLVM optimisation once per kernel, not once per level of calls: a shorter compile.

Numba compiles every function into a library of its own and finalises it at once: it links in the modules of
the functions it calls, runs LLVM's full module pipeline (O3) over the whole and emits machine code
(numba/core/codegen.py CPUCodeLibrary.finalize). A caller then links that optimised module into its own and
optimises everything again, so code called from deep inside a kernel (the event step's pieces, four levels
down) is optimised once per level.

The scalar kernels' pieces that only compiled code calls (engine/jit.py njit_inner, njit_piece and njit_generic: the
time loop, the event step, the scoring's functions and their helpers, without a Python or C entry) never run from
their own library: only a caller's copy of their code runs, and that caller (in the end a kernel's entry, called
from Python) optimises the whole module, their code included, with the same pipeline. Those decorators register
their functions here (`optimised_by_callers`), and `install` makes a registered function's library skip its own
module pipeline and its machine code; it still runs Numba's function passes (the cleanup before linking), and the
disk cache keeps its module for the next caller to link. Not registered: the lane kernel's own pieces
(jit.njit_step, jit.njit_generic_lanes), of which LLVM makes faster code in two passes (optimised once, its event
case took 1.18x as long and its quiet loop 1.14x). Nor a piece in a recursion Numba resolves at run time (its own
code is jumped to), nor anything else: a user's own Numba functions, Numba's overloads and @cfunc callbacks keep
Numba's pipeline.

The other way round, a large piece with a module of its own that LLVM has already optimised (the lane kernel's
scalar step, `optimised_once`) would be optimised again in its caller's module, and its machine code made
again. Its caller (`install`'s finalize) optimises its own code with only the piece's declarations in its
module, then links the piece's optimised code in and makes the machine code of the whole: the kernel stays one
self-contained library (cached and loaded alone), and the piece is optimised once. The LLVM time of the lane
kernel's entry for a new pair of story counts, its step cached: 2.9-3.0 s against 4.8-5.9 s
(benchmarks/profile_compile.py --case 2 --after 1; docs/explanation/performance.md).

Arithmetic is the same either way: without fast-math flags LLVM may not reorder or fuse floating-point
operations, so where the optimiser inlines, unrolls or vectorises differently the results stay bit-identical
(benchmarks/check_identity.py: every table); only where Numba finds Intel's SVML could a loop vectorised in one
build and not the other call a vector math function that differs from libm's in the last bit. The module relies
on how Numba builds, finalises, caches and links a library, so it is installed only where the methods read for
it (METHODS) are unchanged (KNOWN_SOURCES); elsewhere nothing changes but the compile time. Figures:
docs/explanation/performance.md.
"""

from __future__ import annotations

import functools

from llvmlite import binding as ll
from numba.core import codegen, itanium_mangler, typed_passes

from pounding_sweep.engine import numba_source

#: the Numba methods this module relies on: where a library is made and marked, the libraries it links
#: (finalised when added), how it is finalised and optimised, the module its callers link (a _shared_module set
#: beforehand is used as it is), how a library is cached and loaded, and the run-time resolution of recursive
#: calls
METHODS = (
    (typed_passes.BaseNativeLowering, "run_pass"),
    (codegen.CPUCodeLibrary, "__init__"),
    (codegen.CPUCodeLibrary, "add_linking_library"),
    (codegen.CPUCodeLibrary, "finalize"),
    (codegen.CPUCodeLibrary, "_optimize_final_module"),
    (codegen.CPUCodeLibrary, "_get_module_for_linking"),
    (codegen.CPUCodeLibrary, "_finalize_final_module"),
    (codegen.CPUCodeLibrary, "serialize_using_object_code"),
    (codegen.CPUCodeLibrary, "_unserialize"),
    (codegen.RuntimeLinker, "scan_unresolved_symbols"),
    (codegen.RuntimeLinker, "resolve"),
)
#: SHA-256 (16 hex digits) of the source of METHODS as this module was written against (numba 0.68.1)
KNOWN_SOURCES = frozenset({"a3d15ed0ade4cf2c"})
#: the attribute that marks a library whose code only its callers' libraries optimise
MARK = "_optimised_by_callers"
#: the Python functions whose compiled code only their callers' libraries optimise (optimised_by_callers)
_REGISTERED: set = set()
#: the pieces optimised once, in their own module (optimised_once): their qualified name -> their symbols' prefixes
_ONCE: dict[str, set[str]] = {}
_ONCE_FUNCTIONS: set = set()
#: the attribute of a caller's library that holds the optimised modules it links after its own optimisation
_AFTER = "_linked_after_optimisation"


def source_digest() -> str:
    """The digest KNOWN_SOURCES holds, of this Numba's METHODS (their own source, not the installed wrappers)."""
    return numba_source.digest(METHODS)


def optimised_by_callers(fn):
    """Register fn, a function compiled without a Python or C entry, as one whose code its callers optimise."""
    if fn in _ONCE_FUNCTIONS:
        raise ValueError(f"{fn.__qualname__} is registered optimised_once: it cannot be optimised_by_callers too")
    _REGISTERED.add(fn)
    return fn


def optimised_once(fn):
    """Register fn, a piece compiled without a Python or C entry whose own module LLVM optimises: its callers
    link its optimised code after optimising their own, not before (it is not optimised a second time)."""
    ident = f"{fn.__module__}.{fn.__qualname__}"
    if fn in _REGISTERED:  # its own module is not optimised: linked after its callers', it would stay so
        raise ValueError(f"{ident} is registered optimised_by_callers: it cannot be optimised_once too")
    prefix = "_Z" + itanium_mangler.mangle_identifier(ident)[:-1]  # Numba's symbol for fn, up to its tags
    _ONCE.setdefault(fn.__qualname__, set()).add(prefix)
    _ONCE_FUNCTIONS.add(fn)
    return fn


def _once_module(library):
    """The module a caller links of this library, if the library is an optimised_once piece's, else None."""
    prefixes = _ONCE.get(library.name)
    if not prefixes:
        return None
    module = library._get_module_for_linking()
    for fn in module.functions:
        if fn.is_declaration:
            continue
        for prefix in prefixes:  # the symbol, then its ABI tags (B...) or its end (E)
            if fn.name.startswith(prefix) and fn.name[len(prefix) : len(prefix) + 1] in ("B", "E"):
                return module
    return None


def _declarations(module):
    """A module that declares the functions `module` defines for its callers (no code, no other globals)."""
    lines = [f'target triple = "{module.triple}"', f'target datalayout = "{module.data_layout}"']
    for fn in module.functions:
        if fn.is_declaration or fn.linkage not in (ll.Linkage.linkonce_odr, ll.Linkage.external):
            continue
        fty = str(fn.global_value_type)  # e.g. "i32 (ptr, ptr, i64)"
        ret, params = fty.split(" (", 1)
        lines.append(f'declare {ret} @"{fn.name}"({params}')
    return ll.parse_assembly("\n".join(lines) + "\n")


def _link_after(library) -> None:
    """Link into the caller's (optimised) module the optimised modules of its optimised_once pieces."""
    for module in getattr(library, _AFTER, ()):
        library._final_module.link_in(module, preserve=True)


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


def _in_recursion(library) -> bool:
    """Whether the library takes part in a recursion Numba resolves at run time (numba/core/codegen.py
    RuntimeLinker): it calls a function not yet defined through a `.numba.unresolved$` pointer, or defines one
    that such a pointer waits for. Then the JIT jumps to this library's own machine code, so it keeps Numba's
    pipeline (no engine piece recurses; a mutual recursion of two marked pieces crashed without this)."""
    prefix = codegen.RuntimeLinker.PREFIX
    if any(gv.name.startswith(prefix) for gv in library._final_module.global_variables):
        return True
    waiting = library.codegen._rtlinker._unresolved
    return any(fn.name in waiting for fn in library._final_module.functions if not fn.is_declaration)


def _known() -> bool:
    """Whether this Numba's METHODS are the ones this module was written against."""
    return numba_source.known(METHODS, KNOWN_SOURCES)


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
    finalize = codegen.CPUCodeLibrary.finalize

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
        if getattr(self, MARK, False) and not _in_recursion(self):
            _link_after(self)
            _for_linking_only(self)  # its callers' libraries optimise this code with theirs
            return None
        out = optimize(self)
        _link_after(self)
        return out

    @functools.wraps(finalize)
    def finalize_library(self):
        once = {}  # library -> (its module, the declarations this library links before its optimisation)
        for lib in dict.fromkeys(self._linking_libraries):
            module = _once_module(lib)
            if module is None:
                continue
            try:
                once[lib] = (module, _declarations(module))
            except Exception:  # noqa: BLE001 (a type the declarations cannot name: link it as Numba does)
                continue
        if not once:
            return finalize(self)
        # finalize links each library's _shared_module: the declarations while this one is optimised
        setattr(self, _AFTER, [module for module, _ in once.values()])
        try:
            for lib, (_, declared) in once.items():
                lib._shared_module = declared
            return finalize(self)
        finally:
            for lib, (module, _) in once.items():
                lib._shared_module = module
            setattr(self, _AFTER, ())

    marking_run_pass.marks_libraries = True  # type: ignore[attr-defined]
    lowering.run_pass = marking_run_pass  # type: ignore[method-assign]
    codegen.CPUCodeLibrary._optimize_final_module = optimize_final_module  # type: ignore[method-assign]
    codegen.CPUCodeLibrary.finalize = finalize_library  # type: ignore[method-assign]
    return True
