"""engine/linking.py: the engine's registered pieces (no entry) skip their own LLVM module pipeline, their
callers run it over their code, and nothing else changes."""

from __future__ import annotations

import os
import subprocess
import sys

import numba
import numpy as np
import pytest
from llvmlite import binding as ll
from numba.core import typed_passes

from pounding_sweep.engine import linking
from pounding_sweep.engine.bookkeeping import median_inplace

installed = pytest.mark.skipif(
    not getattr(typed_passes.BaseNativeLowering.run_pass, "marks_libraries", False),
    reason=f"this Numba's lowering and code library (source digest {linking.source_digest()}) are not the ones "
    "engine/linking.py was written against (KNOWN_SOURCES): nothing installed, the kernels compile more slowly "
    "to the same code; read the new methods and add their digest if the module's reasoning still holds",
)

FULL = "Module passes (full optimization)"  # Numba's name for the module pipeline's timing record


def _pipelines(library) -> list[str]:
    return [r.name for r in library.recorded_timings]


def _fresh(flags: dict):
    """median_inplace's Python function (registered by jit.njit_inner) compiled afresh, without the disk cache."""
    return numba.njit(cache=False, _nrt=False, **flags)(median_inplace.py_func)


@installed
def test_piece_without_entry_is_optimised_only_in_its_caller(monkeypatch):
    monkeypatch.setattr(numba.config, "LLVM_PASS_TIMINGS", True)  # so each library records its pipelines
    piece = _fresh(dict(no_cpython_wrapper=True, no_cfunc_wrapper=True))

    @numba.njit(cache=False)
    def caller(x, k):
        return piece(x, k)

    x = np.array([4.0, -1.0, 2.5, 7.0, 0.5, 3.0])
    assert caller(x.copy(), 6) == np.median(x)  # (2.5 + 3.0) / 2: exact in binary, the same bit for bit
    (piece_cres,) = piece.overloads.values()
    (caller_cres,) = caller.overloads.values()
    assert getattr(piece_cres.library, linking.MARK, False)
    assert FULL not in _pipelines(piece_cres.library)  # its own module pipeline was skipped ...
    assert FULL in _pipelines(caller_cres.library)  # ... and its caller ran it, over the piece's code as well
    assert not getattr(caller_cres.library, linking.MARK, False)
    # no machine code of its own (nothing runs it, and loaded beside its callers it slowed them), and a module
    # whose definitions its next caller can link
    own = [fn.linkage for fn in piece_cres.library._final_module.functions if not fn.is_declaration]
    assert own and all(k == ll.Linkage.available_externally for k in own)
    shared = piece_cres.library._get_module_for_linking()
    assert {fn.linkage for fn in shared.functions if not fn.is_declaration} == {ll.Linkage.linkonce_odr}


@installed
def test_functions_with_an_entry_or_not_registered_keep_numbas_pipeline(monkeypatch):
    monkeypatch.setattr(numba.config, "LLVM_PASS_TIMINGS", True)
    with_entry = _fresh({})  # callable from Python: its own library's code runs, so it must be optimised
    x = np.array([2.0, 1.0, 3.0])
    assert with_entry(x.copy(), 3) == 2.0

    def outside(x):  # not registered: as a user's own function without entries
        return x[0] + 1.0

    outside_piece = numba.njit(cache=False, no_cpython_wrapper=True, no_cfunc_wrapper=True)(outside)

    @numba.njit(cache=False)
    def call_outside(x):
        return outside_piece(x)

    assert call_outside(x) == 3.0
    for dispatcher in (with_entry, outside_piece):
        (cres,) = dispatcher.overloads.values()
        assert not getattr(cres.library, linking.MARK, False)
        assert FULL in _pipelines(cres.library)


def test_registered_pieces():
    """The decorators say which pieces their callers optimise: the scalar kernels' time loop and event step,
    not the lane kernel's step or vector loops."""
    from pounding_sweep.engine import scalar
    from pounding_sweep.engine.lanes import lane_step, vector

    for loop in (scalar._time_loop_event, scalar._time_loop_implicit, scalar._time_loop_paper):
        assert loop.py_func in linking._REGISTERED
    assert scalar._event_step.py_func in linking._REGISTERED
    assert median_inplace.py_func in linking._REGISTERED
    assert lane_step.lane_step.py_func not in linking._REGISTERED
    assert lane_step._event_step.py_func not in linking._REGISTERED
    assert vector._quiet.py_func not in linking._REGISTERED
    assert "lane_step" in linking._ONCE  # optimised once, in its own module (its callers link it after theirs)
    assert "_quiet" not in linking._ONCE and "_time_loop" not in linking._ONCE


def test_a_piece_is_optimised_once_or_by_its_callers_not_both():
    """Registered both ways, a piece's unoptimised module would be linked after its callers' optimisation."""

    def both(x):
        return x

    linking.optimised_by_callers(both)
    with pytest.raises(ValueError, match="optimised_by_callers"):
        linking.optimised_once(both)
    linking._REGISTERED.discard(both)

    def other(x):
        return x

    linking.optimised_once(other)
    with pytest.raises(ValueError, match="optimised_once"):
        linking.optimised_by_callers(other)
    linking._ONCE.pop(other.__qualname__, None)
    linking._ONCE_FUNCTIONS.discard(other)


@installed
def test_an_optimised_once_piece_is_linked_after_its_callers_optimisation(monkeypatch):
    """A piece registered optimised_once keeps its own module pipeline; its caller optimises its own code with
    only the piece's declaration (so a piece this small is not inlined: the caller's optimiser never saw its
    body), then links the piece's optimised code into its module: the caller is one self-contained library."""
    monkeypatch.setattr(numba.config, "LLVM_PASS_TIMINGS", True)
    flags = dict(_nrt=False, no_cpython_wrapper=True, no_cfunc_wrapper=True, cache=False)

    @numba.njit(**flags)
    @linking.optimised_once
    def tiny(x):
        return 2.0 * x + 1.0

    @numba.njit(cache=False)
    def caller(x):
        return tiny(x) - 1.0

    assert caller(3.0) == 6.0  # small integers: exact in binary
    (piece_cres,) = tiny.overloads.values()
    (caller_cres,) = caller.overloads.values()
    assert FULL in _pipelines(piece_cres.library)  # optimised in its own module ...
    symbol = piece_cres.fndesc.mangled_name
    module = caller_cres.library._final_module
    assert not module.get_function(symbol).is_declaration  # ... its code in the caller's module ...
    caller_ir = str(module.get_function(caller_cres.fndesc.mangled_name))
    assert f'@"{symbol}"' in caller_ir or f"@{symbol}" in caller_ir  # ... and called, not inlined
    # a caller's own callers link its module as before (the piece's code with it)
    assert not caller_cres.library._get_module_for_linking().get_function(symbol).is_declaration


def test_installed_where_the_methods_are_known():
    """install() says whether the patch is in place; it is, exactly where the digest is known."""
    known = linking.source_digest() in linking.KNOWN_SOURCES
    assert linking.install() == known
    assert getattr(typed_passes.BaseNativeLowering.run_pass, "marks_libraries", False) == known


@installed
def test_mutual_recursion_of_pieces_keeps_numbas_pipeline():
    """Two registered pieces calling each other: Numba resolves the call at run time to a piece's own machine
    code, so those pieces keep it (with it skipped, the resolved address was 0 and the call crashed)."""
    flags = dict(_nrt=False, no_cpython_wrapper=True, no_cfunc_wrapper=True, cache=False)

    @numba.njit(**flags)
    @linking.optimised_by_callers
    def even(n):
        if n == 0:
            return 1
        return odd(n - 1)

    @numba.njit(**flags)
    @linking.optimised_by_callers
    def odd(n):
        if n == 0:
            return 0
        return even(n - 1)

    @numba.njit(cache=False)
    def caller(n):
        return even(n)

    assert (caller(10), caller(7)) == (1, 0)


TOY = """
import numba
from pounding_sweep.engine import linking, jit  # jit installs the patch

PIECE = dict(_nrt=False, no_cpython_wrapper=True, no_cfunc_wrapper=True, cache=True)


@numba.njit(**PIECE)
@linking.optimised_by_callers
def piece(x):
    s = 0.0
    for v in x:
        s += v * v
    return s


@numba.njit(cache=True)
def caller1(x):
    return piece(x) + 1.0


@numba.njit(cache=True)
def caller2(x):
    return 2.0 * piece(x)
"""

RUN = """
import sys
import numpy as np
import toy
x = np.arange(1.0, 6.0)
value = getattr(toy, sys.argv[1])(x)
print(value, toy.piece.stats.cache_hits.get(toy.piece.signatures[0], 0), toy.piece.stats.cache_misses.get(toy.piece.signatures[0], 0))
"""


@installed
def test_a_cached_piece_links_into_a_new_caller(tmp_path):
    """A piece compiled and cached with one caller (no machine code of its own) is loaded from the disk cache by
    a later process and linked into a caller compiled there: the new caller runs its own copy of the code."""
    (tmp_path / "toy.py").write_text(TOY)
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "cache"), PYTHONPATH=str(tmp_path))
    got = []
    for caller in ("caller1", "caller2"):
        r = subprocess.run([sys.executable, "-c", RUN, caller], env=env, cwd=tmp_path, capture_output=True, text=True)
        assert r.returncode == 0, r.stderr[-2000:]
        got.append(r.stdout.split())
    # 1 + 4 + 9 + 16 + 25 = 55: sums of small integers, exact in binary
    assert got[0] == ["56.0", "0", "1"]  # compiled in the first process ...
    assert got[1] == ["110.0", "1", "0"]  # ... loaded from the cache in the second, linked into caller2


#: the same piece, registered optimised_once
ONCE_TOY = TOY.replace("@linking.optimised_by_callers", "@linking.optimised_once")
assert ONCE_TOY != TOY

RUN_ONCE = """
import sys
import numpy as np
import toy
caller = getattr(toy, sys.argv[1])
value = caller(np.arange(1.0, 6.0))
sig = caller.signatures[0]
print(value, len(toy.piece.signatures), caller.stats.cache_hits.get(sig, 0), caller.stats.cache_misses.get(sig, 0))
"""


@installed
def test_a_cached_caller_of_an_optimised_once_piece_runs_alone(tmp_path):
    """The piece compiled with a first caller; a second caller compiled in a new process against the piece loaded
    from the disk cache (its library unserialised: the module to link from the cache); that second caller
    loaded from the cache by a third process that never loads the piece, and run: its cached code holds the
    piece's (a call to a symbol no library in that process defined crashed the process before the piece's code
    was linked into its callers)."""
    (tmp_path / "toy.py").write_text(ONCE_TOY)
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "cache"), PYTHONPATH=str(tmp_path))
    got = []
    for caller in ("caller1", "caller2", "caller2"):
        r = subprocess.run(
            [sys.executable, "-c", RUN_ONCE, caller], env=env, cwd=tmp_path, capture_output=True, text=True
        )
        assert r.returncode == 0, r.stderr[-2000:]
        got.append(r.stdout.split())
    # 1 + 4 + 9 + 16 + 25 = 55: sums of small integers, exact in binary
    assert got[0] == ["56.0", "1", "0", "1"]  # the piece and caller1 compiled in the first process
    assert got[1] == ["110.0", "1", "0", "1"]  # caller2 compiled in the second, the piece loaded from the cache
    assert got[2] == ["110.0", "0", "1", "0"]  # caller2 loaded in the third, the piece not even loaded
