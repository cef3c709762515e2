"""Drawing the annotated frame with OpenCV, at the places :func:`~monorarp.app.display.layout.layout_frame` gives."""

from __future__ import annotations

from collections.abc import Sequence

import cv2
import numpy as np

from monorarp.app.display.content import LEGEND, MISSED_TEXT, banner_lines, gauge_text, header_lines, missed_truth
from monorarp.app.display.layout import (FrameLayout, gauge_geometry, header_origins, layout_frame, legend_geometry,
                                         legend_lines)
from monorarp.app.display.placement import Rect, box_rect
from monorarp.app.display.style import (BANNER_RED, BLACK, GREEN, GREY, ORANGE, RED, WHITE, YELLOW, banner_pad,
                                        banner_scales, font_scale, gauge_font_scale, highlight_band,
                                        highlight_outset, legend_font_scale, thickness, ttc_colour)
from monorarp.app.display.text import FONT, line_height, text_rect, text_size
from monorarp.core.types import Box, FrameResult
from monorarp.warning.thresholds import TTC_CUE_THRESHOLD_S


def _text(img: np.ndarray, text: str, org: tuple[int, int], scale: float, colour, bg=BLACK) -> int:
    """Text with a filled background box at ``org`` (top-left, see :func:`text_rect`); returns its height (px)."""
    x1, y1, x2, y2 = text_rect(img.shape, text, org, scale)
    _, th, _ = text_size(text, scale, thickness(scale))
    cv2.rectangle(img, (x1, y1), (x2 - 1, y2 - 1), bg, -1)
    cv2.putText(img, text, (x1 + 1, y1 + th + 1), FONT, scale, colour, thickness(scale), cv2.LINE_AA)
    return y2 - 1 - y1


def draw_risk_gauge(img: np.ndarray, risk: float, full_scale: float = 1.0, warning_s: float = TTC_CUE_THRESHOLD_S,
                    kind: str = "inverse_ttc", warned: bool = False) -> None:
    """Vertical gauge at the right edge: fill = risk / full_scale.

    ``kind="inverse_ttc"``: risk in 1/s, coloured as the per-object TTC cue of 1 / risk, a tick at
    1 / warning_s. ``"probability"``: risk in [0, 1] on a full scale of 1, green/yellow/orange by
    quarters. Red only when ``warned`` (the warning stage warns this frame).
    """
    probability = kind == "probability"
    if probability:
        full_scale = 1.0
    h, w = img.shape[:2]
    geo = gauge_geometry(h, w, gauge_text(risk, kind))
    x1, y1, x2, y2 = geo.bar
    frac = float(np.clip(risk / full_scale, 0.0, 1.0)) if full_scale > 0 else 0.0
    cv2.rectangle(img, (x1, y1), (x2, y2), (40, 40, 40), -1)
    fill_top = int(round(y2 - frac * (y2 - y1)))
    if warned:                      # red only while the warning stage warns: one meaning of red
        colour = RED
    elif probability:
        colour = (GREEN, YELLOW, ORANGE, ORANGE)[min(3, int(frac * 4))]
    else:
        colour = ttc_colour(1.0 / risk if risk > 0 else None, warning_s)
    if frac > 0:
        cv2.rectangle(img, (x1, fill_top), (x2, y2), colour, -1)
    cv2.rectangle(img, (x1, y1), (x2, y2), WHITE, 1)
    tick = 1.0 / warning_s / full_scale
    if not probability and 0 < tick <= 1:
        ty = int(round(y2 - tick * (y2 - y1)))
        cv2.line(img, (x1 - 3, ty), (x2, ty), ORANGE, 1)   # the cue's 1 / warning_s
    scale = gauge_font_scale(h)
    _text(img, "risk", geo.top, scale, WHITE)
    _text(img, gauge_text(risk, kind), geo.bottom, scale, colour)


def _dashed_rect(img: np.ndarray, r: Rect, colour, dash: int = 6) -> None:
    """A 1 px dashed rectangle over ``r``'s pixels (dashes of ``dash`` px, gaps as long)."""
    x1, y1, x2, y2 = r[0], r[1], r[2] - 1, r[3] - 1
    for a in range(x1, x2 + 1, 2 * dash):
        b = min(a + dash - 1, x2)
        cv2.line(img, (a, y1), (b, y1), colour, 1)
        cv2.line(img, (a, y2), (b, y2), colour, 1)
    for a in range(y1, y2 + 1, 2 * dash):
        b = min(a + dash - 1, y2)
        cv2.line(img, (x1, a), (x1, b), colour, 1)
        cv2.line(img, (x2, a), (x2, b), colour, 1)


def _draw_truth(img: np.ndarray, result: FrameResult, truth_boxes: Sequence[Box], scale: float) -> None:
    """Truth boxes thin grey; those no track overlaps (:func:`~.content.missed_truth`) dashed, labelled "missed"."""
    missed = set(missed_truth(truth_boxes, result.tracks))
    for i, b in enumerate(truth_boxes):
        r = box_rect(b)
        if i not in missed:
            cv2.rectangle(img, (r[0], r[1]), (r[2] - 1, r[3] - 1), GREY, 1)
            continue
        _dashed_rect(img, r, GREY, dash=max(3, img.shape[0] // 90))
        _, th, base = text_size(MISSED_TEXT, scale, thickness(scale))
        _text(img, MISSED_TEXT, (r[0], r[1] - th - base - 4), scale, GREY)


def _draw_legend(img: np.ndarray, rect: Rect, sample: int, lh: int, warning_s: float, scale: float) -> None:
    """The legend box: a sample of each kind of box beside its text, then the TTC cue's colour key."""
    x1, y1, x2, y2 = rect
    roi = img[y1:y2, x1:x2]
    roi[:] = (roi.astype(np.uint16) * 2 // 5).astype(np.uint8)      # darkened, the scene still shows through
    thick = thickness(scale)
    for k, text in enumerate(legend_lines(warning_s)):
        top = y1 + 3 + k * lh
        sx1, sy1, sx2, sy2 = x1 + 4, top + 2, x1 + sample - 2, top + lh - 3
        kind = LEGEND[k][0] if k < len(LEGEND) else None
        if kind == "box":                  # green: a box's colour without a TTC (the key below gives the others)
            cv2.rectangle(img, (sx1, sy1), (sx2, sy2), GREEN, thick + 1)
        elif kind == "thin":
            cv2.rectangle(img, (sx1, sy1), (sx2, sy2), GREEN, 1)
        elif kind == "dashed":
            _dashed_rect(img, (sx1, sy1, sx2 + 1, sy2 + 1), GREY, dash=3)
        elif kind == "warned":
            cv2.rectangle(img, (sx1, sy1), (sx2, sy2), RED, max(2, thick + 1))
            cv2.rectangle(img, (sx1 - 2, sy1 - 2), (sx2 + 2, sy2 + 2), WHITE, 1)
        _, th, _ = text_size(text, scale, thick)
        tx = x1 + sample + 4 if kind is not None else x1 + 4
        cv2.putText(img, text, (tx, top + th + 1), FONT, scale, WHITE, thick, cv2.LINE_AA)


def _nearest_point(rect: Rect, p: tuple[float, float]) -> tuple[int, int]:
    """The pixel of ``rect`` nearest to point ``p``."""
    return (int(np.clip(p[0], rect[0], rect[2] - 1)), int(np.clip(p[1], rect[1], rect[3] - 1)))


def _draw_warning(img: np.ndarray, layout: FrameLayout, result: FrameResult, boxes: dict[int, Rect]) -> None:
    """The warned object's red frame and marker, and the banner (all at the places ``layout`` gives)."""
    h = img.shape[0]
    thick = thickness(font_scale(h))
    r = boxes.get(result.warning.track_id) if result.warning.track_id is not None else None
    if r is not None:
        out, band = highlight_outset(h), highlight_band(h)
        c = 2 + band // 2                              # red band from 2 to 1 + band px outside, white edge at 2 + band
        cv2.rectangle(img, (r[0] - c, r[1] - c), (r[2] - 1 + c, r[3] - 1 + c), RED, band)
        cv2.rectangle(img, (r[0] - out, r[1] - out), (r[2] - 1 + out, r[3] - 1 + out), WHITE, 1)
    if layout.marker is not None:
        mx1, my1, mx2, my2 = layout.marker
        down = r is None or my2 <= r[1]
        tip, base = (my2 - 1, my1) if down else (my1, my2 - 1)
        pts = np.array([[mx1, base], [mx2 - 1, base], [(mx1 + mx2 - 1) // 2, tip]], np.int32)
        cv2.fillConvexPoly(img, pts, RED, cv2.LINE_AA)
        cv2.polylines(img, [pts], True, WHITE, 1, cv2.LINE_AA)
    if layout.banner is not None:
        x1, y1, x2, y2 = layout.banner
        cv2.rectangle(img, (x1, y1), (x2 - 1, y2 - 1), BANNER_RED, -1)
        t = max(1, thick)                              # a white edge inside the banner's rectangle
        cv2.rectangle(img, (x1 + t // 2, y1 + t // 2), (x2 - 1 - t // 2, y2 - 1 - t // 2), WHITE, t)
        big, small = banner_scales(h)
        top, sub = banner_lines(result.warning)
        pad = banner_pad(h)
        bw1, bh1, bb1 = text_size(top, big, thickness(big))
        bw2, bh2, _ = text_size(sub, small, thickness(small))
        cv2.putText(img, top, ((x1 + x2 - bw1) // 2, y1 + pad + bh1), FONT, big, WHITE, thickness(big), cv2.LINE_AA)
        cv2.putText(img, sub, ((x1 + x2 - bw2) // 2, y1 + 2 * pad + bh1 + bb1 + bh2), FONT, small, WHITE,
                    thickness(small), cv2.LINE_AA)


def draw_frame(image: np.ndarray, result: FrameResult, *, warning_s: float = TTC_CUE_THRESHOLD_S, risk_full_scale: float = 1.0,
               ego_speed: float | None = None, truth_boxes: Sequence[Box] = (), legend: bool = False,
               copy: bool = True) -> np.ndarray:
    """The annotated frame for ``result`` drawn on ``image`` (BGR uint8, H x W x 3).

    ``warning_s``: the per-object TTC cue (s) of the box colours and the gauge's tick;
    ``ego_speed`` (m/s) overrides ``result.ego_speed`` for the header;
    ``truth_boxes`` (optional, e.g. ground truth in a simulator) are drawn thin grey, dashed and labelled
    "missed" where no track overlaps them; ``legend``: a legend of the box kinds at the bottom left.
    Positions come from :func:`~monorarp.app.display.layout.layout_frame`.
    """
    img = image.copy() if copy else image
    scale = font_scale(img.shape[0])
    thick = thickness(scale)
    line_h = line_height(scale)
    layout = layout_frame(img.shape, result, warning_s=warning_s, ego_speed=ego_speed, legend=legend)
    _draw_truth(img, result, truth_boxes, scale)
    coasting = {t.id: t.coasting for t in result.tracks}
    boxes = {lab.track_id: lab.box for lab in layout.labels}
    # Farthest first, so that nearer (more important) boxes are drawn on top.
    for lab in reversed(layout.labels):
        r = lab.box
        cv2.rectangle(img, (r[0], r[1]), (r[2] - 1, r[3] - 1), lab.colour, 1 if coasting[lab.track_id] else thick + 1)
    if result.warning.active:
        _draw_warning(img, layout, result, boxes)
    for lab in layout.labels:                         # leader lines under every label
        if lab.rect is not None and lab.leader:
            rect = lab.rect
            p = _nearest_point(lab.anchor, ((rect[0] + rect[2]) / 2, (rect[1] + rect[3]) / 2))
            q = _nearest_point(rect, p)
            cv2.line(img, q, p, lab.colour, 1, cv2.LINE_AA)
            cv2.circle(img, p, max(1, thick), lab.colour, -1)
    for lab in layout.labels:
        if lab.rect is None:
            continue
        x1, y1, x2, y2 = lab.rect
        cv2.rectangle(img, (x1, y1), (x2 - 1, y2 - 1), BLACK, -1)
        cv2.rectangle(img, (x1, y1), (x2 - 1, y2 - 1), lab.colour, 1)
        for k, text in enumerate(lab.lines):
            _, th, _ = text_size(text, scale, thick)
            cv2.putText(img, text, (x1 + 2, y1 + 1 + k * line_h + th + 1), FONT, scale, lab.colour, thick,
                        cv2.LINE_AA)
    lines = header_lines(result, ego_speed)
    for text, org in zip(lines, header_origins(img.shape, lines, scale)):
        _text(img, text, org, scale, WHITE)
    if layout.indicator is not None:
        x1, y1, x2, y2 = layout.indicator
        cv2.rectangle(img, (x1, y1), (x2 - 1, y2 - 1), BLACK, -1)
        rad = max(2, (y2 - y1) // 2 - 3)
        cv2.circle(img, (x1 + 3 + rad, (y1 + y2) // 2), rad, GREEN, -1, cv2.LINE_AA)
        _, th, _ = text_size("FCW ready", scale, thick)
        cv2.putText(img, "FCW ready", (x1 + 2 * rad + 8, y1 + 2 + th), FONT, scale, GREY, thick, cv2.LINE_AA)
    draw_risk_gauge(img, float(result.risk.risk), risk_full_scale, warning_s, getattr(result.risk, "kind", "inverse_ttc"),
                    warned=bool(result.warning.active))
    if layout.legend is not None:
        _, sample, lh = legend_geometry(img.shape[0], img.shape[1], warning_s)
        _draw_legend(img, layout.legend, sample, lh, warning_s, legend_font_scale(img.shape[0]))
    return img
