"""engine/cache_lock.py: two saves of different entries of one function at once keep both, each with its own data."""

from __future__ import annotations

import os
import pickle
import subprocess
import sys
import threading

import numba
import pytest
from gates import SAFETY_S
from numba.core import caching

from pounding_sweep.engine import cache_lock, jit  # noqa: F401 (importing jit installs the lock)

#: the tests of this module's own save (data before index): skipped, and named, on a Numba whose save differs from
#: the one it was written against (there Numba's own save runs under the lock: install)
ours = pytest.mark.skipif(
    cache_lock.source_digest() not in cache_lock.KNOWN_SOURCES,
    reason=f"numba {numba.__version__}: its cache save (digest {cache_lock.source_digest()}) is not the one "
    "engine/cache_lock.py was written against (KNOWN_SOURCES): Numba's own save runs, under the lock",
)

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
    assert read.wait(SAFETY_S), "the first save never read the index"
    second.save(("b",), {"entry": "b"})
    second_done.set()
    thread.join(SAFETY_S)
    assert not errors and not thread.is_alive()
    reader = _index(tmp_path)
    names = reader._load_index()
    assert sorted(names) == [("a",), ("b",)], names
    assert len(set(names.values())) == 2, names
    assert reader.load(("a",)) == {"entry": "a"}
    assert reader.load(("b",)) == {"entry": "b"}


WRITER = """
import os
import sys
import time
from numba.core import caching
from pounding_sweep.engine import jit  # installs the lock
folder, who, n = sys.argv[1], sys.argv[2], int(sys.argv[3])
index = caching.IndexDataCacheFile(folder, "fn", "stamp")
open(os.path.join(folder, "ready-" + who), "w").close()
while len([f for f in os.listdir(folder) if f.startswith("ready-")]) < 2:
    time.sleep(0.001)  # both started: the saves overlap however long each took to start
for i in range(n):
    index.save((who, i), (who, i))
"""


def test_processes_adding_entries_at_once_keep_every_entry(tmp_path):
    """Two processes, each adding its own entries of one function's index at the same time (as two test workers
    or Dask workers compiling new types do; a barrier starts their saves together): every entry is in the index
    with its own data file and data."""
    n = 200
    procs = [
        subprocess.Popen([sys.executable, "-c", WRITER, str(tmp_path), who, str(n)], stderr=subprocess.PIPE, text=True)
        for who in ("p", "q")
    ]
    for p in procs:
        _, err = p.communicate(timeout=SAFETY_S)
        assert p.returncode == 0, err[-2000:]
    reader = _index(tmp_path)
    names = reader._load_index()
    assert len(names) == 2 * n and len(set(names.values())) == 2 * n
    for key in names:
        assert reader.load(key) == key
    assert not [f for f in os.listdir(tmp_path) if ".tmp." in f]


@ours
def test_the_index_names_an_entry_only_once_its_data_is_written(tmp_path):
    """A load between the save's two writes finds no entry (Numba's own order, index first, would hand it a data
    file not written yet, or a stale one of that name)."""
    index = _index(tmp_path)
    index.save(("old",), "old")
    stale = tmp_path / index._data_name(2)
    stale.write_bytes(pickle.dumps("stale"))  # left by an earlier index of that name
    seen: list = []
    write_data = index._save_data

    def save_data_then_look(name, data):
        seen.append(_index(tmp_path).load(("new",)))  # before the data
        write_data(name, data)
        seen.append(_index(tmp_path).load(("new",)))  # after the data, before the index

    index._save_data = save_data_then_look
    index.save(("new",), "new")
    assert seen == [None, None]
    assert _index(tmp_path).load(("new",)) == "new" and _index(tmp_path).load(("old",)) == "old"


@ours
def test_the_save_is_the_one_written_against_this_numba():
    """Installed only where Numba's methods are the ones it was written against (else Numba's save, locked): a newer
    Numba than that is a skip that names it (-ra), not a red suite on a fresh install."""
    assert caching.IndexDataCacheFile.save.__code__ is cache_lock._save.__code__


@pytest.mark.skipif(not hasattr(os, "fork") or cache_lock.fcntl is None, reason="no fork or no fcntl here")
def test_a_child_forked_during_a_save_does_not_keep_the_lock(tmp_path):
    """A process forked while a save holds the lock closes its copy of the lock, so the parent's next save does not
    wait for the child."""
    import fcntl

    r, w = os.pipe()
    with cache_lock.folder_lock(str(tmp_path)):
        pid = os.fork()
        if pid == 0:  # the child: is the lock free once the parent lets go? wait for the parent's word, then try
            os.read(r, 1)
            fd = os.open(tmp_path / cache_lock.LOCK_NAME, os.O_RDONLY)
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
                os._exit(0)
            except BlockingIOError:
                os._exit(1)
    os.write(w, b"x")  # the parent has released the lock
    _, status = os.waitpid(pid, 0)
    assert os.waitstatus_to_exitcode(status) == 0, "the forked child kept the lock"


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
