"""The lane kernel's model record (engine/inputs.py LaneModel) for a coupled system."""

from __future__ import annotations

from pounding_sweep.engine import layout as L
from pounding_sweep.engine.inputs import KernelOptions, LaneModel, building_split
from pounding_sweep.engine.lanes.rows import coefficient_table
from pounding_sweep.model.coupled import SystemArrays
from pounding_sweep.model.modal import ModalArrays, modal_arrays


def lane_model(sys: SystemArrays, opts: KernelOptions, ma: ModalArrays | None = None) -> LaneModel:
    """The system's modal data at its dt (`ma`: when the caller has them, from lanes.lane_modes), its floor
    counts and which metric groups are constants."""
    ma = ma if ma is not None else modal_arrays(sys, building_split(sys))
    # every metric group (the default) as a compile-time constant, so the vector steps carry no test for a
    # group (as runtime flags they cost the lane kernel 6-12 %: benchmarks/compare_checkouts.py); a caller
    # leaving groups out gets the one other compiled variant, whose steps test opts.groups at run time
    gt = (0,) if opts.groups & L.GROUPS_ALL == L.GROUPS_ALL else ()
    return LaneModel(
        float(sys.dt),
        int(sys.m.size),
        building_split(sys),
        gt,
        ma.phi,
        ma.psi,
        ma.om2,
        ma.dmp,
        ma.gam,
        ma.W,
        coefficient_table(ma),
    )
