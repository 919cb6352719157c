"""A one-line progress meter on stderr for long work (sweeps, video tracking); silent off a terminal."""

from __future__ import annotations

import sys
import time


class Progress:
    """Call with (done, total): refreshes at most 5 times a second, prints rate and ETA in `unit`s."""

    def __init__(self, enabled: bool = True, unit: str = "runs"):
        self.enabled = enabled and sys.stderr.isatty()
        self.unit = unit
        self.t0 = time.perf_counter()
        self.last = 0.0

    def __call__(self, done: int, total: int) -> None:
        now = time.perf_counter()
        if not self.enabled or (now - self.last < 0.2 and done < total):
            return
        self.last = now
        rate = done / max(now - self.t0, 1e-9)
        eta = (total - done) / rate if rate > 0 else float("inf")
        pct = 100 * done / total if total else 100.0
        sys.stderr.write(f"\r  {done}/{total} {self.unit} ({pct:5.1f} %), {rate:,.0f} {self.unit}/s, ETA {eta:,.0f} s ")
        if done >= total:
            sys.stderr.write("\n")
        sys.stderr.flush()
