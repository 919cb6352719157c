"""The scalar and Hertz-type kernels' two compiled variants: without scoring (no scoring code compiled) and with
it (engine/scalar.py _batch_kernel, engine/nonlinear.py _nonlinear_kernel)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from conftest import SWEEPS
from numba.core import ir
from numba.core.analysis import dead_branch_prune
from numba.core.compiler import run_frontend

from pounding_sweep.engine import nonlinear, scalar
from pounding_sweep.engine.driver import ScoreSpec, run_chunk
from pounding_sweep.scene import load_scene
from pounding_sweep.sweep.prepare import prepare


def _attributes_called(dispatcher) -> set[str]:
    """The module attributes the compiled function's IR reads once Numba has pruned its constant branches
    (the untyped pipeline's dead_branch_prune: the closure constant `scored` decides the branch)."""
    func_ir = run_frontend(dispatcher.py_func)
    dead_branch_prune(func_ir, ())
    return {
        st.value.attr
        for block in func_ir.blocks.values()
        for st in block.body
        if isinstance(st, ir.Assign) and isinstance(st.value, ir.Expr) and st.value.op == "getattr"
    }


@pytest.mark.parametrize("module", [scalar, nonlinear], ids=["scalar", "nonlinear"])
def test_only_the_scored_variant_holds_the_scoring(module):
    unscored, scored = module._VARIANTS
    assert "score_run" not in _attributes_called(unscored)
    assert "score_run" in _attributes_called(scored)
    assert "close_row" in _attributes_called(unscored)  # the rest of the run's end is in both


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
