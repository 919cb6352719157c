"""Compile time of the kernels a first run pays, measured through the command line.

    python benchmarks/bench_compile.py [--repeats N]

For each case a scene is run twice by `python -m pounding_sweep` in a fresh process with an empty Numba
cache (NUMBA_CACHE_DIR pointing at a new temporary folder): the first run compiles, the second loads the
cache. The runs are 10 ms long, so both are start-up plus compile or cache load; their difference is the
compile time a user waits for once. Wall time is what a user waits; on a shared machine it grows with the
other processes' load, so the table also gives the runs' CPU time (user + system of the run and of the
second process that compiles some pieces beside it, engine/aside.py): the work done, which a loaded machine
does not change, and which a second CPU does not shorten. Cases: the README's scored scene (the scalar kernel with scoring),
the Duzce metrics-only scene (the lane kernel), the same with another pair of story counts (4 + 2) from an empty
cache and from one that holds the Duzce scene's compile (what a new building pair costs once the lane kernel is
cached: that case's cold run follows an untimed run of the Duzce scene into its cache), and the 6 Hz scene with
histories (the scalar kernel without scoring).
The runs are not --quiet: the table says whether the cold run announced its compile on stderr
('compiling ... for this machine') and whether the warm one stayed silent about it.
Then, with a warm cache, the README's scored scene in full (20 runs of 5 s and the refinement) and the
same command again into the same folder (everything kept: what a resumed, finished sweep costs).
Works for any version of the package on the path (PYTHONPATH=OTHER_CHECKOUT to measure another).
"""

from __future__ import annotations

import argparse
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
SWEEPS = REPO / "sweeps"


def _short(text: str) -> str:
    """The scene cut to 10 ms and one grid point (start-up and compile only)."""
    out = []
    skip = False
    for line in text.splitlines():
        s = line.strip()
        if s.startswith("[") and s != "[sweep]":
            skip = False
        if s == "[sweep]":
            skip = True
            continue
        if skip or s.startswith("path ="):
            continue
        if s.startswith("duration_s"):
            line = "duration_s = 0.01"
        if s.startswith("refine"):
            line = "refine = false"
        out.append(line)
    text = "\n".join(out) + "\n"
    if "duration_s" not in text:  # a record scene: cut it
        text = text.replace("[excitation]", "[excitation]\nduration_s = 0.01", 1)
    if "ks_ratio" not in text.split("[contact]", 1)[1].split("[", 1)[0]:
        text = text.replace("[contact]", "[contact]\nks_ratio = 1.0", 1)
    if "\nr = " not in text.split("[contact]", 1)[1].split("[", 1)[0]:
        text = text.replace("[contact]", "[contact]\nr = 0.4", 1)
    return text.replace('"records/', f'"{SWEEPS}/records/').replace('"experiments/', f'"{SWEEPS}/experiments/')


#: the cases whose cache first holds another case's compile (not timed): what a new pair of story counts costs once
#: the lane kernel is cached, as it is for anyone who ran one lane scene before
AFTER = {"Duzce, 4 + 2 stories, lane kernel cached (a new pair)": "Duzce, metrics only (lane kernel)"}


def cases(folder: Path) -> dict[str, Path]:
    six = (SWEEPS / "paper_6hz.toml").read_text()
    duzce = (SWEEPS / "paper_duzce.toml").read_text()
    texts = {
        "scored 6 Hz (README scene; scalar kernel + scoring)": _short((SWEEPS / "scored_6hz.toml").read_text()),
        "Duzce, metrics only (lane kernel)": _short(duzce),
        "Duzce, 4 + 2 stories (lane kernel, new sizes)": _short(duzce)
        .replace("masses_kg = [1.7, 1.7, 1.6]", "masses_kg = [1.7, 1.7, 1.6, 1.6]")
        .replace("masses_kg = [0.56, 0.56, 0.45]", "masses_kg = [0.56, 0.45]"),
        "6 Hz with histories (scalar kernel)": _short(six).replace("[output]", '[output]\nhistories = ["disp_b1f3"]'),
    }
    texts["Duzce, 4 + 2 stories, lane kernel cached (a new pair)"] = texts[
        "Duzce, 4 + 2 stories (lane kernel, new sizes)"
    ]
    out = {}
    for i, (name, text) in enumerate(texts.items()):
        p = folder / f"case{i}.toml"
        p.write_text(text)
        out[name] = p
    return out


def _children_cpu() -> float:
    ru = resource.getrusage(resource.RUSAGE_CHILDREN)
    return ru.ru_utime + ru.ru_stime


def timed_run(scene: Path, cache: Path, out: Path) -> tuple[float, float, str]:
    """(wall seconds, CPU seconds, stderr) of one run through the command line."""
    env = dict(os.environ, NUMBA_CACHE_DIR=str(cache))
    t0, c0 = time.perf_counter(), _children_cpu()
    r = subprocess.run(
        [sys.executable, "-m", "pounding_sweep", str(scene), "--out", str(out), "--yes"],
        env=env,
        capture_output=True,
        text=True,
    )
    dt, dc = time.perf_counter() - t0, _children_cpu() - c0
    if r.returncode:
        raise SystemExit(f"{scene}: exit {r.returncode}: {r.stderr.strip()[-400:]}")
    return dt, dc, r.stderr


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repeats", type=int, default=1, help="cold/warm pairs per case (the least is kept)")
    args = ap.parse_args(argv)
    import pounding_sweep

    with open("/proc/loadavg") as f:
        print(f"package: {Path(pounding_sweep.__file__).parent}; load average {' '.join(f.read().split()[:3])}")
    rows = []
    with tempfile.TemporaryDirectory() as d:
        d = Path(d)
        listed = cases(d)
        for name, scene in listed.items():
            cold, warm, cold_cpu, warm_cpu, said, silent = [], [], [], [], [], []
            for k in range(args.repeats):
                cache = d / f"cache-{scene.stem}-{k}"
                if name in AFTER:  # the other case's compile first, untimed
                    timed_run(listed[AFTER[name]], cache, d / f"o-{scene.stem}-{k}-prime.parquet")
                t, c, err = timed_run(scene, cache, d / f"o-{scene.stem}-{k}-a.parquet")
                cold.append(t)
                cold_cpu.append(c)
                said.append("compiling" in err)
                t, c, err = timed_run(scene, cache, d / f"o-{scene.stem}-{k}-b.parquet")
                warm.append(t)
                warm_cpu.append(c)
                silent.append("compiling" not in err)
            comp_cpu = min(cold_cpu) - min(warm_cpu)
            rows.append((name, min(cold), min(warm), min(cold) - min(warm), comp_cpu, all(said), all(silent)))
        w = max(len(r[0]) for r in rows)
        print(
            f"{'case':<{w}}  {'empty cache [s]':>15}  {'warm cache [s]':>14}  {'compile [s]':>11}  "
            f"{'compile CPU [s]':>15}  {'cold run announced':>18}  {'warm run silent':>15}"
        )
        for name, c, wa, comp, comp_cpu, said, silent in rows:
            print(
                f"{name:<{w}}  {c:15.1f}  {wa:14.1f}  {comp:11.1f}  {comp_cpu:15.1f}  {str(said):>18}  {str(silent):>15}"
            )
        full = d / "scored.toml"
        full.write_text((SWEEPS / "scored_6hz.toml").read_text().replace('"experiments/', f'"{SWEEPS}/experiments/'))
        cache = d / f"cache-{cases(d)['scored 6 Hz (README scene; scalar kernel + scoring)'].stem}-0"
        first, _, _ = timed_run(full, cache, d / "full.parquet")
        again, _, _ = timed_run(full, cache, d / "full.parquet")
        print(
            f"\nscored 6 Hz in full, warm cache: {first:.1f} s; the same command again (everything kept, "
            f"refinement stored): {again:.1f} s"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
