"""Reading and writing video with OpenCV (opencv-python-headless, FFMPEG backend), and the one
error class of the video package.

Facts this module relies on, measured on this project's machine (OpenCV 5.0, FFMPEG backend):

- FFV1 (.mkv or .avi) and HFYU (.avi) write and read back bit-exactly; FFV1 is the default for
  rendered videos. MJPG (.avi) and mp4v (.mp4) write but are lossy; H.264 ('avc1') cannot be
  written by this build.
- `CAP_PROP_FRAME_COUNT` comes from the container header and is unreliable (OpenCV docs of
  VideoCaptureProperties; opencv/opencv#15569 and many others): frames are counted by reading
  them. The header count is used only as the progress bar's total.
- `CAP_PROP_POS_MSEC` after a `read()` is the time stamp of the frame just read; it is used to
  refuse variable-frame-rate video, whose frame index is not a clock.

OpenCV is imported here and in the other modules of this package only: `import pounding_sweep`
and a sweep never import it.
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from pounding_sweep.errors import VideoError  # noqa: F401  (raised here; imported by callers from here too)

#: fourcc -> container suffix this machine writes it to; lossless ones first
CODECS = {"FFV1": ".mkv", "HFYU": ".avi", "MJPG": ".avi", "mp4v": ".mp4"}
LOSSLESS = {"FFV1", "HFYU"}
VIDEO_SUFFIXES = {".mkv", ".avi", ".mp4", ".mov", ".m4v", ".webm", ".mpg", ".mpeg", ".wmv", ".mts"}


def cv2_module():
    """Import OpenCV quietly (its own log lines would break the one-line error contract)."""
    # FFmpeg's own log lines ("EBML header parsing failed", ...) would break the one-line error
    # contract: quiet (AV_LOG_QUIET = -8) unless the user asked otherwise; read when FFmpeg starts
    os.environ.setdefault("OPENCV_FFMPEG_LOGLEVEL", "-8")
    try:
        import cv2
    except ImportError as e:  # pragma: no cover - cv2 is in the test extra
        raise VideoError("opencv", "the video commands need OpenCV: python -m pip install '.[video]'", e) from None
    try:
        cv2.utils.logging.setLogLevel(cv2.utils.logging.LOG_LEVEL_SILENT)
    except AttributeError:  # pragma: no cover - older builds
        pass
    return cv2


@dataclass(frozen=True)
class VideoInfo:
    path: str
    width: int
    height: int
    fps: float  # from the container (may be overridden by the caller)
    frame_count_hint: int  # header value: for progress only, never trusted
    fourcc: str
    backend: str


class VideoReader:
    """Frames of a video file, in order, as uint8 BGR arrays (OpenCV's convention).

    Opening checks that the file exists, that OpenCV can decode it, and that it has at least one
    frame; every failure is a VideoError naming the file.
    """

    def __init__(self, path: str | Path, fps: float | None = None):
        cv2 = cv2_module()
        self._cv2 = cv2
        p = Path(path)
        if not p.exists():
            raise VideoError(p, "video file not found")
        if not p.is_file():
            raise VideoError(p, "not a file")
        try:
            with open(p, "rb") as fh:
                fh.read(1)
        except OSError as e:
            raise VideoError(p, "cannot read the video file", e.strerror or e) from None
        cap = cv2.VideoCapture(str(p), cv2.CAP_FFMPEG)
        if not cap.isOpened():
            cap.release()
            raise VideoError(p, "not a video OpenCV can decode", f"{p.stat().st_size} bytes")
        self._cap = cap
        ok, first = cap.read()
        if not ok or first is None:
            cap.release()
            raise VideoError(p, "the video has no frames", "0 frames decoded")
        self._first = first
        self._first_ms = cap.get(cv2.CAP_PROP_POS_MSEC)
        code = int(cap.get(cv2.CAP_PROP_FOURCC))
        fourcc = "".join(chr((code >> (8 * i)) & 0xFF) for i in range(4)) if code > 0 else "?"
        container_fps = float(cap.get(cv2.CAP_PROP_FPS) or 0.0)
        use_fps = container_fps if fps is None else float(fps)
        if not (np.isfinite(use_fps) and use_fps > 0):
            cap.release()
            raise VideoError(p, "the video states no frame rate: give one (fps)", container_fps)
        self.info = VideoInfo(
            str(p),
            first.shape[1],
            first.shape[0],
            use_fps,
            max(int(cap.get(cv2.CAP_PROP_FRAME_COUNT) or 0), 0),
            fourcc.strip("\x00"),
            cap.getBackendName(),
        )
        self.container_fps = container_fps
        self.timestamps_ms: list[float] = []

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def close(self) -> None:
        if getattr(self, "_cap", None) is not None:
            self._cap.release()
            self._cap = None

    def frames(self) -> Iterator[np.ndarray]:
        """Every frame from the first, counted by reading (not from the header); time stamps of
        the container are collected in `timestamps_ms`."""
        if self._first is None:
            raise RuntimeError("frames() can be iterated once")
        cap, cv2 = self._cap, self._cv2
        first, self._first = self._first, None
        self.timestamps_ms = [self._first_ms]
        yield first
        shape = first.shape
        while True:
            ok, frame = cap.read()
            if not ok or frame is None:
                self._check_complete(len(self.timestamps_ms))
                return
            if frame.shape != shape:
                raise VideoError(
                    self.info.path,
                    f"frame {len(self.timestamps_ms)} changes size",
                    f"{frame.shape[1]}x{frame.shape[0]} after {shape[1]}x{shape[0]}",
                )
            self.timestamps_ms.append(cap.get(cv2.CAP_PROP_POS_MSEC))
            yield frame

    def _check_complete(self, decoded: int) -> None:
        """A file that stops decoding well before the frame count its container states was cut
        (a copy or recording interrupted): refuse it rather than track a shorter run. The count is
        only a header value, so a shortfall of 2 frames or 2 % is let pass."""
        hint = self.info.frame_count_hint
        if hint > 0 and decoded < hint - max(2, 0.02 * hint):
            raise VideoError(
                self.info.path,
                "the video ends early: truncated or damaged",
                f"{decoded} of the {hint} frames its container states decoded",
            )

    def check_uniform_timestamps(self, fps_container: float | None = None) -> None:
        """Refuse variable-frame-rate video (dropped or repeated frames make the frame index a
        false clock). Skipped when the container gives no usable time stamps."""
        ts = np.asarray(self.timestamps_ms, dtype=float)
        if ts.size < 3 or not np.all(np.isfinite(ts)):
            return
        d = np.diff(ts)
        if np.all(d == 0) or np.any(d < 0):  # no time stamps, or ones OpenCV cannot order: nothing to check
            return
        step = 1000.0 / (fps_container or self.container_fps or 1.0)
        dev = np.abs(d - step)
        if np.any(dev > 0.5 * step):
            k = int(np.argmax(dev > 0.5 * step)) + 1
            raise VideoError(
                self.info.path,
                f"variable frame rate: frame {k} is {d[k - 1]:.3f} ms after frame {k - 1}, "
                f"not {step:.3f} ms; re-encode at a constant rate (ffmpeg -fps_mode cfr)",
                f"{ts[k]:.3f} ms",
            )


def write_video(path: str | Path, frames, fps: float, codec: str = "FFV1", color: bool = True) -> Path:
    """Write uint8 frames (H x W x 3 BGR, or H x W grey with color=False) with a fourcc this
    machine can write; the file appears only when complete (written as <name>.tmp<suffix>, renamed)."""
    cv2 = cv2_module()
    path = Path(path)
    if codec not in CODECS:
        raise VideoError(path, f"codec must be one of {', '.join(CODECS)}", codec)
    tmp = path.with_name(path.stem + ".tmp" + path.suffix)  # the suffix picks the container
    it = iter(frames)
    first = next(it, None)
    if first is None:
        raise VideoError(path, "no frames to write", 0)
    h, w = first.shape[:2]
    writer = cv2.VideoWriter(str(tmp), cv2.CAP_FFMPEG, cv2.VideoWriter_fourcc(*codec), float(fps), (w, h), color)
    if not writer.isOpened():
        raise VideoError(path, "OpenCV cannot write this codec/container here", f"{codec} {path.suffix}")
    try:
        writer.write(first)
        for f in it:
            writer.write(f)
        writer.release()
        os.replace(tmp, path)
    except BaseException:
        writer.release()
        tmp.unlink(missing_ok=True)
        raise
    return path


def read_all(path: str | Path, channel: int | None = None) -> np.ndarray:
    """All frames of a (small) video as one array (n, H, W, 3), or one channel (n, H, W)."""
    with VideoReader(path) as r:
        out = [f if channel is None else f[:, :, channel].copy() for f in r.frames()]
    return np.stack(out)
