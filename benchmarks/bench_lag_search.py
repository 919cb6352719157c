"""The correlation lag search (engine/score.py best_lag) against the direct search over every lag, timed.

Usage (from the repository root):

    python benchmarks/bench_lag_search.py

For records of 20,000 to 200,000 samples and 41 to 4001 lags: the least of 5 timings of best_lag (FFT
estimates, then only the lags that could be the best recomputed) and of best_lag_direct (every lag), in ms,
and their ratio (the claim tests/engine/test_lag_search.py counts instead of timing: the FFT path recomputes
at most a few lags of n operations each, the direct one all of them). Both are compiled (or loaded) first.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from pounding_sweep.engine.score import best_lag, best_lag_direct  # noqa: E402

REPEATS = 5


def least_time(f, *args) -> tuple[float, tuple]:
    best, out = np.inf, None
    for _ in range(REPEATS):
        t0 = time.perf_counter()
        out = f(*args)
        best = min(best, time.perf_counter() - t0)
    return best, out


def main() -> None:
    rng = np.random.default_rng(5)
    best_lag(np.zeros(300) + rng.normal(size=300), rng.normal(size=300), 200)  # compiled before timing
    best_lag_direct(np.zeros(300), np.zeros(300), 10)
    print(f"{'samples':>8} {'lags':>6} {'best_lag ms':>12} {'direct ms':>10} {'direct / best_lag':>18}")
    for n, max_lag in ((20_000, 20), (20_000, 400), (200_000, 400), (200_000, 2000)):
        t = np.arange(n) * 1e-4
        xe = np.sin(2 * np.pi * 6.0 * t) + rng.normal(0.0, 0.05, n)
        xd = np.sin(2 * np.pi * 6.0 * (t - 0.01))
        t_fast, fast = least_time(best_lag, xd, xe, max_lag)
        t_direct, direct = least_time(best_lag_direct, xd, xe, max_lag)
        assert fast[1] == direct[1], (fast, direct)
        print(f"{n:>8,} {2 * max_lag + 1:>6} {t_fast * 1e3:>12.2f} {t_direct * 1e3:>10.2f} {t_direct / t_fast:>18.1f}")


if __name__ == "__main__":
    main()
