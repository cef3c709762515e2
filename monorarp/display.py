"""Annotated display of one pipeline frame (the paper's Fig. 2), pure OpenCV on BGR images.

Draws each track's box coloured by its time to collision (red below the
warning threshold, orange below twice it, yellow for any other TTC within the
horizon, green when not on a collision course), its id, ``d_x``/``d_y`` (m) and
TTC (s); a vertical risk gauge (risk = max 1/TTC, 1/s) at the right edge; and a
header with frame index, frame time, pipeline time per frame and, when known,
the ego speed. Inputs are never modified unless ``copy=False``. The gauge reads ``result.risk.kind``: ``"inverse_ttc"`` (1/s) or
``"probability"`` (0..1).
"""

from __future__ import annotations

from collections.abc import Sequence

import cv2
import numpy as np

from monorarp.types import Box, FrameResult

RED, ORANGE, YELLOW, GREEN = (40, 40, 230), (0, 140, 255), (0, 220, 240), (60, 200, 60)
WHITE, BLACK, GREY = (255, 255, 255), (0, 0, 0), (170, 170, 170)
FONT = cv2.FONT_HERSHEY_SIMPLEX


def ttc_colour(ttc: float | None, warning_s: float = 2.0) -> tuple[int, int, int]:
    """BGR colour of a box with time to collision ``ttc`` (s; None = no collision course)."""
    if ttc is None or not np.isfinite(ttc):
        return GREEN
    if ttc < warning_s:
        return RED
    if ttc < 2 * warning_s:
        return ORANGE
    return YELLOW


def _text(img: np.ndarray, text: str, org: tuple[int, int], scale: float, colour, bg=BLACK) -> int:
    """Text with a filled background box at ``org`` (top-left); returns the height used (px)."""
    thick = max(1, int(round(scale * 2)))
    (tw, th), base = cv2.getTextSize(text, FONT, scale, thick)
    x, y = org
    h, w = img.shape[:2]
    x = int(np.clip(x, 0, max(0, w - tw - 2)))
    y = int(np.clip(y, 0, max(0, h - th - base - 2)))
    cv2.rectangle(img, (x, y), (x + tw + 2, y + th + base + 2), bg, -1)
    cv2.putText(img, text, (x + 1, y + th + 1), FONT, scale, colour, thick, cv2.LINE_AA)
    return th + base + 2


def draw_risk_gauge(img: np.ndarray, risk: float, full_scale: float = 1.0, warning_s: float = 2.0,
                    kind: str = "inverse_ttc") -> None:
    """Vertical gauge at the right edge: fill = risk / full_scale.

    ``kind="inverse_ttc"``: risk in 1/s, red tick at 1 / warning_s. ``"probability"``:
    risk in [0, 1] on a full scale of 1, coloured green/yellow/orange/red by quarters.
    """
    probability = kind == "probability"
    if probability:
        full_scale = 1.0
    h, w = img.shape[:2]
    gw = max(6, w // 60)
    x2, x1 = w - 4, w - 4 - gw
    y1, y2 = int(h * 0.2), int(h * 0.85)
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
    (tw, _), _ = cv2.getTextSize("risk", FONT, scale, 1)
    _text(img, "risk", (x2 - tw - 2, y1 - int(22 * scale) - 4), scale, WHITE)
    _text(img, f"P={risk:.2f}" if probability else f"{risk:.2f}/s", (x1 - 60, y2 + 3), scale, colour)


def draw_frame(image: np.ndarray, result: FrameResult, *, warning_s: float = 2.0, risk_full_scale: float = 1.0,
               ego_speed: float | None = None, truth_boxes: Sequence[Box] = (), copy: bool = True) -> np.ndarray:
    """The annotated frame for ``result`` drawn on ``image`` (BGR uint8, H x W x 3).

    ``ego_speed`` (m/s) overrides ``result.ego_speed`` for the header;
    ``truth_boxes`` (optional, e.g. ground truth in a simulator) are drawn thin grey.
    """
    img = image.copy() if copy else image
    h, w = img.shape[:2]
    scale = max(0.33, h / 1000)
    thick = max(1, int(round(h / 360)))
    for b in truth_boxes:
        cv2.rectangle(img, (int(round(b[0] + 0.5)), int(round(b[1] + 0.5))),
                      (int(round(b[2] - 0.5)), int(round(b[3] - 0.5))), GREY, 1)
    # Nearest last so that its label is on top.
    order = sorted(result.tracks, key=lambda t: -result.states[t.id].d_y if t.id in result.states else np.inf)
    for tr in order:
        ttc = result.risk.ttc.get(tr.id)
        colour = ttc_colour(ttc, warning_s)
        x1, y1, x2, y2 = (int(round(v)) for v in (tr.box[0] + 0.5, tr.box[1] + 0.5, tr.box[2] - 0.5, tr.box[3] - 0.5))
        cv2.rectangle(img, (x1, y1), (x2, y2), colour, 1 if tr.coasting else thick + 1)
        lines = [f"#{tr.id}" + (f" TTC {ttc:.1f}s" if ttc is not None and np.isfinite(ttc) else "")]
        st = result.states.get(tr.id)
        if st is not None:
            lines.append(f"x{st.d_x:+.1f} y{st.d_y:.1f}m")
        line_h = int(22 * scale) + 6
        y = y1 - line_h * len(lines)
        for text in lines:
            y += _text(img, text, (x1, y), scale, colour)
    header = [f"frame {result.index}  t={result.t:.2f}s"]
    total = result.timings_ms.get("total")
    if total is not None:
        header[0] += f"  pipeline {total:.1f} ms" + (f" ({1000 / total:.0f} fps)" if total > 0 else "")
    speed = ego_speed if ego_speed is not None else result.ego_speed
    if speed is not None and np.isfinite(speed):
        header.append(f"ego {speed:.1f} m/s ({speed * 3.6:.0f} km/h)")
    y = 2
    for text in header:
        y += _text(img, text, (2, y), scale, WHITE)
    draw_risk_gauge(img, float(result.risk.risk), risk_full_scale, warning_s, getattr(result.risk, "kind", "inverse_ttc"))
    return img
