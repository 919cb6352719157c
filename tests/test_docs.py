"""Every file, module and function the README and docs/ name exists, so the documentation cannot point
at code that moved or was deleted. Names are read from `code spans` and from the import lines of code
blocks: a path under one of the repository's folders, or a dotted name under pounding_sweep."""

from __future__ import annotations

import importlib
import re
from pathlib import Path

import pytest
from conftest import REPO

DOCS = sorted(
    [REPO / "README.md"] + [p for p in (REPO / "docs").rglob("*.md") if "_build" not in p.parts],
    key=str,
)
GENERATED = {"reference/scene-keys.md", "reference/cli.md"}  # written from the code at build time
TOP = ("pounding_sweep/", "tests/", "benchmarks/", "sweeps/", "notebooks/", "docs/", ".ci/")
SPAN = re.compile(r"`([^`\n]+)`")
PATH = re.compile(r"^(?:\./)?((?:pounding_sweep|tests|benchmarks|sweeps|notebooks|docs|\.ci)/[\w./*-]*\w)")
DOTTED = re.compile(r"^(pounding_sweep(?:\.\w+)+)")
SHORT = re.compile(r"^([a-z_][a-z0-9_]*(?:\.[A-Za-z_]\w*)+)(?:\(|$)")  # lanes.lane_modes, scipy.linalg
#: dotted words in the docs that are not code: TOML tables, file-name parts, objects of a snippet
NOT_CODE = {"experiment", "notes", "cm", "cluster", "pa", "pd", "np", "pl", "duckdb", "meta", "df"}
THIRD_PARTY = {"scipy", "numpy", "numba", "pandas", "pyarrow", "cv2", "dask", "matplotlib", "llvmlite"}
MODULES = {p.stem: p for p in (REPO / "pounding_sweep").rglob("*.py") if p.stem != "__init__"} | {
    p.parent.name: p for p in (REPO / "pounding_sweep").rglob("__init__.py")
}
FROM_IMPORT = re.compile(r"^\s*from (pounding_sweep[\w.]*) import ([\w, ()]+)", re.M)


def names(text: str) -> tuple[set[str], set[str]]:
    """(paths, dotted names) a page names."""
    paths, dotted = set(), set()
    for span in SPAN.findall(text):
        for word in span.split():
            word = word.strip("(),;:'\"")
            if m := PATH.match(word):
                paths.add(m.group(1))
            elif m := DOTTED.match(word):
                dotted.add(m.group(1))
            elif (m := SHORT.match(word)) and not re.search(r"\.(py|md|toml|parquet|csv|png|json|txt|AT2)$", word):
                head = m.group(1).split(".")[0]
                if head in THIRD_PARTY:
                    dotted.add(m.group(1))
                elif head not in NOT_CODE:
                    dotted.add(qualified(m.group(1)))
    for mod, items in FROM_IMPORT.findall(text):
        dotted.update(f"{mod}.{n.strip()}" for n in items.strip("()").split(",") if n.strip())
    return paths, dotted


def qualified(short: str) -> str:
    """'lanes.lane_modes' -> 'pounding_sweep.engine.lanes.lane_modes'; an unknown module stays as it is."""
    head, _, rest = short.partition(".")
    path = MODULES.get(head)
    if path is None:
        return short
    mod = ".".join(path.relative_to(REPO).with_suffix("").parts)
    mod = mod.removesuffix(".__init__")
    return f"{mod}.{rest}"


def resolves(dotted: str) -> bool:
    """A module, or an attribute of one (a function, class or constant)."""
    parts = dotted.split(".")
    for i in range(len(parts), 0, -1):
        name = ".".join(parts[:i])
        try:
            obj = importlib.import_module(name)
        except ModuleNotFoundError as e:
            if e.name is None or not name.startswith(e.name):  # a missing dependency, not a missing module
                raise
            continue
        for attr in parts[i:]:
            if not hasattr(obj, attr):
                return False
            obj = getattr(obj, attr)
        return True
    return False


def path_exists(p: str) -> bool:
    if p.startswith("docs/_build"):  # the docs' own build output
        return True
    if "*" in p:
        return any(REPO.glob(p))
    return (REPO / p).exists()


@pytest.mark.parametrize("page", DOCS, ids=lambda p: str(p.relative_to(REPO)))
def test_every_file_and_name_a_page_names_exists(page: Path):
    if str(page.relative_to(REPO / "docs")) in GENERATED if page.is_relative_to(REPO / "docs") else False:
        pytest.skip("generated from the code at build time")
    paths, dotted = names(page.read_text())
    missing = sorted(p for p in paths if not path_exists(p)) + sorted(d for d in dotted if not resolves(d))
    assert not missing, f"{page.relative_to(REPO)} names what does not exist: {missing}"


def test_the_checker_finds_what_is_missing():
    """The checker itself: a stale path and a stale name are caught, present ones pass."""
    paths, dotted = names(
        "see `tests/reference.py` and `pounding_sweep/engine/driver.py`;\n"
        "```python\nfrom pounding_sweep.sweep.results import read_metadata, no_such_function\n```\n"
        "`pounding_sweep.kernel_lanes.lanes_ineligible_reason` `kernel_lanes.lanes_ineligible_reason` "
        "`scipy.signal.sosfilt` `results.read_metadata` `experiment.video`"
    )
    assert {p for p in paths if not path_exists(p)} == {"tests/reference.py"}
    assert {d for d in dotted if not resolves(d)} == {
        "pounding_sweep.sweep.results.no_such_function",
        "pounding_sweep.kernel_lanes.lanes_ineligible_reason",
        "kernel_lanes.lanes_ineligible_reason",
    }


TOML_BLOCK = re.compile(r"```toml\n(.*?)```", re.S)


@pytest.mark.parametrize("page", DOCS, ids=lambda p: str(p.relative_to(REPO)))
def test_every_toml_block_is_toml_a_reader_can_paste(page):
    """A ```toml block is pasted into a scene as it stands, so each must parse (an inline table written over
    several lines, as TOML 1.0 forbids, failed a helper's per-story scene)."""
    import tomllib

    text = page.read_text(encoding="utf-8")
    for m in TOML_BLOCK.finditer(text):
        line = text[: m.start()].count("\n") + 1
        try:
            tomllib.loads(m.group(1))
        except tomllib.TOMLDecodeError as e:
            pytest.fail(f"{page.relative_to(REPO)}:{line}: the toml block does not parse: {e}")
