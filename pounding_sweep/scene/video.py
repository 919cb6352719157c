"""The `[experiment.video]` scene section: a shake-table video whose LED markers are tracked into the
experiment table (instead of `[experiment] table`). Plain data and its checks only: OpenCV is never
imported here (pounding_sweep.video tracks; `python -m pounding_sweep track --help` lists the same keys).

The tracked table is the README's tracked-displacement format: `t_s` (frame / fps, uniform), one
column per floor marker (displacement relative to the table, mm), plus `frame`, `<marker>_quality`
(bit flags, video.tracker.QUALITY) and `table_in_camera_mm`, which scoring ignores.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, fields
from pathlib import Path

from pounding_sweep.errors import ConfigError
from pounding_sweep.scene.files import resolve
from pounding_sweep.scene.keys import check_keys

FLOOR_NAME = re.compile(r"(?:b(\d+)f(\d+)|model(\d+)_floor(\d+))(?:_mm)?")


def floor_code(name: str) -> str | None:
    """'b1f3', 'b1f3_mm', 'model1_floor3', 'model1_floor3_mm' -> 'b1f3'; anything else -> None."""
    m = FLOOR_NAME.fullmatch(name)
    if not m:
        return None
    b, f = (m.group(1), m.group(2)) if m.group(1) else (m.group(3), m.group(4))
    return f"b{int(b)}f{int(f)}"


@dataclass(frozen=True)
class VideoSpec:
    """What to track in a video and how (the `[experiment.video]` keys; `python -m pounding_sweep
    track --help` has the same options)."""

    path: str  # video file (absolute once parsed)
    markers: tuple[str, ...]  # every marker, references included; floor markers become table columns
    references: tuple[str, ...]  # markers fixed to the shaking table (>= 2 also removes camera roll)
    positions_px: tuple[tuple[float, float], ...] | None = (
        None  # first-frame (x, y) of each marker; None: automatic layout
    )
    mm_per_px: float | None = None  # image scale; or scale_markers + scale_distance_mm
    scale_markers: tuple[str, ...] | None = None  # two markers a known distance apart
    scale_distance_mm: float | None = None
    fps: float | None = None  # override the container's frame rate
    start_frame: int = 0
    max_frames: int | None = None
    roi_px: tuple[int, int, int, int] | None = None  # x0, y0, x1, y1 (x1, y1 exclusive)
    channel: str = "blue"  # the paper's B component; 'green', 'red' or 'grey'
    method: str = "weighted"  # 'weighted' (sub-pixel, this package) or 'paper' (0.99 binary, sec. 3)
    threshold: float | None = (
        None  # weighted: fraction of each marker's own peak above background (0.2); paper: of full scale (0.99)
    )
    detect_level: float | None = (
        None  # grey levels above the background that detect a marker (default: from the first frame's noise)
    )
    median_ksize: int = 3  # the paper's median filter, on the detection image
    min_area_px: int = 2  # smaller bright specks are unrelated pixels
    max_step_px: float = 10.0  # largest move of a marker from its predicted position between frames
    max_gap_frames: int = 10  # a marker lost (or merged) for longer is an error; shorter gaps are interpolated
    area_factor: float = 1.8  # a marker core larger than this times its usual area is flagged (shape)
    max_elongation: float = 1.6  # ... or more elongated than this (ratio of principal axes)
    reflection_radius_px: float = 12.0  # other bright spots this close to a marker are flagged as reflections
    positive_direction: str = "right"  # image direction of the model's +x (building 1 toward building 2)
    axis: str = "references"  # displacement along the line through the first and last reference, or 'image' x
    transform: str = "similarity"  # camera motion removed with references: 'similarity', 'rigid' or 'translation'
    rest_frames: int = 1  # frames averaged as the rest position (from the first tracked frame)

    @property
    def floor_markers(self) -> tuple[str, ...]:
        return tuple(m for m in self.markers if m not in self.references)

    def default_channels(self) -> dict[str, str]:
        """Table column -> model floor for every marker named by a floor code."""
        return {m: floor_code(m) for m in self.floor_markers if floor_code(m)}

    @property
    def effective_threshold(self) -> float:
        if self.threshold is not None:
            return self.threshold
        return 0.99 if self.method == "paper" else 0.2


SECTION = "[experiment.video]"
_KEYS = {f.name for f in fields(VideoSpec)} - {"positions_px"}


def _err(key, value, what):
    return ConfigError(f"{SECTION} {key} = {value!r}: {what}")


def _num(table, key, *, positive=False, minimum=None, integer=False, default=None, maximum=None):
    if key not in table:
        return default
    v = table[key]
    if isinstance(v, bool) or not isinstance(v, (int, float)) or (integer and not isinstance(v, int)):
        raise _err(key, v, "expected an integer" if integer else "expected a number")
    if not math.isfinite(v):
        raise _err(key, v, "must be finite")
    if positive and v <= 0:
        raise _err(key, v, "must be > 0")
    if minimum is not None and v < minimum:
        raise _err(key, v, f"must be >= {minimum}")
    if maximum is not None and v > maximum:
        raise _err(key, v, f"must be <= {maximum}")
    return int(v) if integer else float(v)


def _choice(table, key, options, default):
    v = table.get(key, default)
    if v not in options:
        raise _err(key, v, "expected " + " or ".join(repr(o) for o in options))
    return v


def _names(table, key, value) -> tuple[str, ...]:
    if not isinstance(value, list) or not all(isinstance(x, str) and x for x in value):
        raise _err(key, value, "expected a list of marker names")
    if len(set(value)) != len(value):
        dup = next(x for x in value if value.count(x) > 1)
        raise _err(key, value, f"marker '{dup}' is listed twice")
    return tuple(value)


def parse_video_section(table: dict, base_dir: Path) -> VideoSpec:
    """Check an `[experiment.video]` table and resolve its path against the scene's folder."""
    if not isinstance(table, dict):
        raise ConfigError(f"'video' must be a table {SECTION}, got {table!r}")
    check_keys(table, _KEYS, SECTION)
    if "path" not in table:
        raise ConfigError(f"missing key 'path' in {SECTION} (the video file to track)")
    path = table["path"]
    if not isinstance(path, str) or not path or "\x00" in path:
        raise _err("path", path, "expected a file name")
    if "markers" not in table:
        raise ConfigError(f"missing key 'markers' in {SECTION} (names, or name = [x, y] first-frame pixel positions)")
    raw_m = table["markers"]
    positions = None
    if isinstance(raw_m, dict):
        if not raw_m:
            raise _err("markers", raw_m, "expected at least one marker")
        names, pos = [], []
        for n, xy in raw_m.items():
            ok = (
                isinstance(xy, list)
                and len(xy) == 2
                and all(
                    isinstance(c, (int, float)) and not isinstance(c, bool) and math.isfinite(c) and c >= 0 for c in xy
                )
            )
            if not ok:
                raise ConfigError(
                    f"{SECTION} markers.{n} = {xy!r}: expected [x, y], the marker's pixel position in the first frame"
                )
            names.append(str(n))
            pos.append((float(xy[0]), float(xy[1])))
        markers, positions = tuple(names), tuple(pos)
    else:
        markers = _names(table, "markers", raw_m)
        if not markers:
            raise _err("markers", raw_m, "expected at least one marker")
    refs = _names(table, "references", table.get("references", []))
    if not refs:
        raise _err(
            "references",
            list(refs),
            "name at least one marker fixed to the table (two or more also remove camera roll)",
        )
    for r in refs:
        if r not in markers:
            raise _err("references", list(refs), f"'{r}' is not one of the markers")
    if len(refs) == len(markers):
        raise _err("references", list(refs), "every marker is a reference: no floor is tracked")
    for m in markers:
        if m in ("t_s", "frame", "table_in_camera_mm") or m.endswith("_quality"):
            raise _err("markers", list(markers), f"'{m}' is a reserved column name")
    if positions is None:
        others = [m for m in markers if m not in refs and floor_code(m) is None]
        if others:
            raise _err(
                "markers",
                list(markers),
                f"automatic layout needs floor names (b1f3 or model1_floor3_mm), not '{others[0]}': "
                "give first-frame positions instead, markers = {name = [x, y], ...}",
            )
        codes = [floor_code(m) for m in markers if m not in refs]
        if len(set(codes)) != len(codes):
            raise _err("markers", list(markers), "two markers name the same floor")
    mm = _num(table, "mm_per_px", positive=True)
    sm = table.get("scale_markers")
    sd = _num(table, "scale_distance_mm", positive=True)
    if sm is not None:
        sm = _names(table, "scale_markers", sm)
        if len(sm) != 2 or any(x not in markers for x in sm):
            raise _err("scale_markers", list(sm), "expected two of the markers")
    if (mm is None) == (sm is None or sd is None) or (mm is not None and (sm is not None or sd is not None)):
        raise ConfigError(
            f"{SECTION}: give the image scale either as mm_per_px or as scale_markers = [a, b] with "
            f"scale_distance_mm (got mm_per_px = {mm!r}, scale_markers = {sm!r}, scale_distance_mm = {sd!r})"
        )
    roi = table.get("roi_px")
    if roi is not None:
        if not (
            isinstance(roi, list)
            and len(roi) == 4
            and all(isinstance(v, int) and not isinstance(v, bool) and v >= 0 for v in roi)
            and roi[0] < roi[2]
            and roi[1] < roi[3]
        ):
            raise _err("roi_px", roi, "expected [x0, y0, x1, y1], integers with x0 < x1 and y0 < y1")
        roi = tuple(roi)
    method = _choice(table, "method", ("weighted", "paper"), "weighted")
    thr = _num(table, "threshold", positive=True, maximum=1.0)
    ksize = _num(table, "median_ksize", integer=True, minimum=1, default=3)
    if ksize % 2 == 0:
        raise _err("median_ksize", ksize, "must be odd (1: no median filter)")
    p = Path(path)
    return VideoSpec(
        path=str(resolve(base_dir / p)) if not p.is_absolute() else str(p),
        markers=markers,
        references=refs,
        positions_px=positions,
        mm_per_px=mm,
        scale_markers=sm,
        scale_distance_mm=sd,
        fps=_num(table, "fps", positive=True),
        start_frame=_num(table, "start_frame", integer=True, minimum=0, default=0),
        max_frames=_num(table, "max_frames", integer=True, minimum=2),
        roi_px=roi,
        channel=_choice(table, "channel", ("blue", "green", "red", "grey"), "blue"),
        method=method,
        threshold=thr,
        detect_level=_num(table, "detect_level", positive=True, maximum=254.0),
        median_ksize=ksize,
        min_area_px=_num(table, "min_area_px", integer=True, minimum=1, default=2),
        max_step_px=_num(table, "max_step_px", positive=True, default=10.0),
        max_gap_frames=_num(table, "max_gap_frames", integer=True, minimum=0, default=10),
        area_factor=_num(table, "area_factor", minimum=1.0, default=1.8),
        max_elongation=_num(table, "max_elongation", minimum=1.0, default=1.6),
        reflection_radius_px=_num(table, "reflection_radius_px", positive=True, default=12.0),
        positive_direction=_choice(table, "positive_direction", ("right", "left"), "right"),
        axis=_choice(table, "axis", ("references", "image"), "references"),
        transform=_choice(table, "transform", ("similarity", "rigid", "translation"), "similarity"),
        rest_frames=_num(table, "rest_frames", integer=True, minimum=1, default=1),
    )
