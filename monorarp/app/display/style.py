"""Colours (BGR) and sizes (px) of the annotated display, as functions of the image height; pure."""

from __future__ import annotations

import numpy as np

from monorarp.warning.thresholds import TTC_CUE_THRESHOLD_S

RED, ORANGE, YELLOW, GREEN = (40, 40, 230), (0, 140, 255), (0, 220, 240), (60, 200, 60)
WHITE, BLACK, GREY = (255, 255, 255), (0, 0, 0), (170, 170, 170)
BANNER_RED = (0, 0, 200)

Colour = tuple[int, int, int]


def ttc_colour(ttc: float | None, warning_s: float = TTC_CUE_THRESHOLD_S) -> Colour:
    """BGR colour of a box with per-object time to collision ``ttc`` (s; None = no collision course), the
    paper's cue: orange below ``warning_s``, yellow below twice it, green otherwise. Red is kept for the
    object the warning stage alerts on (:func:`..content.box_colour`), so a red box always means a warning."""
    if ttc is None or not np.isfinite(ttc):
        return GREEN
    if ttc < warning_s:
        return ORANGE
    if ttc < 2 * warning_s:
        return YELLOW
    return GREEN


def font_scale(h: int) -> float:
    """Font scale of the labels, header and indicator on an image ``h`` px high."""
    return max(0.33, h / 1000)


def legend_font_scale(h: int) -> float:
    """Font scale of the legend's texts (smaller than the labels')."""
    return max(0.3, 0.8 * font_scale(h))


def gauge_font_scale(h: int) -> float:
    """Font scale of the risk gauge's texts."""
    return max(0.3, h / 900)


def banner_scales(h: int) -> tuple[float, float]:
    """Font scales of the banner's two lines ("BRAKE!", then the sub-line)."""
    return max(0.6, h / 330), max(0.4, h / 800)


def thickness(scale: float) -> int:
    """Stroke thickness (px) of text drawn at ``scale``."""
    return max(1, int(round(scale * 2)))


def banner_pad(h: int) -> int:
    """Padding (px) inside the warning banner."""
    return max(4, h // 90)


def highlight_band(h: int) -> int:
    """Width (px) of the red frame around the warned object's box on an image ``h`` px high."""
    return max(3, h // 120) | 1


def highlight_outset(h: int) -> int:
    """How far (px) the warned object's highlight frame (red band, then a white edge) reaches outside its box."""
    return 2 + highlight_band(h)
