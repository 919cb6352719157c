"""Slow, obviously-correct references the kernels are tested and benchmarked against (the oracles).

Nothing here is fast on purpose: each step assembles and solves the full coupled system with NumPy, or
solve_ivp integrates the continuous problem, so the arithmetic can be read line by line against the
equations it implements (paper eqs. 1-2, 8-16). Layer: above the sweep layer (it resolves a scene's
single point as simulate does); tests and benchmarks import it, the package's own code never does.
Modules: newmark (the implicit, paper and event schemes), ivp (continuous time, contact events),
closed_form (no contact: modal superposition).
"""

from pounding_sweep.reference.closed_form import classical_modes, modal_free_vibration, modal_harmonic_response
from pounding_sweep.reference.ivp import contact_force, contact_set_systems, ivp_reference
from pounding_sweep.reference.newmark import (
    Problem,
    newmark_reference,
    paper_scheme_reference,
    resolve,
    restitution_damping_ratio,
)

__all__ = [
    "classical_modes",
    "modal_free_vibration",
    "modal_harmonic_response",
    "contact_force",
    "contact_set_systems",
    "ivp_reference",
    "Problem",
    "newmark_reference",
    "paper_scheme_reference",
    "resolve",
    "restitution_damping_ratio",
]
