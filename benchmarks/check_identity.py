"""Bit-identity of results across a change that must not change them (a refactor, a reorganisation).

    python benchmarks/check_identity.py run OUT_DIR        # run the fixed set of scenes into OUT_DIR
    python benchmarks/check_identity.py compare A_DIR B_DIR  # every table of A equal to B's, bit for bit
    python benchmarks/check_identity.py rows OUT.npz         # the lane kernel's scenes' metric rows, in process
    python benchmarks/check_identity.py compare-rows A.npz B.npz

`run` writes the scenes it uses into OUT_DIR/scenes (the shipped scenes, the throughput benchmark's
uneven grids for both lane schemes and both laws, a history-producing scene, a record and scale
sweep, a dt = "auto" sweep) and runs each through the command line (`python -m pounding_sweep`), so
the same script drives any version of the package. `compare` reads every Parquet table (metrics,
best runs, histories), drops the run-time columns (wall clock), and requires every other column
equal value for value (NaN equal to NaN, 0.0 equal to -0.0); columns B adds (new metrics) are listed,
columns of A that B lacks are a difference. It prints one line per table and exits 1 on any difference.

`rows` is the quick check of a change to the lane kernel on a busy machine: it runs only the scenes the
lane kernel computes (the four uneven grids, the paper's Duzce and 6 Hz grids) through
sweep.prepare in this process (one compile, no subprocess per scene) and saves each scene's metric rows;
`compare-rows` requires them equal slot for slot (NaN equal to NaN); where they differ it says by how
much (each slot against the largest value of its column), for a change meant to move results by rounding.
Run it from a folder other than the checkout with PYTHONPATH=OTHER_CHECKOUT for the other side.
"""

from __future__ import annotations

import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
SWEEPS = REPO / "sweeps"
RECORD = SWEEPS / "records" / "RSN1605_DUZCE_DZC180.AT2"
WALL_CLOCK = ("run_time_s",)


def _grid(values) -> str:
    return "[" + ", ".join(repr(float(v)) for v in values) + "]"


def _uneven(scheme: str, law: str) -> str:
    """bench_throughput's uneven grid (gaps 0..20 mm, k_s/k 0.01..100, r 0..1), 1 s of the 6 Hz scene."""
    text = (SWEEPS / "paper_6hz.toml").read_text()
    text = text.replace("duration_s = 5.0", "duration_s = 1.0")
    head, _, _ = text.partition("[sweep]")
    return (
        head.replace('law = "classic"', f'law = "{law}"').replace('scheme = "event"', f'scheme = "{scheme}"')
        + f"\n[sweep]\ngap_m = {_grid((0.0, 0.002, 0.02))}\nks_ratio = {_grid(np.geomspace(0.01, 100, 6))}\n"
        f"r = {_grid(np.linspace(0.0, 1.0, 5))}\n"
    )


def scenes(out: Path) -> dict[str, Path]:
    """Write the scenes (copies of the shipped ones, with their relative paths made absolute)."""
    d = out / "scenes"
    d.mkdir(parents=True, exist_ok=True)
    files: dict[str, str] = {}
    for p in sorted(SWEEPS.glob("*.toml")):
        text = p.read_text()
        text = text.replace('"records/', f'"{SWEEPS}/records/').replace('"experiments/', f'"{SWEEPS}/experiments/')
        files[p.stem] = text
    for scheme in ("event", "implicit"):
        for law in ("classic", "no_tension"):
            files[f"uneven_{scheme}_{law}"] = _uneven(scheme, law)
    six = (SWEEPS / "paper_6hz.toml").read_text().replace("duration_s = 5.0", "duration_s = 1.0")
    files["histories_6hz"] = six.replace(
        "[output]",
        '[output]\nhistories = ["disp_b1f3", "vel_b2f2", "abs_acc_b2f3", '
        '"force_f3", "ground_acc"]\nhistory_decimate = 7',
    )
    duzce = (SWEEPS / "paper_duzce.toml").read_text().replace('"records/', f'"{SWEEPS}/records/')
    head, _, _ = duzce.partition("[sweep]")
    files["record_scale"] = head + "\n[sweep]\nscale = [0.5, 1.0]\nks_ratio = [1.0, 10.0]\nr = [0.2, 0.8]\n"
    auto = six.replace("dt_s = 1e-4", 'dt_s = "auto"')
    assert auto != six, "paper_6hz.toml no longer sets dt_s = 1e-4"
    files["auto_dt"] = auto
    paths = {}
    for name, text in files.items():
        lines = [ln for ln in text.splitlines() if not ln.strip().startswith("path =")]
        p = d / f"{name}.toml"
        p.write_text("\n".join(lines) + "\n")
        paths[name] = p
    return paths


def run(out: Path) -> int:
    out = out.resolve()
    for name, scene in scenes(out).items():
        target = out / "results" / f"{name}.parquet"
        cmd = [sys.executable, "-m", "pounding_sweep", str(scene), "--out", str(target), "--quiet", "--yes"]
        r = subprocess.run(cmd, capture_output=True, text=True)
        print(f"{name}: exit {r.returncode}" + (f" ({r.stderr.strip().splitlines()[-1]})" if r.returncode else ""))
        if r.returncode:
            return 1
    return 0


def _tables(d: Path) -> dict[str, Path]:
    res = d / "results"
    out = {}
    for p in sorted(res.iterdir()):
        if p.name.endswith(".parquet"):
            out[p.name] = p
    return out


def compare(a: Path, b: Path) -> int:
    import pandas as pd

    ta, tb = _tables(a), _tables(b)
    bad = 0
    for name in sorted(set(ta) | set(tb)):
        if name not in ta or name not in tb:
            print(f"{name}: only in {a if name in ta else b}")
            bad += 1
            continue
        x = pd.read_parquet(ta[name]).drop(columns=list(WALL_CLOCK), errors="ignore")
        y = pd.read_parquet(tb[name]).drop(columns=list(WALL_CLOCK), errors="ignore")
        if len(x) != len(y):
            print(f"{name}: rows differ ({len(x)} vs {len(y)})")
            bad += 1
            continue
        added = [c for c in y.columns if c not in x.columns]
        gone = [c for c in x.columns if c not in y.columns]
        if gone:
            print(f"{name}: columns of A missing in B: {', '.join(gone)}")
            bad += 1
            continue
        diff = []
        for c in x.columns:  # every column of A; B may add new ones (reported)
            u, v = x[c].to_numpy(), y[c].to_numpy()
            if u.dtype.kind == "f" or v.dtype.kind == "f":
                u, v = u.astype(float), v.astype(float)
                same = (u == v) | (np.isnan(u) & np.isnan(v))
            else:
                same = (u == v) | (pd.isna(u) & pd.isna(v))
            if not np.all(same):
                diff.append(f"{c} ({int((~same).sum())} rows)")
        new = f" (B adds {len(added)}: {', '.join(added[:3])}{', ...' if len(added) > 3 else ''})" if added else ""
        print(
            f"{name}: {len(x)} rows x {len(x.columns)} columns "
            + ("identical" if not diff else "DIFFER: " + ", ".join(diff))
            + new
        )
        bad += bool(diff)
    print(f"{len(set(ta) | set(tb))} tables, {bad} differing")
    return 1 if bad else 0


LANE_SCENES = (
    "uneven_event_classic",
    "uneven_event_no_tension",
    "uneven_implicit_classic",
    "uneven_implicit_no_tension",
    "paper_duzce",
    "paper_6hz",
)


def rows(out: Path) -> int:
    import tempfile

    from pounding_sweep.scene import load_scene
    from pounding_sweep.sweep.prepare import prepare

    found = {}
    with tempfile.TemporaryDirectory() as d:
        paths = scenes(Path(d))
        for name in LANE_SCENES:
            prep = prepare(load_scene(paths[name]))
            found[name] = prep.run(prep.grid.chunk(0, prep.grid.size), threads=2)[0]
            print(f"{name}: {found[name].shape[0]} runs x {found[name].shape[1]} slots", flush=True)
    np.savez(out, **found)
    return 0


def compare_rows(a: Path, b: Path) -> int:
    x, y = np.load(a), np.load(b)
    bad = 0
    for name in sorted(set(x.files) | set(y.files)):
        if name not in x.files or name not in y.files:
            print(f"{name}: only in {a if name in x.files else b}")
            bad += 1
            continue
        u, v = x[name], y[name]
        if u.shape != v.shape:
            print(f"{name}: shapes differ {u.shape} vs {v.shape}")
            bad += 1
            continue
        diff = ~((u == v) | (np.isnan(u) & np.isnan(v)))
        differ = int(diff.sum())
        said = "identical"
        if differ:
            # how far, for a change meant to move results by rounding only: each slot's difference over the
            # largest magnitude its column (metric) takes in either table
            with np.errstate(invalid="ignore", divide="ignore"), warnings.catch_warnings():
                warnings.simplefilter("ignore", RuntimeWarning)  # a column of NaN in both: "All-NaN slice"
                scale = np.maximum(np.nanmax(np.abs(u), axis=0), np.nanmax(np.abs(v), axis=0))
                rel = np.where(diff, np.abs(u - v) / np.where(scale > 0, scale, 1.0), 0.0)
            rel = np.where(np.isnan(rel), np.inf, rel)  # NaN on one side only
            worst = np.unravel_index(int(np.argmax(rel)), rel.shape)
            said = (
                f"DIFFER: {differ} slots in {int(diff.any(axis=1).sum())} rows, largest {rel[worst]:.2g} of its "
                f"column's largest value (row {worst[0]}, slot {worst[1]}); median {np.median(rel[diff]):.2g}"
            )
        print(f"{name}: {u.shape[0]} rows x {u.shape[1]} slots " + said)
        bad += bool(differ)
    return 1 if bad else 0


def main(argv: list[str]) -> int:
    if len(argv) == 2 and argv[0] == "run":
        return run(Path(argv[1]))
    if len(argv) == 3 and argv[0] == "compare":
        return compare(Path(argv[1]), Path(argv[2]))
    if len(argv) == 2 and argv[0] == "rows":
        return rows(Path(argv[1]))
    if len(argv) == 3 and argv[0] == "compare-rows":
        return compare_rows(Path(argv[1]), Path(argv[2]))
    print(__doc__, file=sys.stderr)
    return 2


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
