"""Compiling a kernel's self-contained pieces in a second process (engine/aside.py).

The second process compiles the scoring code, or the lane kernel's scalar step, into the disk cache; the
kernel's own compile must then find it there, so the signature must be exactly the one the kernels call it
with (bookkeeping.score_run_signature, groups._lane_step_signature). This process waits for the second one when
it needs the piece first, so the checks do not depend on which process is faster. And the second process
starts only where it can help.
"""

from __future__ import annotations

import os
import pickle
import subprocess
import sys
import time

import numba
import numpy as np
import pytest
from conftest import SWEEPS

from pounding_sweep.codes import SCHEME_EVENT, SCHEME_IMPLICIT, SCHEME_PAPER
from pounding_sweep.engine import aside, bookkeeping, cache_lock, nonlinear, scalar
from pounding_sweep.engine.inputs import ScoreSpec

RUN = f"""
import dataclasses
import sys
from pounding_sweep.engine import aside, driver
from pounding_sweep.engine import bookkeeping as bk
from pounding_sweep.engine.lanes.lane_step import lane_step
from pounding_sweep.scene import load_scene
from pounding_sweep.sweep.prepare import prepare

aside._cpus = lambda: 2  # as on a machine with a CPU to spare, whatever this one has
aside.WAIT_S = float("inf")  # however slow the machine: the wait still ends when the second process does
name, piece, laws = {{"scored": ("scored_6hz", bk.score_run, ("classic", "hertzdamp")),
                     "lanes": ("paper_duzce", lane_step, ("classic",))}}[sys.argv[1]]
scene = load_scene({str(SWEEPS)!r} + f"/{{name}}.toml")
scene = dataclasses.replace(scene, sweep=())
for law in laws:
    prep = prepare(dataclasses.replace(scene, contact=dataclasses.replace(scene.contact, law=law)))
    kernel = "scalar" if prep.score.active else "lanes"
    driver.compile_kernel(prep.sysarr, prep.opts, prep.hist, prep.score, kernel, prep.law_codes_used)
    sig = piece.signatures[0]
    print(law, len(piece.signatures), piece.stats.cache_hits.get(sig, 0), piece.stats.cache_misses.get(sig, 0))
if sys.argv[1] == "scored":  # the scalar kernel's event-step pieces and the run's end, compiled aside before the scoring
    from pounding_sweep.engine import scalar

    for d, _ in scalar.event_pieces(prep.opts.scheme) + bk.row_end_pieces():
        sig = d.signatures[0]
        print(d.py_func.__name__, len(d.signatures), d.stats.cache_hits.get(sig, 0), d.stats.cache_misses.get(sig, 0))
    # the Hertz-type kernel's own pieces (pair_pieces, the scalar kernel's, was cached before it)
    from pounding_sweep.engine import nonlinear

    for d, _ in nonlinear.event_pieces():
        sig = d.signatures[0]
        hits, misses = d.stats.cache_hits.get(sig, 0), d.stats.cache_misses.get(sig, 0)
        print("hertz", d.py_func.__name__, len(d.signatures), hits, misses)
if sys.argv[1] == "lanes":  # a new pair of floor counts (4 + 2), the step cached: the contact loop is aside
    from pounding_sweep.engine.lanes.groups import _integrate_groups
    from pounding_sweep.engine.lanes.loops import contact_loop

    b1 = dataclasses.replace(scene.building1, masses_kg=(1.7, 1.7, 1.6, 1.6))
    b2 = dataclasses.replace(scene.building2, masses_kg=(0.56, 0.45))
    prep = prepare(dataclasses.replace(scene, building1=b1, building2=b2))
    driver.compile_kernel(prep.sysarr, prep.opts, prep.hist, prep.score, "lanes", prep.law_codes_used)
    loop = contact_loop(6, 4)
    sig = loop.signatures[-1]
    print("4+2", len(loop.signatures), loop.stats.cache_hits.get(sig, 0), loop.stats.cache_misses.get(sig, 0))
    # the group driver holds no floor count in its types: the new pair compiled no new one
    print("driver", len(_integrate_groups.signatures))
    # the step, loaded from the cache, is linked into the kernels after their optimisation (engine/linking.py)
    from pounding_sweep.engine import linking

    library = piece.overloads[piece.signatures[0]].library
    print("optimised_once", linking._once_module(library) is not None or not linking._known())
    # the two compiles' times are remembered apart: the second, the step cached, is shorter (compile_times.AGAIN)
    import json
    from pounding_sweep.engine import compile_times, jit

    print("recorded", *sorted(json.loads((jit._root() / compile_times.COMPILE_TIMES).read_text())))
# every engine function typed in this process (with an empty cache: all the kernels' pieces but those aside) compiled
# once per argument type: none again for a constant (a literal True, False or 0 passed by a call site: engine/events.py
# AT_END), as two argument types that differ only in literal types would show
import collections
from numba.core import types
from numba.core.registry import CPUDispatcher

copies = []
for obj in __import__("gc").get_objects():
    if type(obj) is CPUDispatcher and obj.py_func.__module__.startswith("pounding_sweep.engine"):
        by_type = collections.Counter(tuple(types.unliteral(a) for a in sig) for sig in obj.overloads)
        copies += [obj.py_func.__qualname__] * sum(n > 1 for n in by_type.values())
print("compiled again for a constant:", *sorted(copies))
"""


#: logs when a process starts and every cache entry it saves (pid, what, time, index file, key), in this process
#: and the second ones alike. It wraps Numba's Cache.save_overload, not IndexDataCacheFile.save: engine/cache_lock.py
#: replaces that one with its own save (data, then index) only where it reads as Numba's, so a wrapper there made
#: these processes run Numba's save (index, then data) under the lock, not the engine's
SITE = """
import os
import sys
import time
from numba.core import caching


def _log(what, index="", key=""):
    with open(os.environ["ASIDE_LOG"], "a") as f:
        f.write(f"{os.getpid()}|{what}|{time.time()!r}|{index}|{key}\\n")


_log("start")
if os.environ.pop("ASIDE_PARENT", None) is None:  # a second process (the variable is gone from its environment):
    # its standard error (discarded by engine/aside.py start) into a file, and its exit code into the log
    _err = open(os.environ["ASIDE_LOG"] + f".stderr.{os.getpid()}", "w")
    os.dup2(_err.fileno(), 2)
    _exit = sys.exit

    def _exit_logged(code=0):
        _log("exit", "", str(code))
        _exit(code)

    sys.exit = _exit_logged
_save = caching.Cache.save_overload


def save_overload(self, sig, data):  # sig: the first item of the entry's key
    index = os.path.basename(self._cache_file._index_path)
    _log("saving", index, sig)
    _save(self, sig, data)
    _log("saved", index, sig)


caching.Cache.save_overload = save_overload
"""


#: the last line of RUN: no engine function compiled twice for one argument type (its literal constants aside)
NO_COPIES = ["compiled", "again", "for", "a", "constant:"]


def _compile_with_an_empty_cache(tmp_path, what: str) -> tuple[list[list[str]], str]:
    """Compile in a fresh process with an empty cache; its lines, and what the second processes said on their
    standard error and how they exited (a miss would be theirs to explain). A second process must have saved
    entries, and no function's index may be written by this process and a second one with different keys while
    that one runs: the two share no work (engine/cache_lock.py makes such saves safe; Numba's own, caching.py
    IndexDataCacheFile.save, is not)."""
    (tmp_path / "site").mkdir()
    (tmp_path / "site" / "sitecustomize.py").write_text(SITE)
    log = tmp_path / "saves.log"
    path = os.pathsep.join([str(tmp_path / "site"), os.environ.get("PYTHONPATH", "")])
    env = dict(
        os.environ, NUMBA_CACHE_DIR=str(tmp_path / "cache"), PYTHONPATH=path, ASIDE_LOG=str(log), ASIDE_PARENT="1"
    )
    r = subprocess.run([sys.executable, "-c", RUN, what], env=env, cwd=tmp_path, capture_output=True, text=True)
    assert r.returncode == 0, r.stderr[-3000:]
    events = [line.split("|") for line in log.read_text().splitlines()]
    # what the second processes said and how they ended, for the messages of the tests' assertions
    said = {p.name.rsplit(".", 1)[1]: p.read_text()[-2000:] for p in tmp_path.glob("saves.log.stderr.*")}
    ended = {pid: key for pid, kind, _, _, key in events if kind == "exit"}
    report = "; ".join(
        f"second process {pid}: exit {ended.get(pid, '?')}, stderr {text!r}" for pid, text in said.items()
    )
    starts = {pid: float(t) for pid, kind, t, _, _ in events if kind == "start"}
    saves = []  # (pid, began, ended, index, key): a process saves one entry at a time
    for pid, kind, t, index, key in events:
        if kind == "saving":
            saves.append([pid, float(t), None, index, key])
        elif kind == "saved":
            [entry] = [e for e in saves if e[0] == pid and e[2] is None]
            entry[2] = float(t)
    parent = min(starts, key=starts.get)
    children = {e[0] for e in saves} - {parent}
    assert children, ("this process saved every entry", report)
    for child in children:
        mine = [e for e in saves if e[0] == child]
        # its last save ended: it writes nothing after (a save killed by this process's stop() never ends)
        until = max(float("inf") if e[2] is None else e[2] for e in mine)
        # a save of this process that overlaps the child's life, from its start to its last save's end
        during = [e for e in saves if e[0] == parent and e[1] <= until and e[2] >= starts[child]]
        for _, _, _, index, key in during:
            assert all(k == key for _, _, _, i, k in mine if i == index), (index, key, mine, report)
    return [line.split() for line in r.stdout.splitlines()], report


def test_both_scalar_kernels_load_the_scoring_code_the_second_process_compiled(tmp_path):
    """With an empty cache: the second process compiles the scalar kernel's event-step pieces, the run's end
    book-keeping, then score_run, and the scalar kernel's compile loads each from the cache (a hit, no compile
    here; it waits for the second process if it needs a piece first); the Hertz-type kernel then calls score_run,
    the book-keeping and pair_pieces with the same types (still one signature each), and a second process compiles
    its own contact solve and event-step pieces. A signature that drifted from the kernels' call
    (scalar.event_pieces, nonlinear.event_pieces, bookkeeping.row_end_pieces, bookkeeping.score_run_signature)
    would show as a miss."""
    got, report = _compile_with_an_empty_cache(tmp_path, "scored")
    assert got == [
        ["classic", "1", "1", "0"],
        ["hertzdamp", "1", "1", "0"],
        ["_advance", "1", "1", "0"],
        ["pair_pieces", "1", "1", "0"],
        ["_switch", "1", "1", "0"],
        ["close_row", "1", "1", "0"],
        ["energy_row", "1", "1", "0"],
        ["run_counts", "1", "1", "0"],
        ["hertz", "solve_pairs", "1", "1", "0"],
        ["hertz", "_advance", "1", "1", "0"],
        ["hertz", "pair_pieces", "1", "1", "0"],
        ["hertz", "_switch", "1", "1", "0"],
        NO_COPIES,
    ], (got, report)  # every line, not only the first that differs


def test_the_lane_kernel_loads_the_step_the_second_process_compiled(tmp_path):
    """The same for the lane kernel's scalar step (groups._lane_step_signature against groups._scalar_steps' call);
    then, for a new pair of floor counts with the step cached, that pair's contact loop (loops.loop_signatures
    against _integrate_groups' call), loaded from the cache, and no new compile of the group driver. The second
    compile's time is recorded apart from the first's (engine/compile_times.py AGAIN)."""
    got, report = _compile_with_an_empty_cache(tmp_path, "lanes")
    assert got == [
        ["classic", "1", "1", "0"],
        ["4+2", "1", "1", "0"],
        ["driver", "1"],
        ["optimised_once", "True"],
        ["recorded", "lanes", "lanes_again"],
        NO_COPIES,
    ], (got, report)  # every line, not only the first that differs


def test_only_the_pieces_a_scene_compiles_are_left_aside():
    """No scoring code without scoring, no event-step pieces for the paper's scheme (it has no event step); no
    pieces, no second process."""
    assert bookkeeping.score_pieces(ScoreSpec.none()) == ()
    assert bookkeeping.score_pieces(None) == ()
    assert scalar.event_pieces(SCHEME_PAPER) == ()
    assert len(scalar.event_pieces(SCHEME_EVENT)) == len(scalar.event_pieces(SCHEME_IMPLICIT)) == 3
    assert len(nonlinear.event_pieces()) == 4  # its time loop holds the event step whatever the scheme
    assert aside.start(tuple) is None


def test_waiting_ends_when_the_piece_is_saved_not_when_the_second_process_ends(monkeypatch):
    """This process waits for the piece it needs, not for the second process's later pieces: a piece in the cache
    index ends the wait while the second process runs on."""
    _plus_one(np.int64(1))  # compiled and saved to the cache by this process
    assert aside._in_cache(_plus_one, (numba.int64,))
    proc = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    monkeypatch.setattr(aside, "WAIT_S", 30.0)
    a = aside.Aside(proc, [(_plus_one, (numba.int64,))])
    try:
        a._wait(_plus_one, (numba.int64,))
        assert proc.poll() is None  # still running: not waited for, not killed
    finally:
        a.stop()
    assert proc.poll() is not None


#: a second process that saves `twice` as Numba's own save does (engine/cache_lock.py installs ours only on the
#: Numba it was written against), under the cache folder's lock: the index first, then, once this process has
#: loaded (the file `loaded`) or 2 s have passed, the data
SAVE_LATE = """
import inspect, os, sys, time
import numba
from numba.core import caching
from pounding_sweep.engine import cache_lock

folder = sys.argv[1]
sys.path.insert(0, folder)
import piece_for_aside

cls = caching.IndexDataCacheFile
cls.save = cache_lock._locked(inspect.unwrap(cls.save))
write_data = cls._save_data


def data_written_late(self, name, data):
    open(os.path.join(folder, "listed"), "w").close()
    t = time.monotonic()
    while not os.path.exists(os.path.join(folder, "loaded")) and time.monotonic() - t < 2.0:
        time.sleep(0.01)
    write_data(self, name, data)


cls._save_data = data_written_late
numba.njit(cache=True)(piece_for_aside.twice).compile((numba.float64,))
"""


@pytest.mark.skipif(cache_lock.fcntl is None, reason="no fcntl here: saves take no lock, none to wait for")
def test_a_piece_listed_before_its_data_is_written_is_loaded_once_the_save_is_done(tmp_path, monkeypatch):
    """Where a save lists the entry in the index before its data file is written (Numba's own order), the wait
    ends only when that save, which holds the cache folder's lock throughout, has ended: the load finds the data
    and the piece is not compiled here. (The lane kernel once compiled its step itself so, this file's SITE
    having put Numba's save back.) Without the lock looked at, the load comes while the second process holds
    the data back, and misses; with it, it waits for the data (2 s later)."""
    (tmp_path / "piece_for_aside.py").write_text("def twice(x):\n    return 2.0 * x\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setattr(numba.config, "CACHE_DIR", str(tmp_path / "cache"))  # read when a function is decorated
    monkeypatch.delitem(sys.modules, "piece_for_aside", raising=False)  # this test's own file, on every run
    import piece_for_aside

    mine = numba.njit(cache=True)(piece_for_aside.twice)
    args = (numba.float64,)
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "cache"))
    proc = subprocess.Popen([sys.executable, "-c", SAVE_LATE, str(tmp_path)], env=env)
    a = aside.Aside(proc, [(mine, args)])
    try:
        while not (tmp_path / "listed").exists():  # the index names the entry; the data is held back
            assert proc.poll() is None, "the second process ended before it saved"
            time.sleep(0.01)
        mine.compile(args)  # as the kernel's typing does: the cache first (waiting), else a compile here
        (tmp_path / "loaded").touch()
    finally:
        a.stop()
        sys.modules.pop("piece_for_aside", None)
    assert (mine.stats.cache_hits.get(args, 0), mine.stats.cache_misses.get(args, 0)) == (1, 0)


@pytest.mark.skipif(cache_lock.fcntl is None, reason="no fcntl here: saves take no lock, none to wait for")
def test_a_second_process_stuck_inside_its_save_is_killed_and_its_entry_not_loaded(tmp_path, monkeypatch):
    """The wait for a save to end keeps to WAIT_S too: a second process that holds the cache folder's lock past
    it is killed, and the piece it listed is compiled here, not loaded (its data may never have been written)."""
    _plus_one(np.int64(1))  # compiled and saved: listed in the index
    folder = _plus_one._cache._cache_path
    holds = tmp_path / "holds"
    hold = (
        "import time\n"
        "from pounding_sweep.engine import cache_lock\n"
        f"with cache_lock.folder_lock({folder!r}):\n"
        f"    open({str(holds)!r}, 'w').close()\n"
        "    time.sleep(600)\n"
    )
    proc = subprocess.Popen([sys.executable, "-c", hold])
    monkeypatch.setattr(aside, "WAIT_S", 0.5)
    a = aside.Aside(proc, [(_plus_one, (numba.int64,))])
    try:
        while not holds.exists():
            assert proc.poll() is None, "the process meant to hold the lock ended"
            time.sleep(0.01)
        # the entry is there, and loads once the second process has ended; not while it held the lock
        assert _plus_one._cache.load_overload((numba.int64,), _plus_one.targetctx) is None
        assert proc.poll() is not None  # killed, its lock gone with it
        assert _plus_one._cache.load_overload((numba.int64,), _plus_one.targetctx) is not None
    finally:
        a.stop()


def test_an_error_listing_the_pieces_leaves_the_compile_here(monkeypatch):
    """start() runs inside Numba's compile: a failing list of pieces starts nothing and raises nothing."""
    monkeypatch.setattr(aside, "_cpus", lambda: 2)

    def broken():
        raise TypeError("a signature that cannot be built")

    assert aside.start(broken) is None


def test_one_cpu_starts_no_second_process(monkeypatch):
    """With one CPU the second process would only take turns with this one."""
    monkeypatch.setattr(aside, "_cpus", lambda: 1)
    spec = ScoreSpec.none()._replace(dof=np.zeros(1, dtype=np.int64))
    assert aside.start(lambda: bookkeeping.score_pieces(spec)) is None


def _cgroup(tmp_path, membership: str, files: dict) -> tuple:
    """A /proc/self/cgroup and a /sys/fs/cgroup tree with the files given (path under the tree -> text)."""
    tmp_path.mkdir(parents=True, exist_ok=True)
    proc = tmp_path / "cgroup"
    proc.write_text(membership)
    root = tmp_path / "sys"
    for rel, text in files.items():
        (root / rel).parent.mkdir(parents=True, exist_ok=True)
        (root / rel).write_text(text)
    return proc, root


def test_a_cgroup_cpu_quota_counts_as_fewer_cpus(tmp_path):
    """A container given one CPU's time may see every core: the quota (cgroup v2 cpu.max, v1 cfs quota and period,
    the least of the process's cgroup and its ancestors) is what a second process could use."""
    v2 = _cgroup(tmp_path / "a", "0::/job\n", {"job/cpu.max": "150000 100000\n", "cpu.max": "max 100000\n"})
    assert aside._quota_cpus(*v2) == 1.5
    none = _cgroup(tmp_path / "b", "0::/\n", {"cpu.max": "max 100000\n"})
    assert aside._quota_cpus(*none) is None
    v1 = _cgroup(
        tmp_path / "c",
        "3:cpuset:/\n2:cpu,cpuacct:/box\n",
        {
            "cpu,cpuacct/box/cpu.cfs_quota_us": "400000\n",
            "cpu,cpuacct/box/cpu.cfs_period_us": "100000\n",
            "cpu,cpuacct/cpu.cfs_quota_us": "100000\n",
            "cpu,cpuacct/cpu.cfs_period_us": "100000\n",
        },
    )
    assert aside._quota_cpus(*v1) == 1.0  # the parent's quota binds
    unlimited = _cgroup(
        tmp_path / "d", "1:cpu:/\n", {"cpu/cpu.cfs_quota_us": "-1\n", "cpu/cpu.cfs_period_us": "100000\n"}
    )
    assert aside._quota_cpus(*unlimited) is None
    assert aside._quota_cpus(tmp_path / "missing", tmp_path / "sys") is None


def test_one_cpu_of_quota_starts_no_second_process(monkeypatch):
    """_cpus() takes the quota: one CPU's time, whatever the cores, starts nothing."""
    monkeypatch.setattr(aside, "_quota_cpus", lambda: 1.0)
    assert aside._cpus() == 1
    monkeypatch.setattr(aside, "_quota_cpus", lambda: None)
    assert aside._cpus() == len(os.sched_getaffinity(0))


@numba.njit(cache=True)
def _plus_one(x):
    return x + 1.0


def test_pieces_compiled_here_or_not_importable_are_left_out():
    """A piece this process has compiled (or loaded) already is left out, and so is one a second process could
    not import by name (a function made inside another)."""

    @numba.njit(cache=True)
    def local(x):
        return x + 1.0

    _plus_one(1.0)
    assert aside._wanted([[(_plus_one, (numba.float64,))]]) == []
    assert aside._wanted([[(local, (numba.float64,))]]) == []


def test_only_the_pieces_a_second_process_takes_are_looked_up():
    """start() takes the first group with a piece to compile, all of that group's missing pieces: the groups after
    it are not looked at (their cache indexes not read)."""

    class Untouchable:
        @property
        def _cache(self):
            raise AssertionError("looked up")

    _plus_one(1.0)
    done = ((_plus_one, (numba.float64,)),)  # compiled here: nothing to take in this group
    wanted = ((_plus_one, (numba.int16,)), (_plus_one, (numba.float64,)), (_plus_one, (numba.int8,)))
    assert aside._wanted((done, wanted, ((Untouchable(), (numba.float64,)),))) == [
        (_plus_one, (numba.int16,)),
        (_plus_one, (numba.int8,)),
    ]
    with pytest.raises(AssertionError, match="looked up"):
        aside._wanted((done, ((Untouchable(), (numba.float64,)),)))


def test_the_second_process_skips_a_piece_whose_cache_is_elsewhere():
    """A second process that finds a piece's cache in another folder than this one's (another checkout first on
    its path) compiles nothing there and says so (exit 1, and which piece on its standard error)."""
    names = [("pounding_sweep.engine.bookkeeping", "score_run", (), "/nowhere/this/process/reads")]
    r = subprocess.run(
        [sys.executable, "-m", "pounding_sweep.engine.aside"], input=pickle.dumps(names), capture_output=True
    )
    assert r.returncode == 1, r.stderr[-2000:]
    assert b"pounding_sweep.engine.bookkeeping.score_run not compiled" in r.stderr, r.stderr[-2000:]
    assert b"/nowhere/this/process/reads" in r.stderr, r.stderr[-2000:]


def test_no_python_to_start_starts_nothing(monkeypatch):
    """In a program that embeds Python (sys.executable empty or None) nothing is started, and nothing raises."""
    monkeypatch.setattr(aside, "_cpus", lambda: 2)
    for exe in (None, ""):
        monkeypatch.setattr(sys, "executable", exe)
        assert aside.start(lambda: (((_plus_one, (numba.int64,)),),)) is None


def test_a_stuck_second_process_is_killed_and_the_caches_are_put_back(monkeypatch):
    """Waiting ends after WAIT_S (the piece is then compiled here); stop() puts each cache's loading back as it
    was, an attribute set before included."""
    _plus_one(1.0)
    cache = _plus_one._cache
    proc = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    monkeypatch.setattr(aside, "WAIT_S", 0.1)
    a = aside.Aside(proc, [(_plus_one, (numba.uint16,))])  # a signature nothing compiles: never in the cache
    assert "load_overload" in cache.__dict__
    a._wait(_plus_one, (numba.uint16,))
    assert proc.poll() is not None
    a.stop()
    assert "load_overload" not in cache.__dict__

    def mine(sig, target_context):
        return None

    cache.load_overload = mine
    try:
        b = aside.Aside(subprocess.Popen([sys.executable, "-c", "pass"]), [(_plus_one, (numba.int64,))])
        assert cache.load_overload is not mine
        b.stop()
        assert cache.load_overload is mine
    finally:
        del cache.load_overload
