"""LED tracking: accuracy per case on rendered videos with known motion, and speed at 640 x 480.

Usage (from the repository root, after `pip install ".[test]"`):

    python benchmarks/bench_tracking.py [--quick] [--only accuracy|speed]

Prints, for the paper's recipe (blue channel > 0.99, median filter, binary centroid: `method =
"paper"`) and this package's sub-pixel tracker (`method = "weighted"`), on each case: the RMS
image-position error over every marker and frame [px] (2-D, and x alone), the RMS error of the
floors' displacement relative to the table [mm], and the frames flagged. Cases: clean, sensor
noise, motion blur, MJPG and mp4v compression, unsaturated LEDs, camera roll 0.3 deg with shake,
reflections next to two markers, buildings touching (the real model at 6 Hz, 10 mm gap, markers on
the facing slab edges). Then tracking speed in frames/s at 640 x 480 (8 markers, FFV1), decoding
included (file -> table) and excluded (frames already in memory), and the decoding alone.
The machine is shared and noisy: speeds vary by tens of percent from run to run.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]

from pounding_sweep.scene import load_scene  # noqa: E402
from pounding_sweep.scene.video import VideoSpec  # noqa: E402
from pounding_sweep.sweep.simulate import simulate  # noqa: E402
from pounding_sweep.video.io import VideoError, VideoReader  # noqa: E402
from pounding_sweep.video.render import (  # noqa: E402
    Reflection,
    RenderOptions,
    harmonic_table,
    motion_from_history,
    render_video,
    shake_table_layout,
)
from pounding_sweep.video.tracker import QUALITY, track_frames, track_video  # noqa: E402


def sway(layout, top_mm=6.0):
    """Floors swaying at 4.25 Hz, top_mm at floor 3, on the paper's 2 mm 6 Hz table motion."""
    table = harmonic_table(2.0, 6.0)

    def motion(t):
        t = np.asarray(t, dtype=float)
        out = {"table": table(t)}
        for n in layout.floor_markers:
            out[n] = top_mm * int(n[-1]) / 3 * np.sin(2 * np.pi * 4.25 * t)
        return out

    return motion


def spec_for(rv, **kw):
    lay = rv.layout
    args = dict(
        path=str(rv.path),
        markers=lay.names,
        references=lay.references,
        positions_px=tuple(map(tuple, rv.truth_px[0])),
        mm_per_px=lay.mm_per_px,
    )
    return VideoSpec(**{**args, **kw})


def score(res, rv):
    """(RMS 2-D px, RMS x px, RMS 2-D px over measured (not interpolated) positions, RMS displacement mm,
    frames flagged, frames interpolated). With one reference the other table marker is tracked as a
    floor marker: only the floors are scored in mm."""
    ex = res.x_px - rv.truth_px[:, :, 0]
    ey = res.y_px - rv.truth_px[:, :, 1]
    e2 = ex**2 + ey**2
    d = np.array(
        [
            res.displacement_mm[:, j] - rv.truth_rel_mm[n]
            for j, n in enumerate(res.floor_markers)
            if n in rv.truth_rel_mm
        ]
    )
    flagged = int((res.quality > 0).any(axis=1).sum())
    interp = int(((res.quality & QUALITY["interpolated"]) > 0).any(axis=1).sum())
    return (
        float(np.sqrt(np.mean(e2))),
        float(np.sqrt(np.mean(ex**2))),
        float(np.sqrt(np.mean(e2[res.measured]))),
        float(np.sqrt(np.mean(d**2))),
        flagged,
        interp,
    )


def cases(n):
    lay = shake_table_layout()
    big = shake_table_layout(size=(640, 480), mm_per_px=2.5)
    on = np.zeros(n, bool)
    on[n // 4 : n // 2] = True
    yield "clean", lay, sway(lay), RenderOptions(), {}
    yield "noise 3 grey", lay, sway(lay), RenderOptions(noise=3.0, seed=1), {}
    yield (
        "blur (exposure 1 frame, streaks to 3.3 px)",
        lay,
        sway(lay, 60.0),
        RenderOptions(exposure=1.0, noise=1.0, seed=2),
        {},
    )
    yield "MJPG", lay, sway(lay), RenderOptions(codec="MJPG", noise=1.0, seed=3), {}
    yield "mp4v", lay, sway(lay), RenderOptions(codec="mp4v", noise=1.0, seed=4), {}
    yield "unsaturated (peak 150)", lay, sway(lay), RenderOptions(peak=150.0, noise=1.0, seed=5), {}
    yield (
        "roll 0.3 deg + shake (640x480, 2.5 mm/px)",
        big,
        sway(big),
        RenderOptions(roll_deg=0.3, shake_px=0.5, sigma_px=2.0, seed=6),
        {},
    )
    yield (
        "  same, one reference (no roll removal)",
        big,
        sway(big),
        RenderOptions(roll_deg=0.3, shake_px=0.5, sigma_px=2.0, seed=6),
        {"references": ("table_left",)},
    )
    yield (
        "reflections (2 markers, 1/4 of frames)",
        lay,
        sway(lay),
        RenderOptions(
            noise=2.0,
            seed=7,
            reflections=(Reflection("b1f3", (0.0, 8.0), 0.4, on), Reflection("b2f2", (5.0, 5.0), 0.5, on)),
        ),
        {},
    )
    scene = load_scene(REPO / "sweeps" / "paper_6hz.toml")
    hist, _ = simulate(
        scene, channels=[f"disp_b{b}f{f}" for b in (1, 2) for f in (1, 2, 3)], ks_ratio=5.0, r=0.4, gap_m=0.01
    )
    tl = shake_table_layout(gap_mm=10.0, marker_inset_mm=12.0)
    yield (
        "touching (model, 10 mm gap)",
        tl,
        motion_from_history(hist, harmonic_table(2.0, 6.0)),
        RenderOptions(noise=1.0, seed=8),
        {},
    )


def accuracy(tmp: Path, n: int) -> None:
    print(f"accuracy on rendered videos ({n} frames at 100 fps, 8 markers; truth: exposure-averaged position)")
    head = (
        f"{'case':44s} {'method':9s} {'RMS px':>8s} {'RMS x px':>9s} {'measured':>9s} {'RMS mm':>8s} "
        f"{'flagged':>8s} {'interp':>7s}"
    )
    print(head)
    print("-" * len(head))
    for k, (name, lay, motion, opts, extra) in enumerate(cases(n)):
        suffix = {"FFV1": ".mkv", "MJPG": ".avi", "mp4v": ".mp4"}[opts.codec]
        rv = render_video(tmp / f"case{k}{suffix}", lay, motion, n, opts)
        for method in ("paper", "weighted"):
            try:
                res = track_video(spec_for(rv, method=method, **extra))
            except VideoError as e:
                print(f"{name:44s} {method:9s} fails: {e.what[:70]}")
            else:
                px2, pxx, pxm, mm, fl, it = score(res, rv)
                print(f"{name:44s} {method:9s} {px2:8.4f} {pxx:9.4f} {pxm:9.4f} {mm:8.4f} {fl:8d} {it:7d}")
            name = ""
    print(
        "RMS px: image position of every marker in every frame (interpolated ones too); measured: only the\n"
        "positions measured in their frame; RMS mm: floors' displacement relative to the table; flagged /\n"
        "interp: frames with any quality flag / any interpolated marker."
    )


def speed(tmp: Path, n: int) -> None:
    lay = shake_table_layout(size=(640, 480), mm_per_px=2.5)
    rv = render_video(tmp / "speed.mkv", lay, sway(lay), n, RenderOptions(noise=2.0, sigma_px=2.0))
    t0 = time.perf_counter()
    with VideoReader(rv.path) as r:
        frames = list(r.frames())
    dec = time.perf_counter() - t0
    print(f"\nspeed at 640x480, {n} frames, 8 markers, FFV1 colour (frames/s; decoding alone: {n / dec:,.0f} frames/s)")
    print(f"{'method':10s} {'decoding included':>18s} {'decoding excluded':>18s}")
    for method in ("paper", "weighted"):
        spec = spec_for(rv, method=method)
        best_in, best_ex = 0.0, 0.0
        for _ in range(3):
            t0 = time.perf_counter()
            track_video(spec)
            best_in = max(best_in, n / (time.perf_counter() - t0))
            t0 = time.perf_counter()
            track_frames(frames, spec, 100.0)
            best_ex = max(best_ex, n / (time.perf_counter() - t0))
        print(f"{method:10s} {best_in:18,.0f} {best_ex:18,.0f}")
    print("(best of 3 runs; decoding runs ahead in its own thread while the tracker works)")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="fewer frames")
    ap.add_argument("--only", choices=["accuracy", "speed"], help="run one part")
    args = ap.parse_args()
    n = 60 if args.quick else 200
    with tempfile.TemporaryDirectory() as d:
        if args.only != "speed":
            accuracy(Path(d), n)
        if args.only != "accuracy":
            speed(Path(d), 100 if args.quick else 300)


if __name__ == "__main__":
    sys.exit(main())
