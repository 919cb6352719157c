"""The metric groups [output] metrics may name: the scene layer's copy of engine/layout.py GROUPS' names (the scene
cannot import the engine; tests/sweep/test_metric_groups.py checks that the two agree)."""

from __future__ import annotations

METRIC_GROUPS = ("energy", "drift", "closest", "phases", "accel")
#: groups split off after [output] metrics existed, whose columns every earlier run computed: a scene computing one
#: hashes as it did then, one leaving it out is marked no_<group> (scene/hashing.py), so earlier results resume only
#: into a sweep that computes the same columns
SPLIT_LATER = ("accel",)


def metric_group_names(metrics: tuple[str, ...] | None) -> tuple[str, ...]:
    """The groups [output] metrics names ('all' and None: every one; 'none': none), in METRIC_GROUPS order."""
    if metrics is None or "all" in metrics:
        return METRIC_GROUPS
    return tuple(g for g in METRIC_GROUPS if g in metrics)
