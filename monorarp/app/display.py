"""Annotated display of one pipeline frame (the paper's Fig. 2), pure OpenCV on BGR images.

Draws each track's box coloured by its time to collision (red below the
warning threshold, orange below twice it, yellow for any other TTC within the
horizon, green when not on a collision course); a label per track (id, TTC,
``d_x``/``d_y`` in m; one compact line ``#id y..m TTC ..s`` for small, far
boxes); a vertical risk gauge (risk = max 1/TTC, 1/s) at the right edge; and a
header with frame index, frame time, pipeline time per frame and, when known,
the ego speed. The gauge reads ``result.risk.kind``: ``"inverse_ttc"`` (1/s) or
``"probability"`` (0..1).

**Forward-collision warning** (``result.warning``), as a driver sees it: while
a warning is active, a red banner "BRAKE! / COLLISION WARNING" (with the TTC
when known) at the top centre, and the object it is for framed thick red with a
red marker above it; while inactive only a small "FCW ready" indicator. Nothing
depends on the wall clock (no flashing): the same result gives the same pixels.

**Label layout.** Labels never overlap one another, the header, the banner, the
warning marker or the gauge, and stay inside the image: :func:`place_labels`
(pure maths) places them greedily, most important first (the warned object,
then by TTC, then by distance), each at the cheapest free position next to its
box or, where none is free, displaced (with a thin leader line to its box).
:func:`layout_frame` computes every rectangle of a frame without drawing;
:func:`draw_frame` draws it. Inputs are never modified unless ``copy=False``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import cv2
import numpy as np

from monorarp.warning.thresholds import TTC_CUE_THRESHOLD_S
from monorarp.core.types import Box, FrameResult, Track

RED, ORANGE, YELLOW, GREEN = (40, 40, 230), (0, 140, 255), (0, 220, 240), (60, 200, 60)
WHITE, BLACK, GREY = (255, 255, 255), (0, 0, 0), (170, 170, 170)
BANNER_RED = (0, 0, 200)
FONT = cv2.FONT_HERSHEY_SIMPLEX

#: Integer pixel rectangle ``(x1, y1, x2, y2)``, ``x2``/``y2`` exclusive (covers columns x1..x2-1).
Rect = tuple[int, int, int, int]


def ttc_colour(ttc: float | None, warning_s: float = TTC_CUE_THRESHOLD_S) -> tuple[int, int, int]:
    """BGR colour of a box with time to collision ``ttc`` (s; None = no collision course)."""
    if ttc is None or not np.isfinite(ttc):
        return GREEN
    if ttc < warning_s:
        return RED
    if ttc < 2 * warning_s:
        return ORANGE
    return YELLOW


# ----------------------------------------------------------------------------------------------
# Layout maths (pure: rectangles in, rectangles out)


def rects_overlap(a: Rect, b: Rect) -> bool:
    """True when rectangles ``a`` and ``b`` share at least one pixel."""
    return a[0] < b[2] and b[0] < a[2] and a[1] < b[3] and b[1] < a[3]


def _box_rect(box: Box) -> Rect:
    """The pixels a continuous box covers (see :mod:`monorarp.core.types`) as a :data:`Rect`."""
    x1, y1 = int(round(box[0] + 0.5)), int(round(box[1] + 0.5))
    return x1, y1, max(x1 + 1, int(round(box[2] - 0.5)) + 1), max(y1 + 1, int(round(box[3] - 0.5)) + 1)


def place_labels(sizes: Sequence[tuple[int, int]], anchors: Sequence[Rect], image_size: tuple[int, int],
                 obstacles: Sequence[Rect] = (), *, gap: int = 2, cover_weight: float | None = None
                 ) -> list[Rect | None]:
    """Greedy non-overlapping placement of label ``sizes[i] = (w, h)`` next to box ``anchors[i]``.

    Labels are placed in the given order (most important first), each at its cheapest
    *free* candidate: inside the image (``image_size = (W, H)``), overlapping no obstacle
    and no label placed before it. Candidates: a coarse grid over the whole image whose columns
    and rows include those touching the box (above, below, left, right, aligned with its edges)
    and those stacking labels away from it (a column above and below, a row left and right).
    Cost (px): distance from the label to its box beyond ``gap``, plus ``cover_weight``
    (default 8 label heights) times (the fraction of each box, its own included, that it
    hides, plus half the fraction of the label that lies on boxes), tripled for the boxes of
    labels placed before it; ties go to the candidate nearest to "above, left-aligned".
    Returns each label's rectangle, None where no candidate is free.
    """
    W, H = int(image_size[0]), int(image_size[1])
    n_anchor, n_obst = len(anchors), len(obstacles)
    # Every rectangle the cost looks at: the boxes, then obstacles and the labels placed so far.
    R = np.empty((n_anchor + n_obst + len(sizes), 4))
    R[:n_anchor] = np.asarray(anchors, dtype=float).reshape(-1, 4)
    R[n_anchor:n_anchor + n_obst] = np.asarray(obstacles, dtype=float).reshape(-1, 4)
    n_rect = n_anchor + n_obst
    inv_area = 1.0 / np.maximum(1.0, (R[:n_anchor, 2] - R[:n_anchor, 0]) * (R[:n_anchor, 3] - R[:n_anchor, 1]))
    grids: dict[tuple[int, int], tuple[np.ndarray, np.ndarray]] = {}
    out: list[Rect | None] = []
    for i, (lw, lh) in enumerate(sizes):
        lw, lh = int(lw), int(lh)
        if lw > W or lh > H or lw <= 0 or lh <= 0:
            out.append(None)
            continue
        ax1, ay1, ax2, ay2 = (int(v) for v in R[i])
        x0, y0 = ax1, ay1 - gap - lh                    # the preferred place: above, left-aligned
        if (lw, lh) not in grids:
            grids[lw, lh] = (np.append(np.arange(0, W - lw + 1, max(2, lw // 2)), W - lw).astype(float),
                             np.append(np.arange(0, H - lh + 1, lh), H - lh).astype(float))
        # Candidate columns and rows (every combination is a candidate): a coarse grid plus the
        # columns and rows touching the box, and rows/columns stacking labels away from it.
        sx, sy = lw + gap, lh + gap
        touch_x = [ax1, (ax1 + ax2 - lw) // 2, ax2 - lw] + [ax2 + gap + k * sx for k in range(3)] \
            + [ax1 - gap - lw - k * sx for k in range(3)]
        touch_y = [ay1, ay2 - lh] + [y0 - k * sy for k in range(6)] + [ay2 + gap + k * sy for k in range(6)]
        gx = np.concatenate([grids[lw, lh][0], [min(max(v, 0), W - lw) for v in touch_x]])
        gy = np.concatenate([grids[lw, lh][1], [min(max(v, 0), H - lh) for v in touch_y]])
        # Overlap is separable: (overlap in x) x (overlap in y) for every candidate and rectangle,
        # so one matrix product weighs them all: boxes by the fraction hidden, obstacles by 1e9.
        r = R[:n_rect]
        ox = np.maximum(np.minimum(gx[:, None] + lw, r[:, 2]) - np.maximum(gx[:, None], r[:, 0]), 0.0)
        oy = np.maximum(np.minimum(gy[:, None] + lh, r[:, 3]) - np.maximum(gy[:, None], r[:, 1]), 0.0)
        w = np.full(n_rect, 1e9)
        w[:n_anchor] = (8.0 * lh if cover_weight is None else float(cover_weight)) * (inv_area + 0.5 / (lw * lh))
        w[:min(i, n_anchor)] *= 3.0
        cost = (ox * w) @ oy.T
        dx = np.maximum(np.maximum(ax1 - (gx + lw), gx - ax2), 0.0)
        dy = np.maximum(np.maximum(ay1 - (gy + lh), gy - ay2), 0.0)
        cost += np.maximum(np.hypot(dx[:, None], dy) - gap, 0.0)
        cost += 1e-4 * (np.abs(gx - x0)[:, None] + np.abs(gy - y0))
        k = int(np.argmin(cost))
        if cost.flat[k] >= 1e8:                          # every candidate overlaps something
            out.append(None)
            continue
        c, rr = divmod(k, len(gy))
        rect = (int(gx[c]), int(gy[rr]), int(gx[c]) + lw, int(gy[rr]) + lh)
        R[n_rect] = rect
        n_rect += 1
        out.append(rect)
    return out


def _text_size(text: str, scale: float, thick: int) -> tuple[int, int, int]:
    """(width, height above baseline, baseline) of ``text`` (px)."""
    (tw, th), base = cv2.getTextSize(text, FONT, scale, thick)
    return tw, th, base


def _text_rect(shape: tuple[int, ...], text: str, org: tuple[int, int], scale: float) -> Rect:
    """The rectangle :func:`_text` fills for ``text`` at ``org`` (top-left, moved inside the image)."""
    h, w = int(shape[0]), int(shape[1])
    tw, th, base = _text_size(text, scale, _thick(scale))
    x = int(np.clip(org[0], 0, max(0, w - tw - 3)))
    y = int(np.clip(org[1], 0, max(0, h - th - base - 3)))
    return x, y, x + tw + 3, y + th + base + 3


@dataclass(frozen=True)
class Label:
    """One track's label: its lines, colour, where it goes and whether it needs a leader line."""

    track_id: int
    lines: tuple[str, ...]
    colour: tuple[int, int, int]
    box: Rect               # the box's pixels
    anchor: Rect            # what the label is placed next to: the box (with its highlight, if warned)
    rect: Rect | None       # None: no free place (not drawn)
    leader: bool


@dataclass(frozen=True)
class FrameLayout:
    """Every rectangle of an annotated frame (px, :data:`Rect`), computed without drawing."""

    header: Rect
    gauge: tuple[Rect, ...]
    banner: Rect | None              # only while the warning is active
    indicator: Rect | None           # "FCW ready", only while inactive
    marker: Rect | None              # the triangle above the warned object's box
    highlight: Rect | None           # the warned object's box with its red frame
    labels: tuple[Label, ...] = field(default_factory=tuple)

    @property
    def obstacles(self) -> list[Rect]:
        """The fixed elements labels must keep clear of."""
        return [self.header, *self.gauge] + [r for r in (self.banner, self.indicator, self.marker, self.highlight)
                                             if r is not None]


def _highlight_band(h: int) -> int:
    """Width (px) of the red frame around the warned object's box on an image ``h`` px high."""
    return max(3, h // 120) | 1


def _highlight_outset(h: int) -> int:
    """How far (px) the warned object's highlight frame (red band, then a white edge) reaches outside its box."""
    return 2 + _highlight_band(h)


def _scale(h: int) -> float:
    return max(0.33, h / 1000)


def _thick(scale: float) -> int:
    return max(1, int(round(scale * 2)))


def _line_h(scale: float) -> int:
    _, th, base = _text_size("Ag", scale, _thick(scale))
    return th + base + 2


def _gauge_geometry(h: int, w: int, risk_text: str) -> tuple[tuple[int, int, int, int], tuple[Rect, ...],
                                                                     tuple[int, int], tuple[int, int]]:
    """Bar corners (inclusive), the rectangles it and its texts cover, and the texts' origins."""
    gw = max(6, w // 60)
    x2, x1 = w - 4, w - 4 - gw
    y1, y2 = int(h * 0.2), int(h * 0.85)
    scale = max(0.3, h / 900)
    tw, _, _ = _text_size("risk", scale, _thick(scale))
    top = _text_rect((h, w), "risk", (x2 - tw - 2, y1 - int(22 * scale) - 4), scale)
    bottom = _text_rect((h, w), risk_text, (x1 - 60, y2 + 3), scale)
    rects = ((min(x1 - 3, top[0]), min(y1, top[1]), w, y2 + 1), bottom)
    return (x1, y1, x2, y2), rects, top[:2], bottom[:2]


def _gauge_text(risk: float, kind: str) -> str:
    return f"P={risk:.2f}" if kind == "probability" else f"{risk:.2f}/s"


def _header_lines(result: FrameResult, ego_speed: float | None) -> list[str]:
    header = [f"frame {result.index}  t={result.t:.2f}s"]
    total = result.timings_ms.get("total")
    if total is not None:
        header[0] += f"  pipeline {total:.1f} ms" + (f" ({1000 / total:.0f} fps)" if total > 0 else "")
    speed = ego_speed if ego_speed is not None else result.ego_speed
    if speed is not None and np.isfinite(speed):
        header.append(f"ego {speed:.1f} m/s ({speed * 3.6:.0f} km/h)")
    return header


def _banner_lines(result: FrameResult) -> tuple[str, str]:
    ttc = result.warning.ttc
    sub = "COLLISION WARNING" + (f"  TTC {ttc:.1f} s" if ttc is not None and np.isfinite(ttc) else "")
    return "BRAKE!", sub


def _banner_scales(h: int) -> tuple[float, float]:
    return max(0.6, h / 330), max(0.4, h / 800)


def _label_lines(tr: Track, result: FrameResult, compact: bool) -> tuple[str, ...]:
    ttc = result.risk.ttc.get(tr.id)
    ttc_s = f"TTC {ttc:.1f}s" if ttc is not None and np.isfinite(ttc) else ""
    st = result.states.get(tr.id)
    if st is None:
        return (f"#{tr.id} {ttc_s}".strip(),)
    if compact:
        return (f"#{tr.id} y{st.d_y:.0f}m {ttc_s}".strip(),)
    return (f"#{tr.id} {ttc_s}".strip(), f"x{st.d_x:+.1f} y{st.d_y:.1f}m")


def _priority(tr: Track, result: FrameResult) -> tuple:
    """Sort key: the warned object, then lowest TTC, then nearest (d_y, else lowest box bottom)."""
    ttc = result.risk.ttc.get(tr.id)
    st = result.states.get(tr.id)
    warned = result.warning.active and tr.id == result.warning.track_id
    return (not warned, ttc if ttc is not None and np.isfinite(ttc) else np.inf,
            st.d_y if st is not None else np.inf, -tr.box[3], tr.id)


def layout_frame(shape: tuple[int, ...], result: FrameResult, *, warning_s: float = TTC_CUE_THRESHOLD_S,
                 ego_speed: float | None = None) -> FrameLayout:
    """Where everything of :func:`draw_frame` goes on an image of ``shape`` (H, W[, 3]); draws nothing."""
    h, w = int(shape[0]), int(shape[1])
    scale = _scale(h)
    thick = _thick(scale)
    line_h = _line_h(scale)
    header = (0, 0, 1, 1)                                # top left, drawn by :func:`_text` from y = 2
    y = 2
    for text in _header_lines(result, ego_speed):
        r = _text_rect(shape, text, (2, y), scale)
        header = (0, 0, max(header[2], r[2]), max(header[3], r[3]))
        y = r[3] - 1
    _, gauge, _, _ = _gauge_geometry(h, w, _gauge_text(float(result.risk.risk),
                                                       getattr(result.risk, "kind", "inverse_ttc")))
    banner = indicator = marker = highlight = None
    warning = result.warning
    if warning.active:
        big, small = _banner_scales(h)
        top, sub = _banner_lines(result)
        bw1, bh1, bb1 = _text_size(top, big, _thick(big))
        bw2, bh2, bb2 = _text_size(sub, small, _thick(small))
        pad = max(4, h // 90)
        bw = min(w, max(bw1, bw2, int(0.45 * w)) + 4 * pad)
        bh = bh1 + bb1 + bh2 + bb2 + 3 * pad
        by = header[3] + pad
        banner = ((w - bw) // 2, by, (w - bw) // 2 + bw, min(h, by + bh))
    else:
        iw, ih, ib = _text_size("FCW ready", scale, thick)
        dot = ih + ib
        indicator = (max(0, w - 4 - iw - dot - 6), 2, w - 2, 2 + ih + ib + 4)
    tracks = sorted(result.tracks, key=lambda t: _priority(t, result))
    boxes = [_box_rect(t.box) for t in tracks]
    anchors = list(boxes)
    obstacles = [header, *gauge] + [r for r in (banner, indicator) if r is not None]
    if warning.active:
        for i, (tr, r) in enumerate(zip(tracks, boxes)):
            if tr.id != warning.track_id:
                continue
            out = _highlight_outset(h) + 1               # the highlight frame, outside the box
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
    lines = [_label_lines(tr, result, compact=(r[3] - r[1]) < small_h) for tr, r in zip(tracks, boxes)]
    sizes = [(max(_text_size(t, scale, thick)[0] for t in ls) + 4, line_h * len(ls) + 2) for ls in lines]
    gap = 2
    rects = place_labels(sizes, anchors, (w, h), obstacles, gap=gap)
    labels = []
    for tr, r, a, ls, rect in zip(tracks, boxes, anchors, lines, rects):
        leader = False
        if rect is not None:
            dx = max(a[0] - rect[2], rect[0] - a[2], 0)
            dy = max(a[1] - rect[3], rect[1] - a[3], 0)
            leader = max(dx, dy) > gap + 1
        labels.append(Label(tr.id, ls, ttc_colour(result.risk.ttc.get(tr.id), warning_s), r, a, rect, leader))
    return FrameLayout(header, gauge, banner, indicator, marker, highlight, tuple(labels))


# ----------------------------------------------------------------------------------------------
# Drawing


def _text(img: np.ndarray, text: str, org: tuple[int, int], scale: float, colour, bg=BLACK) -> int:
    """Text with a filled background box at ``org`` (top-left, see :func:`_text_rect`); returns its height (px)."""
    x1, y1, x2, y2 = _text_rect(img.shape, text, org, scale)
    _, th, _ = _text_size(text, scale, _thick(scale))
    cv2.rectangle(img, (x1, y1), (x2 - 1, y2 - 1), bg, -1)
    cv2.putText(img, text, (x1 + 1, y1 + th + 1), FONT, scale, colour, _thick(scale), cv2.LINE_AA)
    return y2 - 1 - y1


def draw_risk_gauge(img: np.ndarray, risk: float, full_scale: float = 1.0, warning_s: float = TTC_CUE_THRESHOLD_S,
                    kind: str = "inverse_ttc") -> None:
    """Vertical gauge at the right edge: fill = risk / full_scale.

    ``kind="inverse_ttc"``: risk in 1/s, red tick at 1 / warning_s. ``"probability"``:
    risk in [0, 1] on a full scale of 1, coloured green/yellow/orange/red by quarters.
    """
    probability = kind == "probability"
    if probability:
        full_scale = 1.0
    h, w = img.shape[:2]
    (x1, y1, x2, y2), _, top, bottom = _gauge_geometry(h, w, _gauge_text(risk, kind))
    frac = float(np.clip(risk / full_scale, 0.0, 1.0)) if full_scale > 0 else 0.0
    cv2.rectangle(img, (x1, y1), (x2, y2), (40, 40, 40), -1)
    fill_top = int(round(y2 - frac * (y2 - y1)))
    if probability:
        colour = (GREEN, YELLOW, ORANGE, RED)[min(3, int(frac * 4))]
    else:
        colour = ttc_colour(1.0 / risk if risk > 0 else None, warning_s)
    if frac > 0:
        cv2.rectangle(img, (x1, fill_top), (x2, y2), colour, -1)
    cv2.rectangle(img, (x1, y1), (x2, y2), WHITE, 1)
    tick = 1.0 / warning_s / full_scale
    if not probability and 0 < tick <= 1:
        ty = int(round(y2 - tick * (y2 - y1)))
        cv2.line(img, (x1 - 3, ty), (x2, ty), RED, 1)
    scale = max(0.3, h / 900)
    _text(img, "risk", top, scale, WHITE)
    _text(img, _gauge_text(risk, kind), bottom, scale, colour)


def _nearest_point(rect: Rect, p: tuple[float, float]) -> tuple[int, int]:
    """The pixel of ``rect`` nearest to point ``p``."""
    return (int(np.clip(p[0], rect[0], rect[2] - 1)), int(np.clip(p[1], rect[1], rect[3] - 1)))


def _draw_warning(img: np.ndarray, layout: FrameLayout, result: FrameResult, boxes: dict[int, Rect]) -> None:
    """The warned object's red frame and marker, and the banner (all at the places ``layout`` gives)."""
    h = img.shape[0]
    thick = _thick(_scale(h))
    r = boxes.get(result.warning.track_id) if result.warning.track_id is not None else None
    if r is not None:
        out, band = _highlight_outset(h), _highlight_band(h)
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
        big, small = _banner_scales(h)
        top, sub = _banner_lines(result)
        pad = max(4, h // 90)
        bw1, bh1, bb1 = _text_size(top, big, _thick(big))
        bw2, bh2, _ = _text_size(sub, small, _thick(small))
        cv2.putText(img, top, ((x1 + x2 - bw1) // 2, y1 + pad + bh1), FONT, big, WHITE, _thick(big), cv2.LINE_AA)
        cv2.putText(img, sub, ((x1 + x2 - bw2) // 2, y1 + 2 * pad + bh1 + bb1 + bh2), FONT, small, WHITE,
                    _thick(small), cv2.LINE_AA)


def draw_frame(image: np.ndarray, result: FrameResult, *, warning_s: float = TTC_CUE_THRESHOLD_S, risk_full_scale: float = 1.0,
               ego_speed: float | None = None, truth_boxes: Sequence[Box] = (), copy: bool = True) -> np.ndarray:
    """The annotated frame for ``result`` drawn on ``image`` (BGR uint8, H x W x 3).

    ``ego_speed`` (m/s) overrides ``result.ego_speed`` for the header;
    ``truth_boxes`` (optional, e.g. ground truth in a simulator) are drawn thin grey.
    Positions come from :func:`layout_frame`.
    """
    img = image.copy() if copy else image
    scale = _scale(img.shape[0])
    thick = _thick(scale)
    line_h = _line_h(scale)
    layout = layout_frame(img.shape, result, warning_s=warning_s, ego_speed=ego_speed)
    for b in truth_boxes:
        cv2.rectangle(img, (int(round(b[0] + 0.5)), int(round(b[1] + 0.5))),
                      (int(round(b[2] - 0.5)), int(round(b[3] - 0.5))), GREY, 1)
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
            _, th, _ = _text_size(text, scale, thick)
            cv2.putText(img, text, (x1 + 2, y1 + 1 + k * line_h + th + 1), FONT, scale, lab.colour, thick,
                        cv2.LINE_AA)
    y = 2
    for text in _header_lines(result, ego_speed):
        _text(img, text, (2, y), scale, WHITE)
        y = _text_rect(img.shape, text, (2, y), scale)[3] - 1
    if layout.indicator is not None:
        x1, y1, x2, y2 = layout.indicator
        cv2.rectangle(img, (x1, y1), (x2 - 1, y2 - 1), BLACK, -1)
        rad = max(2, (y2 - y1) // 2 - 3)
        cv2.circle(img, (x1 + 3 + rad, (y1 + y2) // 2), rad, GREEN, -1, cv2.LINE_AA)
        _, th, _ = _text_size("FCW ready", scale, thick)
        cv2.putText(img, "FCW ready", (x1 + 2 * rad + 8, y1 + 2 + th), FONT, scale, GREY, thick, cv2.LINE_AA)
    draw_risk_gauge(img, float(result.risk.risk), risk_full_scale, warning_s, getattr(result.risk, "kind", "inverse_ttc"))
    return img
