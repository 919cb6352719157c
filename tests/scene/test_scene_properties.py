"""Property-based tests of the scene loader and grid expansion (hypothesis): any input either
loads into a valid scene whose grid is the product of its axes, or raises one ConfigError."""

from __future__ import annotations

import copy
import math
import tomllib

import numpy as np
from conftest import SWEEPS
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from pounding_sweep.model.grid import Grid
from pounding_sweep.scene import ConfigError, scene_from_dict

BASE = tomllib.loads((SWEEPS / "paper_6hz.toml").read_text())

scalars = st.one_of(
    st.none(),
    st.booleans(),
    st.integers(-10, 10**6),
    st.floats(allow_nan=True, allow_infinity=True),
    st.text(max_size=8),
    st.lists(st.floats(-1e3, 1e3), max_size=4),
)
KEYS = [(sec, key) for sec, table in BASE.items() if isinstance(table, dict) for key in table]
EXTRA_KEYS = ["ks_ration", "mass_kg", "dt", "gap", "r_", "histories", "damping_modes", "spacing"]


@st.composite
def mutated_scene(draw):
    raw = copy.deepcopy(BASE)
    for _ in range(draw(st.integers(1, 4))):
        what = draw(st.integers(0, 3))
        if what == 0:  # change a value
            sec, key = draw(st.sampled_from(KEYS))
            if isinstance(raw.get(sec), dict):
                raw[sec][key] = draw(scalars)
        elif what == 1:  # drop a key or a section
            sec, key = draw(st.sampled_from(KEYS))
            if draw(st.booleans()):
                if isinstance(raw.get(sec), dict):
                    raw[sec].pop(key, None)
            else:
                raw.pop(sec, None)
        elif what == 2:  # add an unknown or misplaced key
            sec = draw(st.sampled_from(list(BASE)))
            if isinstance(raw.get(sec), dict):
                raw[sec][draw(st.sampled_from(EXTRA_KEYS))] = draw(scalars)
        else:  # a sweep axis: list or range
            axis = draw(st.sampled_from(["ks_ratio", "r", "gap_m", "amplitude_m", "frequency_Hz", "scale", "nope"]))
            if draw(st.booleans()):
                spec = draw(st.lists(st.floats(-2, 20), max_size=5))
            else:
                spec = {
                    "start": draw(st.floats(-1, 10)),
                    "stop": draw(st.floats(-1, 10)),
                    "num": draw(st.integers(-1, 6)),
                    "spacing": draw(st.sampled_from(["linear", "log", "cubic"])),
                }
            if isinstance(raw.get("sweep", {}), dict):
                raw.setdefault("sweep", {})[axis] = spec
    return raw


def _with_contact(**kw):
    raw = copy.deepcopy(BASE)
    raw["contact"].update(kw)
    return raw


@settings(max_examples=1000, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(mutated_scene())
@example(_with_contact(k_ref_N_per_m=1.797693134862316e307))  # found by hypothesis: k_s = 10 k_ref overflowed
def test_any_scene_loads_valid_or_raises_config_error(raw):
    try:
        scene = scene_from_dict(raw, base_dir=SWEEPS, source="prop.toml")
    except ConfigError as e:
        assert str(e) and "\n" not in str(e)
        return
    # loaded: the invariants a valid scene promises
    c = scene.contact
    assert 0.0 <= c.r <= 1.0 and c.gap_m >= 0.0
    assert all(m > 0 for m in scene.building1.masses_kg + scene.building2.masses_kg)
    assert scene.integration.dt_s > 0 and math.isfinite(scene.integration.dt_s)
    g = Grid.from_scene(scene)
    assert g.size == int(np.prod([len(v) for _, v in g.axes], dtype=np.int64)) if g.axes else g.size == 1
    chunk = g.chunk(0, min(g.size, 50))
    assert np.all((chunk["r"] >= 0) & (chunk["r"] <= 1)) and np.all(chunk["gap_m"] >= 0)
    ks = np.where(np.isnan(chunk["ks_N_per_m"]), chunk["ks_ratio"] * c.k_ref_N_per_m, chunk["ks_N_per_m"])
    assert np.all(ks > 0)
