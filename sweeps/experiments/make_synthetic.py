"""Regenerate the shipped SYNTHETIC experiments (stand-ins for the paper's unpublished measurements).

Usage, from the repository root:  python sweeps/experiments/make_synthetic.py
Each table is made from a shipped scene, hidden contact parameters on the paper's grid, a
structure perturbed by a few percent (model error) and 0.05 mm of tracking noise at 100 fps.
"""

from __future__ import annotations

from pathlib import Path

from pounding_sweep.scene import load_scene
from pounding_sweep.synthetic import make_experiment, write_experiment

HERE = Path(__file__).resolve().parent
SWEEPS = HERE.parent

#: table name -> (scene it is made from, hidden parameters, seed)
EXPERIMENTS = {
    "synthetic_6hz.parquet": ("paper_6hz.toml", {"ks_ratio": 5.0, "r": 0.4}, 6),
    "synthetic_duzce.parquet": ("paper_duzce.toml", {"ks_ratio": 1.0, "r": 0.6}, 1999),
}


def build(name: str):
    scene_file, hidden, seed = EXPERIMENTS[name]
    return make_experiment(load_scene(SWEEPS / scene_file), hidden, seed=seed)


def main() -> None:
    for name in EXPERIMENTS:
        df, prov = build(name)
        write_experiment(df, prov, HERE / name)
        print(f"wrote {HERE / name}: {len(df)} samples, hidden {prov['hidden_parameters']}")


if __name__ == "__main__":
    main()
