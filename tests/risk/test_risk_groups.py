"""The risk study's runs compute only the metric groups the study reads (sweep/metricgroups.py READERS: closest
approach of the contact-free runs, story drifts and peak absolute accelerations of both kinds for the
consequences), whatever [output] metrics says; its tables are those of a study computing every group, exactly (the
kept columns are the same kernel's same arithmetic: tests/sweep/test_metric_groups.py says why bit for bit)."""

from __future__ import annotations

import dataclasses

import pandas as pd
from test_study import runs, small

from pounding_sweep.risk.study import TABLES, contact_scene, free_scene, risk_study
from pounding_sweep.sweep.results import read_metadata


def with_metrics(scene, metrics):
    return dataclasses.replace(scene, output=dataclasses.replace(scene.output, metrics=metrics))


def groups(folder) -> list[str]:
    return read_metadata(folder)["metric_groups"]["computed"]


def test_the_study_asks_for_what_it_reads_and_its_tables_are_the_full_ones(tmp_path):
    lean = risk_study(small(tmp_path / "lean"), threads=2)
    full = risk_study(with_metrics(small(tmp_path / "full"), ("all",)), threads=2)
    assert groups(lean.folder / "runs_free.parquet") == ["drift", "closest", "accel"]
    assert groups(lean.folder / "runs_contact.parquet") == ["drift", "accel"]
    assert groups(full.folder / "runs_free.parquet") == ["energy", "drift", "closest", "phases", "accel"]
    for name in TABLES:  # probabilities, fragilities, required gaps, code rules, consequences, annual rates
        pd.testing.assert_frame_equal(getattr(lean, name), getattr(full, name), check_exact=True)
    for sub in ("runs_free.parquet", "runs_contact.parquet"):
        a, b = runs(lean.folder / sub), runs(full.folder / sub)
        computed = b.columns[b.notna().all()]
        kept = [c for c in computed if a[c].notna().all()]
        assert any(c.startswith("input_energy") for c in set(computed) - set(kept))
        pd.testing.assert_frame_equal(a[kept], b[kept], check_exact=True)


def test_the_groups_the_study_reads_are_computed_whatever_the_key_says(tmp_path):
    """[output] metrics unset or 'none': only what the study reads; groups it names: those as well."""
    base = small(tmp_path)
    for metrics, free, contact in (
        (None, ("drift", "closest", "accel"), ("drift", "accel")),
        (("none",), ("drift", "closest", "accel"), ("drift", "accel")),
        (("energy",), ("energy", "drift", "closest", "accel"), ("energy", "drift", "accel")),
        (("phases", "closest"), ("drift", "closest", "phases", "accel"), ("drift", "closest", "phases", "accel")),
    ):
        s = with_metrics(base, metrics)
        assert free_scene(s).output.metrics == free, metrics
        assert contact_scene(s).output.metrics == contact, metrics
    no_contact = dataclasses.replace(base, risk=dataclasses.replace(base.risk, contact_gaps_m=()))
    assert free_scene(no_contact).output.metrics == ("closest",)  # no consequences: no drift or acceleration read
