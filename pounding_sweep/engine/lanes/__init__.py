"""Lane kernel: LANES runs of a grid advanced side by side in SIMD lanes, in modal coordinates.

Same model, schemes and metric row as the scalar kernel (engine/scalar.py, schemes "event" and
"implicit", the linear contact laws), computed with other algebra: each building's modes
(model/modal.py) turn Newmark's 2N x 2N solve into N scalar recurrences (mode k: dq = cq q + cr r +
cf fsum, two fused multiply-adds and two additions), the floors are Phi q, and contact at the step
end is solved through the lane's precomputed (I + diag(kappa) W)_SS^-1 of its contact set S. Results
agree with the scalar kernel to rounding (tests/engine/test_lanes.py states the tolerance), not bit for bit.

State per lane: modal displacement q and scaled velocity r = (dt / 2) q' (so that r+ = dq - r
is an addition), contact forces F at the step start and their modal resultant g = Psi F, the
contact set, the penetrations at the step start; the acceleration is never stored (equilibrium).
Floor counts are compile-time constants of the vector loops only (compiled per pair: loops.py), not of the
group driver that calls them.

Modules, by concern: rows (where everything is kept: the lane-major rows W, one lane's scalar rows,
the coefficient table), vector (the vector steps: quiet and contact), lane_step (one lane's step in
scalar code at a contact event: engine/events.py's located step with modal pieces, or the implicit
scheme's active-set iteration), groups (the group driver), excitation (ground-motion profiles),
eligibility (why the lane kernel cannot run a chunk), model (its model record), loops (the vector loops of one
pair of floor counts, called by their addresses). A run that diverges is
handed back to the driver, which reruns it with the scalar kernel.
"""

from pounding_sweep.engine.lanes.eligibility import LAWS, lane_modes
from pounding_sweep.engine.lanes.excitation import excitation_profiles
from pounding_sweep.engine.lanes.groups import group_work, integrate_lanes, step_pieces
from pounding_sweep.engine.lanes.model import lane_model
from pounding_sweep.engine.lanes.rows import (
    LANES,
    ST_CALLS,
    ST_FIX_NS,
    ST_FIXUPS,
    ST_N,
    ST_TIMED,
    ST_VSTEPS,
    coefficient_table,
)

__all__ = [
    "LANES",
    "LAWS",
    "ST_CALLS",
    "ST_FIX_NS",
    "ST_FIXUPS",
    "ST_N",
    "ST_TIMED",
    "ST_VSTEPS",
    "coefficient_table",
    "excitation_profiles",
    "group_work",
    "integrate_lanes",
    "lane_model",
    "lane_modes",
    "step_pieces",
]
