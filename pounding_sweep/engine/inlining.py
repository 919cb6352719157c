"""Numba's IR inliner without its quadratic copy: the same inlined code, a third less compile time.

A function decorated `inline="always"` (engine/jit.py `inline`) is inlined by Numba's untyped pass
InlineInlinables through `InlineWorker.inline_function`: the callee's IR is built afresh for this call site
(`run_untyped_passes`), then `inline_ir` deep-copies it block by block, each block with a memo of its own. A
block's statements refer to the function's Scope, which holds every variable of the function, so every block
copies every variable: blocks x variables per inlined call site, twice (related to numba/numba#8989, which
reports the second copy). The lane kernel inlines composite pieces (a piece made of inlined pieces) whose IR
has hundreds of blocks and thousands of variables: in numba 0.68.1 those copies were most of the 20.9 s its
inline pass took of its 44.6 s compile (`python benchmarks/profile_compile.py --case 1`, pass
`inline_inlinables`; 3.7 s of 28.7 s after).

`install` makes `inline_function`'s copies share the callee's scope: a block is copied statement by statement
and keeps the Scope object it points at. The IR that results is the same statement for statement: inline_ir
then renames every callee variable into the caller's scope and points each copied block at the caller's
scope. The callee's own scope only gains the renamed names (inline_ir defines them there too), and that IR is
this call site's alone, built by run_untyped_passes just before and dropped after. Only the untyped path is
changed: a call with types (a typemap to update) and typed_passes' InlineOverloads, which pass a cached IR,
keep Numba's copy. The patch holds for the whole process (a user's own `inline="always"` functions compile
faster too, to the same code). It relies on how Numba's inliner is written, so it is installed only where the
three methods it relies on are the ones read for it (KNOWN_SOURCES); elsewhere nothing changes but the speed.
"""

from __future__ import annotations

import copy
import functools

from numba.core import ir
from numba.core.inline_closurecall import InlineWorker

from pounding_sweep.engine import numba_source

#: SHA-256 (16 hex digits) of the source of InlineWorker.inline_function, run_untyped_passes and inline_ir as
#: this module was written against (numba 0.68.1)
KNOWN_SOURCES = frozenset({"8d7eb51b681f9b24"})
#: the inliner's methods that digest covers
_METHODS = tuple((InlineWorker, name) for name in ("inline_function", "run_untyped_passes", "inline_ir"))


def _copy_sharing_scope(block, memo):
    """A deep copy of an ir.Block whose statements keep pointing at the block's Scope (not a copy of it)."""
    memo.setdefault(id(block.scope), block.scope)
    new = ir.Block.__new__(ir.Block)
    memo[id(block)] = new
    for name, value in vars(block).items():
        setattr(new, name, copy.deepcopy(value, memo))
    return new


def inliner_source_digest() -> str:
    """The digest KNOWN_SOURCES holds, of this Numba's inliner (its own methods, not the installed wrapper)."""
    return numba_source.digest(_METHODS)


def _layout_known() -> bool:
    """Numba's inliner as this module was written against: its source as read, ir.Block without a deep copy
    of its own."""
    return numba_source.known(_METHODS, KNOWN_SOURCES) and "__deepcopy__" not in vars(ir.Block)


def install() -> bool:
    """Replace InlineWorker.inline_function by one whose block copies share the fresh callee's scope; True
    when installed now or before."""
    if getattr(InlineWorker.inline_function, "shares_callee_scope", False):
        return True
    if not _layout_known():
        return False
    original = InlineWorker.inline_function

    @functools.wraps(original)
    def inline_function(self, caller_ir, block, i, function, arg_typs=None):
        if arg_typs is not None or self._permit_update_type_and_call_maps:
            return original(self, caller_ir, block, i, function, arg_typs)  # the typed path: Numba's own copy
        callee_ir = self.run_untyped_passes(function)  # this call site's own IR (nested inlining runs here)
        before = vars(ir.Block).get("__deepcopy__")
        ir.Block.__deepcopy__ = _copy_sharing_scope  # only while inline_ir copies it
        try:
            return self.inline_ir(caller_ir, block, i, callee_ir, function.__code__.co_freevars)
        finally:
            if before is None:
                del ir.Block.__deepcopy__
            else:
                ir.Block.__deepcopy__ = before

    inline_function.shares_callee_scope = True  # type: ignore[attr-defined]
    InlineWorker.inline_function = inline_function  # type: ignore[method-assign]
    return True
