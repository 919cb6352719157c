"""Sphinx configuration of the documentation (Markdown through MyST). Built with
`sphinx-build -W --keep-going -b html docs docs/_build/html`: every warning, a broken link between
pages included, is an error. The reference pages for scene keys and the command line are written from
the code (`--describe`, each command's `--help`) at every build, so they cannot drift from it."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

project = "pounding_sweep"
author = "pounding_sweep developers"
extensions = ["myst_parser"]
source_suffix = {".md": "markdown"}
exclude_patterns = ["_build"]
html_theme = "alabaster"
myst_heading_anchors = 3  # `[x](page.md#a-heading)` links resolve, and a missing anchor is a warning
suppress_warnings: list[str] = []
nitpicky = True

HERE = Path(__file__).parent


def scene_keys_markdown(text: str) -> str:
    """describe()'s text as Markdown: a heading per section, a bullet per key."""
    out = [
        "# Scene keys",
        "",
        "Every section and key of a scene file, with its meaning, its default and whether it is required.",
        "Generated from `python -m pounding_sweep --describe` when the docs are built.",
        "",
    ]
    for line in text.splitlines():
        if not line.strip():
            continue
        if not line.startswith(" "):
            head, _, rest = line.partition("  ")
            out += ["", f"## `{head.strip()}`", "", rest.strip(), ""]
        else:
            key, sep, doc = line.strip().partition(": ")
            out.append(f"- `{key}`: {doc}" if sep else f"- {line.strip()}")
    return "\n".join(out) + "\n"


def _help(*args: str) -> str:
    cmd = [sys.executable, "-m", "pounding_sweep", *args, "--help"]
    return subprocess.run(cmd, capture_output=True, text=True, check=True).stdout.rstrip()


def cli_markdown(subcommands) -> str:
    out = ["# Command line", "", "Generated from each command's `--help` when the docs are built.", ""]
    out += ["## `python -m pounding_sweep SCENE.toml`", "", "```text", _help(), "```", ""]
    for name in subcommands:
        out += [f"## `python -m pounding_sweep {name}`", "", "```text", _help(name), "```", ""]
    return "\n".join(out)


def write_reference(app) -> None:
    from pounding_sweep.cli.run import SUBCOMMANDS
    from pounding_sweep.scene.describe import describe

    ref = HERE / "reference"
    for name, text in (("scene-keys.md", scene_keys_markdown(describe())), ("cli.md", cli_markdown(SUBCOMMANDS))):
        path = ref / name
        if not path.exists() or path.read_text() != text:  # unchanged pages keep their time stamp
            path.write_text(text)


def setup(app):
    app.connect("builder-inited", write_reference)
