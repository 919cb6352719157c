"""The kernels' cache folder: keyed by the sources of compiled code only (a stale kernel is never
loaded, and an edit to plain-Python driver code does not make every user compile every kernel again)."""

from __future__ import annotations

import re

from pounding_sweep.engine import jit

COMPILED = re.compile(r"\bnjit\w*\b|@\w*inline\b|\bintrinsic\b|numba\.(?:jit|njit|vectorize|cfunc)\b|@_cached\b")


def test_the_cache_key_covers_every_module_with_compiled_code():
    engine = sorted(jit.HERE.rglob("*.py"))
    left_out = [p for p in engine if p not in jit.SOURCES]
    assert sorted(p.relative_to(jit.HERE).as_posix() for p in left_out) == sorted(jit.NOT_COMPILED)
    for p in left_out:
        assert not COMPILED.search(p.read_text()), f"{p.name} holds compiled code: it must be in jit.SOURCES"
    for name in ("scalar.py", "lanes/vector.py", "lanes/groups.py", "simd.py", "events.py", "floors.py", "jit.py"):
        assert jit.HERE / name in jit.SOURCES
    for name in ("score.py", "layout.py", "inputs.py"):
        assert jit.HERE / name in jit.SOURCES
    assert jit.HERE.parent / "codes.py" in jit.SOURCES


def test_the_cache_folder_is_named_by_the_sources_hash():
    if jit.CACHE_DIR is not None:
        assert jit.CACHE_DIR.name == f"engine-{jit.engine_hash()}"
