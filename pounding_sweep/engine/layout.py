"""Column layout of the kernel's per-run metric array, shared by the kernel and the writer.

The kernel fills a float64 row per run; `metric_columns` names each slot with its unit.
"""

from __future__ import annotations

# per degree of freedom (building b, floor f)
# DOF_PEAK_DRIFT: largest |interstory drift| of the story below the floor (u_i - u_below; the ground
# story's is u_i itself, displacements being relative to the table)
DOF_PEAK_DISP, DOF_PEAK_DISP_TIME, DOF_PEAK_ABS_ACC, DOF_PEAK_DRIFT = 0, 1, 2, 3
PER_DOF = 4
# per facing floor pair j
(
    PAIR_PEAK_FORCE,
    PAIR_MIN_FORCE,
    PAIR_IMPACTS,
    PAIR_CONTACT_TIME,
    PAIR_COMPRESSION_TIME,
    PAIR_COMPRESSION_PHASES,
    PAIR_MEDIAN_COMPRESSION,
    PAIR_MAX_PENETRATION,
    PAIR_PEAK_FORCE_TIME,
    PAIR_CLOSEST,  # closest approach: least gap - (u1 - u2) over the run [m] (< 0: the floors overlapped)
    PAIR_CLOSEST_TIME,
) = range(11)
PER_PAIR = 11
# per run
RUN_UNSETTLED, RUN_MAX_ITER, RUN_STEPS, RUN_STATUS = range(4)
# energy balance (relative coordinates): E_in = KE + SE + D_struct + D_contact + E_spring + residual
(RUN_E_IN, RUN_E_IN_ABS, RUN_KE, RUN_SE, RUN_D_STRUCT, RUN_D_CONTACT, RUN_E_SPRING, RUN_E_RESIDUAL) = range(4, 12)
PER_RUN = 12

# status bits (the writer turns them into words)
STATUS_NONFINITE = 1  # NaN/inf or |u| > DIVERGED_M: integration stopped
STATUS_UNSETTLED = 2  # the contact solve did not settle in at least one step (events chattered, Newton stalled)
STATUS_UNDERRESOLVED = 4  # dt too coarse for the contact period (set before the run)
STATUS_MEDIAN_TRUNCATED = 8  # more compressive phases than the median buffer holds
STATUS_ENERGY = 16  # |energy residual| > ENERGY_TOL of the input work: contact switching made or lost energy
ENERGY_TOL = 0.01
STATUS_UNSCORED = 32  # the run ended before the experiment's window did (diverged, or a shorter record)
STATUS_DT_UNCONVERGED = 64  # dt = "auto": the tolerance was not met at dt_min (the finest result is kept)
STATUS_GRAZING = 128  # Hertz-damp: an impact's approach speed was below the floor, which was used instead
STATUS_WORDS = {
    STATUS_NONFINITE: "diverged",
    STATUS_UNSETTLED: "contact_unsettled",
    STATUS_UNDERRESOLVED: "contact_underresolved",
    STATUS_MEDIAN_TRUNCATED: "median_truncated",
    STATUS_ENERGY: "energy_residual",
    STATUS_UNSCORED: "unscored",
    STATUS_DT_UNCONVERGED: "dt_tolerance_not_met",
    STATUS_GRAZING: "grazing_impact",
}
# metric groups: the columns a sweep may leave out of the lane kernel's per-step work (KernelOptions.groups, a
# bit mask). A group left out has its columns NaN (not computed) in every kernel's rows, and the status bits
# derived from it cleared, so a row is the same whichever kernel computed it.
GROUP_ENERGY = 1  # the energy balance (RUN_E_*) and STATUS_ENERGY
GROUP_DRIFT = 2  # each story's peak interstory drift (DOF_PEAK_DRIFT)
GROUP_CLOSEST = 4  # each pair's closest approach and its time (PAIR_CLOSEST, PAIR_CLOSEST_TIME)
GROUP_PHASES = 8  # compressive phases: compression time, count, median duration; STATUS_MEDIAN_TRUNCATED
GROUP_ACCEL = 16  # each floor's peak absolute acceleration (DOF_PEAK_ABS_ACC): Phi applied to the modal accelerations
GROUPS = {
    "energy": GROUP_ENERGY,
    "drift": GROUP_DRIFT,
    "closest": GROUP_CLOSEST,
    "phases": GROUP_PHASES,
    "accel": GROUP_ACCEL,
}
GROUPS_ALL = GROUP_ENERGY | GROUP_DRIFT | GROUP_CLOSEST | GROUP_PHASES | GROUP_ACCEL
DIVERGED_M = 1.0e3  # a displacement beyond a kilometre is a numerical blow-up, not physics
MEDIAN_BUFFER = 4096  # compressive phases kept per pair for the median duration


def n_metrics(n_dof: int, n_pairs: int) -> int:
    return PER_DOF * n_dof + PER_PAIR * n_pairs + PER_RUN


def dof_slot(dof: int, what: int) -> int:
    return PER_DOF * dof + what


def pair_slot(n_dof: int, pair: int, what: int) -> int:
    return PER_DOF * n_dof + PER_PAIR * pair + what


def run_slot(n_dof: int, n_pairs: int, what: int) -> int:
    return PER_DOF * n_dof + PER_PAIR * n_pairs + what


def groups_mask(names) -> int:
    """The bit mask of the metric groups named (GROUPS keys; "all", "none"); ValueError for an unknown name."""
    mask = 0
    for name in names:
        name = name.strip()
        if name == "all":
            mask |= GROUPS_ALL
        elif name in ("none", ""):
            continue
        elif name in GROUPS:
            mask |= GROUPS[name]
        else:
            raise ValueError(f"unknown metric group {name!r} (one of: {', '.join(GROUPS)}, all, none)")
    return mask


def group_names(groups: int) -> list[str]:
    """The names of the groups in a mask, in GROUPS order."""
    return [name for name, bit in GROUPS.items() if groups & bit]


def left_out_slots(n_dof: int, n_pairs: int, groups: int) -> list[int]:
    """The metric row's slots of the groups not in `groups` (their columns are NaN)."""
    out: list[int] = []
    if not groups & GROUP_DRIFT:
        out += [dof_slot(i, DOF_PEAK_DRIFT) for i in range(n_dof)]
    if not groups & GROUP_ACCEL:
        out += [dof_slot(i, DOF_PEAK_ABS_ACC) for i in range(n_dof)]
    for j in range(n_pairs):
        if not groups & GROUP_CLOSEST:
            out += [pair_slot(n_dof, j, PAIR_CLOSEST), pair_slot(n_dof, j, PAIR_CLOSEST_TIME)]
        if not groups & GROUP_PHASES:
            out += [
                pair_slot(n_dof, j, w)
                for w in (PAIR_COMPRESSION_TIME, PAIR_COMPRESSION_PHASES, PAIR_MEDIAN_COMPRESSION)
            ]
    if not groups & GROUP_ENERGY:
        out += [run_slot(n_dof, n_pairs, w) for w in range(RUN_E_IN, PER_RUN)]
    return out


def leave_out(metrics, n_dof: int, n_pairs: int, groups: int) -> None:
    """Rows (runs, n_metrics) in place: the slots of the groups left out NaN, the status bits they give cleared."""
    if groups & GROUPS_ALL == GROUPS_ALL or metrics.shape[0] == 0:
        return
    metrics[:, left_out_slots(n_dof, n_pairs, groups)] = float("nan")
    clear = (0 if groups & GROUP_ENERGY else STATUS_ENERGY) | (0 if groups & GROUP_PHASES else STATUS_MEDIAN_TRUNCATED)
    if clear:
        st = run_slot(n_dof, n_pairs, RUN_STATUS)
        metrics[:, st] = (metrics[:, st].astype("int64") & ~clear).astype(metrics.dtype)


def metric_columns(floors: tuple[int, int], n_pairs: int) -> list[str]:
    """Column names, in slot order. Building b in {1, 2}, floor f from 1 (the ground story's top)."""
    cols: list[str] = []
    for b, nf in zip((1, 2), floors):
        for f in range(1, nf + 1):
            cols += [
                f"peak_disp_b{b}f{f}_m",
                f"peak_disp_time_b{b}f{f}_s",
                f"peak_abs_acc_b{b}f{f}_m_s2",
                f"peak_drift_b{b}s{f}_m",
            ]
    for j in range(1, n_pairs + 1):
        cols += [
            f"peak_force_f{j}_N",
            f"min_force_f{j}_N",
            f"impacts_f{j}",
            f"contact_time_f{j}_s",
            f"compression_time_f{j}_s",
            f"compression_phases_f{j}",
            f"median_compression_phase_f{j}_s",
            f"max_penetration_f{j}_m",
            f"peak_force_time_f{j}_s",
            f"closest_approach_f{j}_m",
            f"closest_approach_time_f{j}_s",
        ]
    cols += ["unsettled_steps", "max_contact_iterations", "steps", "status_code"]
    cols += [
        "input_energy_J",
        "input_work_abs_J",
        "kinetic_energy_end_J",
        "strain_energy_end_J",
        "structural_damping_energy_J",
        "contact_damping_energy_J",
        "contact_spring_energy_end_J",
        "energy_residual_J",
    ]
    return cols
