"""LED-marker tracking: video -> sub-pixel marker positions -> floor displacement relative to the table.

The paper's recipe (Sekerci & Damci, sec. 3): the blue (B) channel as greyscale, a brightness
threshold of 0.99, removal of unrelated bright pixels, a median filter, and the centre of each
LED's white pixel area. It is kept as `method = "paper"` (binary centroids of
`cv2.connectedComponentsWithStats`). On saturated LEDs its binary centroid is locked to the pixel
grid (about 0.1 px RMS), and LEDs that do not saturate fall below the threshold and are lost.

`method = "weighted"` (default) keeps the paper's steps for *detecting* the markers (blue channel,
median filter, threshold above the background, connected components, small specks removed) and
*locates* each one sub-pixel: inside its detected blob, the pixels brighter than the background
plus `threshold` (0.2) times the marker's own peak above it form the core; its centroid weighted
by (I - T) is the position (the first moments of OpenCV's `cv2.moments` on the weighted core;
thresholded, intensity-weighted centroids as in Crocker & Grier, J. Colloid Interface Sci. 179
(1996) 298, compared in Cheezum et al., Biophys. J. 81 (2001) 2378). Weights that fall to zero at
the core's edge make the position vary smoothly as a pixel enters or leaves the core (less pixel
locking than binary or (I - background) weights), and a threshold relative to each marker's own
peak works for saturated and unsaturated LEDs alike.

Identities: each frame's cores are assigned to the markers by position, minimising the summed
distance to each marker's predicted position (constant velocity from its last two measured
frames) with `scipy.optimize.linear_sum_assignment` (Kuhn-Munkres; Crouse, IEEE TAES 52 (2016)
1679), gated at `max_step_px`. Checks per frame and marker (bit flags, QUALITY):

- lost: no core within the gate -> interpolated in time;
- merged: another marker's predicted position lies inside this marker's core (the buildings'
  facing markers touching) -> both interpolated, never re-assigned to each other;
- swap guard: two markers that sit side by side at rest appear in the opposite order -> both
  interpolated;
- reflection: another bright core not assigned to a marker lies within `reflection_radius_px`, or
  in the same detected blob -> flagged, the marker's own core is still measured;
- shape: the core's area exceeds `area_factor` times the marker's usual area, or its principal
  axes ratio exceeds `max_elongation` (a reflection or blur merged into the core) -> flagged.

OpenCV functions used (OpenCV docs, imgproc "Image Filtering", "Miscellaneous Image
Transformations" and "Structural Analysis and Shape Descriptors"): `medianBlur` (the paper's median
filter), `threshold`, `findContours` (outer contours: each bright area's bounding box; labelling the
whole frame with `connectedComponentsWithStats` costs 10x more at 640 x 480, so that is done inside
each box), `connectedComponentsWithStats` (cores and their areas) and `moments` (m00, m10, m01 and
the central second moments of the weighted core; centroid m10/m00, m01/m00, pixel centres at
integer coordinates, the renderer's convention).

Interpolated gaps (cubic spline through the measured frames) may be at most `max_gap_frames`
long; a longer one is an error. Displacement relative to the table: per frame, the least-squares
similarity (2 or more references; rotation, scale, translation: Umeyama, IEEE PAMI 13 (1991)
376, in the complex form of the 2-D case) that maps the reference markers onto their rest
positions is applied to every marker, which removes the table's own motion, camera shake and
camera roll (one reference removes translation only). The displacement is the component along
the line through the first and last reference at rest (the table's axis), in mm.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import os
import queue
import threading
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
from scipy.interpolate import CubicSpline
from scipy.optimize import linear_sum_assignment

from pounding_sweep.scene.channels import building_floor
from pounding_sweep.scene.video import VideoSpec, floor_code
from pounding_sweep.video.io import VideoError, VideoReader, cv2_module

QUALITY = {
    "lost": 1,  # no core found near the prediction: interpolated
    "merged": 2,  # its core holds another marker too (buildings touching): interpolated
    "reflection": 4,  # another bright core next to it (reflection?): measured on its own core
    "shape": 8,  # core too large or elongated: measured, but suspect
    "interpolated": 16,  # the value is interpolated in time
    "reference": 32,  # a reference marker was flagged (any of these) in this frame: the table frame is less sure
    "swap_guard": 64,  # appeared on the wrong side of its neighbour: interpolated
    "deblended": 128,  # its core touched a neighbour's and was split from it: measured, may lean toward it
}
_NOT_MEASURED = QUALITY["lost"] | QUALITY["merged"] | QUALITY["swap_guard"]
CHANNELS = {"blue": 0, "green": 1, "red": 2}
_BIG = 1e9
SPLIT_ELONGATION = 1.3  # cores more elongated than this are tested for two spots
DEBLEND_LEVELS = (0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9)  # fractions of (peak - T)


def describe_quality(code: int) -> str:
    """13 -> 'lost+reflection+shape'; 0 -> 'ok'."""
    words = [k for k, v in QUALITY.items() if code & v]
    return "+".join(words) if words else "ok"


@dataclass
class Candidates:
    """Bright cores of one frame (ROI coordinates)."""

    x: np.ndarray
    y: np.ndarray
    area: np.ndarray
    elong: np.ndarray
    flux: np.ndarray
    blob: np.ndarray
    split: np.ndarray  # bool: separated from a neighbour's core by deblending

    @classmethod
    def empty(cls):
        z = np.zeros(0)
        return cls(z, z, z, z, z, np.zeros(0, int), np.zeros(0, bool))

    def __len__(self):
        return self.x.size


@dataclass
class TrackResult:
    spec: VideoSpec
    names: tuple[str, ...]
    fps: float
    frame: np.ndarray  # video frame index
    x_px: np.ndarray  # (frames, markers) image position, gaps interpolated
    y_px: np.ndarray
    measured: np.ndarray  # bool (frames, markers): position measured in this frame (not interpolated)
    quality: np.ndarray  # uint8 bit flags (frames, markers)
    area_px: np.ndarray
    displacement_mm: np.ndarray  # (frames, floor markers), relative to the table
    table_in_camera_mm: np.ndarray
    mm_per_px: float
    roll_deg: np.ndarray  # camera roll removed per frame (0 with one reference)
    provenance: dict

    @property
    def t_s(self) -> np.ndarray:
        return self.frame / self.fps

    @property
    def floor_markers(self) -> tuple[str, ...]:
        return self.spec.floor_markers

    def index(self, name: str) -> int:
        return self.names.index(name)

    def table(self, pixels: bool = False) -> pd.DataFrame:
        """The tracked-displacement table: t_s, one column per floor marker [mm], then
        frame, <marker>_quality and table_in_camera_mm (ignored by scoring)."""
        d = {"t_s": self.t_s}
        for j, name in enumerate(self.floor_markers):
            d[name] = self.displacement_mm[:, j]
        d["frame"] = self.frame.astype(np.int64)
        for name in self.floor_markers:
            d[f"{name}_quality"] = self.quality[:, self.index(name)].astype(np.int64)
        for name in self.spec.references:
            d[f"{name}_quality"] = self.quality[:, self.index(name)].astype(np.int64)
        d["table_in_camera_mm"] = self.table_in_camera_mm
        if pixels:
            for i, name in enumerate(self.names):
                d[f"{name}_x_px"] = self.x_px[:, i]
                d[f"{name}_y_px"] = self.y_px[:, i]
        return pd.DataFrame(d)


class Tracker:
    """Frame-by-frame tracker: `process(frame)` for each frame in order, then `finish()`."""

    def __init__(self, spec: VideoSpec, fps: float, path: str = "<frames>"):
        self.cv2 = cv2_module()
        self.spec, self.fps, self.path = spec, float(fps), path
        self.names = spec.markers
        self.n = len(self.names)
        self.frac = spec.effective_threshold
        self.k = 0
        self.rows_x, self.rows_y, self.rows_q, self.rows_a = [], [], [], []
        self.ref_area = np.full(self.n, np.nan)
        self._areas: list[list[float]] = [[] for _ in range(self.n)]
        self.last = np.zeros((self.n, 2))
        self.last_k = np.zeros(self.n, int)
        self.vel = np.zeros((self.n, 2))
        self.off = np.zeros(2)
        self._pairs: list[tuple[int, int, float]] = []

    # ------------------------------------------------------------------ per frame

    def _channel(self, frame: np.ndarray) -> np.ndarray:
        s = self.spec
        if frame.ndim == 3:
            if s.channel == "grey":
                g = self.cv2.cvtColor(frame, self.cv2.COLOR_BGR2GRAY)
            else:
                g = frame[:, :, CHANNELS[s.channel]]
        else:
            g = frame
        if s.roi_px is not None:
            x0, y0, x1, y1 = s.roi_px
            g = g[y0:y1, x0:x1]
        return np.ascontiguousarray(g)

    def _init_levels(self, ch: np.ndarray) -> None:
        s = self.spec
        if ch.dtype != np.uint8:
            raise VideoError(self.path, "frames must be 8-bit", str(ch.dtype))
        self.bg = float(np.median(ch))
        self.noise = float(1.4826 * np.median(np.abs(ch.astype(np.float32) - self.bg)))
        above = s.detect_level if s.detect_level is not None else max(8.0 * self.noise, 15.0)
        self.level = int(min(round(self.bg + above), 254))
        self.paper_level = int(np.ceil(self.frac * 255.0 - 1e-9)) if s.method == "paper" else None

    def _candidates(self, ch: np.ndarray) -> Candidates:
        cv2, s = self.cv2, self.spec
        if s.method == "paper":
            # sec. 3: B channel > 0.99 (of full scale) -> binary, median filter, white areas' centres
            _, binary = cv2.threshold(ch, self.paper_level - 1, 255, cv2.THRESH_BINARY)
            if s.median_ksize > 1:
                binary = cv2.medianBlur(binary, s.median_ksize)
            n, _, st, cen = cv2.connectedComponentsWithStats(binary, connectivity=8)
            keep = np.nonzero(st[1:, cv2.CC_STAT_AREA] >= s.min_area_px)[0] + 1
            w, h = st[keep, cv2.CC_STAT_WIDTH], st[keep, cv2.CC_STAT_HEIGHT]
            el = np.maximum(w, h) / np.maximum(np.minimum(w, h), 1)
            return Candidates(
                cen[keep, 0],
                cen[keep, 1],
                st[keep, cv2.CC_STAT_AREA].astype(float),
                el.astype(float),
                st[keep, cv2.CC_STAT_AREA].astype(float),
                keep,
                np.zeros(keep.size, bool),
            )
        det = cv2.medianBlur(ch, s.median_ksize) if s.median_ksize > 1 else ch
        _, mask = cv2.threshold(det, self.level, 255, cv2.THRESH_BINARY)
        # blobs by their outer contours (much cheaper than labelling the whole frame), then each
        # blob's pixels by labelling its own bounding box
        contours, _ = cv2.findContours(mask, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
        H, W = ch.shape
        xs, ys, ar, el, fl, bl, sp = [], [], [], [], [], [], []
        for b, cnt in enumerate(contours):
            x0, y0, bw, bh = cv2.boundingRect(cnt)
            if bw * bh < s.min_area_px:
                continue
            xa, ya = max(x0 - 1, 0), max(y0 - 1, 0)
            xb, yb = min(x0 + bw + 1, W), min(y0 + bh + 1, H)
            nb, blab, bst, _ = cv2.connectedComponentsWithStats(mask[ya:yb, xa:xb], connectivity=8)
            own = blab[cnt[0, 0, 1] - ya, cnt[0, 0, 0] - xa]
            if own == 0 or bst[own, cv2.CC_STAT_AREA] < s.min_area_px:
                continue
            win = ch[ya:yb, xa:xb].astype(np.float32)
            inblob = blab == own
            peak = float(win[inblob].max())
            T = max(self.bg + self.frac * (peak - self.bg), float(self.level))
            core = ((win > T) & inblob).astype(np.uint8)
            m, lab, cst, _ = cv2.connectedComponentsWithStats(core, connectivity=8)
            for j in range(1, m):
                a = cst[j, cv2.CC_STAT_AREA]
                if a < s.min_area_px and m > 2:
                    continue  # a lone rim pixel of a blob that has a real core
                comp = lab == j
                got = self._measure(win, comp, T)
                if got is None:
                    continue
                parts = [(got, T, False)]
                if got[3] > SPLIT_ELONGATION and a >= 2 * s.min_area_px + 2:
                    parts = self._deblend(win, comp, T, float(win[comp].max())) or parts
                for (cx, cy, a2, e2, f2), _level, split in parts:
                    xs.append(cx + xa)
                    ys.append(cy + ya)
                    ar.append(float(a2))
                    el.append(e2)
                    fl.append(f2)
                    bl.append(b)
                    sp.append(split)
        return Candidates(
            np.array(xs), np.array(ys), np.array(ar), np.array(el), np.array(fl), np.array(bl, int), np.array(sp, bool)
        )

    def _measure(self, win: np.ndarray, mask: np.ndarray, T: float):
        """(x, y, area, elongation, flux) of the pixels in `mask` weighted by (I - T) (window coordinates)."""
        mo = self.cv2.moments(np.where(mask, win - np.float32(T), np.float32(0.0)))
        m00 = mo["m00"]
        if m00 <= 0:
            return None
        mu20, mu02, mu11 = mo["mu20"] / m00, mo["mu02"] / m00, mo["mu11"] / m00
        half = 0.5 * (mu20 + mu02)
        root = np.sqrt(max(0.25 * (mu20 - mu02) ** 2 + mu11**2, 0.0))
        lo = half - root
        elong = float(np.sqrt((half + root) / lo)) if lo > 1e-6 else 1.0
        return mo["m10"] / m00, mo["m01"] / m00, int(mask.sum()), elong, m00

    def _deblend(self, win: np.ndarray, comp: np.ndarray, T: float, peak: float):
        """Split a core holding two or more spots (multi-threshold deblending, as SExtractor does:
        Bertin & Arnouts, A&AS 117 (1996) 393): raise the threshold until the core falls apart, then
        measure each part halfway between that level and the peak, where the neighbour's tail
        weighs little. None if it never splits (one spot, or spots merged into one plateau)."""
        cv2, s = self.cv2, self.spec
        for f in DEBLEND_LEVELS:
            L = T + f * (peak - T)
            sub = ((win > L) & comp).astype(np.uint8)
            m, lab, st, _ = cv2.connectedComponentsWithStats(sub, connectivity=8)
            depth = max(4.0 * self.noise, 0.1 * (peak - T), 2.0)  # a real second spot rises well above the saddle
            big = [
                j for j in range(1, m) if st[j, cv2.CC_STAT_AREA] >= s.min_area_px and win[lab == j].max() - L >= depth
            ]
            if len(big) < 2:
                continue
            L2 = L + 0.5 * (peak - L)
            parts = []
            for j in big:
                part = self._grow(win, lab == j, comp, L2)
                got = self._measure(win, part, L2)
                if got is not None:
                    parts.append((got, L2, True))
            return parts if len(parts) >= 2 else None
        return None

    def _grow(self, win, seed, comp, L):
        """Pixels above L in `comp` connected to `seed` (the part of the core at level L)."""
        m, lab = self.cv2.connectedComponents(((win > L) & comp).astype(np.uint8), connectivity=8)
        ids = np.unique(lab[seed & (lab > 0)])
        return np.isin(lab, ids) if ids.size else seed

    def _initial(self, c: Candidates) -> np.ndarray:
        """Candidate index of each marker in the first frame."""
        s = self.spec
        if s.positions_px is not None:
            p = np.asarray(s.positions_px, float) - self.off
            gate = 2 * s.max_step_px
            D = (
                np.hypot(p[:, None, 0] - c.x[None, :], p[:, None, 1] - c.y[None, :])
                if len(c)
                else np.zeros((self.n, 0))
            )
            C = np.where(D <= gate, D, _BIG)
            idx = np.full(self.n, -1)
            if len(c):
                r, k = linear_sum_assignment(C)
                ok = C[r, k] < _BIG
                idx[r[ok]] = k[ok]
            for i in np.nonzero(idx < 0)[0]:
                near = (
                    f"; the nearest bright spot is {D[i].min():.1f} px away"
                    if len(c)
                    else "; no bright spot in the frame"
                )
                if len(c) and D[i].min() <= gate:
                    near += " but belongs to another marker (merged spots? start at a frame where they are apart)"
                raise VideoError(
                    self.path,
                    f"marker '{self.names[i]}' not found within {gate:g} px of its first-frame position"
                    f"{near} (frame {s.start_frame})",
                    f"x = {s.positions_px[i][0]:g}, y = {s.positions_px[i][1]:g}",
                )
            return idx
        if len(c) != self.n:
            raise VideoError(
                self.path,
                f"expected {self.n} markers in the first frame (frame {s.start_frame}), found {len(c)} "
                "bright spots: give first-frame positions, a region of interest (roi_px) or a detect_level",
                f"{len(c)} != {self.n}",
            )
        idx = np.full(self.n, -1)
        order = np.argsort(-c.y, kind="stable")
        nref = len(s.references)
        refs = sorted(order[:nref], key=lambda j: c.x[j])  # the lowest spots, left to right in the listed order
        for name, j in zip(s.references, refs):
            idx[self.names.index(name)] = j
        rest = [j for j in order[nref:]]
        codes = {m: floor_code(m) for m in s.floor_markers}
        buildings = sorted({building_floor(codes[m])[0] for m in codes})
        xs = sorted(rest, key=lambda j: c.x[j])
        groups = {}
        if len(buildings) == 1:
            groups[buildings[0]] = xs
        else:
            gaps = np.diff([c.x[j] for j in xs])
            cut = int(np.argmax(gaps)) + 1 if gaps.size else 0
            left_b, right_b = (
                (buildings[0], buildings[1]) if s.positive_direction == "right" else (buildings[1], buildings[0])
            )
            groups[left_b], groups[right_b] = xs[:cut], xs[cut:]
        for b in buildings:
            ms = sorted(
                [m for m in codes if building_floor(codes[m])[0] == b], key=lambda m: building_floor(codes[m])[1]
            )
            js = sorted(groups[b], key=lambda j: -c.y[j])  # floor 1 lowest
            if len(js) != len(ms):
                raise VideoError(
                    self.path,
                    f"automatic layout: building {b} has {len(ms)} markers but {len(js)} bright spots "
                    "sit in its column: give first-frame positions",
                    f"{len(js)} != {len(ms)}",
                )
            for m, j in zip(ms, js):
                idx[self.names.index(m)] = j
        return idx

    def process(self, frame: np.ndarray) -> None:
        ch = self._channel(frame)
        s = self.spec
        if self.k == 0:
            if s.roi_px is not None:
                x0, y0, x1, y1 = s.roi_px
                H, W = frame.shape[:2]
                if x1 > W or y1 > H:
                    raise VideoError(self.path, f"roi_px lies outside the {W}x{H} frame", list(s.roi_px))
                self.off = np.array([x0, y0], float)
            self._init_levels(ch)
        c = self._candidates(ch)
        q = np.zeros(self.n, np.uint8)
        pos = np.full((self.n, 2), np.nan)
        area = np.full(self.n, np.nan)
        if self.k == 0:
            idx = self._initial(c)
            pos[:, 0], pos[:, 1], area = c.x[idx], c.y[idx], c.area[idx]
            for i in range(self.n):  # side-by-side neighbours close enough to be confused: order must persist
                for j in range(i + 1, self.n):
                    dx, dy = pos[j] - pos[i]
                    if abs(dx) > 2 * abs(dy) and abs(dx) < 4 * s.max_step_px:
                        self._pairs.append((i, j, float(np.sign(dx))))
        else:
            pred = self.last + self.vel * np.minimum(self.k - self.last_k, 2)[:, None]
            idx = np.full(self.n, -1)
            if len(c):
                D = np.hypot(pred[:, None, 0] - c.x[None, :], pred[:, None, 1] - c.y[None, :])
                C = np.where(D <= s.max_step_px, D, _BIG)
                r, k = linear_sum_assignment(C)
                ok = C[r, k] < _BIG
                idx[r[ok]] = k[ok]
                req = np.sqrt(c.area / np.pi) + 0.5
                for i in range(self.n):  # merged: another marker's prediction inside this marker's core
                    if idx[i] < 0:
                        continue
                    for j in range(self.n):
                        if j == i or D[j, idx[i]] >= req[idx[i]]:
                            continue
                        if idx[j] >= 0 and D[j, idx[j]] < D[j, idx[i]]:
                            continue  # j has a better core of its own
                        q[i] |= QUALITY["merged"]
                        q[j] |= QUALITY["merged"]
                for i in np.nonzero(idx < 0)[0]:
                    if not q[i] & QUALITY["merged"]:
                        q[i] |= QUALITY["lost"]
                for i in np.nonzero(idx >= 0)[0]:
                    if q[i] & QUALITY["merged"]:
                        continue
                    j = idx[i]
                    pos[i] = c.x[j], c.y[j]
                    area[i] = c.area[j]
                    if c.split[j]:
                        q[i] |= QUALITY["deblended"]
                    ra = self.ref_area[i]
                    if (np.isfinite(ra) and c.area[j] > s.area_factor * ra) or c.elong[j] > s.max_elongation:
                        q[i] |= QUALITY["shape"]
                free = np.setdiff1d(np.arange(len(c)), idx[idx >= 0])
                for i in np.nonzero(idx >= 0)[0]:
                    j = idx[i]
                    for u in free:
                        if (
                            c.blob[u] == c.blob[j]
                            or np.hypot(c.x[u] - c.x[j], c.y[u] - c.y[j]) < s.reflection_radius_px
                        ):
                            q[i] |= QUALITY["reflection"]
                            break
                for i, j, sgn in self._pairs:
                    if np.isfinite(pos[i, 0]) and np.isfinite(pos[j, 0]) and np.sign(pos[j, 0] - pos[i, 0]) != sgn:
                        q[i] |= QUALITY["swap_guard"]
                        q[j] |= QUALITY["swap_guard"]
                pos[(q & _NOT_MEASURED) > 0] = np.nan
            else:
                q[:] = QUALITY["lost"]
        good = np.isfinite(pos[:, 0])
        gap = self.k - self.last_k
        self.vel[good] = np.where((gap[good] == 1)[:, None], pos[good] - self.last[good], 0.0) if self.k else 0.0
        self.last[good] = pos[good]
        self.last_k[good] = self.k
        for i in np.nonzero(good & (q == 0))[0]:
            if len(self._areas[i]) < 10:
                self._areas[i].append(area[i])
                self.ref_area[i] = float(np.median(self._areas[i]))
        self.rows_x.append(pos[:, 0] + self.off[0])
        self.rows_y.append(pos[:, 1] + self.off[1])
        self.rows_q.append(q)
        self.rows_a.append(area)
        self.k += 1

    # ------------------------------------------------------------------ whole record

    def finish(self, provenance: dict | None = None) -> TrackResult:
        s = self.spec
        nf = self.k
        if nf < 2:
            raise VideoError(self.path, "fewer than 2 frames to track", f"{nf} frame(s) from frame {s.start_frame}")
        X, Y = np.array(self.rows_x), np.array(self.rows_y)
        Q, A = np.array(self.rows_q, dtype=np.uint8), np.array(self.rows_a)
        frames = np.arange(nf) + s.start_frame
        measured = np.isfinite(X)
        for i, name in enumerate(self.names):
            bad = ~measured[:, i]
            if bad.all():
                raise VideoError(self.path, f"marker '{name}' is never found after the first frame", f"{nf} frames")
            run_start, longest, cur = 0, (0, 0), 0
            for k in range(nf):
                if bad[k]:
                    if cur == 0:
                        run_start = k
                    cur += 1
                    if cur > longest[1]:
                        longest = (run_start, cur)
                else:
                    cur = 0
            if longest[1] > s.max_gap_frames:
                k0, L = longest
                why = (
                    "merged with another marker"
                    if Q[k0 : k0 + L, i].any() and (Q[k0 : k0 + L, i] & QUALITY["merged"]).all()
                    else "lost"
                )
                raise VideoError(
                    self.path,
                    f"marker '{name}' {why} for {L} frames from frame {k0 + s.start_frame} "
                    f"(t = {(k0 + s.start_frame) / self.fps:.3f} s); at most max_gap_frames may be interpolated",
                    f"max_gap_frames = {s.max_gap_frames}",
                )
            if bad.any():
                X[:, i] = _fill(X[:, i])
                Y[:, i] = _fill(Y[:, i])
                Q[bad, i] |= QUALITY["interpolated"]
        ref_idx = [self.names.index(r) for r in s.references]
        ref_flagged = (Q[:, ref_idx] > 0).any(axis=1)
        Q[ref_flagged] |= QUALITY["reference"]

        Z = X + 1j * Y
        Zr = Z[:, ref_idx]
        nrest = min(s.rest_frames, nf)
        W = Zr[:nrest].mean(axis=0)
        mode = s.transform if len(ref_idx) >= 2 else "translation"
        zc = Zr - Zr.mean(axis=1, keepdims=True)
        wc = W - W.mean()
        if mode != "translation":
            spread = np.sqrt((np.abs(zc) ** 2).sum(axis=1))
            if spread.min() < 1.0:
                k = int(np.argmin(spread))
                raise VideoError(
                    self.path,
                    f"the references {', '.join(s.references)} are less than 1 px apart in frame "
                    f"{k + s.start_frame}: they cannot give the camera's rotation",
                    f"{spread[k]:.3g} px",
                )
        if mode == "translation":
            a = np.ones(nf, complex)
        else:
            a = (wc[None, :] * np.conj(zc)).sum(axis=1) / (np.abs(zc) ** 2).sum(axis=1)
            if mode == "rigid":
                a = a / np.abs(a)
        b = W.mean() - a * Zr.mean(axis=1)
        Qz = a[:, None] * Z + b[:, None]  # every marker in the table's rest frame
        rest = Qz[:nrest].mean(axis=0)
        if s.axis == "references" and len(ref_idx) >= 2:
            e = W[-1] - W[0]
            if abs(e.real) < 0.5 * abs(e):
                raise VideoError(
                    self.path,
                    "axis = 'references' needs the first and last reference side by side on the table "
                    "(use axis = 'image')",
                    f"{s.references[0]} -> {s.references[-1]}",
                )
            e = e / abs(e) * (1.0 if e.real > 0 else -1.0)
        else:
            e = 1.0 + 0j
        sign = 1.0 if s.positive_direction == "right" else -1.0
        if s.mm_per_px is not None:
            mm = float(s.mm_per_px)
        else:
            ia, ib = (self.names.index(m) for m in s.scale_markers)
            dpx = abs(rest[ia] - rest[ib])
            if dpx < 1.0:
                raise VideoError(
                    self.path,
                    f"scale markers {s.scale_markers[0]} and {s.scale_markers[1]} are less than 1 px apart",
                    f"{dpx:.3g} px",
                )
            mm = float(s.scale_distance_mm) / dpx
        floor_idx = [self.names.index(m) for m in s.floor_markers]
        disp = ((Qz[:, floor_idx] - rest[floor_idx]) * np.conj(e)).real * sign * mm
        table_cam = ((Zr - Zr[:nrest].mean(axis=0)) * np.conj(e)).real.mean(axis=1) * sign * mm
        roll = np.rad2deg(-np.angle(a))
        prov = dict(provenance or {})
        prov.update(
            {
                "what": "marker displacement tracked from video by pounding_sweep.video (relative to the table, mm)",
                "method": s.method,
                "threshold": self.frac,
                "background_grey": self.bg,
                "noise_grey": self.noise,
                "detect_level_grey": self.level,
                "fps": self.fps,
                "frames": int(nf),
                "start_frame": int(s.start_frame),
                "mm_per_px": mm,
                "transform": mode,
                "references": list(s.references),
                "axis_unit_vector": [float(e.real), float(e.imag)],
                "max_abs_roll_removed_deg": float(np.abs(roll).max()),
                "first_frame_positions_px": {n: [float(X[0, i]), float(Y[0, i])] for i, n in enumerate(self.names)},
                "reference_area_px": {
                    n: (None if not np.isfinite(v) else float(v)) for n, v in zip(self.names, self.ref_area)
                },
                "quality_bits": QUALITY,
                "flagged_frames": {
                    n: {k: int(((Q[:, i] & v) > 0).sum()) for k, v in QUALITY.items()} for i, n in enumerate(self.names)
                },
                "spec": _jsonable(dataclasses.asdict(s)),
            }
        )
        return TrackResult(s, self.names, self.fps, frames, X, Y, measured, Q, A, disp, table_cam, mm, roll, prov)


def _fill(x: np.ndarray) -> np.ndarray:
    """Fill NaN gaps: cubic spline through the measured samples inside, nearest value at the ends."""
    t = np.arange(x.size)
    good = np.isfinite(x)
    out = x.copy()
    tg, xg = t[good], x[good]
    inside = ~good & (t > tg[0]) & (t < tg[-1])
    if inside.any():
        out[inside] = CubicSpline(tg, xg)(t[inside]) if tg.size >= 4 else np.interp(t[inside], tg, xg)
    out[t < tg[0]] = xg[0]
    out[t > tg[-1]] = xg[-1]
    return out


def _jsonable(d):
    return json.loads(json.dumps(d, default=str))


def track_frames(
    frames, spec: VideoSpec, fps: float, path: str = "<frames>", progress=None, total: int = 0
) -> TrackResult:
    """Track an iterable of frames (uint8 BGR or grey), e.g. already decoded ones."""
    tr = Tracker(spec, fps, path)
    n = 0
    for f in frames:
        tr.process(f)
        n += 1
        if progress is not None:
            progress(n, max(total, n))
    if progress is not None:
        progress(n, n)
    return tr.finish()


def prefetch(frames, depth: int = 16):
    """Yield from `frames` while a thread decodes ahead (OpenCV releases the GIL while decoding, so
    decoding and tracking overlap on two cores). Errors of the decoder are raised here, and the
    thread is stopped and joined before this generator ends, however it ends."""
    q: queue.Queue = queue.Queue(maxsize=depth)
    stop = threading.Event()
    done = object()
    errors: list[BaseException] = []

    def hand_over_end():
        """The end-of-frames marker to the consumer (unless it stopped reading)."""
        while True:
            try:
                q.put(done, timeout=0.05)
                return
            except queue.Full:
                if stop.is_set():
                    return

    def run():
        try:
            for f in frames:
                while not stop.is_set():
                    try:
                        q.put(f, timeout=0.05)
                        break
                    except queue.Full:
                        continue
                if stop.is_set():
                    return
        except BaseException as e:  # handed to the consumer
            errors.append(e)
        finally:
            hand_over_end()

    th = threading.Thread(target=run, name="video-decode", daemon=True)
    th.start()
    try:
        while True:
            f = q.get()
            if f is done:
                break
            yield f
    finally:
        stop.set()
        while th.is_alive():
            try:
                q.get(timeout=0.05)
            except queue.Empty:
                pass
        th.join()
    if errors:
        raise errors[0]


def track_video(spec: VideoSpec, progress=None) -> TrackResult:
    """Open, read (frames counted by reading) and track the video of `spec`."""
    import pounding_sweep

    with VideoReader(spec.path, fps=spec.fps) as reader:
        info = reader.info
        cv2 = cv2_module()

        def frames():
            for k, f in enumerate(reader.frames()):
                if k < spec.start_frame:
                    continue
                if spec.max_frames is not None and k >= spec.start_frame + spec.max_frames:
                    return
                yield f

        hint = max(info.frame_count_hint - spec.start_frame, 0)
        if spec.max_frames is not None:
            hint = min(hint, spec.max_frames) if hint else spec.max_frames
        tr = Tracker(spec, info.fps, info.path)
        n = 0
        for f in prefetch(frames()):
            tr.process(f)
            n += 1
            if progress is not None:
                progress(n, max(hint, n))
        if progress is not None:
            progress(n, n)
        if n == 0:
            raise VideoError(info.path, "no frames at or after start_frame", f"start_frame = {spec.start_frame}")
        reader.check_uniform_timestamps()
        prov = {
            "video": info.path,
            "video_size_px": [info.width, info.height],
            "video_fourcc": info.fourcc,
            "video_backend": info.backend,
            "container_fps": reader.container_fps,
            "opencv_version": cv2.__version__,
            "pounding_sweep_version": pounding_sweep.__version__,
        }
        return tr.finish(prov)


def write_tracked_table(df: pd.DataFrame, provenance: dict, out: str | Path) -> Path:
    """CSV or Parquet by suffix (Parquet keeps the provenance in its key-value metadata); written as
    <out>.tmp and renamed, so a failure leaves no half-written table."""
    out = Path(out)
    suffix = out.suffix.lower()
    if suffix not in (".csv", ".parquet"):
        raise VideoError(out, "the output table must be .csv or .parquet", out.suffix or "no suffix")
    tmp = out.with_name(out.name + ".tmp")
    try:
        if suffix == ".parquet":
            import pyarrow as pa
            import pyarrow.parquet as pq

            t = pa.Table.from_pandas(df, preserve_index=False)
            t = t.replace_schema_metadata({b"tracked_video": b"true", b"provenance": json.dumps(provenance).encode()})
            pq.write_table(t, tmp)
        else:
            df.to_csv(tmp, index=False, float_format="%.6f")
        os.replace(tmp, out)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    return out


def cached_track(spec: VideoSpec, cache_dir: Path, progress=None):
    """(table, provenance), from `cache_dir` when the same video (SHA-256) was tracked with the same spec."""
    h = hashlib.sha256()
    with open(spec.path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    key = hashlib.sha256(
        (h.hexdigest() + json.dumps(_jsonable(dataclasses.asdict(spec)), sort_keys=True)).encode()
    ).hexdigest()[:20]
    path = Path(cache_dir) / f"{Path(spec.path).stem}.{key}.tracked.parquet"
    if path.is_file():
        import pyarrow.parquet as pq

        t = pq.read_table(path)
        return t.to_pandas(), json.loads(t.schema.metadata[b"provenance"])
    res = track_video(spec, progress)
    df, prov = res.table(), res.provenance
    Path(cache_dir).mkdir(parents=True, exist_ok=True)
    write_tracked_table(df, prov, path)
    return df, prov


def tracked_table(spec: VideoSpec, progress=None, cache_dir: str | Path | None = None):
    """Track the video of `spec`; return (DataFrame in the tracked-table format, provenance dict).

    Raises pounding_sweep.video.io.VideoError (one line: file, what, value) for a missing or
    unreadable video, no frames, markers not found, or a marker lost for too long.
    With `cache_dir`, the table is kept as Parquet named by the video's SHA-256 and the spec, and
    read back when both are unchanged.
    """
    if cache_dir is not None:
        return cached_track(spec, Path(cache_dir), progress)
    result = track_video(spec, progress=progress)
    return result.table(), result.provenance
