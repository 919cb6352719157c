"""`python -m pounding_sweep track VIDEO ...` and `python -m pounding_sweep identify TABLE ...`.

Exit status 0 when done, 2 on bad input with one line `error: <file>: <what> (<value>)` on stderr
(no traceback) and no output file: tables are written as `<out>.tmp` and renamed when complete.
"""

from __future__ import annotations

import argparse
import os
import sys
import tomllib
from pathlib import Path

EXIT_BAD_INPUT = 2


def _split(s: str) -> list[str]:
    return [x.strip() for x in s.split(",") if x.strip()]


def _numbers(s: str, n: int, what: str, cast=float) -> list:
    parts = _split(s)
    try:
        vals = [cast(x) for x in parts]
    except ValueError:
        raise ValueError(f"{what} = {s!r}: expected {n} numbers separated by commas") from None
    if len(vals) != n:
        raise ValueError(f"{what} = {s!r}: expected {n} numbers separated by commas")
    return vals


def _track_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
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
    p.add_argument("--scene", help="take the [experiment.video] section of this scene file; options given here override its keys")
    p.add_argument("--marker", action="append", default=[], metavar="NAME=X,Y", help="a marker and its first-frame position in pixels (repeat)")
    p.add_argument("--markers", help="marker names, comma-separated, for the automatic layout")
    p.add_argument("--references", help="markers fixed to the table, comma-separated (two or more also remove camera roll)")
    p.add_argument("--mm-per-px", type=float, help="image scale [mm per pixel]")
    p.add_argument("--scale", metavar="A,B,MM", help="image scale from two markers a known distance apart [mm]")
    p.add_argument("--fps", type=float, help="frame rate (default: the container's)")
    p.add_argument("--roi", metavar="X0,Y0,X1,Y1", help="region of interest in pixels")
    p.add_argument("--channel", choices=["blue", "green", "red", "grey"], help="colour channel (default blue, as the paper)")
    p.add_argument("--method", choices=["weighted", "paper"], help="sub-pixel weighted centroids (default) or the paper's 0.99 binary recipe")
    p.add_argument("--threshold", type=float, help="weighted: fraction of each marker's peak (default 0.2); paper: of full scale (0.99)")
    p.add_argument("--detect-level", type=float, help="grey levels above the background that detect a marker (default: from the noise)")
    p.add_argument("--start-frame", type=int, help="first frame to track (the markers must be apart in it)")
    p.add_argument("--max-frames", type=int, help="frames to track at most")
    p.add_argument("--max-gap", type=int, help="longest gap (frames) that may be interpolated (default 10)")
    p.add_argument("--max-step", type=float, help="largest move between frames in pixels (default 10)")
    p.add_argument("--positive-direction", choices=["right", "left"], help="image direction of the model's +x (default right)")
    p.add_argument("--transform", choices=["similarity", "rigid", "translation"], help="camera motion removed with the references")
    p.add_argument("--pixels", action="store_true", help="also write every marker's image position (<name>_x_px, <name>_y_px)")
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
            raise _Bad(sp, "cannot read the scene file", e.strerror or e) from None
        except (tomllib.TOMLDecodeError, UnicodeDecodeError) as e:
            raise _Bad(sp, "not a TOML scene file", e) from None
        sec = raw.get("experiment", {}).get("video") if isinstance(raw.get("experiment"), dict) else None
        if not isinstance(sec, dict):
            raise _Bad(sp, f"no {SECTION} section", "needed with --scene")
        table = dict(sec)
        base = sp.resolve().parent
    table["path"] = str(video.resolve())
    if args.marker:
        pos = {}
        for m in args.marker:
            name, _, xy = m.partition("=")
            if not name or not xy:
                raise ValueError(f"--marker {m!r}: expected NAME=X,Y")
            pos[name.strip()] = _numbers(xy, 2, f"--marker {name}")
        table["markers"] = pos
    if args.markers:
        if args.marker:
            raise ValueError("--markers and --marker: give one of them")
        table["markers"] = _split(args.markers)
    if args.references:
        table["references"] = _split(args.references)
    if args.mm_per_px is not None:
        table["mm_per_px"] = args.mm_per_px
        table.pop("scale_markers", None)
        table.pop("scale_distance_mm", None)
    if args.scale:
        a, b, mm = (_split(args.scale) + ["", "", ""])[:3]
        try:
            table["scale_distance_mm"] = float(mm)
        except ValueError:
            raise ValueError(f"--scale {args.scale!r}: expected A,B,MM (two marker names and their distance in mm)") from None
        table["scale_markers"] = [a, b]
        table.pop("mm_per_px", None)
    if args.roi:
        table["roi_px"] = _numbers(args.roi, 4, "--roi", int)
    for opt, key in (("fps", "fps"), ("channel", "channel"), ("method", "method"), ("threshold", "threshold"),
                     ("detect_level", "detect_level"), ("start_frame", "start_frame"), ("max_frames", "max_frames"),
                     ("max_gap", "max_gap_frames"), ("max_step", "max_step_px"), ("positive_direction", "positive_direction"),
                     ("transform", "transform")):
        v = getattr(args, opt)
        if v is not None:
            table[key] = v
    return parse_video_section(table, base)


class _Bad(Exception):
    def __init__(self, path, what, value=None):
        super().__init__(f"{path}: {what}" + ("" if value is None else f" ({value})"))


def track_main(argv: list[str]) -> int:
    args = _track_parser().parse_args(argv)
    from pounding_sweep.scene import ConfigError
    from pounding_sweep.progress import Progress
    from pounding_sweep.video.io import VideoError

    video = args.video
    out = Path(args.out) if args.out else Path(video).with_suffix(".tracked.csv")
    try:
        if out.suffix.lower() not in (".csv", ".parquet"):
            raise _Bad(out, "the output table must be .csv or .parquet", out.suffix or "no suffix")
        spec = _spec_from_args(args)
        from pounding_sweep.video.tracker import describe_quality, track_video, write_tracked_table

        res = track_video(spec, progress=Progress(not args.quiet, unit="frames"))
        write_tracked_table(res.table(pixels=args.pixels), res.provenance, out)
    except _Bad as e:
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
        rows = [("video", p["video"]), ("frames", f"{p['frames']} at {res.fps:g} fps ({p['frames'] / res.fps:.2f} s)"),
                ("method", f"{p['method']}, threshold {p['threshold']:g}"), ("scale", f"{res.mm_per_px:.5g} mm/px"),
                ("camera motion", f"{p['transform']} from {', '.join(spec.references)}; largest roll removed "
                                  f"{p['max_abs_roll_removed_deg']:.3f} deg")]
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


# ----------------------------------------------------------------------------- identify


def _identify_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="python -m pounding_sweep identify",
        description="Modal identification from a displacement table (e.g. one written by track): spectrum peaks, "
        "damping (half-power bandwidth; logarithmic decrement with --free-vibration) and mode-shape ratios per "
        "building; with --scene, the model update that matches each building's first frequency (paper sec. 3).",
    )
    p.add_argument("table", help="displacement table, .csv or .parquet, with a time column")
    p.add_argument("--columns", help="columns to analyse, comma-separated (default: every displacement column)")
    p.add_argument("--time-column", default="t_s", help="time column [s] (default t_s)")
    p.add_argument("--modes", type=int, default=3, help="modes per building (default 3)")
    p.add_argument("--fmin", type=float, default=0.0, help="lowest frequency considered [Hz]")
    p.add_argument("--fmax", type=float, help="highest frequency considered [Hz]")
    p.add_argument("--start", type=float, default=0.0, help="analyse from this time on [s] (e.g. after the release)")
    p.add_argument("--free-vibration", action="store_true", help="the record is free vibration: also logarithmic decrement")
    p.add_argument("--scene", help="scene whose buildings are updated to the identified first frequencies")
    p.add_argument("--update-damping", action="store_true", help="with --scene, also set damping_ratio to the identified one")
    p.add_argument("--out", help="with --scene: write the updated [buildingN] sections to this TOML file")
    return p


def _groups(columns) -> dict:
    from pounding_sweep.scene.video import floor_code

    g: dict = {}
    for c in columns:
        code = floor_code(c)
        b, f = (int(code[1:].split("f")[0]), int(code.split("f")[1])) if code else (0, 0)
        g.setdefault(b, []).append((f, c))
    return {b: [c for _, c in sorted(v)] for b, v in g.items()}


def identify_main(argv: list[str]) -> int:
    args = _identify_parser().parse_args(argv)
    import numpy as np

    from pounding_sweep.scene import ConfigError, load_scene
    from pounding_sweep.model.experiment import ExperimentError, read_table
    from pounding_sweep.identify.update import update_scene
    from pounding_sweep.identify.modes import identify

    src = args.table
    try:
        if Path(src).suffix.lower() in {".mkv", ".avi", ".mp4", ".mov", ".m4v", ".webm"}:
            raise _Bad(src, "identify reads a displacement table: track the video first", "python -m pounding_sweep track VIDEO")
        if args.modes < 1:
            raise _Bad(src, "--modes must be >= 1", args.modes)
        if args.out and not args.scene:
            raise _Bad(args.out, "--out writes updated buildings: it needs --scene", "--out without --scene")
        df, _ = read_table(src)
        if args.time_column not in df.columns:
            raise _Bad(src, f"no time column '{args.time_column}'", ", ".join(map(str, df.columns)))
        t = df[args.time_column].to_numpy(dtype=float)
        if t.size < 16 or not np.all(np.isfinite(t)) or np.any(np.diff(t) <= 0):
            raise _Bad(src, f"column '{args.time_column}' must hold at least 16 increasing finite times", f"{t.size} rows")
        dt = np.diff(t)
        if np.max(np.abs(dt / np.median(dt) - 1)) > 0.01:
            raise _Bad(src, f"column '{args.time_column}' is not uniformly sampled (within 1 %)", f"steps {dt.min():.6g} .. {dt.max():.6g} s")
        fs = 1.0 / float(np.median(dt))
        if args.columns:
            cols = _split(args.columns)
            for c in cols:
                if c not in df.columns:
                    raise _Bad(src, f"no column '{c}'", ", ".join(map(str, df.columns)))
        else:
            skip = {args.time_column, "frame", "table_in_camera_mm"}
            cols = [c for c in df.columns if c not in skip and not str(c).endswith(("_quality", "_px"))
                    and np.issubdtype(df[c].dtype, np.number)]
        if not cols:
            raise _Bad(src, "no displacement columns to analyse", ", ".join(map(str, df.columns)))
        for c in cols:
            x = df[c].to_numpy(dtype=float)
            if not np.all(np.isfinite(x)):
                raise _Bad(src, f"column '{c}' holds non-finite values", f"row {int(np.argmax(~np.isfinite(x))) + 1}")
        scene = load_scene(args.scene) if args.scene else None
        groups = _groups(cols)
        results = {}
        for b, cs in sorted(groups.items()):
            X = np.column_stack([df[c].to_numpy(dtype=float) for c in cs])
            try:
                results[b] = identify(X, fs, cs, n_modes=args.modes, fmin=args.fmin, fmax=args.fmax,
                                      free_vibration=args.free_vibration, start_s=args.start)
            except ValueError as e:
                raise _Bad(src, f"cannot identify {', '.join(cs)}", e) from None
        updates = []
        if scene is not None:
            targets = {b: r.modes[0].frequency_Hz for b, r in results.items() if b in (1, 2) and r.modes}
            if not targets:
                raise _Bad(src, "no building's floors among the columns (name them b1f3 or model1_floor3_mm) to update", ", ".join(cols))
            damp = None
            if args.update_damping:
                damp = {}
                for b in targets:
                    m = results[b].modes[0]
                    z = m.damping_log_decrement if m.damping_log_decrement is not None else m.damping_half_power
                    if z is not None and np.isfinite(z):
                        damp[b] = z
            updates = update_scene(scene, targets, damp)
        text = "".join(u.toml() + "\n" for u in updates)
        if args.out:
            out = Path(args.out)
            tmp = out.with_name(out.name + ".tmp")
            try:
                tmp.write_text(f"# written by python -m pounding_sweep identify {src}\n" + text, encoding="utf-8")
                os.replace(tmp, out)
            except OSError as e:
                tmp.unlink(missing_ok=True)
                raise _Bad(out, "cannot write", e.strerror or e) from None
    except _Bad as e:
        print(f"error: {e}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except (ConfigError, ExperimentError) as e:
        print(f"error: {e}", file=sys.stderr)
        return EXIT_BAD_INPUT
    for b, r in sorted(results.items()):
        head = f"building {b}" if b else "other columns"
        print(f"{head} ({', '.join(r.channels)}; shapes relative to {r.reference}; {fs:g} samples/s, "
              f"resolution {r.spectrum.resolution_Hz:.3g} Hz)")
        for k, m in enumerate(r.modes, 1):
            ld = "" if m.damping_log_decrement is None else f", log decrement {100 * m.damping_log_decrement:.2f} %"
            hp = "n/a" if not np.isfinite(m.damping_half_power) else f"{100 * m.damping_half_power:.2f} %"
            shape = ", ".join(f"{c} {v:+.3f}" for c, v in m.shape.items())
            print(f"  mode {k}: {m.frequency_Hz:.4f} Hz, damping half-power {hp}{ld}; shape {shape}")
        for n in r.notes:
            print(f"  note: {n}")
    if updates:
        print()
        for u in updates:
            print(f"{u.section}: f1 {u.f1_model_Hz:.4f} -> {u.f1_target_Hz:.4f} Hz: stiffness x {u.factor:.4f}")
        print()
        print(text if not args.out else f"updated sections written to {args.out}")
    return 0
