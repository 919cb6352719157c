"""The book-keeping every kernel shares: the compressive phases' median."""

from __future__ import annotations

import numba
import numpy as np

from pounding_sweep.engine.bookkeeping import median_inplace


@numba.njit
def _median_of_lane(buf, l, j, k):
    """As the lane kernel calls it: on one lane's and pair's row of its 3-D buffer."""
    return median_inplace(buf[l, j], k)


def test_median_of_compressive_phases_equals_numpys():
    """The in-place heapsort median (scalar, Hertz-type and lane kernels) against np.median, exactly (the
    same two middle values and the same (a + b) / 2), odd and even counts, ties, zeros and the empty buffer;
    only the buffer's first k values are read."""
    rng = np.random.default_rng(11)
    for k in [0, 1, 2, 3, 4, 7, 8, 100, 4096]:
        x = rng.choice([1e-3, 2e-3, 2.3e-2, 0.0], k) if k % 3 == 0 else rng.random(k)
        buf = np.full((2, 3, k + 5), 7.0)  # values past k must not count
        buf[1, 2, :k] = x
        got = _median_of_lane(buf, 1, 2, k)
        assert got == (np.median(x) if k else 0.0)
        assert np.array_equal(np.sort(buf[1, 2, :k]), np.sort(x))  # sorted in place, nothing lost
