"""H.264 ``.mp4`` writing (and reading back, for tests and tools).

:class:`VideoWriter` pipes BGR uint8 frames to the ffmpeg binary bundled with
``imageio-ffmpeg`` (libx264, ``yuv420p`` so that every common player opens the
file, ``+faststart``). It is single-threaded and bit-exact (no encoder/muxer
version strings, no creation time), so identical frames give an identical file
for a given ffmpeg build. Odd frame sizes are padded by one replicated row /
column at the bottom / right (yuv420p needs even sizes); pixel coordinates of
the original image are unchanged. If no ffmpeg with libx264 can be found it
falls back to OpenCV's ``mp4v`` (MPEG-4 part 2) writer.
"""

from __future__ import annotations

import functools
import logging
import re
import subprocess
from collections.abc import Iterator
from dataclasses import dataclass
from fractions import Fraction
from pathlib import Path
from types import TracebackType

import cv2
import numpy as np

log = logging.getLogger(__name__)


@functools.lru_cache(maxsize=1)
def _ffmpeg_h264() -> str | None:
    """Path of the ffmpeg (bundled with imageio-ffmpeg) if it has libx264, else None."""
    try:
        import imageio_ffmpeg

        exe = imageio_ffmpeg.get_ffmpeg_exe()
        encoders = subprocess.run([exe, "-hide_banner", "-encoders"], capture_output=True,
                                  text=True, timeout=30).stdout
    except Exception:  # noqa: BLE001 - missing package or binary: fall back
        return None
    return exe if re.search(r"\blibx264\b", encoders) else None


class VideoWriter:
    """Write BGR uint8 frames of size ``(width, height)`` at ``fps`` to an H.264 ``.mp4``.

    ``crf`` is x264's constant rate factor (0 = lossless luma, 18 = visually
    lossless, 23 = x264's default); ``preset`` is x264's speed/size trade-off.
    Use as a context manager; :meth:`close` finishes the file.
    """

    def __init__(self, path: str | Path, fps: float, size: tuple[int, int], *,
                 crf: int = 18, preset: str = "fast", backend: str = "auto") -> None:
        self.path = Path(path)
        self.width, self.height = int(size[0]), int(size[1])
        if self.width <= 0 or self.height <= 0:
            raise ValueError(f"frame size must be positive, got {size}")
        if not fps > 0:
            raise ValueError(f"fps must be positive, got {fps}")
        if not 0 <= crf <= 51:
            raise ValueError(f"crf must be in 0..51, got {crf}")
        self.fps = fps
        self.count = 0
        self._pad = (self.height % 2, self.width % 2)  # rows, cols added at bottom / right
        exe = _ffmpeg_h264() if backend in ("auto", "ffmpeg") else None
        if exe is None and backend == "ffmpeg":
            raise RuntimeError("no ffmpeg binary found (install imageio-ffmpeg)")
        self._gen = None
        self._cv: cv2.VideoWriter | None = None
        if exe is not None:
            import imageio_ffmpeg

            enc_size = (self.width + self._pad[1], self.height + self._pad[0])
            self._gen = imageio_ffmpeg.write_frames(
                str(self.path), enc_size, pix_fmt_in="bgr24", pix_fmt_out="yuv420p",
                fps=Fraction(fps).limit_denominator(1001), quality=None, codec="libx264",
                macro_block_size=1, ffmpeg_log_level="error",
                output_params=["-crf", str(int(crf)), "-preset", preset, "-threads", "1",
                               "-movflags", "+faststart", "-map_metadata", "-1",
                               "-fflags", "+bitexact", "-flags:v", "+bitexact"],
            )
            self._gen.send(None)
            self.backend = "ffmpeg-libx264"
        else:
            log.warning("imageio-ffmpeg not available; writing %s with OpenCV mp4v", self.path)
            self._cv = cv2.VideoWriter(str(self.path), cv2.VideoWriter_fourcc(*"mp4v"), float(fps),
                                       (self.width, self.height))
            if not self._cv.isOpened():
                raise RuntimeError(f"{self.path}: OpenCV cannot open an mp4v writer")
            self.backend = "opencv-mp4v"

    def write(self, image_bgr: np.ndarray) -> None:
        """Append one frame: (height, width, 3) uint8, BGR."""
        img = np.asarray(image_bgr)
        if img.shape != (self.height, self.width, 3) or img.dtype != np.uint8:
            raise ValueError(f"expected a ({self.height}, {self.width}, 3) uint8 BGR frame, "
                             f"got {img.shape} {img.dtype}")
        if self._gen is not None:
            if any(self._pad):
                img = np.pad(img, ((0, self._pad[0]), (0, self._pad[1]), (0, 0)), mode="edge")
            self._gen.send(np.ascontiguousarray(img).tobytes())
        elif self._cv is not None:
            self._cv.write(img)
        else:
            raise ValueError(f"{self.path}: writer is closed")
        self.count += 1

    def close(self) -> None:
        """Finish the file (waits for the encoder)."""
        if self._gen is not None:
            gen, self._gen = self._gen, None
            quiet = logging.getLogger("imageio_ffmpeg")
            level = quiet.level
            if self.count == 0:   # closed before a frame (a run ended early): imageio-ffmpeg's warning that
                quiet.setLevel(logging.ERROR)   # the file is invalid is noise beside the run's own one line
            try:
                gen.close()
            finally:
                quiet.setLevel(level)
        if self._cv is not None:
            cv, self._cv = self._cv, None
            cv.release()

    def __enter__(self) -> "VideoWriter":
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.close()


@dataclass(frozen=True)
class VideoFrame:
    index: int          # 0-based decode order
    t: float            # presentation timestamp, s
    image: np.ndarray   # (H, W, 3) uint8 BGR


def read_video(path: str | Path, size: tuple[int, int] | None = None) -> Iterator[VideoFrame]:
    """Decode a video file with OpenCV; ``size=(w, h)`` crops away writer padding."""
    cap = cv2.VideoCapture(str(path))
    if not cap.isOpened():
        raise OSError(f"{path}: cannot open video")
    try:
        i = 0
        while True:
            ok, img = cap.read()
            if not ok:
                break
            t = cap.get(cv2.CAP_PROP_POS_MSEC) / 1000.0
            if size is not None:
                img = img[: size[1], : size[0]]
            yield VideoFrame(i, t, img)
            i += 1
    finally:
        cap.release()
