"""Numba's compile flags hashed and compared without rebuilding their dicts: the same answers, a shorter compile.

Numba's overload templates keep the implementation of each call they have typed under (typing context, argument
types, keywords, compile flags) (numba/core/typing/templates.py, _OverloadFunctionTemplate._get_impl), and the
type inference asks them again at every pass over a function. TargetConfig.__hash__ and __eq__ (numba/core/
targetconfig.py) build a dict of every option, each read through a property, for the hash and for each side of
each comparison. The README scene's first compile built 82,816 of those dicts in 29,990 lookups: 1.7 s of a
20.4 s profile of that compile (cProfile, numba 0.68.1).

The hash Numba computes is that of the sorted option names (sorted() of a dict lists its keys), so it is the same
for every instance of a class: `install` computes it once per class. Two instances of one class whose explicitly
set options are equal are equal (every other option is the class's default); any other pair is compared by Numba's
own __eq__. The answers are Numba's, hash for hash and comparison for comparison (tests/engine/test_flag_compare.py);
the patch holds for the whole process. It is installed only where the methods it stands in for read as they did
when it was written (KNOWN_SOURCES); elsewhere nothing changes but the compile time.
"""

from __future__ import annotations

import functools

from numba.core import targetconfig

from pounding_sweep.engine import numba_source

#: the methods replaced, and values(), on which both rely
METHODS = (
    (targetconfig.TargetConfig, "__hash__"),
    (targetconfig.TargetConfig, "__eq__"),
    (targetconfig.TargetConfig, "values"),
)
#: SHA-256 (16 hex digits) of the source of METHODS as this module was written against (numba 0.68.1)
KNOWN_SOURCES = frozenset({"475e57699d35308e"})
#: the class of a TargetConfig -> the hash Numba gives its every instance
_HASHES: dict[type, int] = {}


def source_digest() -> str:
    """The digest KNOWN_SOURCES holds, of this Numba's METHODS (their own source, not the installed wrappers)."""
    return numba_source.digest(METHODS)


def install() -> bool:
    """Replace TargetConfig.__hash__ and __eq__ by the shortcuts above; True when installed now or before."""
    cls = targetconfig.TargetConfig
    if getattr(cls.__hash__, "hashes_by_class", False):
        return True
    if not numba_source.known(METHODS, KNOWN_SOURCES):
        return False
    numba_hash, numba_eq = cls.__hash__, cls.__eq__

    @functools.wraps(numba_hash)
    def __hash__(self):
        kind = type(self)
        h = _HASHES.get(kind)
        if h is None:
            h = _HASHES[kind] = numba_hash(self)  # the sorted option names': the same for every instance
        return h

    @functools.wraps(numba_eq)
    def __eq__(self, other):
        if type(other) is type(self) and self._values == other._values:
            return True  # the same class, the same options set: every option reads the same
        return numba_eq(self, other)

    __hash__.hashes_by_class = True  # type: ignore[attr-defined]
    cls.__hash__ = __hash__  # type: ignore[method-assign]
    cls.__eq__ = __eq__  # type: ignore[method-assign]
    return True
