"""engine/cache_lock.py: two saves of different entries of one function at once keep both, each with its own data."""

from __future__ import annotations

import os
import pickle
import subprocess
import sys
import threading

import pytest
from numba.core import caching

from pounding_sweep.engine import cache_lock, jit  # noqa: F401 (importing jit installs the lock)

#: how long the first save, paused inside with its index read, waits for the second one to finish: with the lock the
#: second cannot finish, so the first always waits this long; without it the second finishes in far less (a few file
#: writes), and the test sees the two entries share a data file
PAUSE_S = 2.0


def _index(folder, stamp="stamp") -> caching.IndexDataCacheFile:
    return caching.IndexDataCacheFile(str(folder), "fn", stamp)


def test_importing_the_engine_installs_the_lock():
    assert cache_lock.installed()


def test_a_save_while_another_has_read_the_index_takes_another_data_file(tmp_path):
    """The first save reads the index and pauses before naming its data file; the second save, started then, waits
    for it (the lock) and names another file. Both keys load their own data afterwards. Without the lock both
    take fn.1.nbc: the index keeps one key and the file the other's data."""
    first, second = _index(tmp_path), _index(tmp_path)
    read = threading.Event()
    second_done = threading.Event()
    load = first._load_index

    def load_then_pause():
        got = load()
        read.set()
        second_done.wait(PAUSE_S)  # the second save runs now, unless the lock holds it
        return got

    first._load_index = load_then_pause
    errors: list = []

    def save_first():
        try:
            first.save(("a",), {"entry": "a"})
        except Exception as e:  # noqa: BLE001 (reported below)
            errors.append(e)

    thread = threading.Thread(target=save_first)
    thread.start()
    assert read.wait(60), "the first save never read the index"
    second.save(("b",), {"entry": "b"})
    second_done.set()
    thread.join(60)
    assert not errors and not thread.is_alive()
    reader = _index(tmp_path)
    names = reader._load_index()
    assert sorted(names) == [("a",), ("b",)], names
    assert len(set(names.values())) == 2, names
    assert reader.load(("a",)) == {"entry": "a"}
    assert reader.load(("b",)) == {"entry": "b"}


WRITER = """
import sys
from numba.core import caching
from pounding_sweep.engine import jit  # installs the lock
index = caching.IndexDataCacheFile(sys.argv[1], "fn", "stamp")
for i in range(int(sys.argv[3])):
    index.save((sys.argv[2], i), (sys.argv[2], i))
"""


def test_processes_adding_entries_at_once_keep_every_entry(tmp_path):
    """Two processes, each adding its own entries of one function's index at the same time (as two test workers
    or Dask workers compiling new types do): every entry is in the index with its own data file and data."""
    n = 60
    procs = [
        subprocess.Popen([sys.executable, "-c", WRITER, str(tmp_path), who, str(n)], stderr=subprocess.PIPE, text=True)
        for who in ("p", "q")
    ]
    for p in procs:
        _, err = p.communicate(timeout=600)
        assert p.returncode == 0, err[-2000:]
    reader = _index(tmp_path)
    names = reader._load_index()
    assert len(names) == 2 * n and len(set(names.values())) == 2 * n
    for key in names:
        assert reader.load(key) == key
    assert not [f for f in os.listdir(tmp_path) if ".tmp." in f]


def test_a_folder_that_cannot_be_locked_saves_as_numba_does(tmp_path, monkeypatch):
    """No lock file (a folder the lock cannot be made in): the save still runs, unlocked."""

    def refuse(*args, **kwargs):
        raise PermissionError("read-only")

    monkeypatch.setattr(cache_lock.os, "open", refuse)
    index = _index(tmp_path)
    index.save(("k",), [1, 2])
    assert index.load(("k",)) == [1, 2]


@pytest.mark.skipif(cache_lock.fcntl is None, reason="no fcntl here (not POSIX): saves are Numba's, unlocked")
def test_the_lock_is_released_after_a_save(tmp_path):
    """After a save, another open of the lock file takes it at once (no descriptor kept open)."""
    import fcntl

    _index(tmp_path).save(("k",), pickle.dumps(1))
    fd = os.open(tmp_path / cache_lock.LOCK_NAME, os.O_RDWR)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)  # raises BlockingIOError if still held
    finally:
        os.close(fd)
