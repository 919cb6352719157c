"""Ensembles of ground motions in a scene: the `[stochastic]` section (with `[excitation] type = 'stochastic'`), a
filtered-white-noise ground motion whose realisation is a seed (`seed`, or a `[sweep] seed` axis), and the
checks of `[excitation]`'s intensity keys and of `[risk]`. Plain data and checks; the motion itself is
model/stochastic.py (its docstring has the filters, the envelope and the sampling), the intensity measures
model/intensity.py."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from pounding_sweep.errors import ConfigError, shown

FILTERS = ("kanai_tajimi", "clough_penzien")
ENVELOPES = ("none", "jennings")
STARTS = ("stationary", "rest")
#: seeds are SeedSequence entropy: non-negative integers; a float above 2^53 is no longer an exact integer
MAX_SEED = 2**53


def _f(doc: str, default=None, when: str | None = None):
    """An optional key with its --describe text."""
    return field(default=default, metadata={"doc": doc, "when": when})


def _required(doc: str):
    """A required key with its --describe text."""
    return field(metadata={"doc": doc, "when": None})


@dataclass(frozen=True)
class StochasticConfig:
    """Filtered white noise (Kanai-Tajimi or Clough-Penzien), stationary or enveloped; a realisation per seed."""

    ground_frequency_Hz: float = _required("soil filter frequency f_g [Hz] (w_g = 2 pi f_g)")
    ground_damping: float = _required("soil filter damping ratio zeta_g [-]")
    s0_m2_per_s3: float = _required(
        "two-sided spectral density S0 of the bedrock white noise, E[w(t) w(t + tau)] = 2 pi S0 delta(tau) [m^2/s^3]"
    )
    filter: str = _f("'kanai_tajimi' or 'clough_penzien' (a second, high-pass filter)", "kanai_tajimi")
    highpass_frequency_Hz: float | None = _f(
        "Clough-Penzien high-pass frequency f_f [Hz]", None, "required with filter = 'clough_penzien'"
    )
    highpass_damping: float | None = _f(
        "Clough-Penzien high-pass damping ratio zeta_f [-]", None, "required with filter = 'clough_penzien'"
    )
    envelope: str = _f("'none' (stationary) or 'jennings' (Jennings, Housner & Tsai 1968)", "none")
    rise_s: float | None = _f("jennings: end t1 of the (t / t1)^2 rise [s]", None, "required with envelope")
    strong_end_s: float | None = _f("jennings: end t2 of the strong phase [s]", None, "required with envelope")
    decay_per_s: float | None = _f("jennings: decay rate c of exp(-c (t - t2)) [1/s]", None, "required with envelope")
    start: str = _f(
        "'stationary' (the filter's state drawn from its stationary distribution: stationary from t = 0) or 'rest'",
        "stationary",
    )
    sample_dt_s: float | None = _f(
        "sample step of the generated motion [s] (the engine interpolates linearly between samples)",
        None,
        "default: [integration] dt_s",
    )
    seed: int = _f("the realisation's seed when [sweep] has no seed axis (a non-negative integer)", 0)


def check_seed(value, key: str) -> None:
    """A seed: a non-negative integer (a float axis value must be a whole number)."""
    if not (isinstance(value, int | float) and math.isfinite(value) and value == int(value) and 0 <= value < MAX_SEED):
        raise ConfigError(f"{key} = {shown(value)}: a seed is a whole number from 0 to 2^53")


INTENSITIES = ("none", "pga", "sa")
SCALINGS = ("factor", "intensity")


def validate_ensemble(scene) -> None:
    """The stochastic excitation, the intensity keys of [excitation], and [risk]."""
    from pounding_sweep.scene.risk import validate_risk

    validate_stochastic(scene)
    e = scene.excitation
    if e.intensity not in INTENSITIES:
        raise ConfigError(f"[excitation] intensity = {shown(e.intensity)}: expected one of {list(INTENSITIES)}")
    if e.scaling not in SCALINGS:
        raise ConfigError(f"[excitation] scaling = {shown(e.scaling)}: expected one of {list(SCALINGS)}")
    if e.type == "harmonic" and (e.intensity != "none" or e.scaling != "factor"):
        raise ConfigError("[excitation] intensity, scaling: only for ground motions (type = 'record' or 'stochastic')")
    if e.scaling == "intensity" and e.intensity == "none":
        raise ConfigError(
            "[excitation] scaling = 'intensity': name the measure it scales to, intensity = 'pga' or 'sa'"
        )
    if e.intensity_period_s is not None:
        if e.intensity != "sa":
            raise ConfigError("[excitation] intensity_period_s: only with intensity = 'sa'")
        if not e.intensity_period_s > 0:
            raise ConfigError(f"[excitation] intensity_period_s = {e.intensity_period_s!r}: must be > 0")
    validate_risk(scene)


def validate_stochastic(scene) -> None:
    """[excitation] type = 'stochastic' and its [stochastic] section, and the seed axis."""
    e, s = scene.excitation, scene.stochastic
    seeds = scene.axis_values("seed")
    if e.type != "stochastic":
        if s is not None:
            raise ConfigError("[stochastic]: only with [excitation] type = 'stochastic'")
        if seeds:
            raise ConfigError("[sweep] seed: only with [excitation] type = 'stochastic'")
        return
    if s is None:
        raise ConfigError(
            "[excitation] type = 'stochastic' needs a [stochastic] section (filter, frequency, damping, S0)"
        )
    if e.duration_s is None:
        raise ConfigError("[excitation] missing key 'duration_s' for a stochastic excitation (length of each motion)")
    if not e.duration_s > 0:
        raise ConfigError(f"[excitation] duration_s = {e.duration_s!r}: must be > 0")
    dt = scene.integration.first_dt_s
    if isinstance(dt, float) and dt >= e.duration_s:
        raise ConfigError(
            f"[integration] dt_s = {dt!r}: must be shorter than [excitation] duration_s = {e.duration_s!r}"
        )
    for k in ("record", "amplitude_m", "frequency_Hz"):
        if getattr(e, k) is not None or scene.axis_values(k):
            raise ConfigError(f"[excitation] {k}: not for a stochastic excitation")
    if e.length_scale != 1.0:
        raise ConfigError(
            f"[excitation] length_scale = {e.length_scale!r}: a stochastic motion is generated at the scale it is "
            "run at (give its frequencies and S0 there)"
        )
    if s.filter not in FILTERS:
        raise ConfigError(f"[stochastic] filter = {shown(s.filter)}: expected one of {list(FILTERS)}")
    for k in ("ground_frequency_Hz", "s0_m2_per_s3"):
        if not getattr(s, k) > 0:
            raise ConfigError(f"[stochastic] {k} = {getattr(s, k)!r}: must be > 0")
    if not 0 < s.ground_damping:
        raise ConfigError(f"[stochastic] ground_damping = {s.ground_damping!r}: must be > 0")
    cp = s.filter == "clough_penzien"
    for k in ("highpass_frequency_Hz", "highpass_damping"):
        v = getattr(s, k)
        if cp and v is None:
            raise ConfigError(f"[stochastic] missing key '{k}' for filter = 'clough_penzien'")
        if not cp and v is not None:
            raise ConfigError(f"[stochastic] {k}: only for filter = 'clough_penzien'")
        if v is not None and not v > 0:
            raise ConfigError(f"[stochastic] {k} = {v!r}: must be > 0")
    if s.envelope not in ENVELOPES:
        raise ConfigError(f"[stochastic] envelope = {shown(s.envelope)}: expected one of {list(ENVELOPES)}")
    env_keys = ("rise_s", "strong_end_s", "decay_per_s")
    for k in env_keys:
        v = getattr(s, k)
        if s.envelope == "jennings" and v is None:
            raise ConfigError(f"[stochastic] missing key '{k}' for envelope = 'jennings'")
        if s.envelope == "none" and v is not None:
            raise ConfigError(f"[stochastic] {k}: only with envelope = 'jennings'")
        if v is not None and v < 0:
            raise ConfigError(f"[stochastic] {k} = {v!r}: must be >= 0")
    if s.envelope == "jennings" and not s.strong_end_s >= s.rise_s:
        raise ConfigError(f"[stochastic] strong_end_s = {s.strong_end_s!r}: must be at least rise_s = {s.rise_s!r}")
    if s.start not in STARTS:
        raise ConfigError(f"[stochastic] start = {shown(s.start)}: expected one of {list(STARTS)}")
    if s.sample_dt_s is not None:
        if not s.sample_dt_s > 0:
            raise ConfigError(f"[stochastic] sample_dt_s = {s.sample_dt_s!r}: must be > 0")
        if s.sample_dt_s >= e.duration_s:
            raise ConfigError(
                f"[stochastic] sample_dt_s = {s.sample_dt_s!r}: must be shorter than [excitation] duration_s = "
                f"{e.duration_s!r}"
            )
    elif scene.integration.auto:
        raise ConfigError("[stochastic] sample_dt_s: needed with [integration] dt_s = 'auto' (the motion's own step)")
    check_seed(s.seed, "[stochastic] seed")
    for v in seeds:
        check_seed(v, "[sweep] seed")
