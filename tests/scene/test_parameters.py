"""The parameter registry (scene/parameters.py): each entry names a real scene key, its roles fit together, its
range is the one the scene checks enforce, and the tables the layers read are its views."""

from __future__ import annotations

import dataclasses
import math

import pytest
from conftest import SWEEPS

from pounding_sweep.scene import ConfigError, load_scene
from pounding_sweep.scene import parameters as P
from pounding_sweep.scene.axes import STRUCTURE_AXES, SWEEPABLE
from pounding_sweep.scene.schema import Scene
from pounding_sweep.scene.validate import FITTABLE


def _section_class(section: str):
    """The dataclass of a scene section (Scene's field type, the optional ones unwrapped)."""
    hints = {f.name: f.type for f in dataclasses.fields(Scene)}
    text = str(hints[section]).split("|")[0].strip()
    import pounding_sweep.scene.schema as schema

    return getattr(schema, text)


@pytest.mark.parametrize("p", P.PARAMETERS, ids=lambda p: p.name)
def test_each_entry_names_a_key_of_its_section(p):
    cls = _section_class(p.section)
    assert p.key in {f.name for f in dataclasses.fields(cls)}, (p.section, p.key)


@pytest.mark.parametrize("p", P.PARAMETERS, ids=lambda p: p.name)
def test_roles_fit_together(p):
    assert p.roles <= set(P.ROLES)
    if p.has(P.STRUCTURE) or p.has(P.PROFILED):
        assert p.has(P.FITTABLE), p.name  # a structure or profiled parameter is one a fit may take
    if p.has(P.FITTABLE):
        assert p.factor is not None, p.name  # a number, not a name
    if p.log:
        assert p.range is P.POSITIVE, p.name  # a logarithm needs values > 0
    assert p.doc and p.unit is not None


def test_names_are_unique_and_the_views_keep_the_order():
    assert len(P.BY_NAME) == len(P.PARAMETERS)
    assert list(SWEEPABLE) == [p.name for p in P.PARAMETERS]
    assert STRUCTURE_AXES == P.names(P.STRUCTURE)
    assert FITTABLE == P.names(P.FITTABLE)
    with pytest.raises(ValueError, match="unknown parameter role"):
        P.names("nonsense")


@pytest.mark.parametrize(
    ("rng", "inside", "outside"),
    [
        (P.POSITIVE, [1e-300, 1.0, math.inf], [0.0, -1.0, math.nan]),
        (P.NON_NEGATIVE, [0.0, 2.0], [-1e-300, math.nan]),
        (P.RESTITUTION, [0.0, 0.5, 1.0], [-1e-12, 1.0 + 1e-12, math.nan]),
        (P.DAMPING_RATIO, [0.0, 0.999], [1.0, -1e-12, math.nan]),
    ],
)
def test_range_ends(rng, inside, outside):
    assert all(rng.holds(v) for v in inside)
    assert not any(rng.holds(v) for v in outside)


def test_default_profile_puts_the_stiffness_first():
    assert P.default_profiled(["r", "kh_N_per_m1_5", "gap_m"]) == ["kh_N_per_m1_5", "r"]
    assert P.default_profiled({"stiffness_scale_b1": 0, "r": 0, "ks_ratio": 0}) == ["ks_ratio", "r"]


def _with(text: str, tmp_path):
    p = tmp_path / "scene.toml"
    p.write_text(text)
    return p


@pytest.mark.parametrize(
    ("axis", "value", "says"),
    [
        ("r", 1.5, "[sweep] r = 1.5: the coefficient of restitution must lie in [0, 1]"),
        ("gap_m", -0.001, "[sweep] gap_m = -0.001: must be >= 0"),
        ("ks_ratio", -1.0, "[sweep] ks_ratio = -1.0: must be > 0"),
        ("stiffness_scale_b1", 0.0, "[sweep] stiffness_scale_b1 = 0.0: must be > 0"),
        ("damping_ratio_b1", 1.0, "[sweep] damping_ratio_b1 = 1.0: must lie in [0, 1)"),
    ],
)
def test_a_sweep_value_outside_the_range_names_axis_and_value(tmp_path, axis, value, says):
    text = (SWEEPS / "paper_6hz.toml").read_text()
    head, _, _ = text.partition("[sweep]")
    scene = _with(head + f"\n[sweep]\n{axis} = [{value!r}]\n", tmp_path)
    with pytest.raises(ConfigError) as e:
        load_scene(scene)
    assert str(e.value).endswith(f"scene.toml: {says}")


def test_calibrate_bounds_outside_the_range():
    msg = P.bounds_out_of_range("r", 0.1, 1.2, "[calibrate] parameters.r")
    assert msg == "[calibrate] parameters.r = [0.1, 1.2]: a coefficient of restitution lies in [0, 1]"
    msg = P.bounds_out_of_range("ks_ratio", 0.0, 10.0, "[calibrate] parameters.ks_ratio")
    assert msg == "[calibrate] parameters.ks_ratio = [0.0, 10.0]: must be > 0"
    assert P.bounds_out_of_range("time_offset_s", -5.0, 5.0, "x") is None  # any clock shift
    assert P.bounds_out_of_range("gap_m", 0.0, 0.01, "x") is None
