"""Text measurement in the display's font (OpenCV's Hershey simplex): the layout's only use of cv2."""

from __future__ import annotations

import cv2
import numpy as np

from monorarp.app.display.placement import Rect
from monorarp.app.display.style import thickness

FONT = cv2.FONT_HERSHEY_SIMPLEX


def text_size(text: str, scale: float, thick: int) -> tuple[int, int, int]:
    """(width, height above baseline, baseline) of ``text`` (px)."""
    (tw, th), base = cv2.getTextSize(text, FONT, scale, thick)
    return tw, th, base


def text_rect(shape: tuple[int, ...], text: str, org: tuple[int, int], scale: float) -> Rect:
    """The rectangle a text on a filled background fills for ``text`` at ``org`` (top-left, moved inside
    an image of ``shape``)."""
    h, w = int(shape[0]), int(shape[1])
    tw, th, base = text_size(text, scale, thickness(scale))
    x = int(np.clip(org[0], 0, max(0, w - tw - 3)))
    y = int(np.clip(org[1], 0, max(0, h - th - base - 3)))
    return x, y, x + tw + 3, y + th + base + 3


def line_height(scale: float) -> int:
    """Height (px) of one line of a label at ``scale``."""
    _, th, base = text_size("Ag", scale, thickness(scale))
    return th + base + 2
