"""Checks of a whole sweep that find a probable mistake in its scene, each where it can first be seen.

Before the runs: a time step too coarse for every run's contact, an r axis the elastic Hertz law ignores, a
low-pass below the buildings' modes (warnings); a measured value no shake-table test gives, and what would make
the calibration after the grid fail (errors: time offsets off the table, a noise floor that cannot be
estimated, a global stage too large). After them: a grid in which no run made contact although the scene is
there to study pounding, and a scored channel no run explains (a unit mix-up, named where one factor fits).
Criteria and their reasons: docs/reference/safeguards.md and the constants below."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np

from pounding_sweep.codes import canonical_unit
from pounding_sweep.model.records import G_STANDARD, MAX_ACC_M_S2
from pounding_sweep.scene.channels import building_floor, shown_value
from pounding_sweep.scene.parameters import CONTACT, STIFFNESS, names
from pounding_sweep.warn import warn

#: sweep axes that are contact parameters: sweeping one says the scene studies pounding
CONTACT_AXES = names(CONTACT)


def round_down_125(x: float) -> float:
    """The largest of 1, 2, 5 x 10^k not above x (a time step to suggest)."""
    e = math.floor(math.log10(x))
    for m in (5.0, 2.0, 1.0):
        if m * 10.0**e <= x * (1 + 1e-12):
            return float(f"{m * 10.0**e:.0e}")
    return float(f"{10.0 ** (e - 1) * 5:.0e}")


#: the sweep axes that set a run's contact stiffness (and so its contact period)
STIFFNESS_AXES = names(STIFFNESS)


def contact_stiffness_grid(grid):
    """The grid's distinct contact stiffnesses as run parameters (Grid.chunk's form): its law and stiffness axes
    crossed, every other parameter at the scene's value or its axis' first value (they do not set k)."""
    from pounding_sweep.model.grid import Grid

    axes = tuple((n, v) for n, v in grid.axes if n in STIFFNESS_AXES)
    fixed = dict(grid.fixed)
    fixed.update({n: v[0] for n, v in grid.axes if n not in STIFFNESS_AXES})
    sub = Grid(axes, fixed)
    return sub.chunk(0, sub.size)


def check_time_step(prep) -> None:
    """Warn when the time step leaves every run's contact under-resolved (each run would be flagged
    contact_underresolved): the softest contact of the grid has the longest contact period, so the
    grid's stiffness values decide it before any run (k_s, or for the Hertz-type laws their tangent stiffness
    at the reference penetration: sweep/prepare.py contact_arrays, whose steps per period this reads). With
    dt_s = 'auto' the step is chosen per run: no check."""
    from pounding_sweep.sweep.prepare import contact_arrays

    scene = prep.scene
    if scene.integration.auto or prep.model.n_pairs == 0:
        return
    params = contact_stiffness_grid(prep.grid)
    k, _, derived, _ = contact_arrays(prep.model, scene, params, prep.dt)
    steps = derived["steps_per_contact_period"]
    dt = prep.dt
    want = scene.integration.min_steps_per_contact_period
    softest = int(np.argmax(steps))
    if steps[softest] >= want:
        return
    soft, stiff = float(steps.max()) * dt, float(steps.min()) * dt  # contact periods [s]
    every = round_down_125(stiff / want)
    some = round_down_125(soft / want)
    hint = f"dt_s = {every:g}" if every == some else f"dt_s = {some:g} (the softest contact) or {every:g} (every run)"
    hertz = "kh_N_per_m1_5" in derived and np.isfinite(derived["kh_N_per_m1_5"][softest])
    what = (
        f"the softest k_h = {float(k[softest]):.4g} N/m^1.5 (tangent stiffness 1.5 k_h sqrt(reference_penetration_m))"
        if hertz
        else f"the softest k_s = {float(k[softest]):.4g} N/m"
    )
    warn(
        "contact_underresolved",
        f"[integration] dt_s = {dt:g} s under-resolves every run's contact: {steps[softest]:.3g} steps per contact "
        f"period 2 pi sqrt(m_eff / k) at {what}, fewer than "
        f"min_steps_per_contact_period = {want:g} (every run is flagged contact_underresolved): "
        f"use {hint}, or dt_s = 'auto'",
    )


#: a grid whose every gap is at least this many times the closest approach of its facing floors is separated on
#: purpose (the motion closes at most half the gap): no run making contact is then what the scene is for
SEPARATED_ON_PURPOSE = 2.0
#: an approach below this fraction of the largest floor displacement is rounding of two equal motions (identical
#: buildings: u1 - u2 is a few ulps of u, about 1e-16 u, grown over the steps), not the floors moving toward each other
ROUNDING_APPROACH = 1e-9
#: gap_m from which "no contact" is named as a gap written in mm (a building gap of half a metre at model scale
#: is not a pounding study; full-scale seismic joints are centimetres)
METRES_HINT_GAP_M = 0.5


class ContactTally:
    """Whether any run made contact, how close the facing floors came, and the range of each floor's peak response,
    over result tables: the approach of a pair is the largest u1 - u2 of a run (gap_m - closest_approach_f*_m: how
    much nearer than at rest its floors came; 0 or less when they never moved toward each other)."""

    def __init__(self):
        self.runs = 0
        self.contact = False
        self.approach = -math.inf  # the largest approach of any pair in any run [m]
        self.pair = 0  # the pair that made it
        self.min_gap = math.inf
        self.peaks: dict[str, tuple[float, float]] = {}  # peak_disp / peak_abs_acc column -> (least, largest) over runs
        # False: the closest group was left out ([output] metrics): its columns are NaN, the approach is unknown
        self.closest_computed = True
        self.kept_disp: dict[str, float] = {}  # peak_disp column -> its largest over the runs not flagged diverged

    def add(self, table, numpy_column) -> None:
        names = table.column_names
        self.runs += table.num_rows
        pairs = [n.removeprefix("impacts_f") for n in names if n.startswith("impacts_f")]
        for j in pairs:
            if np.nansum(numpy_column(table, f"impacts_f{j}")) > 0:
                self.contact = True
            closest = f"closest_approach_f{j}_m"
            if self.closest_computed and closest in names and "gap_m" in names and table.num_rows:
                approach = float(
                    np.nanmax(numpy_column(table, "gap_m") - numpy_column(table, closest), initial=-np.inf)
                )
                if approach > self.approach:
                    self.approach, self.pair = approach, int(j)
        if "gap_m" in names and table.num_rows:
            self.min_gap = min(self.min_gap, float(np.nanmin(numpy_column(table, "gap_m"))))
        kept = np.array(["diverged" not in s for s in table.column("status").to_pylist()], dtype=bool)
        for name in names:
            if name.startswith(("peak_abs_acc_b", "peak_disp_b")) and not name.startswith("peak_disp_time"):
                x = numpy_column(table, name)
                if name.startswith("peak_disp_b"):
                    k = x[kept & np.isfinite(x)]
                    if k.size:
                        self.kept_disp[name] = max(self.kept_disp.get(name, 0.0), float(k.max()))
                x = x[np.isfinite(x)]
                if x.size:
                    lo, hi = self.peaks.get(name, (math.inf, -math.inf))
                    self.peaks[name] = (min(lo, float(x.min())), max(hi, float(x.max())))

    def separated_on_purpose(self) -> bool:
        """Every gap at least SEPARATED_ON_PURPOSE times the closest approach (and below the metres hint); never
        when the closest approach was not computed (it is not known then)."""
        return (
            self.closest_computed
            and 0 < self.min_gap < METRES_HINT_GAP_M
            and self.min_gap >= SEPARATED_ON_PURPOSE * max(self.approach, 0.0)
        )


def check_contact(tally: ContactTally, scene) -> None:
    """Warn when no run of the grid made contact although the scene is there to study pounding: the contact
    parameters then change nothing. Not when the scene is separated on purpose (every gap at least twice the
    closest approach: ContactTally.separated_on_purpose). A gap of half a metre or more is named as the likely
    cause (millimetres written in gap_m, which is in metres)."""
    if scene.contact is None or tally.contact or tally.runs == 0 or tally.separated_on_purpose():  # None: one building
        return
    swept = [a.name for a in scene.sweep if a.name in CONTACT_AXES and len(a.values) > 1]
    gap = tally.min_gap
    scale = max((hi for name, (_, hi) in tally.peaks.items() if name.startswith("peak_disp_b")), default=0.0)
    if not tally.closest_computed:
        moved = (
            f"how near the facing floors came is not known ([output] metrics leaves out closest, the closest "
            f"approach), against a gap of {gap * 1e3:.4g} mm"
        )
    elif tally.approach > ROUNDING_APPROACH * scale:
        moved = (
            f"the facing floors came at most {tally.approach * 1e3:.3g} mm nearer than at rest (floor pair "
            f"{tally.pair}), against a gap of {gap * 1e3:.4g} mm"
        )
    else:
        moved = (
            "the facing floors never moved toward each other (the buildings move in phase), against a gap of "
            f"{gap * 1e3:.4g} mm"
        )
    parts = [f"no run made contact ({tally.runs:,} run(s), largest pounding force 0 N): {moved}"]
    if gap >= METRES_HINT_GAP_M:
        parts.append(f"gap_m is in metres: gap_m = {gap:g} is {gap:g} m (for {gap:g} mm write {gap / 1e3:g})")
    if swept:
        parts.append(f"the swept {', '.join(swept)} change nothing here")
    warn("no_contact", "; ".join(parts))


#: a floor displaced more than this share of its height above the table (a mean drift ratio of 25 %) is far past any
#: frame's linear range: real frames collapse at 4-10 % (ASCE 41's collapse-prevention limit for steel moment
#: frames is 5 %), so a study scaled to high intensities on purpose reaches 10 % (the shipped risk scenes at
#: 1.5 g), while a unit slip moves floors by their height or more (a helper's: 1.1 to 17 times)
MAX_MEAN_DRIFT = 0.25


def check_response_size(tally: ContactTally, scene) -> None:
    """After the grid: warn where a building's floor moved more than MAX_MEAN_DRIFT of its height above the table
    in a run not flagged diverged (where story_height_m is given). A helper's table amplitude typed in mm as m
    (roof 14 m on a 1 m model) and a record in cm/s^2 read as m/s^2 (0.8 m) ran with every status 'ok'."""
    for i, section in enumerate(("building1", "building2"), 1):
        b = getattr(scene, section, None)
        heights = b.story_heights() if b is not None else None  # one value given: every story's
        if not heights:
            continue
        worst = None
        for f in range(1, len(heights) + 1):
            peak = tally.kept_disp.get(f"peak_disp_b{i}f{f}_m")
            h = float(sum(heights[:f]))
            if peak is not None and peak > MAX_MEAN_DRIFT * h and (worst is None or peak / h > worst[0]):
                worst = (peak / h, f, peak, h)
        if worst is not None:
            ratio, f, peak, h = worst
            warn(
                "response_size",
                f"[{section}] {b.name or section}: floor {f} moves up to {peak:.4g} m relative to the table in a run "
                f"not flagged diverged, {ratio:.3g} times its height above it ({h:.4g} m from story_height_m): past "
                f"any frame's linear range (a mean drift above {MAX_MEAN_DRIFT:.0%}); are the excitation's size and "
                "units right ([excitation] units, amplitude_m, scale)? Else see the runs' status (energy_residual: "
                "the contact made energy)",
            )


#: the most memory the calibration's global stage may keep in histories: its Sobol points run as one batch
GLOBAL_STAGE_BYTES = 2**30


def check_calibration(prep) -> None:
    """Before the grid, what would make the calibration after it fail or mislead, each one ConfigError naming
    the key: a time offset (a [sweep] value, or a [calibrate] bound) that moves the scored window off the
    experiment's table; a channel whose noise floor cannot be estimated (too few samples in the window: NaN; or
    none at all: 0) when [calibrate] gives no noise_m for it; a global stage whose histories would not fit in
    GLOBAL_STAGE_BYTES."""
    from pounding_sweep.errors import ConfigError, ExperimentError
    from pounding_sweep.model.experiment import NOISE_MIN_DIFFERENCES, noise_floor
    from pounding_sweep.scene.channels import is_acceleration
    from pounding_sweep.sweep.scoring import score_spec

    scene, exp = prep.scene, prep.experiment
    if exp is None:
        return
    cal = scene.calibrate
    offsets = [("[sweep] time_offset_s", v) for v in scene.axis_values("time_offset_s")]
    if cal is not None and "time_offset_s" in cal.parameters:
        bounds = cal.parameters["time_offset_s"]
        offsets += [
            (f"[calibrate] parameters.time_offset_s = [{bounds[0]:g}, {bounds[1]:g}]", float(b)) for b in bounds
        ]
    for key, offset in offsets:
        moved = dataclasses.replace(scene.experiment, time_offset_s=offset)
        try:
            score_spec(exp, moved, prep.excitation.max_duration_s, prep.dt)
        except ExperimentError as e:
            raise ConfigError(f"{key}: at {offset:g} s, {e}") from None
    _check_coverage(prep)
    _check_record_against_table(prep)
    _check_floor_order(prep)
    if cal is None:
        return
    from pounding_sweep.sweep.calibrate import check_channel_offsets

    check_channel_offsets(prep, cal.parameters)  # a channel's own clock bounded inside half a period
    duration = prep.excitation.max_duration_s
    lo, hi = scene.experiment.window_s or (0.0, duration)
    t_sim = exp.time_s - scene.experiment.time_offset_s
    inside = (t_sim >= lo) & (t_sim <= hi)
    weights = prep.combination.weights if prep.combination is not None else None
    rows = 0
    for i, code in enumerate(prep.score_codes):
        if weights is not None and weights[i] == 0:
            continue
        acc = is_acceleration(code)
        rows += 1 if acc else 2
        if code in getattr(exp, "noise", {}) or (cal.noise_m is not None and not acc):
            continue  # given: [experiment] noise or noise_window_s, or [calibrate] noise_m for a displacement
        y = exp.channels[code][inside]
        sigma, _ = noise_floor(y)
        if not sigma > 0:
            why = (
                f"{y.size} sample(s) in the scored window, fewer than the {NOISE_MIN_DIFFERENCES + 1} its noise floor "
                "is estimated from"
                if not np.isfinite(sigma)
                else "no noise at all (its differences are all 0: quantised or noise-free data)"
            )
            fix = "widen [experiment] window_s, or give" if not np.isfinite(sigma) else "give"
            given = (
                "[experiment] noise for it (in its own unit) or noise_window_s"
                if acc
                else "[calibrate] noise_m (the tracking noise in m) or [experiment] noise"
            )
            raise ConfigError(
                f"[calibrate]: the experiment's channel {code} has {why}; the residuals are weighed by it: {fix} "
                f"{given}"
            )
    per_run = rows * (prep.excitation.max_steps // scene.output.history_decimate + 1) * 8
    if cal.global_points * per_run > GLOBAL_STAGE_BYTES:
        most = max(0, GLOBAL_STAGE_BYTES // per_run)
        raise ConfigError(
            f"[calibrate] global_points = {cal.global_points:,}: its runs are made as one batch and keep "
            f"{cal.global_points * per_run / 2**30:.3g} GiB of histories ({per_run / 2**20:.3g} MiB a run), more than "
            f"{GLOBAL_STAGE_BYTES / 2**30:g} GiB: use at most {most:,} points"
        )


def _check_coverage(prep) -> None:
    """Warn when the record ends before the experiment's motion does: with neither [experiment] window_s nor
    [excitation] duration_s the scored window is the record's span, so a record cut short (a helper's 3 s of a 70 s
    table) silently scored only the quiet lead-in. Named where a measured channel varies more (standard deviation)
    after the record's end than within it."""
    x, exp = prep.scene.experiment, prep.experiment
    if x.window_s is not None or prep.scene.excitation.duration_s is not None:  # a window or span the user chose
        return
    end = prep.excitation.max_duration_s
    t_sim = exp.time_s - x.time_offset_s
    inside, after = (t_sim >= 0) & (t_sim <= end), t_sim > end
    if inside.sum() < 2 or after.sum() < 2:
        return
    for code in prep.score_codes:
        y = exp.channels[code]
        s_in, s_after = float(np.std(y[inside])), float(np.std(y[after]))
        if s_after > s_in:
            warn(
                "record_short",
                f"[experiment] {exp.columns.get(code, code)} ({code}) varies more after the simulation ends at "
                f"{end:.6g} s (standard deviation {shown_value(code, s_after)} over the {t_sim[-1] - end:.6g} s "
                f"after) than within it ({shown_value(code, s_in)}): only its samples in 0-{end:.6g} s (simulation "
                "time) are scored; is the record cut short, or time_offset_s wrong? ([excitation] duration_s runs on "
                "past the record's end, padded with rest, to score a free vibration after it; [experiment] window_s "
                "scores a part on purpose)",
            )
            return


#: a lower floor's amplitude in the first mode's band past this many times a higher floor's is a mapping fault (real
#: Northridge floors 1-3: 0.42, 0.83, 1.0 of the top; noise moves a ratio by a few percent at MODE_BAND_SNR)
FLOOR_ORDER_SLACK = 1.15
#: ... judged only where the channels' band amplitude stands this many times above their noise floor
MODE_BAND_SNR = 5.0


def _check_floor_order(prep) -> None:
    """Warn when a building's measured channels of one kind do not grow with height in its first mode's band
    (model/modal.py height_order_fault, with FLOOR_ORDER_SLACK): relative to the table and so also absolutely
    (|1 + H phi| grows with phi). Two floors' columns exchanged in [experiment] channels fail it (a helper's swap
    of floors 1 and 3 was told only by a larger misfit). The band is 0.8-1.25 times the first resonance the import
    measured where the table is an import's and names the building, else the model's first mode; up to 0.45 times
    the slowest sensor's rate; the order is judged only where the band stands MODE_BAND_SNR above the noise."""
    from scipy.signal import butter, sosfiltfilt

    from pounding_sweep.model.experiment import noise_floor
    from pounding_sweep.model.modal import height_order_fault
    from pounding_sweep.scene.channels import is_acceleration

    exp = prep.experiment
    fs = 1.0 / exp.dt_sample
    settings = exp.sensor_import.get("settings", {})
    rates = [s.get("rate_Hz") for s in exp.sensor_import.get("sensors", {}).values() if isinstance(s, dict)]
    slowest = min([fs] + [float(r) for r in rates if isinstance(r, (int, float)) and r > 0])
    inside = _window(prep)
    for b, building in enumerate(prep.model.buildings, 1):
        measured = settings.get("first_resonance_Hz")
        from_data = str(settings.get("first_resonance_from", "")).startswith(f"b{b}f") and isinstance(
            measured, (int, float)
        )
        f1 = float(measured) if from_data and math.isfinite(measured) else float(building.modes().frequency_Hz[0])
        if not 1.25 * f1 < 0.45 * slowest or inside.sum() < 64:
            continue
        sos = butter(4, (0.8 * f1, 1.25 * f1), btype="bandpass", fs=fs, output="sos")
        for acc in (False, True):
            chans = {}
            for code in prep.score_codes:
                building, floor = building_floor(code)
                if is_acceleration(code) == acc and building == b:
                    y = exp.channels[code][inside]
                    sigma = exp.noise.get(code) or noise_floor(y)[0]
                    chans[floor] = (code, float(np.std(sosfiltfilt(sos, y - y.mean()))), sigma)
            if len(chans) < 2 or not all(a > MODE_BAND_SNR * s for _, a, s in chans.values()):
                continue
            order = sorted(chans)
            k = height_order_fault([chans[f][1] for f in order], FLOOR_ORDER_SLACK)
            if k is None:
                continue
            (c_lo, a_lo, _), (c_hi, a_hi, _) = chans[order[k]], chans[order[k + 1]]
            top = chans[order[-1]][1]
            shown = ", ".join(f"{exp.columns.get(chans[f][0])} {chans[f][1] / top:.2f}" for f in order)
            where = "the import's first resonance" if from_data else "the model's first mode (far from the data's?)"
            warn(
                "floor_order",
                f"[experiment] channels: near building {b}'s first mode ({0.8 * f1:.3g}-{1.25 * f1:.3g} Hz, about "
                f"{where}) {exp.columns.get(c_lo)} ({c_lo}) moves {a_lo / a_hi:.2f} times {exp.columns.get(c_hi)} "
                f"({c_hi}), a floor above it (amplitudes relative to the top: {shown}); in a first mode the floors "
                "move more the higher they are: are two floors' columns exchanged in the mapping?",
            )


#: a record whose peak is within this factor of G_STANDARD times the table's measured one (or 1 / G_STANDARD) is
#: read in the wrong one of g and m/s^2 (a real test's table and record differ by a few percent: one resampling)
UNIT_SLIP = 1.25


def _check_record_against_table(prep) -> None:
    """Warn when the record driving the runs and the table's own measured acceleration (the column the import wrote
    for its reference sensor, 'sensor_import' metadata) differ in peak by a factor g: [excitation] units names the
    wrong one of g and m/s^2 (a helper's 'g' on an m/s^2 record drove the frame 9.8 times too hard, and the scoring's
    own unit hint pointed at the table instead). Only where the runs take the record as read (scale 1)."""
    from pounding_sweep.model.experiment import read_table

    scene, exp = prep.scene, prep.experiment
    e = scene.excitation
    if e.type != "record" or e.scaling == "intensity" or e.scale != 1.0 or set(scene.axis_values("scale")) - {1.0}:
        return
    reference = exp.sensor_import.get("settings", {}).get("reference")
    if not reference:
        return
    df, _ = read_table(exp.path)
    column = f"{reference}_acc_m_s2"
    if column not in df.columns:
        return
    t_sim = exp.time_s - scene.experiment.time_offset_s
    for rec in prep.excitation.records:
        on = (t_sim >= 0) & (t_sim <= rec.duration_s)
        if on.sum() < 2:
            continue
        table = float(np.nanmax(np.abs(df[column].to_numpy(dtype=float)[on])))
        peak = float(np.nanmax(np.abs(rec.acc_m_s2)))
        if not (table > 0 and peak > 0):
            continue
        ratio = peak / table
        for factor, meant in ((G_STANDARD, "m/s2"), (1 / G_STANDARD, "g")):
            if abs(math.log(ratio / factor)) <= math.log(UNIT_SLIP):
                said = f"[excitation] units = {e.units or 'its default'!r}"
                seen = (
                    f"{Path(rec.source).name} read so peaks at {peak:.4g} m/s^2, {ratio:.3g} times the table's own "
                    f"measured peak ({column}: {table:.4g} m/s^2 over the record's span)"
                )
                if e.units is not None and canonical_unit(e.units) == meant:  # the record's unit is said already:
                    warn(  # the table's column is the one off (edited after its import, or another table's)
                        "record_units",
                        f"{said}: {seen}: the record is read in {meant} already; "
                        + (
                            "is the table's column in g, not the m/s^2 its import recorded?"
                            if meant == "m/s2"  # the record g times the table: the table's column in g
                            else "the table's column is g times what its record says: check which of the two "
                            "files holds the other unit"
                        ),
                    )
                else:
                    warn("record_units", f"{said}: {seen}: is the record in {meant} (units = {meant!r})?")


#: the largest |displacement| [m] and |absolute acceleration| [m/s^2] a measured channel may hold: the kernel calls
#: a run diverged beyond 1 km, and 1e6 m/s^2 is 100,000 g; beyond them a table's units are wrong (its eq. 20 sums
#: would overflow to NaN scores)
MEASURED_LIMITS = {"displacement": 1e3, "acceleration": MAX_ACC_M_S2}


def _window(prep) -> np.ndarray:
    """The experiment's samples inside the scored window at the scene's time offset (a mask on its clock)."""
    x = prep.scene.experiment
    lo, hi = x.window_s or (0.0, prep.excitation.max_duration_s)
    t_sim = prep.experiment.time_s - x.time_offset_s
    return (t_sim >= lo) & (t_sim <= hi)


#: a story height above this [m] is another unit typed in metres (a helper's 200 for 200 mm: drift ratios 1000 times
#: too small); the tallest storeys of buildings (lobbies, plant floors) stay well below it
MAX_STORY_HEIGHT_M = 20.0


def check_scene(prep) -> None:
    """Before the grid: values that run but cannot mean what they say. A measured channel beyond MEASURED_LIMITS is
    an ExperimentError (its units are wrong); warnings for an r axis the elastic Hertz law ignores (identical runs)
    and a low-pass filter below the buildings' first modes (it removes the response it scores)."""
    from pounding_sweep.errors import ExperimentError
    from pounding_sweep.scene.channels import is_acceleration

    scene = prep.scene
    for section in ("building1", "building2"):
        b = getattr(scene, section, None)
        tall = [h for h in (b.story_height_m or ()) if h > MAX_STORY_HEIGHT_M] if b is not None else []
        if tall:
            warn(
                "story_height",
                f"[{section}] story_height_m = {tall[0]:g} is {tall[0]:g} m, more than {MAX_STORY_HEIGHT_M:g} m: "
                f"metres are meant (for {tall[0]:g} mm write {tall[0] / 1e3:g}); the drift ratios divide by it",
            )
    r_values = scene.axis_values("r")
    laws = [] if scene.contact is None else list(dict.fromkeys(scene.axis_values("law") or (scene.contact.law,)))
    if len(r_values) > 1 and "hertz" in laws:
        others = [x for x in laws if x != "hertz"]
        who = f"law 'hertz' is elastic and ignores r: the {len(r_values)} values of [sweep] r give identical runs" + (
            f" (for the other laws, {', '.join(others)}, r matters)" if others else ""
        )
        warn("r_ignored", f"[sweep] r: {who}" + ("" if others else "; drop the r axis, or use hertzdamp or jankowski"))
    check_motion(prep)
    x, exp = scene.experiment, prep.experiment
    if exp is None:
        return
    for code, values in exp.channels.items():
        acc = is_acceleration(code)
        kind = "acceleration" if acc else "displacement"
        peak = float(np.nanmax(np.abs(values), initial=0.0))
        if peak > MEASURED_LIMITS[kind] or not np.isfinite(peak):
            unit = x.acc_units if acc else x.units
            factor = (G_STANDARD if unit == "g" else 1.0) if acc else (1e-3 if unit == "mm" else 1.0)
            si = "m/s^2" if acc else "m"
            raise ExperimentError(
                f"{exp.path}: column {exp.columns.get(code, code)!r} ({code}) reaches {peak / factor:.4g} {unit} "
                f"({peak:.4g} {si}), more than the {MEASURED_LIMITS[kind]:g} {si} any shake-table test measures: are its "
                f"units right ([experiment] {'acc_units' if acc else 'units'} = {unit!r})?"
            )
    if x.lowpass_Hz is not None:
        firsts = {
            b.name or f"building {i}": float(b.modes().frequency_Hz[0]) for i, b in enumerate(prep.model.buildings, 1)
        }
        name, f1 = max(firsts.items(), key=lambda kv: kv[1])
        if x.lowpass_Hz < f1:
            warn(
                "lowpass_below_modes",
                f"[experiment] lowpass_Hz = {x.lowpass_Hz:g} Hz is below {name}'s first mode ({f1:.3g} Hz): the filter "
                "removes the response it scores, and every run then matches the filtered experiment about as well "
                f"(the error no longer tells the runs apart); set it above the modes the accelerations should show "
                f"(at least {f1:.3g} Hz)",
            )


def check_motion(prep) -> None:
    """Warnings for records that run but cannot mean what the scene says: a vertical component (its header names
    it) shaking the horizontal model, and a record sampled more finely than the runs step (the kernel reads it at
    the steps, with no anti-alias filter: its content above half the step rate folds onto lower frequencies)."""
    from pounding_sweep.model.records import vertical_component

    exc = prep.excitation
    if exc.kind != "record":
        return
    vertical = [(r, c) for r in exc.records if (c := vertical_component(r)) is not None]
    if vertical:
        warn(
            "record_vertical",
            "; ".join(
                f"{r.source}: a vertical component (its header: '{r.description.split(' [')[0]}')" for r, _ in vertical
            )
            + ": the model is a horizontal one, shaken here by vertical motion; use the record's horizontal components",
        )
    dt = float(exc.dt)
    coarse = [r for r in exc.records if dt > 1.5 * r.dt_s]
    if coarse:
        finest = min(r.dt_s for r in coarse)
        warn(
            "record_step",
            f"[integration] {'dt_max_s' if prep.scene.integration.auto else 'dt_s'} = {dt:g} s steps over the samples of "
            + ", ".join(f"{Path(r.source).name} (every {r.dt_s:.4g} s)" for r in coarse)
            + f": the runs read the record at their steps only (no anti-alias filter), so its content above "
            f"{0.5 / dt:.4g} Hz folds onto lower frequencies and its peaks between steps are missed; use dt_s <= "
            f"{finest:.4g} s",
        )


#: a best eq. 20 error above this explains less than 1 - 0.9^2 = 19 % of a channel's mean square: with a measured
#: peak that one unit factor would put among the runs', the units are the likely cause
POOR_FIT_PCT = 90.0


def check_scale(tally: ContactTally, prep, best) -> None:
    """After the grid: warn for a scored channel that no run explains. Its best eq. 20 error above 100 % (no run
    comes nearer than no motion at all, which scores exactly 100 %) is always said; above POOR_FIT_PCT it is said
    when the measured peak, rescaled by one unit factor (g for m/s^2, mm for m, or back), falls among the runs' peaks
    (within a factor 2), naming that unit: data 9.8 or 1000 times too large score just under 100 % (every run is
    about zero beside them), too small far above it."""
    from pounding_sweep.scene.channels import ACC_PREFIX, is_acceleration

    exp, x = prep.experiment, prep.scene.experiment
    if exp is None or best is None or best.empty:
        return
    inside = _window(prep)
    for code in prep.score_codes:
        rows = best[best.criterion == f"rel_rms_{code}_pct"]
        error = float(rows.error_pct.iloc[0]) if len(rows) else math.nan
        if not error > POOR_FIT_PCT:
            continue
        acc = is_acceleration(code)
        floor = code.removeprefix(ACC_PREFIX)
        lo, hi = tally.peaks.get(f"peak_abs_acc_{floor}_m_s2" if acc else f"peak_disp_{floor}_m", (math.nan, math.nan))
        measured = float(np.nanmax(np.abs(exp.channels[code][inside]), initial=0.0))
        si = "m/s^2" if acc else "m"
        if acc:
            key, unit = "acc_units", x.acc_units
            other = {"m/s2": ("g", G_STANDARD), "g": ("m/s2", 1 / G_STANDARD)}[unit]
        else:
            key, unit = "units", x.units
            other = {"m": ("mm", 1e-3), "mm": ("m", 1e3)}[unit]
        rescaled = measured * other[1]
        if np.isfinite(lo) and lo / 2 <= rescaled <= 2 * hi:
            hint = (
                f"rescaled as {other[0]} its peak would be {rescaled:.3g} {si}, among the runs': is the table in "
                f"{other[0]} ([experiment] {key} = {other[0]!r}, not {unit!r})"
                + (", or the record read in the wrong unit ([excitation] units)?" if acc else "?")
            )
        elif error > 100.0:
            # the grid's runs only (a calibration after it may still fit): the model as much as the data
            hint = (
                "no run of the grid comes nearer than rest: check the model's ranges (masses, stiffness, the record "
                "and its units) as well as the channel mapping, its sign and its units"
            )
        else:
            continue
        warn(
            "scale",
            f"[experiment] channels.{exp.columns.get(code, code)} = {code!r}: no run explains the measured "
            f"{'acceleration' if acc else 'displacement'} (best eq. 20 error {error:.1f} %; a run at rest scores "
            f"100 %); its peak in the scored window is {measured:.3g} {si}, the runs' {lo:.3g} .. {hi:.3g} {si}: {hint}",
        )
