"""Model update: story stiffness / column EI scaled to the identified f1 (paper sec. 3, Table 1)."""

from __future__ import annotations

import dataclasses
import tomllib

import numpy as np
import pytest
from conftest import SWEEPS

from pounding_sweep.identify.update import (
    column_EI_for_story_stiffness,
    frequencies_Hz,
    stiffness_factor_for_f1,
    update_building,
    update_scene,
)
from pounding_sweep.model.coupled import building_from_config
from pounding_sweep.model.structure import column_story_stiffness
from pounding_sweep.scene import BuildingConfig, load_scene

M1, M2 = (1.7, 1.7, 1.6), (0.56, 0.56, 0.45)
INITIAL = dict(column_EI_Nm2=(5.4,), n_columns=4, story_height_m=(0.336,))  # k = 4 x 12 EI / h^3 = 6833 N/m


def test_frequencies_match_the_readme():
    assert frequencies_Hz(M1, 5920.0)[0] == pytest.approx(4.25, abs=0.005)
    assert frequencies_Hz(M2, 5140.0)[0] == pytest.approx(7.17, abs=0.005)


def test_uniform_scaling_is_exact_for_every_mode():
    k = np.array([5000.0, 6000.0, 7000.0])
    c = stiffness_factor_for_f1(M1, k, 4.0)
    # exact in exact arithmetic; the eigenvalues of a well-separated, well-conditioned pencil come out of
    # LAPACK to O(n u) relative (LAPACK Users' Guide, sec. 4.10): 1e-12 is 9000 u
    assert frequencies_Hz(M1, k * c)[0] == pytest.approx(4.0, rel=1e-12)
    assert frequencies_Hz(M1, k * c) == pytest.approx(frequencies_Hz(M1, k) * np.sqrt(c), rel=1e-12)
    with pytest.raises(ValueError, match="must be > 0"):
        stiffness_factor_for_f1(M1, k, -1.0)


def test_column_EI_round_trip():
    k = column_story_stiffness(4.6, 4, 0.336)
    assert column_EI_for_story_stiffness(k, 4, 0.336) == pytest.approx(4.6, rel=1e-12)


def test_paper_model_update_direction_and_values():
    """From EI = 5.4 N m^2 to the measured f1 of Table 1 (Model-1 4.28 Hz, Model-2 7.22 Hz).

    Model-2 lands on the paper's 4.1 N m^2. Model-1 lands on 4.75 N m^2, not the paper's 4.6: the
    paper's own Model-1 numbers disagree by a few percent (EI 4.6 gives f1 = 4.21 Hz and 5.82 kN/m;
    5.92 kN/m is EI 4.68 and f1 = 4.25 Hz; T1 = 0.233 s is 4.29 Hz)."""
    u1 = update_building(BuildingConfig(masses_kg=M1, **INITIAL), 4.28)
    u2 = update_building(BuildingConfig(masses_kg=M2, **INITIAL), 7.22, "building2")
    assert u1.factor < 1 and u2.factor < 1  # both models softer than the nominal columns
    assert u2.updated.column_EI_Nm2[0] == pytest.approx(4.1, rel=0.01)
    assert u1.updated.column_EI_Nm2[0] == pytest.approx(4.75, abs=0.01)
    assert 4.6 < u1.updated.column_EI_Nm2[0] < 4.8
    assert u1.f1_updated_Hz == pytest.approx(4.28, rel=1e-12)
    assert u1.f1_model_Hz == pytest.approx(4.564, abs=1e-3)
    assert frequencies_Hz(M1, column_story_stiffness(4.6, 4, 0.336))[0] == pytest.approx(4.21, abs=0.01)


def test_story_stiffness_form_and_damping_update():
    b = BuildingConfig(masses_kg=M1, story_stiffness_N_per_m=(6000.0, 5900.0, 5800.0), damping_ratio=0.01)
    u = update_building(b, 4.0, damping_ratio=0.0123)
    assert u.updated.story_stiffness_N_per_m == pytest.approx(tuple(k * u.factor for k in (6000.0, 5900.0, 5800.0)))
    assert building_from_config(u.updated, "b").modes().frequency_Hz[0] == pytest.approx(4.0, rel=1e-12)
    assert u.updated.damping_ratio == 0.0123


def test_written_section_loads_in_a_scene_and_gives_the_target(tmp_path):
    scene = load_scene(SWEEPS / "paper_6hz.toml")
    ups = update_scene(scene, {1: 4.1, 2: 7.3})
    text = (SWEEPS / "paper_6hz.toml").read_text()
    for u in ups:  # each section parses on its own
        assert tomllib.loads(u.toml())[u.section]["name"] == getattr(scene, u.section).name
    rest = text.split("[contact]", 1)[1]  # the scene with its building sections replaced by the updated ones
    (tmp_path / "updated.toml").write_text(ups[0].toml() + "\n" + ups[1].toml() + "\n[contact]" + rest)
    new = load_scene(tmp_path / "updated.toml")
    assert building_from_config(new.building1, "1").modes().frequency_Hz[0] == pytest.approx(4.1, rel=1e-5)
    assert building_from_config(new.building2, "2").modes().frequency_Hz[0] == pytest.approx(7.3, rel=1e-5)
    assert new.building1.masses_kg == scene.building1.masses_kg and new.building1.name == "Model-1"
    assert "model update: f1 4.2480 Hz -> 4.1000 Hz" in ups[0].toml()
    with pytest.raises(ValueError, match="building must be 1 or 2"):
        update_scene(scene, {3: 5.0})
    assert dataclasses.replace(scene.building1) == scene.building1  # the scene itself is untouched
