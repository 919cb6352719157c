"""The scalar and Hertz-type kernels' compiled variants: without scoring (no scoring code compiled) and with it
(engine/scalar.py _batch_kernel, engine/nonlinear.py _nonlinear_kernel); the scalar kernel's, for each scheme, with
only that scheme's time loop (engine/scalar.py _time_loop_for)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from conftest import SWEEPS
from numba.core import ir
from numba.core.analysis import dead_branch_prune
from numba.core.compiler import run_frontend

from pounding_sweep.codes import SCHEME_EVENT, SCHEME_IMPLICIT, SCHEME_PAPER, SCHEMES
from pounding_sweep.engine import nonlinear, scalar
from pounding_sweep.engine.driver import ScoreSpec, run_chunk
from pounding_sweep.scene import load_scene
from pounding_sweep.sweep.prepare import prepare


def _pruned_ir(dispatcher):
    """The compiled function's IR once Numba has pruned its constant branches (the untyped pipeline's
    dead_branch_prune: the closure constants `scored` and `scheme` decide the branches)."""
    func_ir = run_frontend(dispatcher.py_func)
    dead_branch_prune(func_ir, ())
    return [st for block in func_ir.blocks.values() for st in block.body if isinstance(st, ir.Assign)]


def _attributes_called(dispatcher) -> set[str]:
    """The module attributes the pruned IR reads."""
    return {
        st.value.attr for st in _pruned_ir(dispatcher) if isinstance(st.value, ir.Expr) and st.value.op == "getattr"
    }


def _globals_read(dispatcher) -> set[str]:
    """The module-level names the pruned IR reads."""
    return {st.value.name for st in _pruned_ir(dispatcher) if isinstance(st.value, ir.Global)}


@pytest.mark.parametrize(
    "variants",
    [scalar._VARIANTS[code] for code in sorted(SCHEMES.values())] + [nonlinear._VARIANTS],
    ids=[f"scalar-{name}" for name in sorted(SCHEMES, key=SCHEMES.get)] + ["nonlinear"],
)
def test_only_the_scored_variant_holds_the_scoring(variants):
    unscored, scored = variants
    assert "score_run" not in _attributes_called(unscored)
    assert "score_run" in _attributes_called(scored)
    assert "close_row" in _attributes_called(unscored)  # the rest of the run's end is in both


#: the scalar kernel's pieces each scheme's time loop calls, of those that belong to one scheme or two
SCHEME_PIECES = {
    SCHEME_EVENT: {"_contact_forces", "_contradicts", "_event_step"},
    SCHEME_IMPLICIT: {"_implicit_forces", "_event_step"},  # a step whose set cycles is taken as the event step
    SCHEME_PAPER: {"_paper_forces"},
}


@pytest.mark.parametrize("scheme", sorted(SCHEMES), ids=sorted(SCHEMES))
def test_each_scheme_compiles_only_its_own_loop(scheme):
    """A scene's scheme picks its entry, whose pruned IR calls that scheme's time loop only, and the loop holds
    that scheme's pieces only (the paper's scheme no event step: the largest piece)."""
    code = SCHEMES[scheme]
    pieces = set().union(*SCHEME_PIECES.values())
    loop = getattr(scalar, f"_time_loop_{scheme}")
    assert _globals_read(loop) & pieces == SCHEME_PIECES[code]
    for entry in scalar._VARIANTS[code]:
        assert {g for g in _globals_read(entry) if g.startswith("_time_loop")} == {f"_time_loop_{scheme}"}


def test_scoring_changes_no_metric():
    """A scored chunk and the same chunk unscored (the other variant) give the same metric rows bit for bit;
    only the scored one fills the scores."""
    scene = load_scene(SWEEPS / "scored_6hz.toml")
    scene = dataclasses.replace(scene, excitation=dataclasses.replace(scene.excitation, duration_s=0.5))
    prep = prepare(scene)
    assert prep.score.active
    params = prep.grid.chunk(0, 3)
    runs, rec, _derived = prep.kernel_inputs(params)
    args = (prep.sysarr, runs, rec, prep.hist, prep.opts, 1, 0)
    m1, _t1, _h1, s1 = run_chunk(*args, prep.score, "scalar")
    m0, _t0, _h0, s0 = run_chunk(*args, ScoreSpec.none(), "scalar")
    np.testing.assert_array_equal(m1, m0)
    assert np.isfinite(s1).any()
    assert s0 is None  # no scores without an experiment
