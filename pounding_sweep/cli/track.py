"""`python -m pounding_sweep track VIDEO ...`: a shake-table video's LED markers -> the tracked-displacement table.

Exit status 0 when done, 2 on bad input with one line `error: <file>: <what> (<value>)` on stderr
(no traceback) and no output file: tables are written as `<out>.tmp` and renamed when complete. An existing
--out is replaced only when it is a table track wrote (a user's file is refused before any frame is read).
"""

from __future__ import annotations

import argparse
import sys
import tomllib
from pathlib import Path

from pounding_sweep.cli.common import (
    EXIT_BAD_INPUT,
    Bad,
    OneLineParser,
    check_replaceable,
    first_line,
    numbers,
    split_list,
)


def _written_by_track(path: Path) -> bool:
    """A table track wrote: Parquet carrying its 'tracked_video' metadata, or a CSV whose header is track's (the
    time first, then the frame number, quality flags and the table's camera position, which only track writes)."""
    if path.suffix.lower() == ".parquet":
        try:
            import pyarrow.parquet as pq

            return b"tracked_video" in (pq.read_metadata(path).metadata or {})
        except Exception:  # noqa: BLE001 - not Parquet, or damaged: not shown to be ours
            return False
    header = first_line(path).split(",")
    return header[:1] == ["t_s"] and "frame" in header and "table_in_camera_mm" in header


def _track_parser() -> argparse.ArgumentParser:
    p = OneLineParser(
        prog="python -m pounding_sweep track",
        description="Track the LED markers of a shake-table video and write the displacement of every floor marker "
        "relative to the table (mm) with a per-frame quality flag: the tracked-displacement table that "
        "[experiment] table = ... scores against. Options mirror the [experiment.video] keys.",
        epilog="Markers: --marker NAME=X,Y per marker (its pixel position in the first frame), or --markers with floor "
        "names (b1f3 or model1_floor3_mm) for the automatic layout (references lowest, listed left to right; building 1 "
        "on the left when --positive-direction is right; floor 1 lowest). Quality bits: 1 lost, 2 merged, 4 reflection, "
        "8 shape, 16 interpolated, 32 reference flagged, 64 swap guard, 128 deblended.",
    )
    p.add_argument("video", help="video file (.mkv, .avi, .mp4, ...)")
    p.add_argument("--out", "-o", help="output table, .csv or .parquet (default: <video>.tracked.csv beside the video)")
    p.add_argument(
        "--scene", help="take the [experiment.video] section of this scene file; options given here override its keys"
    )
    p.add_argument(
        "--marker",
        action="append",
        default=[],
        metavar="NAME=X,Y",
        help="a marker and its first-frame position in pixels (repeat)",
    )
    p.add_argument("--markers", help="marker names, comma-separated, for the automatic layout")
    p.add_argument(
        "--references", help="markers fixed to the table, comma-separated (two or more also remove camera roll)"
    )
    p.add_argument("--mm-per-px", type=float, help="image scale [mm per pixel]")
    p.add_argument("--scale", metavar="A,B,MM", help="image scale from two markers a known distance apart [mm]")
    p.add_argument("--fps", type=float, help="frame rate (default: the container's)")
    p.add_argument("--roi", metavar="X0,Y0,X1,Y1", help="region of interest in pixels")
    p.add_argument(
        "--channel", choices=["blue", "green", "red", "grey"], help="colour channel (default blue, as the paper)"
    )
    p.add_argument(
        "--method",
        choices=["weighted", "paper"],
        help="sub-pixel weighted centroids (default) or the paper's 0.99 binary recipe",
    )
    p.add_argument(
        "--threshold",
        type=float,
        help="weighted: fraction of each marker's peak (default 0.2); paper: of full scale (0.99)",
    )
    p.add_argument(
        "--detect-level",
        type=float,
        help="grey levels above the background that detect a marker (default: from the noise)",
    )
    p.add_argument("--start-frame", type=int, help="first frame to track (the markers must be apart in it)")
    p.add_argument("--max-frames", type=int, help="frames to track at most")
    p.add_argument("--max-gap", type=int, help="longest gap (frames) that may be interpolated (default 10)")
    p.add_argument("--max-step", type=float, help="largest move between frames in pixels (default 10)")
    p.add_argument(
        "--positive-direction", choices=["right", "left"], help="image direction of the model's +x (default right)"
    )
    p.add_argument(
        "--transform", choices=["similarity", "rigid", "translation"], help="camera motion removed with the references"
    )
    p.add_argument(
        "--pixels", action="store_true", help="also write every marker's image position (<name>_x_px, <name>_y_px)"
    )
    p.add_argument("--quiet", action="store_true", help="no progress and no summary")
    return p


def _spec_from_args(args):
    """(VideoSpec, the file errors are about)."""
    from pounding_sweep.scene.video import SECTION, parse_video_section

    video = Path(args.video)
    table: dict = {}
    base = Path.cwd()
    if args.scene:
        sp = Path(args.scene)
        try:
            raw = tomllib.loads(sp.read_text(encoding="utf-8"))
        except OSError as e:
            raise Bad(sp, "cannot read the scene file", e.strerror or e) from None
        except (tomllib.TOMLDecodeError, UnicodeDecodeError) as e:
            raise Bad(sp, "not a TOML scene file", e) from None
        sec = raw.get("experiment", {}).get("video") if isinstance(raw.get("experiment"), dict) else None
        if not isinstance(sec, dict):
            raise Bad(sp, f"no {SECTION} section", "needed with --scene")
        table = dict(sec)
        base = sp.resolve().parent
    table["path"] = str(video.resolve())
    if args.marker:
        pos = {}
        for m in args.marker:
            name, _, xy = m.partition("=")
            if not name or not xy:
                raise ValueError(f"--marker {m!r}: expected NAME=X,Y")
            pos[name.strip()] = numbers(xy, 2, f"--marker {name}")
        table["markers"] = pos
    if args.markers:
        if args.marker:
            raise ValueError("--markers and --marker: give one of them")
        table["markers"] = split_list(args.markers)
    if args.references:
        table["references"] = split_list(args.references)
    if args.mm_per_px is not None:
        table["mm_per_px"] = args.mm_per_px
        table.pop("scale_markers", None)
        table.pop("scale_distance_mm", None)
    if args.scale:
        a, b, mm = (split_list(args.scale) + ["", "", ""])[:3]
        try:
            table["scale_distance_mm"] = float(mm)
        except ValueError:
            raise ValueError(
                f"--scale {args.scale!r}: expected A,B,MM (two marker names and their distance in mm)"
            ) from None
        table["scale_markers"] = [a, b]
        table.pop("mm_per_px", None)
    if args.roi:
        table["roi_px"] = numbers(args.roi, 4, "--roi", int)
    for opt, key in (
        ("fps", "fps"),
        ("channel", "channel"),
        ("method", "method"),
        ("threshold", "threshold"),
        ("detect_level", "detect_level"),
        ("start_frame", "start_frame"),
        ("max_frames", "max_frames"),
        ("max_gap", "max_gap_frames"),
        ("max_step", "max_step_px"),
        ("positive_direction", "positive_direction"),
        ("transform", "transform"),
    ):
        v = getattr(args, opt)
        if v is not None:
            table[key] = v
    return parse_video_section(table, base)


def track_main(argv: list[str]) -> int:
    args = _track_parser().parse_args(argv)
    from pounding_sweep.progress import Progress
    from pounding_sweep.scene import ConfigError
    from pounding_sweep.video.io import VideoError

    video = args.video
    out = Path(args.out) if args.out else Path(video).with_suffix(".tracked.csv")
    try:
        if out.suffix.lower() not in (".csv", ".parquet"):
            raise Bad(out, "the output table must be .csv or .parquet", out.suffix or "no suffix")
        check_replaceable(out, _written_by_track, "track")
        spec = _spec_from_args(args)
        from pounding_sweep.video.tracker import describe_quality, track_video, write_tracked_table

        res = track_video(spec, progress=Progress(not args.quiet, unit="frames"))
        write_tracked_table(res.table(pixels=args.pixels), res.provenance, out)
    except Bad as e:
        print(f"error: {e}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except (ConfigError, ValueError) as e:  # VideoError is a ValueError whose message names the file
        msg = str(e)
        print(f"error: {msg}" if isinstance(e, VideoError) else f"error: {video}: {msg}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except OSError as e:
        print(f"error: {out}: cannot write the table ({e.strerror or e})", file=sys.stderr)
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:
        print("interrupted: no table written", file=sys.stderr)
        return 130
    if not args.quiet:
        p = res.provenance
        rows = [
            ("video", p["video"]),
            ("frames", f"{p['frames']} at {res.fps:g} fps ({p['frames'] / res.fps:.2f} s)"),
            ("method", f"{p['method']}, threshold {p['threshold']:g}"),
            ("scale", f"{res.mm_per_px:.5g} mm/px"),
            (
                "camera motion",
                f"{p['transform']} from {', '.join(spec.references)}; largest roll removed "
                f"{p['max_abs_roll_removed_deg']:.3f} deg",
            ),
        ]
        for i, name in enumerate(res.names):
            flags = {}
            for code in res.quality[:, i]:
                if code:
                    for w in describe_quality(int(code)).split("+"):
                        flags[w] = flags.get(w, 0) + 1
            rows.append((name, ", ".join(f"{k} {v}" for k, v in flags.items()) or "every frame ok"))
        rows.append(("table", str(out)))
        w = max(len(k) for k, _ in rows)
        print("\n".join(f"{k:<{w}}  {v}" for k, v in rows))
    return 0
