"""The vector loops of one pair of floor counts, called by the group driver through their addresses
(engine/lanes/loops.py). That they compute what the lane kernel computed before is tests/engine/test_lanes.py's
(every grid there runs through them); here: how they are found and what a wrong call is refused."""

from __future__ import annotations

import numba
import numpy as np
import pytest

from pounding_sweep.engine.lanes import loops


def test_a_pair_s_loops_are_found_by_name_as_the_second_process_asks():
    """engine/aside.py imports a piece by module and name: quiet_loop_N_N1 and contact_loop_N_N1 are the pair's
    loops, made once per process; other names are not attributes."""
    quiet, contact = loops._wrappers(4, 2)
    assert loops.quiet_loop_4_2 is quiet
    assert loops.contact_loop_4_2 is contact is loops.contact_loop(4, 2)
    assert quiet.py_func.__qualname__ == "quiet_loop_4_2"  # no "." in it: aside.py skips such names
    assert loops._wrappers(4, 2) == (quiet, contact)
    for name in ("quiet_loop_4", "nearby_loop_4_2", "quiet_loop_x_2", "contact_loop_4_2_1"):
        with pytest.raises(AttributeError):
            getattr(loops, name)


def test_profiles_of_another_layout_are_refused_before_any_call():
    """The driver passes the profiles on as it got them and the loop is reached by its address, unchecked: a
    Fortran-ordered array would be read with the wrong strides, so floor_loops refuses it, naming both types."""
    prof = np.zeros((3, 2), order="F")
    with pytest.raises(TypeError, match="must be array\\(float64, 2d, C\\)"):
        loops.floor_loops(None, None, None, None, prof)


def test_a_call_with_other_argument_types_than_the_loops_were_compiled_for_does_not_compile():
    """The loop is reached by its address, so arguments of other types would be read wrongly: the call's typing
    refuses them, naming the types it was given and those the loops were compiled for."""

    @numba.njit
    def driver(W):
        return loops.call_quiet(0, W, 1, 2, 1e-4, 0, 0, W, W, W, True, 0, ((), 0))

    with pytest.raises(numba.core.errors.TypingError, match="calls the quiet loop with .* make them agree"):
        driver(np.zeros(8))
