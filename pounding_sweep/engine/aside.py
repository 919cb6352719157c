"""Compile a kernel's self-contained pieces in a second process while this one compiles the rest.

A kernel's first compile is one thread's work: Numba holds one lock. Some of the pieces it calls stand alone:
functions cached on their own, called with one signature, such as the scoring code (bookkeeping.score_run,
about 5 s of the README scene's 19 s compile) and the lane kernel's scalar step (lanes.lane_step, 17 s of its
30 s). A second process compiles them into the disk cache while this one compiles the rest. When the
kernel's typing reaches their call, Numba finds them there (numba/core/dispatcher.py `Dispatcher.compile`
looks in the cache before compiling).

It starts only where it can help: a second CPU (its time, too: a cgroup quota of one CPU counts as one), a disk
cache, and the piece not cached yet. When this
process needs a piece the second one is still compiling, it waits for it, then loads the piece from the cache.
If the second process failed, this one compiles the piece itself; the code is the same either way. The
second process is a plain child, killed when this one is done. `python -m pounding_sweep.engine.aside` is
the child: it reads the pieces (module, name, argument types, cache folder) from its standard input, pickled
by this process (Numba's types
only pickle), not a command for users (tests/cli/test_bad_inputs.py names it as the one exception).
"""

from __future__ import annotations

import importlib
import os
import pickle
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

from numba.core import sigutils
from numba.core.caching import NullCache


def _quota_cpus(cgroups: Path = Path("/proc/self/cgroup"), root: Path = Path("/sys/fs/cgroup")) -> float | None:
    """The CPUs a CFS quota gives this process's cgroup and its ancestors (the least of them), None where there is
    none or it cannot be read: cgroup v2 `cpu.max` ("max" or "QUOTA PERIOD"), v1 `cpu.cfs_quota_us` over
    `cpu.cfs_period_us` (-1: none). A container limited to one CPU's time may still see every core."""
    try:
        lines = cgroups.read_text().splitlines()
    except OSError:
        return None
    found = []
    for line in lines:
        if line.count(":") < 2:
            continue
        _, controllers, path = line.split(":", 2)
        if controllers == "":  # v2, at the root or under unified/ beside v1's (hybrid)
            bases, names = [root, root / "unified"], ("cpu.max",)
        elif "cpu" in controllers.split(","):
            bases, names = [root / controllers, root / "cpu"], ("cpu.cfs_quota_us", "cpu.cfs_period_us")
        else:
            continue
        for base in bases:
            folder = base / path.lstrip("/")
            while True:
                cpus = _read_quota(folder, names)
                if cpus is not None:
                    found.append(cpus)
                if folder == base or folder == folder.parent:  # (a path with "..": never past the root)
                    break
                folder = folder.parent
    return min(found) if found else None


def _read_quota(folder: Path, names: tuple) -> float | None:
    """One cgroup folder's quota in CPUs (see _quota_cpus), None for none."""
    try:
        if len(names) == 1:
            quota, period = (folder / names[0]).read_text().split()[:2]
        else:
            quota, period = ((folder / n).read_text().strip() for n in names)
        if quota == "max" or int(quota) <= 0 or int(period) <= 0:
            return None
        return int(quota) / int(period)
    except (OSError, ValueError):
        return None


def _cpus() -> int:
    """The CPUs this process may run on: its affinity, less where a cgroup quota gives it fewer CPUs' time."""
    try:
        n = len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        n = os.cpu_count() or 1
    quota = _quota_cpus()
    return n if quota is None else max(1, min(n, int(quota)))


def _args(sig) -> tuple:
    return tuple(sigutils.normalize_signature(sig)[0])


#: the longest this process waits for the second one before it kills it and compiles the piece itself: many times
#: what a piece takes (lane_step: 17 s on a quiet 2-core machine, about 50 s on a busy one)
WAIT_S = 300.0


def _in_cache(dispatcher, args: tuple) -> bool:
    """Whether the disk cache's index holds the piece: the key Numba's load_overload looks up (numba/core/caching.py
    Cache._load_overload), without loading the entry, which Numba does when the kernel's typing needs it."""
    cache = dispatcher._cache
    return cache._index_key(args, dispatcher.targetctx.codegen()) in cache._cache_file._load_index()


def _compiled_or_cached(dispatcher, args: tuple) -> bool:
    """Whether a piece needs no compile: compiled in this process, or in its disk cache (where it has one)."""
    return args in dispatcher.overloads or (
        not isinstance(dispatcher._cache, NullCache) and _in_cache(dispatcher, args)
    )


def first_cached(pieces: Callable[[], tuple]) -> bool:
    """Whether the first of a kernel's pieces (its largest: the lane kernel's step) is compiled or cached already:
    then the kernel's compile is only what depends on more than that piece's types (the lane kernel: a new pair of
    floor counts), and its time is recorded apart (engine/compile_times.py AGAIN). False where the pieces cannot be
    listed, as start() does."""
    try:
        listed = pieces()
        if not listed:
            return False
        dispatcher, sig = listed[0]
        return _compiled_or_cached(dispatcher, _args(sig))
    except Exception:  # noqa: BLE001 (called inside Numba's compile, as start() is)
        return False


def _wanted(pieces, limit: int | None = None) -> list:
    """The pieces a second process should compile: cached, importable by name, not compiled or cached yet; the
    first `limit` of them (each cache index is read only until that many are found)."""
    out: list = []
    for dispatcher, sig in pieces:
        if limit is not None and len(out) >= limit:
            break
        args = _args(sig)
        if isinstance(dispatcher._cache, NullCache) or "." in dispatcher.py_func.__qualname__:
            continue  # no disk cache, or not importable by name
        if not _compiled_or_cached(dispatcher, args):
            out.append((dispatcher, args))
    return out


class Aside:
    """The second process, and its pieces' caches told to wait for it: a piece this process needs while the
    second one is still compiling it is loaded from the cache once that one is done, not compiled twice."""

    def __init__(self, proc: subprocess.Popen, wanted: list):
        self.proc = proc
        self.caches: list = []  # (cache, what its load_overload instance attribute was: None for none)
        for dispatcher, _ in wanted:
            cache = dispatcher._cache
            if all(cache is not c for c, _ in self.caches):
                self.caches.append((cache, cache.__dict__.get("load_overload")))
                cache.load_overload = self._waiting(cache.load_overload, {a for d, a in wanted if d is dispatcher})

    def _waiting(self, load, compiled_aside: set):
        def load_overload(sig, target_context):
            if _args(sig) in compiled_aside:
                self._wait()
            return load(sig, target_context)

        return load_overload

    def _wait(self) -> None:
        try:
            self.proc.wait(timeout=WAIT_S)
        except subprocess.TimeoutExpired:  # stuck: compile here
            self.proc.kill()
            self.proc.wait()

    def stop(self) -> None:
        """Kill the second process if it is still running (this one is done and did not need the rest of its
        work; cut short while saving, it may leave a data file no index names yet (engine/cache_lock.py writes the
        data first), which the next save of that function overwrites, or a temporary file) and put the caches'
        loading back as it was."""
        try:
            if self.proc.poll() is None:
                self.proc.kill()
            self.proc.wait()
        finally:
            for cache, before in self.caches:
                if before is not None:
                    cache.load_overload = before
                else:
                    cache.__dict__.pop("load_overload", None)


def start(pieces: Callable[[], tuple]) -> Aside | None:
    """Start compiling, in a second process, the first piece `pieces()` returns ((dispatcher, argument types)
    pairs, in the order a second process should take them) that is not compiled or cached yet: one piece, as
    a kernel's list is ordered so that this process's own work covers the first (the lane kernel: its step,
    else its contact loop; a second piece after the step would keep this process waiting for it); None where
    it would not help (one CPU, no disk cache, nothing left to compile) or cannot start. It is called inside
    Numba's compile, which only a speed-up must not break: an error in `pieces()` leaves the compile to this
    process (tests/engine/test_aside.py would see the miss)."""
    from pounding_sweep.engine import jit

    if jit.CACHE_DIR is None or _cpus() < 2 or not sys.executable or getattr(sys, "frozen", False):
        return None  # no disk cache, no CPU to spare, or no Python to start (an embedding or frozen program)
    try:
        wanted = _wanted(pieces(), limit=1)
    except Exception:  # noqa: BLE001 (see the docstring)
        return None
    if not wanted:
        return None
    # each piece with the cache file it must land in: a second process that imports the package from
    # elsewhere (another checkout first on its path) would write where this one does not read
    names = [(d.py_func.__module__, d.py_func.__qualname__, args, d._cache._cache_path) for d, args in wanted]
    try:
        proc = subprocess.Popen(
            [sys.executable, "-m", "pounding_sweep.engine.aside"],
            stdin=subprocess.PIPE,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
    except Exception:  # noqa: BLE001 (no process to spare, or none can start: compile here)
        return None
    try:
        assert proc.stdin is not None
        proc.stdin.write(pickle.dumps(names))
        proc.stdin.close()
    except OSError:  # it ended at once: compile here
        proc.kill()
        proc.wait()
        return None
    return Aside(proc, wanted)


def stop(aside: Aside | None) -> None:
    """End what start() began (nothing if it began nothing)."""
    if aside is not None:
        aside.stop()


def main() -> int:
    """The second process: compile each piece whose cache is where the first process reads it; exit 1 if one
    was not (another checkout or configuration: its entries would help no one)."""
    names = pickle.load(sys.stdin.buffer)
    missed = 0
    for module, name, args, cache_path in names:
        dispatcher = getattr(importlib.import_module(module), name)
        if getattr(dispatcher._cache, "_cache_path", None) != cache_path:
            missed += 1
            continue
        dispatcher.compile(args)
    return 1 if missed else 0


if __name__ == "__main__":
    sys.exit(main())
