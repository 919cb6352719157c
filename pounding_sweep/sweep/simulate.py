"""One run, in memory: for notebooks, tests and references (the sweep path streams to Parquet).

`simulate(scene, ks_ratio=5, r=0.2)` runs the scene's base point with those overrides and returns
its time histories (a DataFrame, units in the column names) and metrics (a dict).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pandas as pd

from pounding_sweep.engine import layout as L
from pounding_sweep.scene import SWEEPABLE, ConfigError, Scene, validate
from pounding_sweep.scene.axes import KS_FORMS, setting_ks
from pounding_sweep.sweep.ranking import score_table_columns
from pounding_sweep.sweep.results import status_words

ALL_CHANNELS_TEMPLATE = ("disp_b{b}f{f}", "vel_b{b}f{f}", "abs_acc_b{b}f{f}")


def all_channels(floors: tuple[int, int]) -> list[str]:
    """Every displacement, velocity, absolute acceleration and force channel, and ground_acc."""
    out = []
    for t in ALL_CHANNELS_TEMPLATE:
        for b, nf in zip((1, 2), floors):
            out += [t.format(b=b, f=f) for f in range(1, nf + 1)]
    out += [f"force_f{j}" for j in range(1, min(floors) + 1)]
    return out + ["ground_acc"]


def with_overrides(scene: Scene, **overrides) -> Scene:
    """The scene with sweepable parameters (ks_ratio, r, gap_m, law, ...), dt_s/scheme or a contact law's settings
    (restitution_relation, min_impact_speed_m_s, reference_penetration_m) replaced, no sweep."""
    sections = {}
    for key, value in overrides.items():
        if key in SWEEPABLE:
            section, field = SWEEPABLE[key]
        elif key in ("dt_s", "scheme", "max_contact_iterations"):
            section, field = "integration", key
        elif key in ("restitution_relation", "min_impact_speed_m_s", "reference_penetration_m"):
            section, field = "contact", key
        else:
            raise ConfigError(f"simulate: unknown parameter '{key}'")
        sections.setdefault(section, {})[field] = value
    for form in KS_FORMS:
        if form in overrides:
            sections.setdefault("contact", {}).update(setting_ks(form, overrides[form]))
    new = {s: dataclasses.replace(getattr(scene, s), **kv) for s, kv in sections.items()}
    out = dataclasses.replace(scene, sweep=(), **new)
    validate(out)
    return out


def simulate(scene: Scene, channels: list[str] | None = None, decimate: int = 1, **overrides):
    """Run one point; return (histories DataFrame with t_s first, metrics dict incl. 'status' and scores)."""
    from pounding_sweep.sweep.prepare import drift_ratio_columns, prepare

    s = with_overrides(scene, **overrides)
    auto = None
    if s.integration.auto:  # choose dt on the metrics, then keep the histories at that dt
        s = dataclasses.replace(s, output=dataclasses.replace(s.output, histories=()))
        _, _, _, _, derived = prepare(s).run(prepare(s).grid.chunk(0, 1))
        auto = {"dt_s": float(derived["dt_s"][0]), "dt_error_estimate": float(derived["dt_error_estimate"][0])}
        s = with_overrides(s, dt_s=auto["dt_s"])
    floors = s.floors
    s = dataclasses.replace(
        s,
        output=dataclasses.replace(
            s.output, histories=tuple(channels or all_channels(floors)), history_decimate=decimate
        ),
    )
    prep = prepare(s)  # checks the channels (history_spec) and decimate
    params = prep.grid.chunk(0, 1)
    metrics, run_time, hist, scores, derived = prep.run(params)
    df = pd.DataFrame({"t_s": np.arange(hist.shape[2]) * prep.dt * decimate})
    for i, name in enumerate(prep.hist_columns):
        df[name] = hist[0, i]
    names = L.metric_columns(prep.model.floors, prep.model.n_pairs)
    m = dict(zip(names, metrics[0].tolist()))
    m["status"] = status_words(metrics[:1, names.index("status_code")])[0]
    m.update({k: float(v[0]) for k, v in drift_ratio_columns(s, metrics[:1], names).items()})
    m.update({k: float(v[0]) for k, v in derived.items()})  # the contact's derived parameters (ks_N_per_m, ...)
    m["run_time_s"] = float(run_time[0])
    if auto is not None:
        m.update(auto)
    if scores is not None:
        m.update({k: float(v[0]) for k, v in score_table_columns(scores, prep.score_codes, prep.combination).items()})
    return df, m
