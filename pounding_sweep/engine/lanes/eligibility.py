"""Why the lane kernel cannot run a chunk, or the modal data it runs it with (plain Python; the kernel
registry, engine/registry.py, asks it)."""

from __future__ import annotations

import numpy as np

from pounding_sweep.codes import KELVIN_VOIGT_LAWS, SCHEME_EVENT, SCHEME_IMPLICIT
from pounding_sweep.engine.inputs import building_split
from pounding_sweep.engine.simd import SCRATCH
from pounding_sweep.model.modal import ModalArrays, modal_arrays

#: the contact laws the lane kernel integrates (the linear Kelvin-Voigt laws)
LAWS = KELVIN_VOIGT_LAWS


def lane_modes(sys, hist, opts, score, law: int) -> ModalArrays | str:
    """The modal data the lane kernel runs this chunk with, or why it cannot run it.

    The lane kernel computes metric rows only (no histories, no scoring against an experiment), for
    the event and implicit schemes and the linear contact laws (`law`, codes.LAW_*), for two shear frames
    facing floor by floor (pair j: floor j of building 1 and floor j of building 2, min(N1, N2) pairs)
    with classical damping in each.
    """
    if hist is not None and hist.active:
        return "histories requested"
    if score is not None and score.active:
        return "scoring against an experiment"
    if opts.scheme not in (SCHEME_IMPLICIT, SCHEME_EVENT):
        return "scheme is neither 'implicit' nor 'event'"
    if law not in LAWS:
        return "a Hertz-type contact law (engine/nonlinear.py)"
    if opts.scheme == SCHEME_IMPLICIT and opts.max_iter < 1:
        return "max_contact_iterations < 1"
    n = sys.m.size
    p = sys.i1.size
    if p < 1 or n < 2:
        return "no contact pair"
    n1 = building_split(sys)
    if not (np.array_equal(sys.i1, np.arange(p)) and np.array_equal(sys.i2, n1 + np.arange(p))):
        return "contact pairs are not floor j of building 1 facing floor j of building 2"
    if not (1 <= n1 < n and p == min(n1, n - n1)):
        return "pair count is not min(floors)"
    if 6 * n + p > SCRATCH or p > 62:
        return (
            f"{n} floors and {p} pairs: more than the lane kernel's register scratch ({SCRATCH} vectors for "
            "6 N + P, see rows.scratch_entries) or contact-set masks (62 pairs) hold"
        )
    for name in ("m", "C", "K"):
        if not np.all(np.isfinite(getattr(sys, name))):
            return f"non-finite {name}"
    if np.any(sys.C[:n1, n1:] != 0.0) or np.any(sys.K[:n1, n1:] != 0.0):
        return "the buildings are coupled outside the contact pairs"
    try:
        return modal_arrays(sys, n1)
    except ValueError as e:
        return str(e)
