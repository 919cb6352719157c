"""Numba flags and the on-disk cache of the compiled kernels, in one place.

No fastmath anywhere: NaN/inf guards and bit-identical results across executors depend on strict IEEE
arithmetic.

The cache cannot go stale: Numba keys a cached function by its own source file only, so an edit to a
function it calls in another file (the event pieces both kernels share, a flag here) would leave an
old compiled kernel in use. Every engine function is therefore cached in a folder named by a hash of
all the engine's sources (this folder's .py files but the plain-Python driver, and
pounding_sweep/codes.py): any edit there means a new folder and a fresh compile, never a stale kernel. The folder lies under $NUMBA_CACHE_DIR when it
is set, else under the user's cache ($XDG_CACHE_HOME or ~/.cache)/pounding_sweep; the newest
KEEP_CACHES engine folders are kept, older ones (ours, by their name) removed. Where no such folder
can be written, Numba's own cache beside the sources is used.
"""

from __future__ import annotations

import hashlib
import os
import re
import shutil
from pathlib import Path

import numba

from pounding_sweep.engine import cache_lock, flag_compare, inlining, linking

inlining.install()  # Numba's IR inliner without its quadratic copy (the same code, a shorter compile)
linking.install()  # pieces without an entry are optimised once, in their kernel (the same code, a shorter compile)
cache_lock.install()  # processes sharing the cache cannot mix up its entries
flag_compare.install()  # compile flags hashed once per class (the same answers, a shorter compile)

HERE = Path(__file__).resolve().parent
#: engine modules that compile nothing (plain Python driving or choosing the kernels), by their path in the
#: engine: an edit there changes no compiled code, so it must not cost every user a fresh compile of every
#: kernel (tests/engine/test_jit.py checks that no module listed here holds compiled code). linking.py is not
#: one: it decides what a cached piece holds (a module to link, no machine code)
NOT_COMPILED = (
    "compile_times.py",
    "driver.py",
    "registry.py",
    "inlining.py",
    "flag_compare.py",
    "aside.py",
    "cache_lock.py",
    "numba_source.py",
    "lanes/__init__.py",
    "lanes/eligibility.py",
    "lanes/model.py",
)
#: the sources whose compiled code the cache holds
SOURCES = sorted(p for p in HERE.rglob("*.py") if p.relative_to(HERE).as_posix() not in NOT_COMPILED) + [
    HERE.parent / "codes.py"
]
KEEP_CACHES = 3
_CACHE_NAME = re.compile(r"engine-[0-9a-f]{16}")

#: serial kernels: released GIL so a thread pool can run them side by side; cached on disk; no C entry (Numba's
#: cfunc wrapper, for calls through a C function pointer: the engine calls its functions from Python or from
#: compiled code, never so; each wrapper was compiled to machine code of its own, 0.2-0.9 s of the README scene's
#: first compile, docs/explanation/performance.md)
KERNEL_JIT = dict(nogil=True, cache=True, fastmath=False, error_model="numpy", no_cfunc_wrapper=True)
#: the lane kernel: the same, without bounds checks
LANES_JIT = dict(nogil=True, cache=True, fastmath=False, error_model="numpy", boundscheck=False, no_cfunc_wrapper=True)


def engine_hash(sources=None) -> str:
    """SHA-256 (16 hex digits) of the engine's sources, names and contents."""
    h = hashlib.sha256()
    for p in sources or SOURCES:
        name = p.relative_to(HERE).as_posix() if p.is_relative_to(HERE) else p.name
        h.update(name.encode() + b"\0" + p.read_bytes() + b"\0")
    return h.hexdigest()[:16]


def _root() -> Path:
    base = os.environ.get("NUMBA_CACHE_DIR")
    if base:
        return Path(base) / "pounding_sweep"
    return Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "pounding_sweep"


def _cache_dir() -> Path | None:
    """This engine's cache folder, created; None where it cannot be (then Numba's default applies)."""
    root = _root()
    folder = root / f"engine-{engine_hash()}"
    try:
        folder.mkdir(parents=True, exist_ok=True)
        probe = folder / ".writable"
        probe.touch()
        probe.unlink()
    except OSError:
        return None
    try:  # older engines' folders: ours by their name; the newest few are kept for other checkouts
        old = sorted(
            (p for p in root.iterdir() if p.is_dir() and _CACHE_NAME.fullmatch(p.name) and p != folder),
            key=lambda p: p.stat().st_mtime,
            reverse=True,
        )
        for p in old[KEEP_CACHES - 1 :]:
            shutil.rmtree(p, ignore_errors=True)
    except OSError:
        pass
    return folder


CACHE_DIR = _cache_dir()


def _cached(decorate):
    """Apply a Numba decorator with config.CACHE_DIR set to CACHE_DIR (Numba reads it when the function
    is decorated), leaving the setting as it was for anyone else."""

    def wrap(fn):
        if CACHE_DIR is None:
            return decorate(fn)
        saved = numba.config.CACHE_DIR
        numba.config.CACHE_DIR = str(CACHE_DIR)
        try:
            return decorate(fn)
        finally:
            numba.config.CACHE_DIR = saved

    return wrap


def njit_kernel(fn):
    """Decorate a serial numerical kernel with the project's flags."""
    return _cached(numba.njit(**KERNEL_JIT))(fn)


def njit_lanes(fn):
    """Decorate an entry point of the lane kernel (called from Python): it allocates nothing (its work
    arrays come from the caller), so it is compiled without Numba's runtime, whose atomic reference counts
    on the arrays of its record arguments cost the scalar steps a fifth of their time."""
    return _cached(numba.njit(_nrt=False, **LANES_JIT))(fn)


def njit_step(fn):
    """Decorate a function of the lane kernel's time loop: it allocates nothing, so it is compiled without
    Numba's runtime, whose atomic reference counts on every array argument took a third of the scalar
    steps' time; called only from compiled code, so without the Python and C entry wrappers (their
    argument boxing was a good part of the compile time). Its own module is optimised before its caller's
    (not registered with engine/linking.py): LLVM makes faster code of the lane kernel's step and vector
    loops in two passes (its event case took 1.18x as long with one)."""
    return _cached(numba.njit(_nrt=False, no_cpython_wrapper=True, **LANES_JIT))(fn)


def njit_step_once(fn):
    """njit_step for the lane kernel's scalar step, a large piece: LLVM optimises its module on its own, and its
    callers link that optimised code after optimising theirs (engine/linking.py optimised_once), rather than
    optimise it and make its machine code again in every kernel that calls it."""
    return njit_step(linking.optimised_once(fn))


def njit_piece_once(fn):
    """Decorate a large piece of the scalar kernels called once per run from compiled code (the scoring,
    bookkeeping.score_run): the scalar kernels' flags and Numba's runtime (it allocates), no Python or C entry,
    its module optimised on its own and linked into its callers after their optimisation (as njit_step_once's
    step: linking.optimised_once), so a kernel's LLVM pass does not optimise it again."""
    return _cached(numba.njit(no_cpython_wrapper=True, **KERNEL_JIT))(linking.optimised_once(fn))


def njit_piece(fn):
    """Decorate a function of the scoring code (engine/score.py) that only compiled code calls: the scalar kernels'
    flags and Numba's runtime (it allocates), no Python entry, its code optimised only in its callers' modules
    (engine/linking.py, as njit_inner's): compiled for the kernels' scoring (bookkeeping.score_run), it was
    optimised and made machine code of its own, then optimised again in score_run's module (score_run's compile,
    in the second process, engine/aside.py: 6.5-6.7 s before, 5.2 s after). Python calls it through an
    njit_kernel entry."""
    return _cached(numba.njit(no_cpython_wrapper=True, **KERNEL_JIT))(linking.optimised_by_callers(fn))


def njit_inner(fn):
    """Decorate a helper of the scalar kernels' time loop that allocates nothing: no reference counts on
    its array arguments and no Python entry wrapper (as njit_step), with the scalar kernels' flags; its code
    optimised only in its callers' modules (engine/linking.py: once per kernel, not once per level of calls)."""
    fn = linking.optimised_by_callers(fn)
    return _cached(numba.njit(_nrt=False, no_cpython_wrapper=True, **KERNEL_JIT))(fn)


def njit_generic(fn):
    """Decorate a function written once for every kernel and compiled with a kernel's own pieces as closure
    variables (engine/events.py event_functions). As njit_inner, but not cached on its own: Numba keys a
    closure's cache by its cell contents, and a compiled function there pickles with an id of this process,
    so every process would add an entry no other finds (numba#6264). The cached kernels that call it hold
    its code. Registered with engine/linking.py, as njit_inner's functions are: the flags are
    njit_generic_lanes', the one difference is that registration."""
    return njit_generic_lanes(linking.optimised_by_callers(fn))


def njit_generic_lanes(fn):
    """The flags of njit_generic, without its registration: the lane kernel's event step (events.event_functions
    with inline), whose code is optimised in its own module before its callers', as the lane kernel's step is."""
    return numba.njit(_nrt=False, no_cpython_wrapper=True, **dict(KERNEL_JIT, cache=False))(fn)


#: inlined into its callers at Numba's IR level (the lane kernel's vector helpers, and its event step's
#: pieces: a call passing the lane's state record cost its scalar steps as much as the work)
inline = numba.njit(inline="always", **LANES_JIT)
#: njit_generic, inlined (the lane kernel's event step's small functions: events.event_functions(..., inline=True))
inline_generic = numba.njit(inline="always", **dict(LANES_JIT, cache=False))
#: the same with the scalar kernels' flags, for a per-step helper whose call showed in the time (structure_work:
#: about 8 % of the scalar kernel on the 6 Hz grid; inlining the other helpers this way cost more than it saved)
inline_kernel = numba.njit(inline="always", **KERNEL_JIT)
