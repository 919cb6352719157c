"""The digest of the Numba methods one of our patches relies on (engine/inlining.py, linking.py, cache_lock.py):
each patch installs only where this Numba's methods read as they did when it was written (its KNOWN_SOURCES)."""

from __future__ import annotations

import hashlib
import inspect


def digest(methods) -> str:
    """SHA-256 (16 hex digits) of the source of each (owner, name) method in turn: Numba's own, not a wrapper of
    ours installed over it."""
    h = hashlib.sha256()
    for owner, name in methods:
        h.update(inspect.getsource(inspect.unwrap(getattr(owner, name))).encode())
    return h.hexdigest()[:16]


def known(methods, known_sources) -> bool:
    """Whether the digest of `methods` is one of `known_sources`: the Numba a patch was written against. False
    where there is no source to read (then it is not that Numba either)."""
    try:
        return digest(methods) in known_sources
    except (OSError, TypeError, AttributeError):
        return False
