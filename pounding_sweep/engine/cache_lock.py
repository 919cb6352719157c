"""Numba's cache entries saved under a lock, data before index, so that processes sharing a cache cannot mix them up.

Numba saves a compiled function's entry by reading the function's index, naming a data file after the entries
it holds (`fn.N.nbc` for the first N not taken), writing the index, then the data (numba/core/caching.py
`IndexDataCacheFile.save`), with no lock. Two processes that add different entries of one function at once both
read the same index, both take the same N and both write the same data file: the index keeps one of the two
keys, and the file may hold the other entry's code, which the next process to load that key runs for the wrong
types. And between the index write and the data write, a process loading the key opens a data file that is not
written yet, or is a stale one of that name. Processes share this engine's cache wherever a sweep runs:
pytest-xdist's workers, Dask's workers on one machine, and engine/aside.py's second process beside the first.

`install` replaces the save: under an exclusive lock (fcntl.flock on one file per cache folder, named as ours) it
reads the index, names the data file, writes the data, then the index. A second save reads the index the first
one wrote and takes another name; a load (no lock: each file is replaced whole, Numba writing a temporary file
and renaming it) finds an entry only once its data is there. The index reset (`flush`) takes the lock too. Where
there is no fcntl (not POSIX), the lock is skipped; where the lock file cannot be opened, the save runs unlocked,
in that same order. The save is installed only on the Numba it was written against (KNOWN_SOURCES); elsewhere
Numba's own save runs under the lock.
"""

from __future__ import annotations

import contextlib
import functools
import itertools
import os
import time

from numba.core import caching

from pounding_sweep.engine import numba_source

try:
    import fcntl
except ImportError:  # not POSIX: no lock
    fcntl = None  # type: ignore[assignment]

#: the lock file in each cache folder (Numba names its own files after the functions: *.nbi and *.nbc)
LOCK_NAME = "pounding_sweep-index.lock"
#: SHA-256 (16 hex digits) of IndexDataCacheFile's save, _load_index, _save_index and _save_data as this module was
#: written against (numba 0.68.1)
KNOWN_SOURCES = frozenset({"c2faa5ef3b4c927e"})
_METHODS = tuple((caching.IndexDataCacheFile, name) for name in ("save", "_load_index", "_save_index", "_save_data"))

_held: set[int] = set()  # lock descriptors open now: a child forked meanwhile closes its copies


def _close_held_in_child() -> None:
    for fd in _held:
        with contextlib.suppress(OSError):
            os.close(fd)  # the child's copy: the parent's lock is released when the parent closes its own
    _held.clear()


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_close_held_in_child)


def _open_lock(folder: str) -> int:
    """The folder's lock file, opened read-only (flock needs no write access, so processes of other users sharing
    the cache lock it too) and created where missing; OSError where it cannot be."""
    return os.open(os.path.join(folder, LOCK_NAME), os.O_RDONLY | os.O_CREAT, 0o666)


@contextlib.contextmanager
def folder_lock(folder: str):
    """Hold the cache folder's exclusive lock inside (nothing where it cannot be taken)."""
    fd = None
    if fcntl is not None:
        try:
            fd = _open_lock(folder)
            fcntl.flock(fd, fcntl.LOCK_EX)
            _held.add(fd)
        except OSError:
            if fd is not None:
                os.close(fd)
            fd = None
    try:
        yield
    finally:
        if fd is not None:
            _held.discard(fd)
            os.close(fd)  # closing the only descriptor of this open releases its lock


def saves_ended(folder: str, deadline: float, poll_s: float) -> bool:
    """Whether no save holds the folder's lock (the save under way when called has ended), looked at every poll_s
    until `deadline` (time.monotonic): False if it is still held then. True at once where the lock cannot be taken
    (no fcntl, or no lock file: saves there take none either)."""
    if fcntl is None:
        return True
    try:
        fd = _open_lock(folder)
    except OSError:
        return True
    try:
        while True:
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
                return True  # released when fd is closed, below
            except BlockingIOError:
                if time.monotonic() > deadline:
                    return False
                time.sleep(poll_s)
            except OSError:
                return True
    finally:
        os.close(fd)


def source_digest() -> str:
    """The digest KNOWN_SOURCES holds, of this Numba's IndexDataCacheFile methods the save relies on."""
    return numba_source.digest(_METHODS)


def _save(self, key, data) -> None:
    """IndexDataCacheFile.save, under the folder's lock, the data written before the index that names it."""
    with folder_lock(self._cache_path):
        overloads = self._load_index()
        data_name = overloads.get(key)
        if data_name is not None:  # the key's own file, replaced whole
            self._save_data(data_name, data)
            return
        taken = set(overloads.values())
        data_name = next(n for n in (self._data_name(i) for i in itertools.count(1)) if n not in taken)
        self._save_data(data_name, data)
        overloads[key] = data_name
        self._save_index(overloads)


def _locked(method):
    """An IndexDataCacheFile method that writes the index, run under its folder's lock."""

    @functools.wraps(method)
    def locked(self, *args, **kwargs):
        with folder_lock(self._cache_path):
            return method(self, *args, **kwargs)

    return locked


def installed() -> bool:
    """Whether Numba's index writes (save, flush) take the folder's lock in this process."""
    cls = caching.IndexDataCacheFile
    return all(getattr(getattr(cls, name), "pounding_sweep_locked", False) for name in ("save", "flush"))


def install() -> None:
    """Make Numba's index writes take the folder's lock (once per process; for every Numba cache in it): the
    save this module writes where Numba's is the one it was written against, else Numba's own under the lock."""
    cls = caching.IndexDataCacheFile
    if installed():
        return
    known = numba_source.known(_METHODS, KNOWN_SOURCES)
    save = functools.wraps(cls.save)(_save) if known else _locked(cls.save)
    for name, method in (("save", save), ("flush", _locked(cls.flush))):
        method.pounding_sweep_locked = True  # type: ignore[attr-defined]
        setattr(cls, name, method)
