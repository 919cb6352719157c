"""Numba's IR inliner without its quadratic copy: the same inlined code, a third less compile time.

A function decorated `inline="always"` (engine/jit.py `inline`) is inlined by Numba's untyped pass
InlineInlinables through `InlineWorker.inline_function`: the callee's IR is built afresh for this call site
(`run_untyped_passes`), then `inline_ir` deep-copies it block by block, each block with a memo of its own. A
block's statements refer to the function's Scope, which holds every variable of the function, so every block
copies every variable: blocks x variables per inlined call site, twice (numba/numba#8989 reports the copies).
The lane kernel inlines composite pieces (a piece made of inlined pieces) whose IR has hundreds of blocks and
thousands of variables: in numba 0.68 those copies were 15 s of its 47 s compile
(`python benchmarks/profile_compile.py --case 1`, pass `inline_inlinables`).

`install` makes `inline_function`'s copies share the callee's scope: a block is copied statement by statement
and keeps the Scope object it points at. The IR that results is the same statement for statement: inline_ir
then renames every callee variable into the caller's scope and points each copied block at the caller's
scope. The callee's own scope only gains the renamed names (inline_ir defines them there too), and that IR is
this call site's alone, built by run_untyped_passes just before and dropped after. Only the untyped path is
changed: typed_passes' InlineOverloads passes a cached IR to inline_ir directly and keeps Numba's copy.
Where Numba's layout is not the one this relies on, nothing is installed (the compile is then only slower).
"""

from __future__ import annotations

import copy
import functools

from numba.core import ir
from numba.core.inline_closurecall import InlineWorker


def _copy_sharing_scope(block, memo):
    """A deep copy of an ir.Block whose statements keep pointing at the block's Scope (not a copy of it)."""
    memo.setdefault(id(block.scope), block.scope)
    new = ir.Block.__new__(ir.Block)
    memo[id(block)] = new
    for name, value in vars(block).items():
        setattr(new, name, copy.deepcopy(value, memo))
    return new


def _layout_known() -> bool:
    """Numba's inliner as this module expects it: ir.Block without a deep copy of its own, and the worker's
    inline_function built from run_untyped_passes and inline_ir."""
    return (
        "__deepcopy__" not in vars(ir.Block)
        and all(hasattr(InlineWorker, name) for name in ("inline_function", "run_untyped_passes", "inline_ir"))
        and not getattr(InlineWorker.inline_function, "shares_callee_scope", False)
    )


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
        callee_ir = self.run_untyped_passes(function)  # this call site's own IR (nested inlining runs here)
        ir.Block.__deepcopy__ = _copy_sharing_scope  # only while inline_ir copies it
        try:
            return self.inline_ir(caller_ir, block, i, callee_ir, function.__code__.co_freevars, arg_typs=arg_typs)
        finally:
            del ir.Block.__deepcopy__

    inline_function.shares_callee_scope = True  # type: ignore[attr-defined]
    InlineWorker.inline_function = inline_function  # type: ignore[method-assign]
    return True
