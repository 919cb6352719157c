"""Command line: `python -m pounding_sweep SCENE.toml` and its subcommands (plot, track, identify, gaps, risk).

Owns stdout/stderr, exit codes and progress; the top layer (it may import every other one)."""

from pounding_sweep.cli.run import main

__all__ = ["main"]
