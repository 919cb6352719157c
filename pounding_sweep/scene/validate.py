"""The physical and logical checks a scene must pass after its types are right: positive masses and
stiffnesses, r in [0, 1], one form of k_s, known schemes, laws and units, channels that name floors,
sizes that fit. Each failure is one ConfigError naming the key and the value."""

from __future__ import annotations

import math

from pounding_sweep import codes
from pounding_sweep.codes import (
    ACCEPTED_UNITS,
    CONTACT_LAWS,
    RESTITUTION_RELATIONS,
    SCHEMES,
    canonical_unit,
    is_nonlinear,
)
from pounding_sweep.errors import ConfigError, shown
from pounding_sweep.scene.axes import check_ks
from pounding_sweep.scene.channels import experiment_channel, is_acceleration, parse_channel
from pounding_sweep.scene.groups import METRIC_GROUPS
from pounding_sweep.scene.parameters import (
    FAMILIES,
    STIFFNESS_FORMS,
    bounds_out_of_range,
    channel_offset,
    member,
    names,
    out_of_range,
    parameter,
)
from pounding_sweep.scene.parameters import FITTABLE as ROLE_FITTABLE
from pounding_sweep.scene.schema import (
    ACC_UNITS,
    EXECUTORS,
    MAX_CALIBRATE_COUNTS,
    MAX_FLOORS,
    MAX_GRID,
    MAX_LOWPASS_ORDER,
    MAX_STEPS,
    MAX_THREADS,
    NOISE_M_RANGE,
    SENSOR_FILTERS,
    USES,
    WEIGHTINGS,
    BuildingConfig,
    Scene,
)
from pounding_sweep.scene.stochastic import validate_ensemble


def _positive(value, key):
    if value is not None and not value > 0:
        raise ConfigError(f"{key} = {value!r}: must be > 0")


DEFAULT_DAMPING_MODES = (1, 2)


def one_storey_damping_modes(bname: str, modes) -> str:
    """The message for damping_modes on a one-storey building (which has mode 1 only)."""
    return (
        f"[{bname}] damping_modes = {list(modes)}: a one-storey building has only mode 1, where damping_ratio "
        "is met by stiffness-proportional damping alone; remove damping_modes"
    )


def validate(s: Scene) -> None:
    """Physical and logical checks that the type coercion cannot make."""
    for bname in ("building1", "building2"):
        b: BuildingConfig | None = getattr(s, bname)
        if b is None:  # a single-building scene
            continue
        n = len(b.masses_kg)
        if n > MAX_FLOORS:
            raise ConfigError(
                f"[{bname}] masses_kg: {n:,} floors, more than the {MAX_FLOORS:,} a building may have "
                "(see python -m pounding_sweep --describe for what the engine supports)"
            )
        for v in b.masses_kg:
            _positive(v, f"[{bname}] masses_kg")
        has_k = b.story_stiffness_N_per_m is not None
        has_ei = b.column_EI_Nm2 is not None
        if has_k == has_ei:
            raise ConfigError(
                f"[{bname}]: give either story_stiffness_N_per_m or column_EI_Nm2 (+ n_columns, story_height_m), not {'both' if has_k else 'neither'}"
            )
        lists = {
            "story_stiffness_N_per_m": b.story_stiffness_N_per_m,
            "column_EI_Nm2": b.column_EI_Nm2,
            "story_height_m": b.story_height_m,
        }
        for k, vals in lists.items():
            if vals is None:
                continue
            if len(vals) not in (1, n):
                raise ConfigError(f"[{bname}] {k} has {len(vals)} values for {n} floors (give 1 or {n})")
            for v in vals:
                _positive(v, f"[{bname}] {k}")
        if has_ei and (b.n_columns is None or b.story_height_m is None):
            raise ConfigError(f"[{bname}]: column_EI_Nm2 needs n_columns and story_height_m")
        if b.n_columns is not None:
            _positive(b.n_columns, f"[{bname}] n_columns")
        _check_story_stiffness(b, bname, n)
        _check_story_scales(b, bname, n)
        explicit = b.rayleigh_a0_per_s is not None or b.rayleigh_a1_s is not None
        if explicit and b.damping_ratio is not None:
            raise ConfigError(f"[{bname}]: give damping_ratio or rayleigh_a0_per_s/rayleigh_a1_s, not both")
        for k in ("rayleigh_a0_per_s", "rayleigh_a1_s"):
            v = getattr(b, k)
            if v is not None and v < 0:
                raise ConfigError(f"[{bname}] {k} = {v!r}: must be >= 0")
        if b.damping_ratio is not None and not 0 <= b.damping_ratio < 1:
            raise ConfigError(f"[{bname}] damping_ratio = {b.damping_ratio!r}: must lie in [0, 1)")
        if n == 1 and tuple(b.damping_modes) != DEFAULT_DAMPING_MODES:
            raise ConfigError(one_storey_damping_modes(bname, b.damping_modes))
        if len(b.damping_modes) != 2 or len(set(b.damping_modes)) != 2 or not all(1 <= m <= n for m in b.damping_modes):
            if n > 1:
                raise ConfigError(
                    f"[{bname}] damping_modes = {shown(list(b.damping_modes))}: two different modes between 1 and {n}"
                )
    axes = {a.name: a.values for a in s.sweep}
    _check_single_building(s, axes)
    _check_structure_axes(s, axes)
    _check_calibrate(s)
    if s.contact is not None:
        _check_contact(s, axes)
    for k in ("amplitude_m", "frequency_Hz", "scale"):
        _check_axis(axes, k)
    _validate_rest(s, axes)


def require_two_buildings(s: Scene, what: str) -> None:
    """ConfigError naming the scene when `what` (a study of the gap between two buildings) is asked of one
    building on its own."""
    if s.single:
        raise ConfigError(
            f"{s.source}: a single-building scene (no [building2]): {what} needs two buildings and their "
            "[contact]; add them"
        )


def _check_single_building(s: Scene, axes: dict) -> None:
    """A single-building scene sweeps and fits no parameter of the contact or of a second building."""
    if not s.single:
        return
    named = [(f"[sweep] {n}", n) for n in axes]
    named += [(f"[calibrate] parameters.{n}", n) for n in (s.calibrate.parameters if s.calibrate else ())]
    for key, name in named:
        entry = parameter(name)  # a [sweep] axis, or a per-story or per-mode member
        section = entry.section if entry is not None else ""
        if section in ("contact", "building2"):
            raise ConfigError(
                f"{key}: a single-building scene (no [building2]) has no {'contact' if section == 'contact' else 'building 2'}"
                " to vary; add [building2] and [contact], or leave it out"
            )


def _check_contact(s: Scene, axes: dict) -> None:
    """[contact] and the contact axes: r, the laws, one form of k_s, positive stiffnesses, gaps >= 0."""
    c = s.contact
    _in_range("r", c.r, "[contact] r")
    _check_axis(axes, "r")
    _check_laws(c, axes)
    check_ks(c, axes)
    _in_range("ks_ratio", c.ks_ratio, "[contact] ks_ratio")
    _in_range("ks_N_per_m", c.ks_N_per_m, "[contact] ks_N_per_m")
    _positive(c.k_ref_N_per_m, "[contact] k_ref_N_per_m")
    for k in ("ks_ratio", "ks_N_per_m"):
        _check_axis(axes, k)
    _in_range("gap_m", c.gap_m, "[contact] gap_m")
    _check_axis(axes, "gap_m")


def _validate_rest(s: Scene, axes: dict) -> None:
    """The excitation, integration, output, execution and experiment sections."""
    e = s.excitation
    if e.type not in ("harmonic", "record", "stochastic"):
        raise ConfigError(f"[excitation] type = {e.type!r}: expected 'harmonic', 'record' or 'stochastic'")
    validate_ensemble(s)  # [stochastic], the seed axis, the intensity keys, [risk]
    if e.type == "stochastic":
        pass
    elif e.type == "harmonic":
        for k in ("amplitude_m", "frequency_Hz", "duration_s"):
            if getattr(e, k) is None and k not in axes:
                raise ConfigError(f"[excitation] missing key '{k}' for a harmonic excitation")
            _positive(getattr(e, k), f"[excitation] {k}")
        if "record" in axes or e.record is not None:
            raise ConfigError("[excitation] record: only for a record excitation (type = 'record')")
    else:
        if e.record is None and "record" not in axes:
            raise ConfigError("[excitation] missing key 'record' (path of the .AT2 or .csv file)")
        for k in ("amplitude_m", "frequency_Hz"):
            if getattr(e, k) is not None or k in axes:
                raise ConfigError(f"[excitation] {k}: only for a harmonic excitation")
        _positive(e.duration_s, "[excitation] duration_s")
    _positive(e.scale, "[excitation] scale")
    _positive(e.length_scale, "[excitation] length_scale")
    if e.format not in ("auto", "at2", "csv"):
        raise ConfigError(f"[excitation] format = {e.format!r}: expected 'auto', 'at2' or 'csv'")
    if e.units is not None:
        if canonical_unit(e.units) is None:
            raise ConfigError(f"[excitation] units = {e.units!r}: expected one of {ACCEPTED_UNITS}")
    i = s.integration
    if isinstance(i.dt_s, str):
        if i.dt_s != "auto":
            raise ConfigError(f"[integration] dt_s = {i.dt_s!r}: expected a time step in seconds or 'auto'")
        _positive(i.dt_tolerance, "[integration] dt_tolerance")
        _positive(i.dt_min_s, "[integration] dt_min_s")
        if not i.dt_max_s > i.dt_min_s:
            raise ConfigError(f"[integration] dt_max_s = {i.dt_max_s!r}: must be larger than dt_min_s = {i.dt_min_s!r}")
        if s.output.histories:
            raise ConfigError(
                "[output] histories need one time step for all runs: give [integration] dt_s a number "
                "(not 'auto'), e.g. the dt_s an 'auto' sweep chose"
            )
    else:
        _positive(i.dt_s, "[integration] dt_s")
    if i.scheme not in SCHEMES:
        raise ConfigError(f"[integration] scheme = {i.scheme!r}: expected one of {sorted(SCHEMES)}")
    _positive(i.max_contact_iterations, "[integration] max_contact_iterations")
    if i.min_steps_per_contact_period < 0:
        raise ConfigError(
            f"[integration] min_steps_per_contact_period = {i.min_steps_per_contact_period!r}: must be >= 0"
        )
    if e.type == "harmonic" and e.duration_s is not None and i.first_dt_s >= e.duration_s:
        raise ConfigError(
            f"[integration] dt_s = {i.first_dt_s!r}: must be shorter than [excitation] duration_s = {e.duration_s!r}"
        )
    if e.type == "harmonic" and e.duration_s is not None and e.duration_s / i.first_dt_s > MAX_STEPS:
        raise ConfigError(
            f"[integration] {'dt_max_s' if i.auto else 'dt_s'} = {i.first_dt_s!r}: {e.duration_s / i.first_dt_s:.3g} "
            f"steps over [excitation] duration_s = {e.duration_s!r}, more than {MAX_STEPS:,} (dt in the wrong units?)"
        )
    _positive(s.output.history_decimate, "[output] history_decimate")
    _check_metrics(s.output.metrics)
    for ch in s.output.histories:
        parse_channel(ch, s.floors)
    check_workers(s.execution.threads, "[execution] threads")
    if s.execution.batch_runs < 0:
        raise ConfigError(f"[execution] batch_runs = {s.execution.batch_runs}: must be >= 0")
    if s.execution.executor not in EXECUTORS:
        raise ConfigError(f"[execution] executor = {s.execution.executor!r}: expected one of {list(EXECUTORS)}")
    check_workers(s.execution.dask_workers, "[execution] dask_workers")
    if s.execution.dask_address:
        check_dask_address(s.execution.dask_address, "[execution] dask_address")
    if not (s.execution.dask_timeout_s > 0 and math.isfinite(s.execution.dask_timeout_s)):
        raise ConfigError(f"[execution] dask_timeout_s = {s.execution.dask_timeout_s!r}: must be > 0 s and finite")
    if s.execution.max_runs < 1:
        raise ConfigError(f"[execution] max_runs = {s.execution.max_runs}: must be >= 1")
    if s.execution.chunk_runs < 1:
        raise ConfigError(f"[execution] chunk_runs = {s.execution.chunk_runs}: must be >= 1")
    if s.experiment is not None:
        _validate_experiment(s)
    n = 1
    for a in s.sweep:
        n *= len(a.values)
    if n > MAX_GRID:
        raise ConfigError(f"[sweep]: {n} grid points exceed the limit of {MAX_GRID}")


def _check_metrics(metrics: tuple[str, ...] | None) -> None:
    """[output] metrics: metric group names (METRIC_GROUPS), each once, or 'all' or 'none' alone."""
    if metrics is None:
        return
    shown_key = f"[output] metrics = {shown(metrics[0] if len(metrics) == 1 else list(metrics))}"
    for name in metrics:
        if name not in (*METRIC_GROUPS, "all", "none"):
            raise ConfigError(
                f"{shown_key}: {shown(name)} is not a metric group (one of: {', '.join(METRIC_GROUPS)}; or 'all', 'none')"
            )
    if len(set(metrics)) != len(metrics):
        raise ConfigError(f"{shown_key}: a group named twice")
    if len(metrics) > 1 and ("all" in metrics or "none" in metrics):
        raise ConfigError(f"{shown_key}: 'all' and 'none' stand alone, not in a list of groups")


def _check_story_stiffness(b: BuildingConfig, bname: str, n: int) -> None:
    """Each story's stiffness, as the model forms it (k = n_columns 12 EI / h^3 from columns), must be a
    positive number whose stiffness matrix (2 k on the diagonal) stays finite: 1e308 N/m, or an EI and
    h that overflow, would otherwise end in the model's arithmetic."""
    if b.story_stiffness_N_per_m is not None:
        for k in b.story_stiffness_N_per_m:
            if not math.isfinite(2.0 * k):
                raise ConfigError(
                    f"[{bname}] story_stiffness_N_per_m = {k!r}: too large (the stiffness matrix overflows)"
                )
        return
    ei, h = (v if len(v) == n else v * n for v in (b.column_EI_Nm2, b.story_height_m))
    for e, hh in zip(ei, h):
        try:
            k = b.n_columns * 12.0 * e / hh**3
        except OverflowError:  # h^3 beyond the largest float
            k = 0.0
        except ZeroDivisionError:  # h^3 below the smallest
            k = math.inf
        if not (k > 0 and math.isfinite(2.0 * k)):
            raise ConfigError(
                f"[{bname}] column_EI_Nm2 = {e!r}, n_columns = {b.n_columns}, story_height_m = {hh!r}: "
                f"k = n_columns 12 EI / h^3 = {k!r} N/m, not a usable story stiffness"
            )


def _validate_experiment(s: Scene) -> None:
    x = s.experiment
    if (x.table is None) == (x.video is None):
        raise ConfigError(
            "[experiment]: give either table = '...' (a tracked-displacement table) or an "
            "[experiment.video] section (a video to track), not " + ("both" if x.table else "neither")
        )
    if x.video is not None and x.units != "mm":
        raise ConfigError(f"[experiment] units = {x.units!r}: a tracked video gives millimetres; use 'mm'")
    if not x.channels:
        raise ConfigError(
            "[experiment] channels: map at least one table column to a floor, e.g. "
            "channels = { model1_floor3_mm = 'b1f3' }"
        )
    if x.units not in ("mm", "m"):
        raise ConfigError(f"[experiment] units = {x.units!r}: expected 'mm' or 'm'")
    if x.combine not in ("mean", "max", "rms"):
        raise ConfigError(f"[experiment] combine = {x.combine!r}: expected 'mean', 'max' or 'rms'")
    if x.window_s is not None and (len(x.window_s) != 2 or not x.window_s[0] < x.window_s[1]):
        raise ConfigError(f"[experiment] window_s = {shown(list(x.window_s))}: expected [start, end] with start < end")
    if x.noise_window_s is not None and (len(x.noise_window_s) != 2 or not x.noise_window_s[0] < x.noise_window_s[1]):
        raise ConfigError(
            f"[experiment] noise_window_s = {shown(list(x.noise_window_s))}: expected [start, end] with start < end"
        )
    for col, v in (x.noise or {}).items():
        if col not in (x.channels or {}):
            raise ConfigError(
                f"[experiment] noise.{col} = {v!r}: '{col}' is not a mapped channel (channels: {', '.join(x.channels or {})})"
            )
        if not (math.isfinite(v) and v > 0):
            raise ConfigError(f"[experiment] noise.{col} = {v!r}: a noise standard deviation must be > 0")
    if x.max_lag_s < 0:
        raise ConfigError(f"[experiment] max_lag_s = {x.max_lag_s!r}: must be >= 0")
    _positive(x.refine_max_evals, "[experiment] refine_max_evals")
    if x.time_column in x.channels:
        raise ConfigError(
            f"[experiment] channels.{x.time_column} = {x.channels[x.time_column]!r}: '{x.time_column}' is the "
            "time column (time_column), not a displacement; map the floor's displacement column instead"
        )
    floors = s.floors
    seen = {}
    kinds = {}  # column -> codes.H_DISP or codes.H_ABS_ACC
    for col, target in x.channels.items():
        kinds[col], _ = experiment_channel(target, floors, f"[experiment] channels.{col}")
        if target in seen:
            raise ConfigError(f"[experiment] channels: '{seen[target]}' and '{col}' both map to floor '{target}'")
        seen[target] = col
    _validate_acceleration(x, kinds)


def _validate_acceleration(x, kinds: dict) -> None:
    """[experiment]'s acceleration keys (acc_units, lowpass_Hz, lowpass_order) and the combination (use,
    weights), given each channel's kind. The filter's cut-off against the table's Nyquist frequency is checked
    where the table is read (sweep/scoring.py lowpass_sections)."""
    acc = [c for c, k in kinds.items() if k == codes.H_ABS_ACC]
    if x.acc_units not in ACC_UNITS:
        raise ConfigError(f"[experiment] acc_units = {shown(x.acc_units)}: expected one of {list(ACC_UNITS)}")
    if acc and x.video is not None:
        raise ConfigError(
            f"[experiment] channels.{acc[0]} = {x.channels[acc[0]]!r}: a tracked video gives displacements only; "
            "score accelerations from a table (table = '...')"
        )
    if x.lowpass_Hz is not None:
        if not x.lowpass_Hz > 0:
            raise ConfigError(f"[experiment] lowpass_Hz = {x.lowpass_Hz!r}: a cut-off frequency must be > 0")
        if not acc:
            raise ConfigError(
                f"[experiment] lowpass_Hz = {x.lowpass_Hz!r}: it filters acceleration channels, and none is mapped "
                "(map one as 'abs_acc_b1f3', or leave lowpass_Hz out)"
            )
    if not 1 <= x.lowpass_order <= MAX_LOWPASS_ORDER:
        raise ConfigError(f"[experiment] lowpass_order = {x.lowpass_order}: expected 1 to {MAX_LOWPASS_ORDER}")
    _validate_sensor(x, acc)
    if x.use not in USES:
        raise ConfigError(f"[experiment] use = {shown(x.use)}: expected one of {list(USES)}")
    used = [c for c, k in kinds.items() if x.use == "both" or k == USES[x.use]]
    if not used:
        raise ConfigError(
            f"[experiment] use = {x.use!r}: no {x.use} channel is mapped (channels: "
            f"{', '.join(f'{c} = {t!r}' for c, t in x.channels.items())})"
        )
    if isinstance(x.weights, str):
        if x.weights not in WEIGHTINGS:
            raise ConfigError(
                f"[experiment] weights = {shown(x.weights)}: expected one of {list(WEIGHTINGS)} or a table "
                "column -> weight"
            )
        return
    for col, w in x.weights.items():
        if col not in x.channels:
            raise ConfigError(
                f"[experiment] weights.{col} = {w!r}: '{col}' is not a mapped channel (channels: "
                f"{', '.join(x.channels)})"
            )
        if col not in used:
            raise ConfigError(
                f"[experiment] weights.{col} = {w!r}: use = {x.use!r} leaves this channel out of the combined error"
            )
        if not w >= 0:
            raise ConfigError(f"[experiment] weights.{col} = {w!r}: a weight must be >= 0")
    missing = [c for c in used if c not in x.weights]
    if missing:
        raise ConfigError(f"[experiment] weights: no weight for channel '{missing[0]}' (use = {x.use!r} includes it)")
    if not any(x.weights[c] > 0 for c in used):
        raise ConfigError(f"[experiment] weights = {shown(x.weights)}: at least one weight must be > 0")


def _validate_sensor(x, acc: list[str]) -> None:
    """[experiment] sensor_filter and its settings (sweep/sensor.py); the sensor's rate against the table's
    is checked where the table is read."""
    f = x.sensor_filter
    if f not in SENSOR_FILTERS:
        raise ConfigError(f"[experiment] sensor_filter = {shown(f)}: expected one of {list(SENSOR_FILTERS)}")
    if f == "none":
        for key in ("sensor_rate_Hz", "sensor_cutoff_Hz"):
            if getattr(x, key) is not None:
                raise ConfigError(
                    f"[experiment] {key} = {getattr(x, key)!r}: sensor_filter = 'none' has no sensor to set "
                    "(give sensor_filter = 'average' or 'butter', or leave the key out)"
                )
        return
    if not acc:
        raise ConfigError(
            f"[experiment] sensor_filter = {f!r}: it models accelerometers, and no acceleration channel is mapped "
            "(map one as 'abs_acc_b1f3', or leave sensor_filter out)"
        )
    rate = x.sensor_rate_Hz
    if rate is not None and not (rate > 0 and math.isfinite(rate)):
        raise ConfigError(f"[experiment] sensor_rate_Hz = {rate!r}: a sample rate must be > 0 Hz and finite")
    if f == "average":
        if rate is None:
            raise ConfigError(
                "[experiment] sensor_filter = 'average': give sensor_rate_Hz, the sensor's internal rate it averages at"
            )
        if x.sensor_cutoff_Hz is not None:
            raise ConfigError(
                f"[experiment] sensor_cutoff_Hz = {x.sensor_cutoff_Hz!r}: sensor_filter = 'average' has no cut-off "
                "(its window is one output interval); use sensor_filter = 'butter' for a stated cut-off"
            )
        return
    cut = x.sensor_cutoff_Hz
    if cut is None:
        raise ConfigError("[experiment] sensor_filter = 'butter': give sensor_cutoff_Hz, the filter's cut-off in Hz")
    if not (cut > 0 and math.isfinite(cut)):
        raise ConfigError(f"[experiment] sensor_cutoff_Hz = {cut!r}: a cut-off frequency must be > 0 Hz and finite")
    if rate is not None and not cut < rate / 2:
        raise ConfigError(
            f"[experiment] sensor_cutoff_Hz = {cut!r}: at or above the Nyquist frequency {rate / 2:g} Hz of "
            f"sensor_rate_Hz = {rate!r}"
        )
    if not 1 <= x.sensor_order <= MAX_LOWPASS_ORDER:
        raise ConfigError(f"[experiment] sensor_order = {x.sensor_order}: expected 1 to {MAX_LOWPASS_ORDER}")


def _check_laws(c, axes: dict) -> None:
    """Known laws and relation; the Hertz-type laws' keys only where such a law runs; r = 0 refused where a
    law's damping would be infinite (hertzdamp, jankowski: a perfectly plastic impact)."""
    for law, key in [(c.law, "[contact] law")] + [(v, "[sweep] law") for v in axes.get("law", ())]:
        if law not in CONTACT_LAWS:
            raise ConfigError(f"{key} = {law!r}: expected one of {list(CONTACT_LAWS)}")
    if c.restitution_relation not in RESTITUTION_RELATIONS:
        raise ConfigError(
            f"[contact] restitution_relation = {c.restitution_relation!r}: expected one of {list(RESTITUTION_RELATIONS)}"
        )
    _positive(c.reference_penetration_m, "[contact] reference_penetration_m")
    _positive(c.min_impact_speed_m_s, "[contact] min_impact_speed_m_s")
    _in_range("kh_N_per_m1_5", c.kh_N_per_m1_5, "[contact] kh_N_per_m1_5")
    _check_axis(axes, "kh_N_per_m1_5")
    laws = set(axes.get("law", (c.law,)))
    hertz = {x for x in laws if is_nonlinear(CONTACT_LAWS[x])}
    has_kh = c.kh_N_per_m1_5 is not None or "kh_N_per_m1_5" in axes
    if has_kh and not hertz:
        raise ConfigError(
            f"[contact] kh_N_per_m1_5: only the Hertz-type laws use it (law = {sorted(laws)}); "
            "the linear laws take ks_ratio or ks_N_per_m"
        )
    if has_kh and not laws - hertz and (axes.keys() & {"ks_ratio", "ks_N_per_m"}):
        raise ConfigError(
            "[sweep]: ks_ratio / ks_N_per_m would not be used: every law here takes kh_N_per_m1_5 (drop one of the two)"
        )
    plastic = hertz & {"hertzdamp", "jankowski"}
    r_values = axes.get("r", (c.r,))
    if plastic and 0.0 in r_values:
        key = "[sweep] r" if "r" in axes else "[contact] r"
        raise ConfigError(
            f"{key} = 0.0 with law {sorted(plastic)[0]!r}: its damping is infinite at r = 0 (a perfectly "
            "plastic impact); use a small r such as 0.01"
        )


#: what [calibrate] may fit: the numeric sweep parameters (names and laws are chosen, not fitted)
FITTABLE = names(ROLE_FITTABLE)


def _check_calibrate(s: Scene) -> None:
    """[calibrate]: an experiment to fit; known parameters with bounds [lo, hi], lo < hi, inside each
    parameter's own range; counts that make sense."""
    cal = s.calibrate
    if cal is None:
        return
    if s.experiment is None:
        raise ConfigError("[calibrate]: fits the model to an experiment, and the scene has no [experiment]")
    if s.integration.auto:
        raise ConfigError(
            "[calibrate] with [integration] dt_s = 'auto': the calibration compares histories at one step; "
            "give dt_s a number (the auto ladder's choice for this scene, say)"
        )
    if not cal.parameters:
        raise ConfigError("[calibrate] parameters = {}: name at least one parameter to fit, with its bounds")
    for name, bounds in cal.parameters.items():
        key = f"[calibrate] parameters.{name}"
        if name not in FITTABLE and member(name) is None and channel_offset(name) is None:
            per_story = ", ".join(f"{f.name}_{f.per}<{'story' if f.per == 's' else 'mode'}>" for f in FAMILIES)
            raise ConfigError(
                f"{key}: not a parameter the calibration can fit (one of {', '.join(FITTABLE)}; per story or mode: "
                f"{per_story}; per channel: time_offset_s_<channel>)"
            )
        _check_member(s, name, key)
        _check_channel_offset(s, name, key)
        if len(bounds) != 2 or not bounds[0] < bounds[1]:
            raise ConfigError(f"{key} = {shown(bounds)}: expected bounds [low, high] with low < high")
        outside = bounds_out_of_range(name, float(bounds[0]), float(bounds[1]), key)
        if outside:
            raise ConfigError(outside)
    forms = [n for n in STIFFNESS_FORMS if n in cal.parameters]
    if len(forms) > 1:
        raise ConfigError(f"[calibrate] parameters: fit one form of the contact stiffness, not {' and '.join(forms)}")
    for name in cal.parameters:
        if name.startswith("damping_ratio_b"):
            b = getattr(s, f"building{name[-1]}")
            if b.damping_ratio is None:
                raise ConfigError(
                    f"[calibrate] parameters.{name}: [building{name[-1]}] gives no damping_ratio to fit "
                    "(explicit Rayleigh coefficients, or undamped)"
                )
    for key, most in MAX_CALIBRATE_COUNTS.items():
        if getattr(cal, key) < (0 if key in ("global_points", "profile_points") else 1):
            raise ConfigError(f"[calibrate] {key} = {getattr(cal, key)}: too small")
        if getattr(cal, key) > most:
            raise ConfigError(
                f"[calibrate] {key} = {getattr(cal, key):,}: more than {most:,}, the most a calibration runs "
                "(see python -m pounding_sweep --describe)"
            )
    for name in cal.profile:
        if name not in cal.parameters:
            raise ConfigError(f"[calibrate] profile: {name!r} is not among the fitted parameters")
    if cal.noise_m is not None and not NOISE_M_RANGE[0] <= cal.noise_m <= NOISE_M_RANGE[1]:
        raise ConfigError(
            f"[calibrate] noise_m = {cal.noise_m!r}: the tracking noise in metres lies in "
            f"[{NOISE_M_RANGE[0]:g}, {NOISE_M_RANGE[1]:g}] (1e-9 m: a nanometre)"
        )
    _positive(cal.misfit_factor, "[calibrate] misfit_factor")
    _check_start_from(s, cal)
    _check_calibrate_effect(s, cal)


def _check_start_from(s: Scene, cal) -> None:
    """[calibrate] start_from: identify's modes file, readable (scene/starts.py), holding the modes of a building
    whose structure is fitted."""
    if cal.start_from is None:
        return
    from pounding_sweep.scene.starts import read_modes

    modes = read_modes(cal.start_from)
    fitted = {p.section for n in cal.parameters if (p := parameter(n)) is not None and p.section.startswith("building")}
    if not fitted & {f"building{b}" for b in modes}:
        raise ConfigError(
            f"[calibrate] start_from = {cal.start_from!r}: holds the modes of building(s) "
            f"{', '.join(str(b) for b in sorted(modes))}, and the fit names no parameter of their structure "
            "(stiffness_scale_b<b>, damping_ratio_b<b>, story_stiffness_scale_b<b>_s<k>, modal_damping_ratio_b<b>_m<j>)"
        )


def _check_channel_offset(s: Scene, name: str, key: str) -> None:
    """A per-channel clock offset (time_offset_s_abs_acc_b1f3) names an [experiment] channel the fit compares
    (one `use` keeps), and leaves at least one channel on the table's own clock when time_offset_s is fitted too
    (else the table's offset and the channels' are one number asked for twice)."""
    code = channel_offset(name)
    if code is None:
        return
    x = s.experiment
    mapped = list(dict.fromkeys((x.channels or {}).values()))
    if code not in mapped:
        raise ConfigError(
            f"{key}: [experiment] channels maps no channel {code!r} (its channels: {', '.join(mapped) or 'none'}); "
            "name one as time_offset_s_<channel>"
        )

    def fitted(c: str) -> bool:  # the fit compares channel c (as `use` says)
        return x.use == "both" or USES.get(x.use) == (codes.H_ABS_ACC if is_acceleration(c) else codes.H_DISP)

    if not fitted(code):
        raise ConfigError(f"{key}: [experiment] use = {x.use!r} leaves channel {code!r} out of the fit")
    offsets = [n for n in s.calibrate.parameters if channel_offset(n) is not None]
    used = [c for c in mapped if fitted(c)]
    if "time_offset_s" in s.calibrate.parameters and len(offsets) >= len(used):
        raise ConfigError(
            f"{key}: with time_offset_s fitted, every channel's own offset too asks the data for one number twice "
            "(a shift of all channels is the table's offset); leave one channel on the table's clock"
        )


def _check_member(s: Scene, name: str, key: str) -> None:
    """A per-story name (story_stiffness_scale_b1_s2) names a story the building has."""
    found = member(name)
    if found is None:
        return
    fam, index = found
    part = getattr(s, fam.section)
    n = len(part.masses_kg)
    what, many = ("story", "stories") if fam.per == "s" else ("mode", "modes")
    if index > n:
        raise ConfigError(f"{key}: [{fam.section}] has {n} {what if n == 1 else many}, no {what} {index}")
    if fam.neutral is None and getattr(part, fam.key) is None:
        raise ConfigError(f"{key}: [{fam.section}] gives no {fam.key} to fit (give one value per {what})")


def _check_story_scales(b: BuildingConfig, bname: str, n: int) -> None:
    """story_stiffness_scales: one factor > 0 per story; modal_damping_ratios: one ratio in [0, 1) per mode, and
    the only form of damping given."""
    scales = b.story_stiffness_scales
    if scales is not None:
        if len(scales) != n:
            raise ConfigError(
                f"[{bname}] story_stiffness_scales = {shown(list(scales))}: one factor per story, {n} here "
                "(story 1 first)"
            )
        for v in scales:
            _positive(v, f"[{bname}] story_stiffness_scales")
    zeta = b.modal_damping_ratios
    if zeta is None:
        return
    if b.damping_ratio is not None or b.rayleigh_a0_per_s is not None or b.rayleigh_a1_s is not None:
        raise ConfigError(
            f"[{bname}]: give modal_damping_ratios, damping_ratio or rayleigh_a0_per_s/rayleigh_a1_s, one form of "
            "damping"
        )
    if len(zeta) != n:
        raise ConfigError(
            f"[{bname}] modal_damping_ratios = {shown(list(zeta))}: one ratio per mode, {n} here (mode 1 first)"
        )
    for v in zeta:
        _in_range(f"modal_damping_ratio_b{bname[-1]}_m1", v, f"[{bname}] modal_damping_ratios")


def _check_calibrate_effect(s: Scene, cal) -> None:
    """Every fitted parameter changes the runs of every law it is fitted for (a parameter that changes nothing is
    reported 'identified' with an infinite standard error, or leaves a law nothing to fit); r's bounds keep the
    damping finite (r = 0 is a perfectly plastic impact for hertzdamp and jankowski)."""
    params = cal.parameters
    if s.contact is None:  # one building: no contact parameter is fitted (_check_single_building)
        return
    laws = list(dict.fromkeys(s.axis_values("law") or (s.contact.law,)))
    law_key = "[sweep] law" if s.axis_values("law") else "[contact] law"
    if "amplitude_m" in params and s.excitation.type != "harmonic":
        raise ConfigError(
            "[calibrate] parameters.amplitude_m: changes nothing here, the excitation is a record "
            "(fit scale, the factor on its acceleration)"
        )
    hertz = [x for x in laws if is_nonlinear(CONTACT_LAWS[x])]
    linear = [x for x in laws if x not in hertz]
    if "kh_N_per_m1_5" in params and linear:
        raise ConfigError(
            f"[calibrate] parameters.kh_N_per_m1_5: changes nothing for {law_key} = {linear[0]!r} (a linear law "
            "takes k_s); fit ks_ratio, which sets k_h = k_s / sqrt(reference_penetration_m) for the Hertz-type laws"
        )
    has_kh = s.contact.kh_N_per_m1_5 is not None or bool(s.axis_values("kh_N_per_m1_5"))
    for form in ("ks_ratio", "ks_N_per_m"):
        if form in params and has_kh and not linear:
            raise ConfigError(
                f"[calibrate] parameters.{form}: changes nothing here: every law ({', '.join(laws)}) is Hertz-type "
                "and [contact] kh_N_per_m1_5 gives k_h; fit kh_N_per_m1_5 instead"
            )
    if "r" in params:
        if laws == ["hertz"]:
            raise ConfigError(
                f"[calibrate] parameters.r: changes nothing for {law_key} = 'hertz' (elastic: no damping); "
                "fit the stiffness, or use hertzdamp or jankowski"
            )
        if "hertz" in laws and not set(params) - {"r"}:
            raise ConfigError(
                "[calibrate] parameters: only r, which changes nothing for [sweep] law = 'hertz' (elastic): that law "
                "would have nothing to fit; add its stiffness"
            )
        plastic = [x for x in laws if x in ("hertzdamp", "jankowski")]
        if plastic and params["r"][0] <= 0:
            raise ConfigError(
                f"[calibrate] parameters.r = {shown(list(params['r']))}: law {plastic[0]!r} has infinite damping at "
                "r = 0 (a perfectly plastic impact); start the bounds above 0, e.g. 0.01"
            )


def _check_structure_axes(s: Scene, axes: dict) -> None:
    """The structure's scales (> 0), damping ratios in [0, 1) on a building damped by damping_ratio, and a
    time offset only where there is an experiment to offset."""
    for bname, b in (("building1", s.building1), ("building2", s.building2)):
        if b is None:
            continue
        _positive(b.stiffness_scale, f"[{bname}] stiffness_scale")
        _positive(b.mass_scale, f"[{bname}] mass_scale")
    for name in axes:
        if name.startswith(("stiffness_scale_b", "mass_scale_b")):
            _check_axis(axes, name)
        elif name.startswith("damping_ratio_b"):
            b = getattr(s, f"building{name[-1]}")
            if b.rayleigh_a0_per_s is not None or b.rayleigh_a1_s is not None:
                raise ConfigError(
                    f"[sweep] {name}: [building{name[-1]}] is damped by explicit Rayleigh coefficients; "
                    "sweep its damping_ratio only where the scene gives one"
                )
            _check_axis(axes, name)
        elif name == "time_offset_s" and s.experiment is None:
            raise ConfigError("[sweep] time_offset_s: shifts an experiment's clock, and the scene has no [experiment]")


def _in_range(name: str, value, key: str) -> None:
    """A value of parameter `name` (scene/parameters.py) inside its range; None (not given) passes."""
    outside = out_of_range(name, value, key)
    if outside:
        raise ConfigError(outside)


def _check_axis(axes: dict, name: str) -> None:
    """Every value of the [sweep] axis `name` (where swept) inside the parameter's range."""
    for v in axes.get(name, ()):
        _in_range(name, v, f"[sweep] {name}")


def check_workers(value: int, key: str) -> None:
    """A thread or worker-process count: 0 (every core) up to MAX_THREADS."""
    said = f"{key} {value}" if key.startswith("--") else f"{key} = {value}"  # an option, or a scene key
    if value < 0:
        raise ConfigError(f"{said}: must be >= 0")
    if value > MAX_THREADS:
        raise ConfigError(f"{said}: more than {MAX_THREADS:,}, the most a sweep starts (0: every core)")


#: how a Dask scheduler address is written: tcp://host:port (or tls://, ucx://, ws://, wss://), or host:port
_SCHEMES = ("tcp", "tls", "ucx", "ws", "wss")


def check_dask_address(address: str, key: str) -> None:
    """The form of a scheduler address (whether a scheduler answers there is found when connecting)."""
    import re

    scheme, sep, rest = address.partition("://")
    if not sep:  # host:port is tcp://host:port to Dask
        scheme, rest = "tcp", address
    host, colon, port = rest.rpartition(":")
    ok = (
        scheme in _SCHEMES
        and bool(colon)
        and port.isdigit()
        and 0 < int(port) < 65536
        and re.fullmatch(r"[A-Za-z0-9._-]+|\[[0-9A-Fa-f:.]+\]", host) is not None
    )
    if not ok:
        said = f"{key} {shown(address)}" if key.startswith("--") else f"{key} = {shown(address)}"
        raise ConfigError(f"{said}: not a scheduler address; expected tcp://HOST:PORT, e.g. 'tcp://10.0.0.5:8786'")
