"""Compile a kernel's self-contained pieces in a second process while this one compiles the rest.

A kernel's first compile is one thread's work: Numba holds one lock. Some of the pieces it calls stand alone:
functions cached on their own, called with one signature, such as the scoring code (bookkeeping.score_run,
about 5 s of the README scene's compile), the scalar kernel's event-step pieces (about 1 s), the Hertz-type
kernel's contact solve and event-step pieces (about 2 s) and the lane kernel's scalar step (lanes.lane_step,
17 s of its 30 s). A second process compiles them into the disk cache while this one compiles the rest. When
the kernel's typing reaches their call, Numba finds them there (numba/core/dispatcher.py `Dispatcher.compile`
looks in the cache before compiling).

A kernel lists its pieces in groups (`pieces()`): the second process takes the first group that holds a piece not
compiled or cached yet, and compiles that group's missing pieces one after the other, in the order the kernel's
typing reaches them. It starts only where it can help: a second CPU (its time, too: a cgroup quota of one CPU counts
as one), a disk cache, and a piece not cached yet. When this process needs a piece the second one has not saved yet,
it waits for that piece's entry in the cache index (not for the others) and for the save that wrote it to end, then
loads it. If the second process failed, this one compiles the piece itself; the code is the same either way. The
second process is a plain child, killed when this one is done. `python -m pounding_sweep.engine.aside` is the child:
it reads the pieces (module, name, argument types, cache folder) from its standard input, pickled by this process
(Numba's types only pickle), not a command for users (tests/cli/test_bad_inputs.py names it as the one exception).
"""

from __future__ import annotations

import importlib
import os
import pickle
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

from numba.core import sigutils
from numba.core.caching import NullCache

from pounding_sweep.engine import cache_lock


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
#: how often a waiting process looks for the piece in the cache index (a small file, read whole)
POLL_S = 0.02


def _in_cache(dispatcher, args: tuple) -> bool:
    """Whether the disk cache's index holds the piece: the key Numba's load_overload looks up (numba/core/caching.py
    Cache._load_overload), without loading the entry, which Numba does when the kernel's typing needs it."""
    cache = dispatcher._cache
    return cache._index_key(args, dispatcher.targetctx.codegen()) in cache._cache_file._load_index()


def _saved(dispatcher, args: tuple) -> bool:
    """_in_cache, False where the index cannot be read (called inside Numba's compile: a speed-up must not break
    it; the wait then ends with the second process, or at WAIT_S)."""
    try:
        return _in_cache(dispatcher, args)
    except Exception:  # noqa: BLE001
        return False


def _compiled_or_cached(dispatcher, args: tuple) -> bool:
    """Whether a piece needs no compile: compiled in this process, or in its disk cache (where it has one)."""
    return args in dispatcher.overloads or (
        not isinstance(dispatcher._cache, NullCache) and _in_cache(dispatcher, args)
    )


def first_cached(pieces: Callable[[], tuple]) -> bool:
    """Whether every piece of a kernel's first group (the lane kernel: its step, its largest piece) is compiled or
    cached already: then the kernel's compile is only what depends on more than those pieces' types (the lane
    kernel: a new pair of floor counts), and its time is recorded apart (engine/compile_times.py AGAIN). False
    where the pieces cannot be listed, as start() does."""
    try:
        groups = pieces()
        if not groups or not groups[0]:
            return False
        return all(_compiled_or_cached(dispatcher, _args(sig)) for dispatcher, sig in groups[0])
    except Exception:  # noqa: BLE001 (called inside Numba's compile, as start() is)
        return False


def _wanted(groups) -> list:
    """The pieces a second process should compile: those of the first group that holds any, each cached,
    importable by name, and not compiled or cached yet (the groups after it are not looked at: their cache
    indexes are not read)."""
    for group in groups:
        out: list = []
        for dispatcher, sig in group:
            args = _args(sig)
            if isinstance(dispatcher._cache, NullCache) or "." in dispatcher.py_func.__qualname__:
                continue  # no disk cache, or not importable by name
            if not _compiled_or_cached(dispatcher, args):
                out.append((dispatcher, args))
        if out:
            return out
    return []


class Aside:
    """The second process, and its pieces' caches told to wait for it: a piece this process needs before the
    second one has saved it is loaded from the cache once it is there, not compiled twice."""

    def __init__(self, proc: subprocess.Popen, wanted: list):
        self.proc = proc
        self.caches: list = []  # (cache, what its load_overload instance attribute was: None for none)
        for dispatcher, _ in wanted:
            cache = dispatcher._cache
            if all(cache is not c for c, _ in self.caches):
                self.caches.append((cache, cache.__dict__.get("load_overload")))
                compiled_aside = {a for d, a in wanted if d is dispatcher}
                cache.load_overload = self._waiting(cache.load_overload, dispatcher, compiled_aside)

    def _waiting(self, load, dispatcher, compiled_aside: set):
        def load_overload(sig, target_context):
            args = _args(sig)
            if args in compiled_aside and not self._wait(dispatcher, args):
                return None  # its entry may name data its save never wrote: compiled here
            return load(sig, target_context)

        return load_overload

    def _wait(self, dispatcher, args: tuple) -> bool:
        """Until the piece is in the cache index and the save that put it there has ended, the second process has
        ended (done, or failed: then this one compiles the piece), or WAIT_S has passed (stuck: it is killed, and
        this one compiles the piece). False where it was killed inside that save: the entry is not loaded."""
        deadline = time.monotonic() + WAIT_S
        while self.proc.poll() is None:
            if _saved(dispatcher, args):
                # every save holds the cache folder's lock throughout (engine/cache_lock.py), and Numba's own (run
                # where ours is not installed: another Numba, or a wrapper over its save) writes the index before
                # the data: the entry may name a data file not written yet (the load would miss, and the piece be
                # compiled twice) or an older one of that name
                if cache_lock.saves_ended(dispatcher._cache._cache_path, deadline, POLL_S):
                    return True
                self._kill()
                return False
            if time.monotonic() > deadline:
                self._kill()
                return True
            time.sleep(POLL_S)
        return True

    def _kill(self) -> None:
        """Kill the second process, if it has not ended, and reap it (a lock it held goes with it)."""
        self.proc.kill()  # (Popen.kill does nothing once the process has ended)
        self.proc.wait()

    def stop(self) -> None:
        """Kill the second process if it is still running (this one is done and did not need the rest of its
        work; cut short while saving, it may leave a data file no index names yet (engine/cache_lock.py writes the
        data first), which the next save of that function overwrites, or a temporary file) and put the caches'
        loading back as it was."""
        try:
            self._kill()
        finally:
            for cache, before in self.caches:
                if before is not None:
                    cache.load_overload = before
                else:
                    cache.__dict__.pop("load_overload", None)


def start(pieces: Callable[[], tuple]) -> Aside | None:
    """Start compiling, in a second process, the pieces of the first group `pieces()` returns (groups of
    (dispatcher, argument types) pairs) that holds a piece not compiled or cached yet. A kernel's groups are
    alternatives, in the order a second process should take them: the lane kernel's step, else its contact loop
    (after the step, the loop would come too late: this process would wait for it); each scalar kernel's one
    group, its pieces in the order its typing reaches them. None where it would not help (one CPU, no disk cache,
    nothing left to compile) or cannot start. It is called inside Numba's compile, which only a speed-up must not
    break: an error in `pieces()` leaves the compile to this process (tests/engine/test_aside.py would see the
    miss)."""
    from pounding_sweep.engine import jit

    if jit.CACHE_DIR is None or _cpus() < 2 or not sys.executable or getattr(sys, "frozen", False):
        return None  # no disk cache, no CPU to spare, or no Python to start (an embedding or frozen program)
    try:
        wanted = _wanted(pieces())
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
    was not (another checkout or configuration: its entries would help no one), saying which on standard error (the
    first process discards it; tests/engine/test_aside.py shows it)."""
    names = pickle.load(sys.stdin.buffer)
    missed = 0
    for module, name, args, cache_path in names:
        dispatcher = getattr(importlib.import_module(module), name)
        mine = getattr(dispatcher._cache, "_cache_path", None)
        if mine != cache_path:
            here = "it has no disk cache here" if mine is None else f"its cache here is {mine}"
            print(f"aside: {module}.{name} not compiled: {here}, the first process reads {cache_path}", file=sys.stderr)
            missed += 1
            continue
        dispatcher.compile(args)
    return 1 if missed else 0


if __name__ == "__main__":
    sys.exit(main())
