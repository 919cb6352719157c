"""Numba's cache index written under a lock, so that processes sharing a cache cannot mix up its entries.

Numba saves a compiled function's entry by reading the function's index, naming a data file after the entries
it holds (`fn.N.nbc` for the first N not taken), writing the index, then the data (numba/core/caching.py
`IndexDataCacheFile.save`), with no lock. Two processes that add different entries of one function at once both
read the same index, both take the same N and both write the same data file: the index keeps one of the two
keys, and the file may hold the other entry's code, which the next process to load that key runs for the wrong
types. Processes share this engine's cache wherever a sweep runs: pytest-xdist's workers, Dask's workers on one
machine, and engine/aside.py's second process beside the first.

`install` makes each save hold an exclusive lock (fcntl.flock on one file per cache folder) from its read of the
index to the end of its data write, so a second save reads the index the first one wrote and takes another name.
Loading needs no lock: the index and the data are each replaced whole (Numba writes a temporary file and renames
it). Where there is no fcntl (not POSIX) or the lock file cannot be opened (a cache folder that cannot be
written, where the save fails anyway), the save runs as Numba's does.
"""

from __future__ import annotations

import contextlib
import functools
import os

from numba.core import caching

try:
    import fcntl
except ImportError:  # not POSIX: Numba's save as it is
    fcntl = None  # type: ignore[assignment]

#: the lock file in each cache folder (ours: Numba names its files after the functions, *.nbi and *.nbc)
LOCK_NAME = "pounding_sweep-index.lock"


@contextlib.contextmanager
def folder_lock(folder: str):
    """Hold the cache folder's exclusive lock inside (nothing where it cannot be taken)."""
    fd = None
    if fcntl is not None:
        try:
            fd = os.open(os.path.join(folder, LOCK_NAME), os.O_RDWR | os.O_CREAT, 0o666)
            fcntl.flock(fd, fcntl.LOCK_EX)
        except OSError:
            if fd is not None:
                os.close(fd)
            fd = None
    try:
        yield
    finally:
        if fd is not None:
            os.close(fd)  # closing the only descriptor of this open releases its lock


def _locked(method):
    """An IndexDataCacheFile method that writes the index, run under its folder's lock."""

    @functools.wraps(method)
    def locked(self, *args, **kwargs):
        with folder_lock(self._cache_path):
            return method(self, *args, **kwargs)

    locked.pounding_sweep_locked = True  # type: ignore[attr-defined]
    return locked


def installed() -> bool:
    """Whether Numba's index writes (save, flush) take the folder's lock in this process."""
    cls = caching.IndexDataCacheFile
    return all(getattr(getattr(cls, name), "pounding_sweep_locked", False) for name in ("save", "flush"))


def install() -> None:
    """Make Numba's index writes take the folder's lock (once per process; for every Numba cache in it)."""
    cls = caching.IndexDataCacheFile
    for name in ("save", "flush"):
        method = getattr(cls, name)
        if not getattr(method, "pounding_sweep_locked", False):
            setattr(cls, name, _locked(method))
