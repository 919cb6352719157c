"""Test-only pause points of a sweep, so that a fault test acts at a named moment instead of racing the clock.

Set only by the tests (tests/sweep/test_faults.py, test_executors.py); unset, `pause` returns at once and a
sweep never looks at the file system for it.

    POUNDING_SWEEP_TEST_GATE = "POINT[,POINT...]@FOLDER"

At each named point the sweep writes FOLDER/POINT.reached (its process id) and waits until FOLDER/POINT.release
exists; the test meanwhile sends its signal, kills the process, starts a second sweep on the same folder or
stops a Dask scheduler. Points:

* ``part-N``: the N-th part this call wrote has been renamed into place (its manifest and parts 1..N are whole);
* ``calibrate``: the grid is done and its best table written, the calibration not yet started;
* ``best``: the best table is written to its temporary name, not yet renamed into place.

The wait is in the main thread, so Ctrl-C and SIGTERM interrupt it as they would a run. It gives up after
MAX_WAIT_S (a safety net for a test that died without releasing it, far above any test's need).
"""

from __future__ import annotations

import os
import time
from pathlib import Path

ENV = "POUNDING_SWEEP_TEST_GATE"
MAX_WAIT_S = 1800.0


def pause(point: str) -> None:
    """Wait at `point` when the test gate names it; otherwise return at once."""
    spec = os.environ.get(ENV)
    if not spec:
        return
    points, _, folder = spec.rpartition("@")
    if point not in points.split(","):
        return
    folder_path = Path(folder)
    reached = folder_path / f"{point}.reached"
    tmp = folder_path / f".{point}.reached.tmp"
    tmp.write_text(f"{os.getpid()}\n")
    os.replace(tmp, reached)  # whole when it appears: the test may read the process id at once
    release = folder_path / f"{point}.release"
    deadline = time.monotonic() + MAX_WAIT_S
    while not release.exists():
        if time.monotonic() > deadline:
            raise RuntimeError(f"{ENV}: {release} did not appear within {MAX_WAIT_S:g} s")
        time.sleep(0.01)
