"""engine/inlining.py: Numba's IR inliner with shared callee scopes gives the same code as Numba's own."""

from __future__ import annotations

import copy
import re

import numba
import numpy as np
import pytest
from numba.core import ir
from numba.core.compiler import run_frontend
from numba.core.inline_closurecall import InlineWorker

from pounding_sweep.engine import inlining
from pounding_sweep.engine.jit import inline

installed = pytest.mark.skipif(
    not getattr(InlineWorker.inline_function, "shares_callee_scope", False),
    reason=f"this Numba's inliner (source digest {inlining.inliner_source_digest()}) is not the one "
    "engine/inlining.py was written against (KNOWN_SOURCES): nothing installed, the kernels compile more slowly "
    "to the same code; read the new inliner and add its digest if the module's reasoning still holds",
)


@inline
def _piece(x, n):
    """Several blocks (a loop and a branch): the case whose copy was quadratic."""
    s = 0.0
    for k in range(n):
        if x[k] > 0.0:
            s += x[k]
        else:
            s -= 0.5 * x[k]
    return s


@inline
def _composite(x, n):
    """A piece made of inlined pieces, as the lane kernel's are."""
    return _piece(x, n) - 2.0 * _piece(x, n - 2)


def _caller(x, n):
    a = _composite(x, n)
    b = _piece(x, n - 1)
    return a * b


def _llvm(inline_function) -> tuple[float, str]:
    """The caller's optimised LLVM IR, compiled afresh with this InlineWorker.inline_function, with what
    differs between two compiles of the same code taken out: function ids in names (v12) and in the lengths
    of the string constants holding them, block labels (B42, from a process-wide counter) and the aligned
    comments after them."""
    saved = InlineWorker.inline_function
    InlineWorker.inline_function = inline_function
    try:
        f = numba.njit(_caller)
        x = np.linspace(-1.0, 2.0, 9)
        value = f(x, 9)
        text = f.inspect_llvm(f.signatures[0])
    finally:
        InlineWorker.inline_function = saved
    text = re.sub(r"\s*;.*", "", text)
    text = re.sub(r"B\d+|v\d+", "#", text)
    # a string constant's length holds the name's id: v9 and v10 make [138 x i8] and [139 x i8]
    return value, re.sub(r"\[\d+ x i8\]", "[# x i8]", text)


@installed
def test_inlined_code_is_numbas():
    """The kernel of a caller inlining a composite piece and a piece is the same LLVM IR, instruction for
    instruction, with the shared-scope copies as with Numba's own inliner; the result the same bit for bit."""
    ours = InlineWorker.inline_function
    value, text = _llvm(ours)
    value0, text0 = _llvm(ours.__wrapped__)
    assert value == value0
    assert text == text0
    assert "_composite_" in text  # the composite piece's variables live in the caller: it was inlined
    assert not re.search(r"call [^\n]*@\S*_(piece|composite)", text)  # and no piece is left as a call


def test_copy_shares_only_the_scope():
    """A block's copy holds new statements (a mutation of the copy leaves the original alone) pointing at
    the original Scope, not a copy of it."""
    block = next(iter(run_frontend(_caller).blocks.values()))
    before = [str(s) for s in block.body]
    new = inlining._copy_sharing_scope(block, {})
    assert new.scope is block.scope
    assert [str(s) for s in new.body] == before
    assert all(a is not b for a, b in zip(new.body, block.body, strict=True))
    new.body.pop()
    assert [str(s) for s in block.body] == before


@installed
def test_numbas_copy_outside_the_inliner():
    """The shared-scope copy is active only while inline_function copies: a Block deep-copied elsewhere
    (after a compile that inlined) copies its scope, as Numba does."""
    numba.njit(_caller)(np.ones(4), 4)
    assert "__deepcopy__" not in vars(ir.Block)
    block = next(iter(run_frontend(_caller).blocks.values()))
    assert copy.deepcopy(block).scope is not block.scope
    assert inlining.install()  # installing again changes nothing
    assert inlining.inliner_source_digest() in inlining.KNOWN_SOURCES
    assert InlineWorker.inline_function.__wrapped__.__module__ == "numba.core.inline_closurecall"
