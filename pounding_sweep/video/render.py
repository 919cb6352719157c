"""Synthetic shake-table videos with known marker motion, for tests, demos and benchmarks.

A frame is a dark background with one bright spot per LED marker. Each spot is a circular
Gaussian of standard deviation `sigma_px` integrated exactly over every pixel's area,

    I(i, j) = P 2 pi s^2 [Phi((j + 1/2 - x) / s) - Phi((j - 1/2 - x) / s)] [Phi((i + 1/2 - y) / s) - Phi((i - 1/2 - y) / s)]

(Phi the normal CDF, via erf; pixel (i, j) covers x in [j - 1/2, j + 1/2], y in [i - 1/2, i + 1/2],
the pixel-centre convention of OpenCV's moments), so sub-pixel positions are the truth and no
sampling bias is built in. P > 255 grey levels saturates the LED's core, as white LEDs filmed for
tracking do (the paper's 0.99 threshold relies on it); P < 255 renders unsaturated LEDs.

Options: sensor noise (Gaussian, grey levels), motion blur (the sensor integrates the light over
the exposure: sub-frame positions averaged before clipping at 255), reflections (a dimmer spot at
an offset from a marker, in chosen frames), markers of the two buildings on their facing slab
edges (their spots merge when the buildings touch), camera shake (translation) and roll (rotation
about the image centre). The truth returned is the exposure-averaged image position of each
marker (what any centroid can at best see) and the displacement relative to the table in mm.

Motions come from the real model (`pounding_sweep.simulate`) or any function of time. Videos
are written lossless (FFV1 .mkv) by default and read back to check the codec.
"""

from __future__ import annotations

import re
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy.special import ndtr

from pounding_sweep.video.io import CODECS, LOSSLESS, VideoError, read_all, write_video

Motion = Callable[[np.ndarray], dict]
"""t [s] (array) -> {'table': table displacement [mm], '<floor marker>': displacement relative
to the table [mm], ...}, horizontal, positive toward building 2 (the model's +x)."""


# ----------------------------------------------------------------------------- layout


@dataclass(frozen=True)
class Layout:
    """Where the markers are at rest, in image pixels before any camera motion (y downward)."""

    names: tuple[str, ...]
    rest_px: np.ndarray  # (n, 2): x, y
    references: tuple[str, ...]  # markers fixed to the table
    mm_per_px: float
    positive_right: bool  # the model's +x (building 1 toward building 2) is image +x
    size: tuple[int, int]  # (width, height)

    def index(self, name: str) -> int:
        return self.names.index(name)

    @property
    def floor_markers(self) -> tuple[str, ...]:
        return tuple(n for n in self.names if n not in self.references)


def shake_table_layout(
    size=(320, 240),
    mm_per_px: float = 5.0,
    floors=(3, 3),
    story_height_mm: float = 336.0,
    slab_width_mm: float = 200.0,
    marker_inset_mm: float = 100.0,
    gap_mm: float = 0.0,
    reference_spacing_mm: float = 1400.0,
    table_margin_px: float = 14.0,
    positive_right: bool = True,
) -> Layout:
    """Two buildings side by side on the table (building 1 on the left when positive_right), one
    marker per floor `marker_inset_mm` from the slab's facing edge (100: slab centre; small: the
    two buildings' markers nearly meet), two table references `reference_spacing_mm` apart."""
    w, h = size
    s = mm_per_px
    xc = w / 2.0
    y_table = h - table_margin_px
    names, pos = (
        ["table_left", "table_right"],
        [[xc - reference_spacing_mm / 2 / s, y_table], [xc + reference_spacing_mm / 2 / s, y_table]],
    )
    side = {1: -1.0 if positive_right else 1.0, 2: 1.0 if positive_right else -1.0}
    for b, nf in zip((1, 2), floors):
        x = xc + side[b] * (gap_mm / 2 + marker_inset_mm) / s
        for f in range(1, nf + 1):
            names.append(f"b{b}f{f}")
            pos.append([x, y_table - f * story_height_mm / s])
    p = np.asarray(pos, dtype=float)
    if p[:, 1].min() < 4 or p[:, 0].min() < 4 or p[:, 0].max() > w - 5:
        raise ValueError(f"layout does not fit {w}x{h} at {mm_per_px} mm/px")
    return Layout(tuple(names), p, ("table_left", "table_right"), float(mm_per_px), positive_right, (int(w), int(h)))


# ----------------------------------------------------------------------------- motions


def harmonic_table(amplitude_mm: float, frequency_Hz: float) -> Callable[[np.ndarray], np.ndarray]:
    """The paper's table displacement x_g = A sin(2 pi f t) [mm]."""
    return lambda t: amplitude_mm * np.sin(2 * np.pi * frequency_Hz * np.asarray(t, dtype=float))


def motion_from_history(
    hist,
    table: Callable[[np.ndarray], np.ndarray] | None = None,
    columns: dict[str, str] | None = None,
    scale: float = 1e3,
) -> Motion:
    """Motion from time histories (a DataFrame with `t_s`; by default the `disp_b<i>f<j>_m` columns of
    `simulate`, in metres, scaled to mm), linearly interpolated in time; `table(t)` in mm (None: at rest)."""
    t0 = hist["t_s"].to_numpy(dtype=float)
    if columns is None:
        columns = {}
        for c in hist.columns:
            m = re.fullmatch(r"disp_(b\d+f\d+)_m", str(c))
            if m:
                columns[m.group(1)] = c
    data = {name: hist[col].to_numpy(dtype=float) * scale for name, col in columns.items()}

    def motion(t):
        t = np.asarray(t, dtype=float)
        out = {name: np.interp(t, t0, x) for name, x in data.items()}
        out["table"] = np.zeros_like(t) if table is None else table(t)
        return out

    return motion


def table_from_ground_acceleration(t_s: np.ndarray, acc_m_s2: np.ndarray) -> Callable[[np.ndarray], np.ndarray]:
    """Table displacement [mm] from the ground acceleration of a run that starts at rest
    (twice the cumulative trapezoid), as a function of time."""
    from scipy.integrate import cumulative_trapezoid

    v = cumulative_trapezoid(acc_m_s2, t_s, initial=0.0)
    x = cumulative_trapezoid(v, t_s, initial=0.0) * 1e3
    return lambda t: np.interp(np.asarray(t, dtype=float), t_s, x)


def write_pulse_record(
    path: str | Path, peak_m_s2: float = 3.0, frequency_Hz: float = 10.0, dt_s: float = 1e-3
) -> Path:
    """A ground-acceleration record of one full sine cycle (a knock: the table ends at rest, shifted by
    peak / (2 pi f^2)), as the two-column CSV the scenes read; runs padded with zeros give free vibration."""
    t = np.arange(0.0, 1.0 / frequency_Hz + dt_s / 2, dt_s)
    a = peak_m_s2 * np.sin(2 * np.pi * frequency_Hz * t)
    a[-1] = 0.0
    t = np.append(t, t[-1] + dt_s)
    a = np.append(a, 0.0)
    path = Path(path)
    np.savetxt(path, np.column_stack([t, a]), delimiter=",", header="time_s,acc_m_s2", comments="", fmt="%.9g")
    return path


# ----------------------------------------------------------------------------- options and truth


@dataclass(frozen=True)
class Reflection:
    """A dimmer copy of `marker`'s spot at `offset_px`, `brightness` times its peak, in `frames`
    (a slice, or a boolean array over frames; None: every frame)."""

    marker: str
    offset_px: tuple[float, float] = (0.0, 6.0)
    brightness: float = 0.5
    frames: object = None


@dataclass(frozen=True)
class RenderOptions:
    fps: float = 100.0
    sigma_px: float = 1.5  # Gaussian spot standard deviation
    peak: float = 700.0  # continuous peak above background [grey levels]; > 255 saturates the core
    background: float = 10.0
    noise: float = 0.0  # sensor noise RMS [grey levels], added after the optics
    exposure: float = 0.0  # exposure time / frame interval (motion blur); 0: instantaneous
    blur_samples: int = 9
    reflections: tuple[Reflection, ...] = ()
    shake_px: float = 0.0  # RMS of each component of a smooth random camera translation
    roll_deg: float = 0.0  # camera roll amplitude, about the image centre
    roll_frequency_Hz: float = 1.3
    color: bool = True  # white LEDs in BGR (the tracker reads the blue channel), else grey frames
    codec: str = "FFV1"
    seed: int = 0
    peaks: dict = field(default_factory=dict)  # marker name -> its own peak (e.g. one dim LED)
    hidden: tuple = ()  # (marker, frames) pairs: the marker is not drawn in those frames (occlusion)


@dataclass(frozen=True)
class RenderedVideo:
    path: Path
    layout: Layout
    fps: float
    t_s: np.ndarray  # frame times
    truth_px: np.ndarray  # (frames, markers, 2): exposure-averaged image position
    truth_rel_mm: dict  # floor marker -> exposure-averaged displacement relative to the table [mm]
    max_readback_error: int  # largest |written - read| grey level (0 for the lossless codecs)
    codec: str

    def truth(self, name: str) -> np.ndarray:
        return self.truth_px[:, self.layout.index(name)]


def _camera(t: np.ndarray, opts: RenderOptions, rng_phases) -> tuple[np.ndarray, np.ndarray]:
    """Camera roll angle [rad] and translation [px] at times t (smooth: sums of a few sinusoids)."""
    theta = np.deg2rad(opts.roll_deg) * np.sin(2 * np.pi * opts.roll_frequency_Hz * t)
    shift = np.zeros((t.size, 2))
    if opts.shake_px:
        freqs, phases = rng_phases
        for k in range(2):
            comp = sum(np.sin(2 * np.pi * f * t + p) for f, p in zip(freqs[k], phases[k]))
            shift[:, k] = opts.shake_px * np.sqrt(2.0 / len(freqs[k])) * comp
    return theta, shift


def world_positions(layout: Layout, motion: Motion, t: np.ndarray) -> np.ndarray:
    """(len(t), markers, 2) positions before the camera: rest + table motion (+ relative floor motion)."""
    m = motion(t)
    table = np.asarray(m.get("table", np.zeros_like(t)), dtype=float)
    sign = 1.0 if layout.positive_right else -1.0
    out = np.broadcast_to(layout.rest_px, (t.size, *layout.rest_px.shape)).copy()
    for i, name in enumerate(layout.names):
        dx = table if name in layout.references else table + np.asarray(m[name], dtype=float)
        out[:, i, 0] += sign * dx / layout.mm_per_px
    return out


def _spot(img: np.ndarray, x: float, y: float, sigma: float, peak: float) -> None:
    """Add one pixel-integrated Gaussian spot (separable: an outer product of erf differences)."""
    h, w = img.shape
    r = int(np.ceil(5 * sigma)) + 1
    x0, x1 = max(int(np.floor(x)) - r, 0), min(int(np.floor(x)) + r + 2, w)
    y0, y1 = max(int(np.floor(y)) - r, 0), min(int(np.floor(y)) + r + 2, h)
    if x0 >= x1 or y0 >= y1:
        return
    jx = np.arange(x0, x1 + 1) - 0.5
    iy = np.arange(y0, y1 + 1) - 0.5
    gx = np.diff(ndtr((jx - x) / sigma))
    gy = np.diff(ndtr((iy - y) / sigma))
    img[y0:y1, x0:x1] += (peak * 2 * np.pi * sigma**2) * np.outer(gy, gx)


def render_video(
    path: str | Path, layout: Layout, motion: Motion, n_frames: int, opts: RenderOptions = RenderOptions()
) -> RenderedVideo:
    """Render `n_frames` at `opts.fps`, write them with `opts.codec`, read the file back and check it."""
    path = Path(path)
    if opts.codec not in CODECS:
        raise VideoError(path, f"codec must be one of {', '.join(CODECS)}", opts.codec)
    rng = np.random.default_rng(opts.seed)
    shake_phases = (rng.uniform(2.0, 15.0, (2, 4)), rng.uniform(0, 2 * np.pi, (2, 4)))
    w, h = layout.size
    centre = np.array([(w - 1) / 2.0, (h - 1) / 2.0])
    t = np.arange(n_frames) / opts.fps
    ns = opts.blur_samples if opts.exposure > 0 else 1
    offs = (np.arange(ns) + 0.5) / ns - 0.5 if ns > 1 else np.zeros(1)
    sub_t = (t[:, None] + offs[None, :] * opts.exposure / opts.fps).ravel()
    world = world_positions(layout, motion, sub_t)
    theta, shift = _camera(sub_t, opts, shake_phases)
    c, s = np.cos(theta)[:, None], np.sin(theta)[:, None]
    d = world - centre
    img_pos = (
        np.stack([c * d[..., 0] - s * d[..., 1], s * d[..., 0] + c * d[..., 1]], axis=-1) + centre + shift[:, None, :]
    )
    img_pos = img_pos.reshape(n_frames, ns, len(layout.names), 2)
    truth_px = img_pos.mean(axis=1)
    rel = motion(sub_t)
    truth_rel = {n: np.asarray(rel[n], dtype=float).reshape(n_frames, ns).mean(axis=1) for n in layout.floor_markers}

    refl = []
    for r in opts.reflections:
        on = np.ones(n_frames, bool) if r.frames is None else np.zeros(n_frames, bool)
        if r.frames is not None:
            on[r.frames] = True
        refl.append((layout.index(r.marker), np.asarray(r.offset_px, float), r.brightness, on))
    peaks = np.array([opts.peaks.get(n, opts.peak) for n in layout.names], dtype=float)
    shown = np.ones((n_frames, len(layout.names)), bool)
    for name, frames_ in opts.hidden:
        shown[frames_, layout.index(name)] = False

    frames = []
    for k in range(n_frames):
        img = np.zeros((h, w))
        for j in range(ns):
            for i in range(len(layout.names)):
                if shown[k, i]:
                    x, y = img_pos[k, j, i]
                    _spot(img, x, y, opts.sigma_px, peaks[i] / ns)
            for i, off, b, on in refl:
                if on[k]:
                    x, y = img_pos[k, j, i] + off
                    _spot(img, x, y, opts.sigma_px, b * peaks[i] / ns)
        img += opts.background
        if opts.noise:
            img += rng.normal(0.0, opts.noise, img.shape)
        g = np.clip(np.rint(img), 0, 255).astype(np.uint8)
        frames.append(np.repeat(g[:, :, None], 3, axis=2) if opts.color else g)
    write_video(path, frames, opts.fps, opts.codec, color=opts.color)
    back = read_all(path, channel=0)
    if back.shape[0] != n_frames:
        raise VideoError(
            path, "the video does not read back with as many frames as written", f"{back.shape[0]} of {n_frames}"
        )
    written = np.stack([f[:, :, 0] if f.ndim == 3 else f for f in frames])
    err = int(np.abs(back.astype(np.int16) - written.astype(np.int16)).max())
    if opts.codec in LOSSLESS and err:
        raise VideoError(path, f"lossless codec {opts.codec} did not read back exactly", f"max error {err} grey levels")
    return RenderedVideo(path, layout, opts.fps, t, truth_px, truth_rel, err, opts.codec)
