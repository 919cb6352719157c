"""The fast tier (docs/contributing/testing.md): the slow list in tests/conftest.py names tests that exist, so that a test
renamed or removed does not leave a stale entry (and the tier is what the list says)."""

from __future__ import annotations

import ast

from conftest import REPO, SLOW


def test_every_slow_name_is_a_test_function():
    for path, names in SLOW.items():
        tree = ast.parse((REPO / path).read_text())
        tests = {n.name for n in ast.walk(tree) if isinstance(n, ast.FunctionDef) and n.name.startswith("test_")}
        missing = sorted(set(names) - tests)
        assert not missing, f"{path}: {missing} in SLOW, not a test there"
        assert len(set(names)) == len(names), f"{path}: a name twice"
