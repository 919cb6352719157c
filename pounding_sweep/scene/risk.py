"""The `[risk]` scene section: what a probabilistic pounding study (`python -m pounding_sweep risk SCENE`,
pounding_sweep/risk) reports over the scene's ensemble of ground motions. Plain data and its checks.

The ensemble is the scene's own: a `[sweep] record` axis (a record suite) or a `[sweep] seed` axis (a
stochastic family), each motion's intensity measure set by `[excitation] intensity`; with `[excitation]
scaling = 'intensity'` the `[sweep] scale` values are intensity levels in g (incremental dynamic analysis,
one stripe per level), otherwise the motions keep their own intensity (cloud analysis). The section changes
no run: it is left out of the config hash, and a study resumes its runs whatever it asks of them."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from pounding_sweep.errors import ConfigError, shown

#: fewer motions than this cannot give a probability worth an interval
MIN_MOTIONS = 2
MAX_BOOTSTRAP = 100_000


def _f(doc: str, default=None, when: str | None = None):
    """A key with its --describe text."""
    return field(default=default, metadata={"doc": doc, "when": when})


@dataclass(frozen=True)
class RiskConfig:
    """Probability of pounding against the gap, fragility curves and the gap a target probability needs."""

    gaps_m: tuple[float, ...] | None = _f(
        "gaps at which P(pounding) is tabulated [m] (every gap comes from the same contact-free runs)",
        None,
        "default: 100 gaps, geometric, from 1 % to 250 % of the largest gap the ensemble needs",
    )
    intensities_g: tuple[float, ...] | None = _f(
        "intensities [g] of the required-gap and code-rule tables (with scaling = 'intensity': [sweep] scale values)",
        None,
        "default: every [sweep] scale value; a cloud: the ensemble's median intensity",
    )
    targets: tuple[float, ...] = _f("target probabilities of pounding for the required gap", (0.1, 0.02))
    confidence: float = _f("confidence level of every interval (Clopper-Pearson, order statistics, bootstrap)", 0.95)
    bootstrap: int = _f("bootstrap resamples over the motions for the fragility and required-gap intervals", 1000)
    bootstrap_seed: int = _f("seed of the bootstrap's resampling", 0)
    contact_gaps_m: tuple[float, ...] | None = _f(
        "gaps of the contact runs for the consequences (response ratios, forces, impacts) [m]",
        None,
        "optional; without it no contact run is made",
    )
    contact_intensities_g: tuple[float, ...] | None = _f(
        "intensities [g] of the contact runs (with scaling = 'intensity')", None, "default: intensities_g"
    )
    hazard: str | None = _f(
        "hazard curve: a CSV table with columns intensity_g and annual_rate (of exceedance), for the annual "
        "rate of pounding",
        None,
        "optional",
    )
    path: str = _f("output folder of the study (relative to the scene file)", "", "default: results/<name>.risk")


def _positive_list(values, key: str) -> None:
    for v in values:
        if not (math.isfinite(v) and v > 0):
            raise ConfigError(f"{key} = {shown(list(values))}: every value must be > 0 (found {v!r})")
    if len(set(values)) != len(values):
        raise ConfigError(f"{key} = {shown(list(values))}: repeated values")


def validate_risk(scene) -> None:
    """[risk]'s own values, and ground motions with an intensity measure."""
    r = scene.risk
    if r is None:
        return
    for key in ("gaps_m", "intensities_g", "contact_gaps_m", "contact_intensities_g"):
        v = getattr(r, key)
        if v is not None:
            _positive_list(v, f"[risk] {key}")
    for p in r.targets:
        if not 0 < p < 1:
            raise ConfigError(f"[risk] targets = {shown(list(r.targets))}: probabilities lie in (0, 1) (found {p!r})")
    if len(set(r.targets)) != len(r.targets):
        raise ConfigError(f"[risk] targets = {shown(list(r.targets))}: repeated values")
    if not 0.5 <= r.confidence < 1:
        raise ConfigError(f"[risk] confidence = {r.confidence!r}: expected a level in [0.5, 1), e.g. 0.95")
    if not 0 <= r.bootstrap <= MAX_BOOTSTRAP:
        raise ConfigError(f"[risk] bootstrap = {r.bootstrap}: expected 0 (no bootstrap) to {MAX_BOOTSTRAP:,}")
    if r.bootstrap_seed < 0:
        raise ConfigError(f"[risk] bootstrap_seed = {r.bootstrap_seed}: must be >= 0")
    e = scene.excitation
    if e.type == "harmonic":
        raise ConfigError("[risk]: needs ground motions (type = 'record' or 'stochastic'), not a harmonic excitation")
    if e.intensity == "none":
        raise ConfigError("[risk]: needs [excitation] intensity = 'pga' or 'sa' (the intensity measure of the study)")


def check_ensemble(scene) -> None:
    """What a risk study needs of the scene's [sweep] (checked by the study, not when the scene is read: the
    same scene runs as a plain sweep, or one point of it with simulate): an ensemble of motions, [risk]'s
    intensities among the levels, no gap axis."""
    r, e = scene.risk, scene.excitation
    # no record or seed axis: the one motion of [excitation] (a record, or a stochastic motion's one seed)
    motions = len(scene.axis_values("record") or scene.axis_values("seed")) or 1
    if motions < MIN_MOTIONS:
        raise ConfigError(
            f"[risk]: the ensemble has {motions} motion(s); give at least {MIN_MOTIONS} as a [sweep] record or seed axis"
        )
    scales = scene.axis_values("scale")
    if e.scaling == "intensity":
        levels = set(scales or (e.scale,))
        for key in ("intensities_g", "contact_intensities_g"):
            v = getattr(r, key)
            missing = sorted(set(v or ()) - levels)
            if missing:
                raise ConfigError(
                    f"[risk] {key} = {shown(list(v))}: {missing[0]!r} g is not an intensity level of the study "
                    f"([sweep] scale = {shown(sorted(levels))})"
                )
    elif r.contact_intensities_g is not None:
        raise ConfigError(
            "[risk] contact_intensities_g: only with [excitation] scaling = 'intensity' (a cloud keeps each motion's own)"
        )
    if scene.axis_values("gap_m"):
        raise ConfigError("[sweep] gap_m: a risk study sets the gaps itself ([risk] gaps_m, contact_gaps_m)")
