"""The scene as frozen dataclasses: every section and key, with the docstring `--describe` prints.

Plain data, no checks (scene/parse.py builds them from TOML, scene/validate.py checks them).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

from pounding_sweep import codes
from pounding_sweep.scene.risk import RiskConfig
from pounding_sweep.scene.stochastic import StochasticConfig
from pounding_sweep.scene.video import VideoSpec  # plain data; OpenCV stays unimported


def _f(doc: str, default=dataclasses.MISSING, when: str | None = None, **kw):
    """A field with its --describe text; `when`: when a key whose default is None is required (or what
    leaving it out means)."""
    meta = {"doc": doc, "when": when}
    if default is dataclasses.MISSING:
        return field(metadata=meta, **kw)
    return field(default=default, metadata=meta, **kw)


EXECUTORS = ("local", "dask")
#: [experiment] acc_units (model/experiment.py converts them, with records.G_STANDARD for g)
ACC_UNITS = ("m/s2", "g")
#: [experiment] use: which kind of channel enters the combined error ('both': every channel)
USES = {"displacement": codes.H_DISP, "acceleration": codes.H_ABS_ACC, "both": None}
#: [experiment] sensor_filter: the accelerometers' own filter before sampling (sweep/sensor.py)
SENSOR_FILTERS = ("none", "average", "butter")
#: [experiment] weights as a word (or a table column -> weight)
WEIGHTINGS = ("equal", "noise")
#: [experiment] lowpass_order: a Butterworth filter in second-order sections is well conditioned at any
#: order; beyond 12 poles a filter on a few hundred samples is mostly its own start-up transient
MAX_LOWPASS_ORDER = 12
MAX_AXIS_VALUES = 10_000_000  # a range longer than this is a typo, not a sweep
MAX_STEPS = 100_000_000  # steps of one harmonic run (records: the same limit on resampling, records._MAX_SAMPLES)
MAX_GRID = 50_000_000
#: floors of one building: the model's matrices are (floors of both)^2, a run's cost about floors^3.5 on the
#: scalar kernel (the engine's limits: scene/describe.py LIMITS); a longer list is a mistake, not a building
MAX_FLOORS = 1000
#: threads of the local executor, and processes of a Dask LocalCluster: more than any machine has cores
MAX_THREADS = 1024
#: [calibrate] counts (sweep/calibrate.py): the global stage's Sobol points are run as one batch and each
#: profile point is a least-squares refit of the other parameters (up to max_evals / 4 runs), so these bound
#: the work and memory of a calibration that runs after the grid; far above what a fit of a dozen
#: parameters needs (2^12 Sobol points cover 12 dimensions with 2 points per axis-halving)
MAX_CALIBRATE_COUNTS = {"global_points": 4096, "starts": 64, "max_evals": 10_000, "profile_points": 200}
#: [calibrate] noise_m [m]: residuals are divided by it and squared; below a nanometre no tracking measures,
#: above a metre it is not a shake-table test (and 1e-300 would overflow the squares)
NOISE_M_RANGE = (1e-9, 1.0)

# ----------------------------------------------------------------------------- sections


@dataclass(frozen=True)
class BuildingConfig:
    """One shear frame. Floor 1 is the lowest. Give story stiffnesses, or column EI + count + height."""

    masses_kg: tuple[float, ...] = _f("floor masses [kg], floor 1 first")
    name: str = _f("label used in outputs", "")
    story_stiffness_N_per_m: tuple[float, ...] | None = _f(
        "lateral stiffness of each story [N/m] (one value: the same for every story)",
        None,
        when="required unless column_EI_Nm2 is given",
    )
    column_EI_Nm2: tuple[float, ...] | None = _f(
        "column flexural stiffness EI [N m^2] (k = n_columns 12 EI / h^3)",
        None,
        when="instead of story_stiffness_N_per_m",
    )
    n_columns: int | None = _f("columns per story", None, when="required with column_EI_Nm2")
    story_height_m: tuple[float, ...] | None = _f(
        "story height h [m] (one value: every story): with column_EI_Nm2 it sets k = n 12 EI / h^3; with either form "
        "it gives the drift ratios (peak_drift_ratio_*) and the floors' heights for gap studies",
        None,
        when="required with column_EI_Nm2; optional otherwise",
    )
    damping_ratio: float | None = _f(
        "Rayleigh damping ratio matched at damping_modes (0.0105 = 1.05 %)",
        None,
        when="optional; without it or rayleigh_a0_per_s/rayleigh_a1_s the building is undamped",
    )
    damping_modes: tuple[int, ...] = _f(
        "the two modes (1-based) at which damping_ratio holds (not with one storey)", (1, 2)
    )
    rayleigh_a0_per_s: float | None = _f(
        "explicit Rayleigh mass coefficient a0 [1/s]", None, when="optional, instead of damping_ratio"
    )
    rayleigh_a1_s: float | None = _f(
        "explicit Rayleigh stiffness coefficient a1 [s]", None, when="optional, instead of damping_ratio"
    )
    stiffness_scale: float = _f(
        "multiplies every story stiffness (model error: a [sweep] axis or a fitted parameter as stiffness_scale_b1/_b2)",
        1.0,
    )
    mass_scale: float = _f("multiplies every floor mass (a [sweep] axis or fitted as mass_scale_b1/_b2)", 1.0)
    modal_damping_ratios: tuple[float, ...] | None = _f(
        "damping ratio of each mode, mode 1 first, one per mode: C = M Phi diag(2 zeta_n omega_n / M_n) Phi^T M "
        "(Chopra, Dynamics of Structures, sec. 11.5); each fitted as modal_damping_ratio_b1_m1, _m2, ...",
        None,
        when="optional, instead of damping_ratio or rayleigh_a0_per_s/rayleigh_a1_s",
    )
    story_stiffness_scales: tuple[float, ...] | None = _f(
        "a factor on each story's stiffness, story 1 first, on top of stiffness_scale (a frame whose stories differ "
        "from the model's: each fitted as story_stiffness_scale_b1_s1, _s2, ...)",
        None,
        when="optional; one value per story",
    )

    def story_heights(self) -> tuple[float, ...] | None:
        """Each story's height [m], story 1 first (one value given: every story's); None where none is given."""
        h = self.story_height_m
        if not h:
            return None
        return tuple(h) * len(self.masses_kg) if len(h) == 1 else tuple(h)


@dataclass(frozen=True)
class ContactConfig:
    """Pounding element at each facing floor pair: Kelvin-Voigt (eqs. 8-10) or a Hertz-type law."""

    r: float = _f("coefficient of restitution r in [0, 1] (eq. 10; each law's own relation: restitution_relation)")
    gap_m: float = _f("seismic gap d [m] between facing floors at rest", 0.0)
    ks_ratio: float | None = _f(
        "contact stiffness as a ratio k_s / k_ref", None, when="required unless ks_N_per_m is given, or either swept"
    )
    ks_N_per_m: float | None = _f("contact stiffness k_s [N/m]", None, when="instead of ks_ratio")
    k_ref_N_per_m: float = _f("reference story stiffness k for ks_ratio [N/m] (paper: 6830)", 6830.0)
    law: str = _f(
        "'classic' (eq. 8, may pull briefly before separation), 'no_tension' (force >= 0), 'hertz' "
        "(k_h delta^1.5), 'hertzdamp' (Muthukumar & DesRoches 2006) or 'jankowski' (Jankowski 2005)",
        "classic",
    )
    kh_N_per_m1_5: float | None = _f(
        "Hertz-type laws: k_h [N/m^1.5] (default: k_s / sqrt(reference_penetration_m), the same force as k_s "
        "at that penetration)",
        None,
    )
    reference_penetration_m: float = _f(
        "Hertz-type laws: the penetration at which k_h delta^1.5 equals k_s delta, so k_s (or k_s/k) means "
        "the same for every law [m]",
        1e-3,
    )
    restitution_relation: str = _f(
        "how r sets each law's damping: 'authors' (eq. 10; hertzdamp: Ye et al. 2009; jankowski: Jankowski "
        "2006), 'exact' (a single free impact returns exactly r, for every law) or 'muthukumar2006' "
        "(hertzdamp: the original Lankarani-Nikravesh relation)",
        "authors",
    )
    min_impact_speed_m_s: float = _f(
        "hertzdamp: floor on an impact's approach speed v0 (its damping scales as 1 / v0); runs where the "
        "floor acts are flagged grazing_impact [m/s]",
        0.01,
    )


@dataclass(frozen=True)
class ExcitationConfig:
    """Table motion: harmonic displacement, a recorded ground acceleration, or a stochastic one ([stochastic])."""

    type: str = _f("'harmonic', 'record' or 'stochastic' (filtered white noise: the [stochastic] section)")
    name: str = _f("label used in outputs", "")
    amplitude_m: float | None = _f(
        "harmonic: table displacement amplitude [m]", None, when="required for type = 'harmonic'"
    )
    frequency_Hz: float | None = _f("harmonic: table frequency [Hz]", None, when="required for type = 'harmonic'")
    duration_s: float | None = _f(
        "length of the run [s] (a record: longer pads zeros)",
        None,
        when="required for type = 'harmonic'; a record's own length by default",
    )
    record: str | None = _f(
        "record: path of a PEER .AT2 or a two-column CSV (time [s], acceleration)",
        None,
        when="required for type = 'record', unless [sweep] record",
    )
    format: str = _f("record format: 'auto' (by suffix), 'at2' or 'csv'", "auto")
    units: str | None = _f(
        "record acceleration units: 'g', 'm/s2' or 'cm/s2' (an AT2 header naming others is an error)",
        None,
        when="default: an AT2's header's units, else g; a CSV's m/s2",
    )
    scale: float = _f("factor on the motion's acceleration (scaling = 'intensity': the motion's intensity in g)", 1.0)
    length_scale: float = _f(
        "similitude length scale lambda_L (eqs. 17-19): time / sqrt(lambda_L), acceleration kept", 1.0
    )
    intensity: str = _f(
        "record or stochastic: each motion's intensity measure, 'pga' or 'sa' (5 %-damped pseudo-spectral "
        "acceleration at intensity_period_s, exact for piecewise-linear input: Nigam & Jennings 1969), written "
        "per run as intensity_g; 'none': not computed",
        "none",
    )
    scaling: str = _f(
        "'factor': scale multiplies each motion (cloud analysis); 'intensity': each motion is scaled so that its "
        "intensity is scale g (incremental dynamic analysis with [sweep] scale as the levels)",
        "factor",
    )
    intensity_period_s: float | None = _f(
        "intensity = 'sa': the period T of Sa(T) [s]",
        None,
        "default: the geometric mean of the two buildings' first periods",
    )


@dataclass(frozen=True)
class IntegrationConfig:
    """Time integration: Newmark average acceleration (gamma = 1/2, beta = 1/4)."""

    dt_s: float | str = _f(
        "time step [s], or 'auto': per run, halved from dt_max_s until the run's result changes "
        "by less than dt_tolerance (step doubling with a Richardson estimate)",
        1e-4,
    )
    dt_tolerance: float = _f(
        "dt_s = 'auto': relative error allowed in the scored errors (fractions of the "
        "experiment's RMS) and peaks, or without an experiment in the peak displacements and forces",
        1e-3,
    )
    dt_max_s: float = _f("dt_s = 'auto': the coarsest step tried [s]", 2e-3)
    dt_min_s: float = _f("dt_s = 'auto': the finest step tried [s]; runs above the tolerance there are flagged", 1e-6)
    scheme: str = _f(
        "'implicit' (contact in the step, active set), 'event' (steps split at contact switches: second order) "
        "or 'paper' (trial force as load, sec. 2)",
        "event",
    )
    max_contact_iterations: int = _f(
        "implicit scheme: active-set iterations per step before the step is taken as the event scheme takes it "
        "(its contact switches located)",
        16,
    )
    min_steps_per_contact_period: float = _f("flag runs with fewer steps per contact period 2 pi sqrt(m_eff/k_s)", 20.0)

    @property
    def auto(self) -> bool:
        return self.dt_s == "auto"

    @property
    def first_dt_s(self) -> float:
        """The fixed dt, or with 'auto' the coarsest one tried."""
        return self.dt_max_s if self.auto else self.dt_s


@dataclass(frozen=True)
class OutputConfig:
    """Where results go, which time histories to keep and which metric groups to compute."""

    path: str = _f(
        "Parquet dataset folder of one row per run (relative to the scene file)",
        "",
        when="default: results/<name>.parquet",
    )
    histories: tuple[str, ...] = _f(
        "history channels: disp_b1f3, vel_b2f1, abs_acc_b1f3, force_f3, ground_acc (none: metrics only)", ()
    )
    history_decimate: int = _f("keep every n-th step of the histories", 1)
    metrics: tuple[str, ...] | None = _f(
        "the metric groups each run computes: energy (the energy balance, energy_residual flag), drift (peak story "
        "drifts), closest (closest approach), phases (compression time, phases, median phase, median_truncated "
        "flag), accel (peak absolute floor accelerations), or 'all' / 'none'; a group left out is NaN in its "
        "columns and skipped by the lane kernel's steps. What a study reads is computed whatever this says",
        None,
        when="default: all; a risk study's runs: only the groups the study reads",
    )


@dataclass(frozen=True)
class ExecutionConfig:
    """How the grid is run on this machine."""

    threads: int = _f("worker threads of the local executor (0: all cores)", 0)
    batch_runs: int = _f("runs handed to a thread at a time (0: automatic)", 0)
    executor: str = _f(
        "'local' (threads in this process) or 'dask' (Dask distributed: a LocalCluster, or the "
        "scheduler at dask_address)",
        "local",
    )
    dask_address: str = _f("scheduler address, e.g. 'tcp://10.0.0.5:8786' (empty: start a LocalCluster here)", "")
    dask_workers: int = _f("worker processes of the LocalCluster, one thread each (0: all cores)", 0)
    dask_timeout_s: float = _f(
        "seconds a Dask scheduler has to answer, and a lost scheduler or lost workers to come back, before the "
        "sweep stops (the parts written so far are kept)",
        10.0,
    )
    chunk_runs: int = _f("runs per result part (Parquet file) and per task", 4096)
    max_runs: int = _f("largest grid run without confirmation (the command line's --yes lifts it)", 2_000_000)


@dataclass(frozen=True)
class ExperimentConfig:
    """Tracked displacement, and measured acceleration, to score every run against (CSV or Parquet; see the
    README's format)."""

    table: str | None = _f(
        "path of the table of tracked displacement (and measured acceleration) (.csv or .parquet)",
        None,
        when="required unless an [experiment.video] section names a video to track",
    )
    channels: dict | None = _f(
        "table column -> model floor: 'b1f3' for the floor's displacement relative to the table, "
        "'abs_acc_b1f3' for its absolute acceleration (an accelerometer), e.g. "
        "{model1_floor3 = 'b1f3', b1f3_acc = 'abs_acc_b1f3'}",
        None,
        when="required with a table; with a video every marker named by a floor",
    )
    time_column: str = _f("name of the time column [s]", "t_s")
    units: str = _f("units of the displacement columns: 'mm' or 'm'", "mm")
    acc_units: str = _f(
        "units of the acceleration columns: 'm/s2' (or 'm/s^2') or 'g' (9.80665 m/s^2); an import's table records "
        "its columns' units, and a scene reading them otherwise is refused",
        "m/s2",
    )
    lowpass_Hz: float | None = _f(
        "cut-off [Hz] of a Butterworth low-pass filter applied alike to the acceleration channels' samples of "
        "the experiment (scipy.signal.sosfilt) and of every run (the same sections, in the kernel): causal, from "
        "rest at the window's start; below the table's Nyquist frequency",
        None,
        when="optional; without it accelerations are compared unfiltered",
    )
    lowpass_order: int = _f("order of that Butterworth filter (1-12)", 4)
    sensor_filter: str = _f(
        "the accelerometers' own filter before they output a sample (sweep/sensor.py), run on the model's "
        "acceleration at every simulation step, then sampled at the table's instants: 'average' (a moving average "
        "of its internal samples over one output interval: a MEMS part's decimation), 'butter' (a Butterworth "
        "low-pass of sensor_order and sensor_cutoff_Hz at sensor_rate_Hz, or at the simulation step: analog), "
        "'none' (the model's acceleration sampled as it is)",
        "none",
    )
    sensor_rate_Hz: float | None = _f(
        "the accelerometers' internal sample rate [Hz] ('average': a multiple of the table's rate)",
        None,
        when="required with sensor_filter = 'average'; optional with 'butter' (without it: an analog filter)",
    )
    sensor_cutoff_Hz: float | None = _f(
        "cut-off [Hz] of the sensor's Butterworth low-pass; below half of sensor_rate_Hz",
        None,
        when="required with sensor_filter = 'butter'",
    )
    sensor_order: int = _f("order of the sensor's Butterworth low-pass (1-12)", 2)
    use: str = _f(
        "channels whose eq. 20 errors make the combined error (and the refinement's objective): "
        "'displacement', 'acceleration' or 'both' (every channel is scored and written either way)",
        "both",
    )
    weights: dict[str, float] | str = _f(
        "weights of those channels in the combined error: 'equal', 'noise' (each channel by its "
        "signal-to-noise ratio squared, (RMS / noise floor)^2, the noise floor estimated from the table by "
        "differences; with combine = 'rms', least squares weighted by the inverse noise variance), or a table "
        "column -> weight, e.g. {model1_floor3 = 1.0, b1f3_acc = 0.5} ('max' uses only which are > 0)",
        "equal",
    )
    window_s: tuple[float, ...] | None = _f(
        "[start, end] of the compared window in simulation time [s]", None, when="default: all overlap"
    )
    noise: dict[str, float] | None = _f(
        "table column -> its measurement noise (standard deviation) in the column's own units (units for a "
        "displacement, acc_units for an acceleration), e.g. {b1f3_acc_m_s2 = 0.0095}: the noise floor of 'noise' "
        "weights and of [calibrate]'s residuals",
        None,
        when="optional; else noise_window_s, else estimated from the table by differences (an upper bound)",
    )
    noise_window_s: tuple[float, ...] | None = _f(
        "[start, end] of a quiet stretch of the table in experiment time [s] (nothing moves: before the shaking): "
        "each channel's standard deviation there is its noise",
        None,
        when="optional; noise gives a channel's value directly",
    )
    time_offset_s: float = _f(
        "experiment time minus simulation time [s] (the table's t = offset is the simulation's t = 0)", 0.0
    )
    max_lag_s: float = _f("largest lag searched for the best correlation [s]", 0.1)
    combine: str = _f(
        "how the channels (use) combine into one error: the 'mean', 'max' or 'rms' of their eq. 20 errors, "
        "weighted by weights",
        "mean",
    )
    refine: bool = _f("after the grid, minimise the combined error over continuous k_s/k and r (scipy.optimize)", False)
    refine_max_evals: int = _f("simulations the refinement may spend", 80)
    video: VideoSpec | None = _f(
        "[experiment.video]: a shake-table video whose LED markers are tracked into the "
        "table (see python -m pounding_sweep track --help for its keys)",
        None,
        when="instead of table",
    )


@dataclass(frozen=True)
class Axis:
    """One sweep axis: a scene parameter and its values."""

    name: str
    values: tuple


@dataclass(frozen=True)
class CalibrateConfig:
    """Fit contact and structure together to the experiment, with uncertainty (sweep/calibrate.py)."""

    parameters: dict[str, tuple[float, ...]] = _f(
        "the parameters to fit and their bounds, e.g. { ks_ratio = [0.1, 10], r = [0.05, 1], stiffness_scale_b1 = "
        "[0.95, 1.05] }: any numeric [sweep] name (contact, excitation scale, the structure's scales and damping "
        "ratios, time_offset_s); per story or mode story_stiffness_scale_b1_s2, modal_damping_ratio_b1_m1; per "
        "channel time_offset_s_<channel> (e.g. time_offset_s_abs_acc_b1f3: that channel's clock on top of "
        "time_offset_s, bounded inside half its building's first period)"
    )
    global_points: int = _f("Sobol points of the global stage (scipy.stats.qmc, a power of 2)", 64)
    starts: int = _f("local least-squares starts: the best global points (and the sweep's best cell)", 3)
    max_evals: int = _f("simulations each local start may spend", 200)
    profile_points: int = _f("points of each profile curve (ks_ratio and r: fixed on a ladder, the rest refitted)", 9)
    profile: tuple[str, ...] = _f(
        "the parameters to profile", (), when="optional; by default the fitted contact parameters (k_s or k_h, r)"
    )
    noise_m: float | None = _f(
        "the tracking noise (RMS) of every displacement channel [m] (an acceleration channel's: [experiment] noise "
        "or noise_window_s)",
        None,
        when="optional; by default estimated from the data",
    )
    misfit_factor: float = _f("warn when the best fit's residual exceeds this many times the noise floor", 3.0)
    start_from: str | None = _f(
        "a modes file of identify (python -m pounding_sweep identify TABLE --modes-out FILE): a start of the fit "
        "from its values: modal_damping_ratio_b<b>_m<j> mode j's identified damping, damping_ratio_b<b> mode 1's, "
        "stiffness_scale_b<b> and story_stiffness_scale_b<b>_s<k> the factor that puts the model's first mode at the "
        "identified one (each clipped into its bounds; the other fitted values the grid's best cell's, else the "
        "scene's)",
        None,
        when="optional; a path relative to the scene file",
    )


@dataclass(frozen=True)
class Scene:
    """A whole scene, resolved and validated. Paths are absolute."""

    name: str
    description: str
    building1: BuildingConfig
    building2: BuildingConfig | None  # None: a single-building scene (no [building2], no [contact])
    contact: ContactConfig | None  # None exactly when building2 is
    excitation: ExcitationConfig
    integration: IntegrationConfig
    output: OutputConfig
    execution: ExecutionConfig
    sweep: tuple[Axis, ...]
    source: str  # the scene file
    toml_text: str  # the scene file as written
    experiment: ExperimentConfig | None = None
    calibrate: CalibrateConfig | None = None
    stochastic: StochasticConfig | None = None
    risk: RiskConfig | None = None

    def canonical(self) -> dict:
        """Resolved scene as plain data (what the hash covers): scene/hashing.py."""
        from pounding_sweep.scene.hashing import canonical

        return canonical(self)

    def config_hash(self) -> str:
        """SHA-256 of the canonical scene: identifies a sweep (Parquet metadata, resume)."""
        from pounding_sweep.scene.hashing import config_hash

        return config_hash(self)

    @property
    def single(self) -> bool:
        """One building on its own (no [building2]): no contact pairs, no contact columns."""
        return self.building2 is None

    @property
    def floors(self) -> tuple[int, int]:
        """Floors of building 1 and of building 2 (0 in a single-building scene)."""
        return len(self.building1.masses_kg), 0 if self.building2 is None else len(self.building2.masses_kg)

    def axis_values(self, name: str) -> tuple:
        """The values of the sweep axis `name` (empty when it is not swept)."""
        for a in self.sweep:
            if a.name == name:
                return a.values
        return ()


SECTIONS = {
    "building1": BuildingConfig,
    "building2": BuildingConfig,
    "contact": ContactConfig,
    "excitation": ExcitationConfig,
    "integration": IntegrationConfig,
    "output": OutputConfig,
    "execution": ExecutionConfig,
}
TOP_KEYS = {"name", "description", "sweep", "experiment", "calibrate", "stochastic", "risk", *SECTIONS}
