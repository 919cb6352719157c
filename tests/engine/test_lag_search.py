"""Issue 17, item 11: the correlation lag search through the FFT returns what the direct search over
every lag returns, bit for bit (value and lag), and recomputes only a few lags directly on long records.

`best_lag(..., fft_min_lags=0)` forces the FFT path on cases of every size; `best_lag_direct` is the
old loop (lagged_correlation at each lag, first maximum in ascending order, NaN never wins). The cases
include what could make an estimate pick the wrong lag: near-ties (quantised and periodic data), a large
offset (the means' rounding), a single spike, constant data (NaN at every lag), and lags up to the
whole window."""

from __future__ import annotations

import numpy as np
import pytest

from pounding_sweep.engine.score import FFT_MIN_LAGS, best_lag, best_lag_direct, lag_estimates


def _same(a, b) -> bool:
    """Equal value (NaN equal to NaN) and equal lag."""
    return a[1] == b[1] and (a[0] == b[0] or (np.isnan(a[0]) and np.isnan(b[0])))


def _case(rng, kind: int, n: int):
    t = np.arange(n) * 0.01
    xe = np.sin(2 * np.pi * rng.uniform(0.5, 8.0) * t) + rng.normal(0.0, rng.choice([0.0, 1e-3, 0.3]), n)
    xd = np.roll(xe, int(rng.integers(-20, 20))) * rng.uniform(0.5, 2.0) + rng.normal(0.0, 0.01, n)
    if kind == 1:
        xd = xd + 1e3  # an offset 1000x the motion
    elif kind == 2:
        xd, xe = np.round(xd, 1), np.round(xe, 1)  # coarse values: many exact ties
    elif kind == 3:
        xe = np.zeros(n)
        xe[n // 2] = 1.0
    elif kind == 4:
        xd = np.full(n, 3.0)  # no variance: NaN at every lag
    elif kind == 5:
        xd = xe = np.tile([0.0, 1.0, 0.0, -1.0], n // 4 + 1)[:n]  # exactly periodic: equal maxima
    return np.ascontiguousarray(xd), np.ascontiguousarray(xe)


@pytest.mark.parametrize("kind", range(6))
def test_fft_search_equals_the_direct_search(kind):
    rng = np.random.default_rng(17 + kind)
    for _ in range(40):
        n = int(rng.integers(4, 2500))
        max_lag = int(rng.integers(0, n - 1))  # up to n - 2, as score_spec allows
        xd, xe = _case(rng, kind, n)
        with np.errstate(all="ignore"):
            fast = best_lag(xd, xe, max_lag, 0)
            direct = best_lag_direct(xd, xe, max_lag)
        assert _same(fast, direct), (kind, n, max_lag, fast, direct)


def test_the_bound_holds_and_leaves_few_lags_to_check():
    """Every estimate lies within its bound of lagged_correlation's value, and on a realistic case the
    bound is far below the correlation's change between neighbouring lags (few lags rechecked)."""
    from pounding_sweep.engine.score import lagged_correlation

    rng = np.random.default_rng(3)
    n, max_lag = 20_000, 400
    t = np.arange(n) * 1e-3
    xe = 1e-3 * np.sin(2 * np.pi * 6.0 * t) + rng.normal(0.0, 5e-5, n)
    xd = 1.1e-3 * np.sin(2 * np.pi * 6.0 * (t - 0.0123)) + 2e-4
    est, bound, trusted = lag_estimates(xd, xe, max_lag)
    exact = np.array([lagged_correlation(xd, xe, lag) for lag in range(-max_lag, max_lag + 1)])
    assert trusted.all()
    assert np.all(np.abs(est - exact) <= bound)
    assert bound.max() < 1e-9
    lower = np.max(est - bound)
    assert int(np.sum(est + bound >= lower)) <= 3
    assert _same(best_lag(xd, xe, max_lag), best_lag_direct(xd, xe, max_lag))


def test_short_searches_stay_direct_and_long_ones_are_cheap():
    """Below FFT_MIN_LAGS lags the direct loop runs (the shipped scenes: 21 lags); a search over 4001 lags
    of a 200,000-sample record recomputes at most 3 lags directly (each costing n operations), against the
    direct search's 4001: the rest is the FFT's O(n log n). Counted, not timed (the time is
    benchmarks/bench_lag_search.py's)."""
    rng = np.random.default_rng(5)
    n, max_lag = 200_000, 2000
    assert 2 * 10 + 1 < FFT_MIN_LAGS <= 2 * max_lag + 1
    t = np.arange(n) * 1e-4
    xe = np.sin(2 * np.pi * 6.0 * t) + rng.normal(0.0, 0.05, n)
    xd = np.sin(2 * np.pi * 6.0 * (t - 0.01))
    est, bound, trusted = lag_estimates(xd, xe, max_lag)
    assert trusted.all()
    lower = np.max(est - bound)
    rechecked = int(np.sum(est + bound >= lower))  # best_lag's rule: the lags that could still be the best
    assert 1 <= rechecked <= 3, rechecked
    fast, direct = best_lag(xd, xe, max_lag), best_lag_direct(xd, xe, max_lag)
    assert _same(fast, direct) and fast[1] == 100
