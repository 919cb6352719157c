"""The shape of the package's code: the largest files and functions and the widest signatures.

    python benchmarks/code_shape.py [ROOT] [--top 12] [--under pounding_sweep/engine]

Reads the sources (ast), runs nothing. A function's size is its lines from `def` to its last line
(docstring included); its width is the number of parameters it declares (*args and **kwargs count
one each). Used for issue 26's before/after (the import structure itself: `farm-studio look`).
Works on any checkout: ROOT is the folder holding pounding_sweep/ (default: this one).
"""

from __future__ import annotations

import argparse
import ast
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def functions(path: Path):
    """(qualified name, lines, parameters) of every function in the file, nested ones included."""
    tree = ast.parse(path.read_text())
    out = []

    def visit(node, prefix):
        for child in ast.iter_child_nodes(node):
            if isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef)):
                a = child.args
                width = len(a.posonlyargs) + len(a.args) + len(a.kwonlyargs) + bool(a.vararg) + bool(a.kwarg)
                out.append((prefix + child.name, child.end_lineno - child.lineno + 1, width))
                visit(child, prefix + child.name + ".")
            elif isinstance(child, ast.ClassDef):
                visit(child, prefix + child.name + ".")

    visit(tree, "")
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("root", nargs="?", type=Path, default=REPO)
    ap.add_argument("--top", type=int, default=12)
    ap.add_argument("--under", default="pounding_sweep", help="the folder to measure, relative to ROOT")
    args = ap.parse_args(argv)
    base = args.root.resolve()
    files = sorted((base / args.under).rglob("*.py"))
    sizes, funcs = [], []
    for p in files:
        rel = p.relative_to(base).as_posix()
        sizes.append((len(p.read_text().splitlines()), rel))
        funcs += [(rel, *f) for f in functions(p)]
    print(f"{base / args.under}: {len(files)} files, {sum(s for s, _ in sizes)} lines, {len(funcs)} functions")
    print("\nlargest files (lines)")
    for n, rel in sorted(sizes, reverse=True)[: args.top]:
        print(f"  {n:6d}  {rel}")
    print("\nlargest functions (lines)")
    for rel, name, n, _ in sorted(funcs, key=lambda f: -f[2])[: args.top]:
        print(f"  {n:6d}  {rel}:{name}")
    print("\nwidest signatures (parameters)")
    for rel, name, _, w in sorted(funcs, key=lambda f: -f[3])[: args.top]:
        print(f"  {w:6d}  {rel}:{name}")
    over = [f for f in funcs if f[3] > 10]
    print(f"\nfunctions with more than 10 parameters: {len(over)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
