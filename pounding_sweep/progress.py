"""A one-line progress meter on stderr for long work (sweeps, video tracking); silent off a terminal. It
also says when a kernel is compiled for this machine (one line, terminal or not) and, on a terminal,
counts the seconds while Numba compiles (one call that reports nothing until it is done)."""

from __future__ import annotations

import sys
import threading
import time
from collections.abc import Callable


class Progress:
    """Call with (done, total): refreshes at most 5 times a second, prints rate and ETA in `unit`s.

    `enabled` False (--quiet) silences everything; otherwise the meter and the compile clock show on a
    terminal only, and the line announcing a compile shows anywhere (a log keeps it)."""

    def __init__(self, enabled: bool = True, unit: str = "runs"):
        self.announce = enabled
        self.enabled = enabled and sys.stderr.isatty()
        self.unit = unit
        self.t0 = time.perf_counter()
        self.base = 0  # units done before t0 (resumed): not part of the rate
        self.last = 0.0
        self._lock = threading.Lock()

    def __call__(self, done: int, total: int) -> None:
        with self._lock:  # called from worker threads as groups of runs finish
            now = time.perf_counter()
            if not self.enabled or (now - self.last < 0.2 and done < total):
                return
            self.last = now
            rate = (done - self.base) / max(now - self.t0, 1e-9)
            eta = (total - done) / rate if rate > 0 else float("inf")
            pct = 100 * done / total if total else 100.0
            sys.stderr.write(
                f"\r  {done}/{total} {self.unit} ({pct:5.1f} %), {rate:,.0f} {self.unit}/s, ETA {eta:,.0f} s "
            )
            if done >= total:
                sys.stderr.write("\n")
            sys.stderr.flush()

    def restart(self, done: int = 0) -> None:
        """Measure the rate from now, over the units done from here on (after a compile; with `done`
        units resumed from an earlier run)."""
        self.t0 = time.perf_counter()
        self.base = done

    def compiling(
        self, kernel: str, label: str, estimate_s: tuple[float, float], measured_here: bool
    ) -> Callable[[float], None]:
        """Say that `label` is being compiled for this machine, once, and about how long it takes (estimate_s:
        the least and most seconds expected); on a terminal tick the seconds every second. Returns the function
        to call (with the seconds taken) when done."""
        if not self.announce:
            return lambda seconds: None
        least, most = (f"{x:.0f}" for x in estimate_s)
        span = least if least == most else f"{least}-{most}"
        about = f"about {span} s" + (" here last time" if measured_here else " on a 2-core machine")
        sys.stderr.write(f"compiling {label} for this machine (once; {about}; later runs load it from the cache)\n")
        sys.stderr.flush()
        if not self.enabled:
            return lambda seconds: None
        stop = threading.Event()
        t0 = time.perf_counter()

        def tick():
            while not stop.wait(1.0):
                sys.stderr.write(f"\r  compiling: {time.perf_counter() - t0:.0f} s ")
                sys.stderr.flush()

        clock = threading.Thread(target=tick, name="compile-clock", daemon=True)
        clock.start()

        def end(seconds: float) -> None:
            stop.set()
            clock.join()
            sys.stderr.write(f"\r  compiled in {seconds:.1f} s \n")
            sys.stderr.flush()

        return end
