"""The shipped REAL shake-table tests (sweeps/real_northridge.toml, sweeps/real_bonus_event.toml) calibrated as a
uniform frame and as the frame a real structure needs: per-story stiffness and per-mode damping (issue 27 item 5),
then with the floors' own clocks too (time_offset_s_<channel>, item 2), each started from identify's modes
([calibrate] start_from) and without. For Bonus Event also the floors as the source files them (floors 1 and 2
not exchanged; imported afresh from ../shared, skipped where it is absent). Prints per fit the relative RMS error
(eq. 20, mean over the floors), the misfit over the sensors' measured noise, runs and seconds, and the fitted
values with their model-error intervals. About 7 min on 2 busy cores.

    python benchmarks/bench_real_frames.py [--tests northridge,bonus_event] [--threads 2]
"""

from __future__ import annotations

import argparse
import dataclasses
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from pounding_sweep.scene import load_scene, validate
from pounding_sweep.scene.starts import read_modes
from pounding_sweep.sweep.calibrate import calibrate
from pounding_sweep.warn import collecting

REPO = Path(__file__).resolve().parents[1]
SCENES = {
    "northridge": REPO / "sweeps" / "real_northridge.toml",
    "bonus_event": REPO / "sweeps" / "real_bonus_event.toml",
}
SHARED = REPO.parent / "shared" / "data" / "imu_shake_table" / "stiff_3story" / "bonus_event"
UNIFORM = {"stiffness_scale_b1": [0.7, 1.3], "damping_ratio_b1": [0.0005, 0.05], "time_offset_s": [-0.02, 0.02]}
FRAME = {f"story_stiffness_scale_b1_s{k}": [0.4, 3.0] for k in (1, 2, 3)}
FRAME |= {f"modal_damping_ratio_b1_m{j}": [0.0005, 0.05] for j in (1, 2, 3)} | {"time_offset_s": [-0.02, 0.02]}
CLOCKS = {f"time_offset_s_abs_acc_b1f{f}": [-0.03, 0.03] for f in (1, 2)}  # floor 3 on the table's clock


def frame_scene(scene, modes: Path | None):
    """The scene as a frame with per-mode damping (0.5 % each, the start) and identify's modes as its start."""
    b1 = dataclasses.replace(scene.building1, damping_ratio=None, modal_damping_ratios=(0.005, 0.005, 0.005))
    cal = dataclasses.replace(scene.calibrate, start_from=str(modes) if modes else None, profile=(), profile_points=0)
    return dataclasses.replace(scene, building1=b1, calibrate=cal)


def uniform_scene(scene):
    b1 = dataclasses.replace(scene.building1, damping_ratio=0.005, modal_damping_ratios=None)
    cal = dataclasses.replace(scene.calibrate, start_from=None, profile=(), profile_points=0)
    return dataclasses.replace(scene, building1=b1, calibrate=cal)


def fit(scene, parameters: dict, threads: int, label: str) -> None:
    s = dataclasses.replace(scene, sweep=(), calibrate=dataclasses.replace(scene.calibrate, parameters=parameters))
    validate(s)
    t0 = time.perf_counter()
    with collecting():
        f = calibrate(s, threads)[0]
    print(
        f"\n{label}: relative RMS {f.error_pct:.1f} %, misfit {f.misfit_ratio:.1f} x the sensors' noise "
        f"({f.evaluations} runs, {time.perf_counter() - t0:.0f} s)"
    )
    for n in f.names:
        a, b = f.ci95_model.get(n, f.ci95[n])
        print(f"    {n:30s} {f.estimate[n]:10.4g}  (95 % with model error {a:.4g} .. {b:.4g})")


def modes_of(table: Path, out: Path) -> Path:
    """identify's modes of `table`, written to `out` (the command a user runs)."""
    cmd = [sys.executable, "-m", "pounding_sweep", "identify", str(table), "--modes-out", str(out)]
    subprocess.run(cmd, check=True, capture_output=True)
    return out


def as_filed(tmp: Path, scene):
    """Bonus Event imported with the floors as the source files them (floor1.csv as floor 1), or None."""
    if not SHARED.is_dir():
        return None
    out = tmp / "as_filed"
    files = {"ground": "ground.csv", "b1f1": "floor1.csv", "b1f2": "floor2.csv", "b1f3": "floor3.csv"}
    cmd = [sys.executable, "-m", "pounding_sweep", "import", *[f"{k}={SHARED / v}" for k, v in files.items()]]
    subprocess.run([*cmd, "--out", str(out)], check=True, capture_output=True)
    exc = dataclasses.replace(scene.excitation, record=str(out / "record.csv"))
    exp = dataclasses.replace(scene.experiment, table=str(out / "table.parquet"))
    return dataclasses.replace(scene, excitation=exc, experiment=exp)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--tests", default="northridge,bonus_event")
    ap.add_argument("--threads", type=int, default=2)
    a = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        for test in a.tests.split(","):
            scene = load_scene(SCENES[test])
            modes = modes_of(Path(scene.experiment.table), Path(tmp) / f"{test}_modes.toml")
            print(
                f"\n== {test} ({SCENES[test].relative_to(REPO)}; identify's modes "
                f"{', '.join(f'{f:.2f}' for f in read_modes(str(modes))[1].frequencies_Hz)} Hz)"
            )
            fit(uniform_scene(scene), UNIFORM, a.threads, "uniform frame (stiffness_scale_b1, damping_ratio_b1)")
            fit(frame_scene(scene, None), FRAME, a.threads, "per-story stiffness, per-mode damping")
            fit(frame_scene(scene, modes), FRAME, a.threads, "per-story stiffness, per-mode damping, from identify")
            fit(frame_scene(scene, modes), FRAME | CLOCKS, a.threads, "the same with floors 1-2's own clocks")
            if test == "bonus_event":
                filed = as_filed(Path(tmp), scene)
                if filed is None:
                    print("\n(floors as filed: skipped, ../shared absent)")
                    continue
                fit(uniform_scene(filed), UNIFORM, a.threads, "floors as filed: uniform frame")
                fit(frame_scene(filed, None), FRAME, a.threads, "floors as filed: per-story, per-mode")


if __name__ == "__main__":
    main()
