"""Letterboxing: resize keeping the aspect ratio, pad to the network's input size, and undo it.

Coordinates are continuous pixels in the convention of :mod:`monorarp.core.types`
(pixel centres at integers; an image of width W spans [-0.5, W - 0.5]).
A resize by factor ``s`` maps ``x + 0.5`` to ``s * (x + 0.5)``; padding adds
``pad`` pixels on the left/top. Both directions are exact inverses.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np


@dataclass(frozen=True)
class Letterbox:
    """How an image of ``src_w`` x ``src_h`` was placed into a ``dst_w`` x ``dst_h`` canvas."""

    src_w: int
    src_h: int
    dst_w: int
    dst_h: int
    new_w: int     # size of the resized image inside the canvas (px)
    new_h: int
    pad_x: int     # left padding (px)
    pad_y: int     # top padding (px)

    @classmethod
    def fit(cls, src_w: int, src_h: int, dst_w: int, dst_h: int) -> "Letterbox":
        """Ultralytics-style placement: scale ``min(dst/src)``, the resized image centred."""
        r = min(dst_w / src_w, dst_h / src_h)
        new_w, new_h = int(round(src_w * r)), int(round(src_h * r))
        pad_x = int(round((dst_w - new_w) / 2 - 0.1))
        pad_y = int(round((dst_h - new_h) / 2 - 0.1))
        return cls(src_w, src_h, dst_w, dst_h, new_w, new_h, pad_x, pad_y)

    @classmethod
    def top_left(cls, src_w: int, src_h: int, dst_w: int, dst_h: int) -> "Letterbox":
        """YOLOX-style placement: scale ``min(dst/src)``, the resized image in the canvas's top-left corner
        (the padding right and below it); the resized size rounded down, as YOLOX's own preprocessing does."""
        r = min(dst_w / src_w, dst_h / src_h)
        new_w, new_h = max(min(int(src_w * r), dst_w), 1), max(min(int(src_h * r), dst_h), 1)
        return cls(src_w, src_h, dst_w, dst_h, new_w, new_h, 0, 0)

    @property
    def sx(self) -> float:
        return self.new_w / self.src_w

    @property
    def sy(self) -> float:
        return self.new_h / self.src_h

    def apply(self, image: np.ndarray, pad_value: int = 114, interpolation: int | None = None) -> np.ndarray:
        """(src_h, src_w, C) uint8 -> (dst_h, dst_w, C) uint8 canvas. ``interpolation``: a cv2 ``INTER_*`` flag
        (default: area averaging when shrinking, bilinear when enlarging)."""
        if image.shape[1] != self.new_w or image.shape[0] != self.new_h:
            interp = interpolation if interpolation is not None else (
                cv2.INTER_AREA if self.new_w < self.src_w else cv2.INTER_LINEAR)
            image = cv2.resize(image, (self.new_w, self.new_h), interpolation=interp)
        return cv2.copyMakeBorder(image, self.pad_y, self.dst_h - self.new_h - self.pad_y,
                                  self.pad_x, self.dst_w - self.new_w - self.pad_x,
                                  cv2.BORDER_CONSTANT, value=(pad_value,) * 3)

    def to_dst(self, boxes: np.ndarray) -> np.ndarray:
        """(N, 4) source-image boxes (x1, y1, x2, y2) -> canvas boxes."""
        b = np.asarray(boxes, dtype=np.float64).reshape(-1, 4)
        s = np.array([self.sx, self.sy, self.sx, self.sy])
        p = np.array([self.pad_x, self.pad_y, self.pad_x, self.pad_y], dtype=np.float64)
        return (b + 0.5) * s - 0.5 + p

    def to_src(self, boxes: np.ndarray, clip: bool = True) -> np.ndarray:
        """(N, 4) canvas boxes -> source-image boxes, optionally clipped to the image."""
        b = np.asarray(boxes, dtype=np.float64).reshape(-1, 4)
        s = np.array([self.sx, self.sy, self.sx, self.sy])
        p = np.array([self.pad_x, self.pad_y, self.pad_x, self.pad_y], dtype=np.float64)
        out = (b - p + 0.5) / s - 0.5
        if clip:
            out[:, [0, 2]] = np.clip(out[:, [0, 2]], -0.5, self.src_w - 0.5)
            out[:, [1, 3]] = np.clip(out[:, [1, 3]], -0.5, self.src_h - 0.5)
        return out


def to_blob(canvas_bgr: np.ndarray) -> np.ndarray:
    """(H, W, 3) BGR uint8 -> (1, 3, H, W) float32 RGB in [0, 1]."""
    rgb = canvas_bgr[:, :, ::-1]
    return np.ascontiguousarray(rgb.transpose(2, 0, 1)[None], dtype=np.float32) * np.float32(1.0 / 255.0)
