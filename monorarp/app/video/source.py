"""Frames with timestamps from a video file or a webcam (``cv2.VideoCapture``).

Timestamps (s, :attr:`monorarp.core.types.Frame.t`):

* **File**: the container's presentation time of each decoded frame
  (``CAP_PROP_POS_MSEC`` read after the frame is decoded). Where the backend
  gives none (not finite, negative, or not increasing after the first frame)
  the frame gets ``index / fps`` with the container's frame rate, and if even
  that does not increase, the previous time plus one frame period. The wall
  clock never enters: a file processed slowly or quickly gets the same times.
* **Webcam**: a monotonic capture clock, ``time.monotonic()`` read right after
  each ``read()`` returns, minus its value at the first frame (so the first
  frame is at t = 0). A live camera has no container; this is the time at
  which the frame reached the program, including driver latency.

Errors are :class:`VideoSourceError` (one line, a :class:`~monorarp.core.errors.UserError`):
a missing file, a file no backend can decode (random bytes, an empty file),
a webcam index that cannot be opened, and -- while iterating -- a file whose
decoding stops before the frame count its container stores (truncated or
corrupt data). Only MP4/MOV and AVI store a count; for other containers
(Matroska, WebM, MPEG-TS) OpenCV estimates it as duration x frame rate, which
an audio track longer than the video or a variable frame rate exceeds, so
their files are decoded to the end without that check.
"""

from __future__ import annotations

import math
import os
import re
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from types import TracebackType

import cv2
import numpy as np

from monorarp.core.errors import UserError
from monorarp.core.types import Frame

# Frames a container's announced count may exceed the decoded count by before
# the file is reported as truncated (counts from some containers are estimates).
COUNT_SLACK_FRAMES = 2
COUNT_SLACK_FRACTION = 0.01
# Box types that can open an ISO base media file (MP4, MOV, 3GP) at byte 4.
_ISO_BMFF_BOXES = (b"ftyp", b"moov", b"mdat", b"free", b"skip", b"wide", b"pnot")


class VideoSourceError(UserError, OSError):
    """A video input that cannot be opened or decoded."""


@dataclass(frozen=True)
class VideoInfo:
    """What the source reports before decoding: frame size (px), rate (Hz) and count (None if unknown)."""

    name: str
    width: int
    height: int
    fps: float | None
    frame_count: int | None
    is_webcam: bool
    frame_count_exact: bool = False   # stored by the container (MP4/MOV, AVI), not estimated


def parse_input(spec: str | int | Path) -> str | int:
    """An all-digit string (or an int) is a webcam index; anything else a file path."""
    if isinstance(spec, int):
        return spec
    s = str(spec)
    if not re.fullmatch(r"\d+", s.strip()):
        return s
    if len(s.strip().lstrip("0")) > 9:   # cv2 takes a C int; int() refuses 4300+ digits
        raise VideoSourceError(f"webcam {s.strip()[:20]}{'...' if len(s.strip()) > 20 else ''}: index out of "
                               f"range (a file whose name is all digits: write ./{s.strip()[:20]})")
    return int(s)


@contextmanager
def _quiet_opencv() -> Iterator[None]:
    """Silence OpenCV's and FFmpeg's own stderr chatter while opening (errors are ours to report)."""
    os.environ.setdefault("OPENCV_FFMPEG_LOGLEVEL", "-8")  # AV_LOG_QUIET; read when FFmpeg is first used
    log = getattr(getattr(cv2, "utils", None), "logging", None)
    previous = log.getLogLevel() if log is not None else None
    if log is not None:   # SILENT, not ERROR: a corrupt file makes OpenCV log "[ERROR:0] ... Could not find
        log.setLogLevel(log.LOG_LEVEL_SILENT)   # decoder" lines before the one line we print
    try:
        yield
    finally:
        if log is not None and previous is not None:
            log.setLogLevel(previous)


def stores_frame_count(path: str | Path) -> bool:
    """Whether the file's container stores its frame count (MP4/MOV family, AVI), judged by its first bytes."""
    try:
        with open(path, "rb") as f:
            head = f.read(12)
    except OSError:
        return False
    return head[4:8] in _ISO_BMFF_BOXES or (head[:4] == b"RIFF" and head[8:12] == b"AVI ")


def _positive(x: float) -> float | None:
    return float(x) if math.isfinite(x) and x > 0 else None


class VideoSource:
    """Iterate :class:`~monorarp.core.types.Frame` s (BGR uint8) from a file path or webcam index.

    Opening decodes the first frame, so an undecodable input fails here, before
    any output is created. Use as a context manager or call :meth:`close`.
    """

    def __init__(self, spec: str | int | Path) -> None:
        target = parse_input(spec)
        self.is_webcam = isinstance(target, int)
        self.name = f"webcam {target}" if self.is_webcam else str(target)
        if not self.is_webcam:
            path = Path(target)
            try:
                if not path.exists():
                    raise VideoSourceError(f"{path}: no such file")
                if not path.is_file():
                    raise VideoSourceError(f"{path}: not a file")
                if path.stat().st_size == 0:
                    raise VideoSourceError(f"{path}: empty file, not a video")
            except (OSError, ValueError) as e:   # name too long, NUL byte, permission on a parent, ...
                if isinstance(e, VideoSourceError):
                    raise
                raise VideoSourceError(f"{str(path)[:200]!r}: cannot open ({getattr(e, 'strerror', None) or e})") \
                    from None
        with _quiet_opencv():
            self._cap = cv2.VideoCapture(target)
            if not self._cap.isOpened():
                self._cap.release()
                raise VideoSourceError(f"webcam {target}: cannot open camera by index" if self.is_webcam
                                       else f"{target}: cannot open as a video (unknown format or corrupt file)")
            ok, first = self._cap.read()
        if not ok or first is None or first.ndim != 3 or first.shape[2] != 3:
            self._cap.release()
            raise VideoSourceError(f"{self.name}: no decodable frame")
        self._first: np.ndarray | None = first
        self._first_pos_ms = self._cap.get(cv2.CAP_PROP_POS_MSEC)
        self._first_clock = time.monotonic()
        count = self._cap.get(cv2.CAP_PROP_FRAME_COUNT)
        self.info = VideoInfo(
            name=self.name, width=int(first.shape[1]), height=int(first.shape[0]),
            fps=_positive(self._cap.get(cv2.CAP_PROP_FPS)),
            frame_count=None if self.is_webcam or not _positive(count) else int(round(count)),
            is_webcam=self.is_webcam,
            frame_count_exact=not self.is_webcam and stores_frame_count(target),
        )
        self.frames_read = 0

    # ------------------------------------------------------------------ frames
    def frames(self, max_frames: int | None = None) -> Iterator[Frame]:
        """Frames in decode order, index from 0; stops after ``max_frames`` if given.

        Raises :class:`VideoSourceError` if a file stops decoding before the
        frame count its container stores (MP4/MOV, AVI; only when not cut short
        by ``max_frames``). A source yields its frames once.
        """
        if self._first is None:
            raise ValueError(f"{self.name}: frames() can be iterated once, on an open source")
        prev_t = -math.inf
        index = 0
        while max_frames is None or index < max_frames:
            if index == 0:
                img, pos_ms, clock = self._first, self._first_pos_ms, self._first_clock
                self._first = None
            else:
                ok, img = self._cap.read()
                if not ok or img is None:
                    break
                pos_ms, clock = self._cap.get(cv2.CAP_PROP_POS_MSEC), time.monotonic()
            t = (clock - self._first_clock) if self.is_webcam else self._file_time(index, pos_ms, prev_t)
            prev_t = t
            self.frames_read = index + 1
            yield Frame(index=index, t=t, image=img)
            index += 1
        else:
            return
        self._check_complete(index)

    def _file_time(self, index: int, pos_ms: float, prev_t: float) -> float:
        """Container time of frame ``index`` (s); fallbacks in the module docstring."""
        t = pos_ms / 1000.0
        if math.isfinite(t) and t >= 0 and (index == 0 or t > prev_t):
            return t
        fps = self.info.fps
        if fps is None:
            raise VideoSourceError(f"{self.name}: frame {index} has no timestamp and the container "
                                   "gives no frame rate")
        t = index / fps
        return t if t > prev_t else prev_t + 1.0 / fps

    def _check_complete(self, decoded: int) -> None:
        """Refuse a file that decoded fewer frames than its container stores (module docstring)."""
        expected = self.info.frame_count
        if self.is_webcam or expected is None or not self.info.frame_count_exact:
            return
        if expected - decoded > max(COUNT_SLACK_FRAMES, COUNT_SLACK_FRACTION * expected):
            raise VideoSourceError(f"{self.name}: decoding failed after frame {decoded - 1} "
                                   f"(the container announces {expected} frames); file truncated or corrupt")

    # ------------------------------------------------------------- lifecycle
    def close(self) -> None:
        self._first = None
        self._cap.release()

    def __enter__(self) -> "VideoSource":
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.close()
