"""Where everything of the annotated frame goes: :func:`layout_frame` -> :class:`FrameLayout` (px), drawing nothing.

Labels never overlap one another, the header, the banner, the warning marker or the gauge, and stay
inside the image: :func:`~monorarp.app.display.placement.place_labels` places them most important
first (the warned object, then by TTC, then by distance; :func:`~monorarp.app.display.content.label_priority`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from monorarp.app.display.content import (LEGEND, banner_lines, cue_text, gauge_text, header_lines, label_colour,
                                          label_lines, label_priority)
from monorarp.app.display.placement import Rect, box_rect, place_labels
from monorarp.app.display.style import (Colour, banner_pad, banner_scales, font_scale, gauge_font_scale,
                                        highlight_outset, legend_font_scale, thickness)
from monorarp.app.display.text import line_height, text_rect, text_size
from monorarp.core.types import FrameResult
from monorarp.warning.thresholds import TTC_CUE_THRESHOLD_S


@dataclass(frozen=True)
class Label:
    """One track's label: its lines, colour, where it goes and whether it needs a leader line."""

    track_id: int
    lines: tuple[str, ...]
    colour: Colour
    box: Rect               # the box's pixels
    anchor: Rect            # what the label is placed next to: the box (with its highlight, if warned)
    rect: Rect | None       # None: no free place (not drawn)
    leader: bool


@dataclass(frozen=True)
class FrameLayout:
    """Every rectangle of an annotated frame (px, :data:`~monorarp.app.display.placement.Rect`)."""

    header: Rect
    gauge: tuple[Rect, ...]
    banner: Rect | None              # only while the warning is active
    indicator: Rect | None           # "FCW ready", only while inactive
    marker: Rect | None              # the triangle above the warned object's box
    highlight: Rect | None           # the warned object's box with its red frame
    labels: tuple[Label, ...] = field(default_factory=tuple)
    legend: Rect | None = None       # bottom left, only when asked for

    @property
    def obstacles(self) -> list[Rect]:
        """The fixed elements labels must keep clear of."""
        return [self.header, *self.gauge] + [r for r in (self.banner, self.indicator, self.marker, self.highlight,
                                                         self.legend) if r is not None]


@dataclass(frozen=True)
class GaugeGeometry:
    """The risk gauge on an image: bar corners (inclusive), the rectangles it and its texts cover,
    and the origins of its "risk" and value texts (px)."""

    bar: tuple[int, int, int, int]
    rects: tuple[Rect, ...]
    top: tuple[int, int]
    bottom: tuple[int, int]


def gauge_geometry(h: int, w: int, risk_text: str) -> GaugeGeometry:
    """The gauge at the right edge of an image ``h`` x ``w`` px whose value reads ``risk_text``."""
    gw = max(6, w // 60)
    x2, x1 = w - 4, w - 4 - gw
    y1, y2 = int(h * 0.2), int(h * 0.85)
    scale = gauge_font_scale(h)
    tw, _, _ = text_size("risk", scale, thickness(scale))
    top = text_rect((h, w), "risk", (x2 - tw - 2, y1 - int(22 * scale) - 4), scale)
    bottom = text_rect((h, w), risk_text, (x1 - 60, y2 + 3), scale)
    rects = ((min(x1 - 3, top[0]), min(y1, top[1]), w, y2 + 1), bottom)
    return GaugeGeometry((x1, y1, x2, y2), rects, top[:2], bottom[:2])


def header_origins(shape: tuple[int, ...], lines: list[str], scale: float) -> list[tuple[int, int]]:
    """Top-left origin (px) of each header line, stacked from the top left."""
    origins, y = [], 2
    for text in lines:
        origins.append((2, y))
        y = text_rect(shape, text, (2, y), scale)[3] - 1
    return origins


def legend_lines(warning_s: float) -> list[str]:
    """The legend's texts, top to bottom (the first lines get a sample beside them)."""
    return [text for _, text in LEGEND] + [cue_text(warning_s)]


def legend_geometry(h: int, w: int, warning_s: float) -> tuple[Rect, int, int]:
    """(rectangle, sample width, line height) of the legend at the bottom left of an image ``h`` x ``w`` px."""
    scale = legend_font_scale(h)
    lh = line_height(scale)
    sample = 2 * lh
    tw = max(text_size(t, scale, thickness(scale))[0] for t in legend_lines(warning_s))
    lw, lhh = min(w, sample + tw + 10), lh * len(legend_lines(warning_s)) + 6
    return (2, max(0, h - 2 - lhh), 2 + lw, h - 2), sample, lh


def layout_frame(shape: tuple[int, ...], result: FrameResult, *, warning_s: float = TTC_CUE_THRESHOLD_S,
                 ego_speed: float | None = None, legend: bool = False) -> FrameLayout:
    """Where everything of :func:`~monorarp.app.display.draw.draw_frame` goes on an image of ``shape``
    (H, W[, 3]); ``warning_s``: the per-object TTC cue (s) the label colours use; ``legend``: keep the
    bottom-left corner for the legend."""
    h, w = int(shape[0]), int(shape[1])
    scale = font_scale(h)
    thick = thickness(scale)
    line_h = line_height(scale)
    header = (0, 0, 1, 1)                                # top left, drawn from y = 2
    lines = header_lines(result, ego_speed)
    for text, org in zip(lines, header_origins(shape, lines, scale)):
        r = text_rect(shape, text, org, scale)
        header = (0, 0, max(header[2], r[2]), max(header[3], r[3]))
    gauge = gauge_geometry(h, w, gauge_text(float(result.risk.risk), getattr(result.risk, "kind", "inverse_ttc"))).rects
    banner = indicator = marker = highlight = None
    warning = result.warning
    if warning.active:
        big, small = banner_scales(h)
        top, sub = banner_lines(warning)
        bw1, bh1, bb1 = text_size(top, big, thickness(big))
        bw2, bh2, bb2 = text_size(sub, small, thickness(small))
        pad = banner_pad(h)
        bw = min(w, max(bw1, bw2, int(0.45 * w)) + 4 * pad)
        bh = bh1 + bb1 + bh2 + bb2 + 3 * pad
        by = header[3] + pad
        banner = ((w - bw) // 2, by, (w - bw) // 2 + bw, min(h, by + bh))
    else:
        iw, ih, ib = text_size("FCW ready", scale, thick)
        dot = ih + ib
        indicator = (max(0, w - 4 - iw - dot - 6), 2, w - 2, 2 + ih + ib + 4)
    tracks = sorted(result.tracks, key=lambda t: label_priority(t, result))
    boxes = [box_rect(t.box) for t in tracks]
    anchors = list(boxes)
    legend_rect = legend_geometry(h, w, warning_s)[0] if legend else None
    obstacles = [header, *gauge] + [r for r in (banner, indicator, legend_rect) if r is not None]
    if warning.active:
        for i, (tr, r) in enumerate(zip(tracks, boxes)):
            if tr.id != warning.track_id:
                continue
            out = highlight_outset(h) + 1                # the highlight frame, outside the box
            anchors[i] = (r[0] - out, r[1] - out, r[2] + out, r[3] + out)
            mh = max(8, int(h / 30))
            m_w = int(mh * 1.2)
            mx = int(np.clip((r[0] + r[2]) // 2 - m_w // 2, 0, max(0, w - m_w)))
            my = anchors[i][1] - 2 - mh
            if my < 0:                                   # no room above: below the box, pointing up
                my = anchors[i][3] + 2
            my = int(np.clip(my, 0, max(0, h - mh)))
            marker = (mx, my, mx + m_w, my + mh)
            # Nothing may hide the warned object or its marker.
            highlight = anchors[i]
            obstacles += [marker, highlight]
            break
    small_h = 2.5 * line_h
    texts = [label_lines(tr, result, compact=(r[3] - r[1]) < small_h) for tr, r in zip(tracks, boxes)]
    sizes = [(max(text_size(t, scale, thick)[0] for t in ls) + 4, line_h * len(ls) + 2) for ls in texts]
    gap = 2
    rects = place_labels(sizes, anchors, (w, h), obstacles, gap=gap)
    labels = []
    for tr, r, a, ls, rect in zip(tracks, boxes, anchors, texts, rects):
        leader = False
        if rect is not None:
            dx = max(a[0] - rect[2], rect[0] - a[2], 0)
            dy = max(a[1] - rect[3], rect[1] - a[3], 0)
            leader = max(dx, dy) > gap + 1
        labels.append(Label(tr.id, ls, label_colour(tr.id, result, warning_s), r, a, rect, leader))
    return FrameLayout(header, gauge, banner, indicator, marker, highlight, tuple(labels), legend_rect)
