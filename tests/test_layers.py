"""The package's layers, checked on its own import statements (lazy ones inside functions included):
data flows one way, scene -> model -> engine -> sweep -> command line and plots, and no module
reaches up or sideways. Reading the statements (ast), not importing, so the check costs nothing."""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

from conftest import REPO

PKG = REPO / "pounding_sweep"

#: layer of each top-level part of the package; a module may import its own part and lower layers only
LAYERS = {
    "errors": 0,
    "codes": 0,
    "progress": 0,
    "warn": 0,
    "": 0,  # shared bottom modules (and the package's version)
    "scene": 1,  # TOML -> validated dataclasses
    "model": 2,  # scene -> arrays: structure, contact parameters, records, excitation, grid, experiment tables
    "engine": 3,  # the Numba kernels and their driver: arrays in, metric rows out
    "video": 4,
    "identify": 4,  # tracking videos; modal identification and model update (siblings)
    "sweep": 5,  # prepare, run, resume, results, executors, scoring, ranking, autodt, simulate
    "reference": 6,  # the slow oracles
    "synthetic": 7,  # demo data (synthetic experiments), made by the engine or by the references
    "accuracy": 7,
    "gaps": 7,  # error against run time, stability of runs; seismic-gap studies
    "risk": 7.5,  # probabilistic pounding: above the gap studies (their rules), below plots
    "plots": 8,
    "cli": 9,
    "__main__": 10,
}


def part_of(module: str) -> str:
    """'pounding_sweep.sweep.run' -> 'sweep'; 'pounding_sweep' -> ''."""
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else ""


def module_name(path: Path) -> str:
    rel = path.relative_to(REPO).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def imports(path: Path) -> set[str]:
    """Every pounding_sweep module this file imports, anywhere in it (absolute names)."""
    tree = ast.parse(path.read_text())
    out = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = module_name(path).split(".")
                base = base[: len(base) - node.level + (path.name == "__init__.py")]
                mod = ".".join(base + ([node.module] if node.module else []))
            else:
                mod = node.module or ""
            if mod.startswith("pounding_sweep"):
                out.add(mod)
                for alias in node.names:  # `from pounding_sweep.engine import lanes` imports a module too
                    if (PKG.parent / (mod + "." + alias.name).replace(".", "/")).with_suffix(".py").exists():
                        out.add(f"{mod}.{alias.name}")
        elif isinstance(node, ast.Import):
            out.update(a.name for a in node.names if a.name.startswith("pounding_sweep"))
    return out


def graph() -> dict[str, set[str]]:
    return {module_name(p): imports(p) - {module_name(p)} for p in sorted(PKG.rglob("*.py"))}


def test_every_part_has_a_layer():
    assert {part_of(m) for m in graph()} <= set(LAYERS), {part_of(m) for m in graph()} - set(LAYERS)


def test_no_module_imports_up_or_sideways():
    bad = []
    for mod, deps in graph().items():
        mine = part_of(mod)
        for dep in deps:
            theirs = part_of(dep)
            if theirs != mine and LAYERS[theirs] >= LAYERS[mine] and theirs != "":
                bad.append(f"{mod} (layer {LAYERS[mine]}) imports {dep} (layer {LAYERS[theirs]})")
    assert not bad, "\n".join(bad)


def test_the_import_graph_has_no_cycle():
    g = graph()
    state: dict[str, int] = {}

    def visit(m, path):
        state[m] = 1
        for d in g.get(m, ()):
            if d not in g:
                continue
            if state.get(d) == 1:
                raise AssertionError("import cycle: " + " -> ".join(path + [m, d]))
            if state.get(d) is None:
                visit(d, path + [m])
        state[m] = 2

    for m in g:
        if m not in state:
            visit(m, [])


def test_the_scene_layer_loads_no_heavy_library():
    """Reading and refusing a scene never waits for Numba, SciPy, pandas, pyarrow or OpenCV."""
    code = (
        "import sys; import pounding_sweep.scene as s; s.load_scene(sys.argv[1]); "
        "print([m for m in ('numba', 'scipy', 'pandas', 'pyarrow', 'cv2', 'matplotlib') if m in sys.modules])"
    )
    r = subprocess.run(
        [sys.executable, "-c", code, str(REPO / "sweeps" / "scored_duzce.toml")], capture_output=True, text=True
    )
    assert r.stdout.strip() == "[]", (r.stdout, r.stderr)
