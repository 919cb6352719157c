"""Shared test fixtures: paths to the repo's scenes and to ../shared (skipped where absent)."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest
from hypothesis import settings

# property tests draw the same examples on every run (a CI run on a fresh clone must not turn red by the
# luck of the draw); HYPOTHESIS_PROFILE=explore draws new ones (and keeps failures in .hypothesis/). No
# per-example deadline: Hypothesis' default (200 ms) fails an example by the machine's speed and load.
settings.register_profile("ci", derandomize=True, database=None, deadline=None)
settings.register_profile("explore", max_examples=5000, deadline=None)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "ci"))

REPO = Path(__file__).resolve().parents[1]
SWEEPS = REPO / "sweeps"
SHARED = REPO.parent / "shared"


@pytest.fixture
def shared_dir() -> Path:
    if not SHARED.is_dir():
        pytest.skip(f"{SHARED} not present: tests that read the paper's shared data need ../shared beside the repo")
    return SHARED


@pytest.fixture(autouse=True)
def _numpy_raises_on_fp_errors():
    """Tests make NumPy raise on invalid operations and division by zero (overflow too)."""
    with np.errstate(invalid="raise", divide="raise", over="raise"):
        yield
