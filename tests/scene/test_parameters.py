"""The parameter registry (scene/parameters.py): each entry names a real scene key, its roles fit together, its
range is the one the scene checks enforce, and the tables the layers read are its views."""

from __future__ import annotations

import dataclasses
import math

import pytest
from conftest import SWEEPS

from pounding_sweep.scene import ConfigError, load_scene, validate
from pounding_sweep.scene import parameters as P
from pounding_sweep.scene.axes import STRUCTURE_AXES, SWEEPABLE
from pounding_sweep.scene.schema import CalibrateConfig, ExperimentConfig, Scene
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


B1 = {"damping_ratio": None}  # building 1 without its Rayleigh ratio: room for modal_damping_ratios


@pytest.mark.parametrize(
    ("change", "says"),
    [
        ({"story_stiffness_scales": (1.0, 1.0)}, " story_stiffness_scales = [1.0, 1.0]: one factor per story, 3 here"),
        ({"story_stiffness_scales": (1.0, 0.0, 1.0)}, " story_stiffness_scales = 0.0: must be > 0"),
        ({"modal_damping_ratios": (0.01,) * 3}, ": give modal_damping_ratios, damping_ratio or rayleigh_a0_per_s"),
        ({**B1, "modal_damping_ratios": (0.01, 0.01)}, " modal_damping_ratios = [0.01, 0.01]: one ratio per mode, 3"),
        ({**B1, "modal_damping_ratios": (0.01, 1.0, 0.01)}, " modal_damping_ratios = 1.0: must lie in [0, 1)"),
    ],
)
def test_a_per_story_or_per_mode_list_is_checked(change, says):
    s = load_scene(SWEEPS / "paper_6hz.toml")
    bad = dataclasses.replace(s, building1=dataclasses.replace(s.building1, **change))
    with pytest.raises(ConfigError) as e:
        validate(bad)
    assert str(e.value).startswith(f"[building1]{says}"), str(e.value)


@pytest.mark.parametrize(
    ("change", "name", "says"),
    [
        ({}, "story_stiffness_scale_b1_s4", "[building1] has 3 stories, no story 4"),
        ({}, "modal_damping_ratio_b1_m2", "[building1] gives no modal_damping_ratios to fit (give one value per mode)"),
        (
            {**B1, "modal_damping_ratios": (0.01,) * 3},
            "modal_damping_ratio_b1_m4",
            "[building1] has 3 modes, no mode 4",
        ),
    ],
)
def test_a_family_member_names_what_the_building_has(tmp_path, change, name, says):
    s = load_scene(SWEEPS / "paper_6hz.toml")
    exp = ExperimentConfig(table=str(tmp_path / "none.csv"), channels={"x": "b1f3"})
    cal = CalibrateConfig(parameters={name: (0.01, 0.1)})
    b1 = dataclasses.replace(s.building1, **change)
    with pytest.raises(ConfigError) as e:
        validate(dataclasses.replace(s, building1=b1, experiment=exp, calibrate=cal))
    assert str(e.value) == f"[calibrate] parameters.{name}: {says}"
