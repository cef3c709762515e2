"""Rectangles and the greedy placement of labels next to their boxes: pure maths (px, no drawing).

:data:`Rect` is an integer pixel rectangle ``(x1, y1, x2, y2)``, ``x2``/``y2`` exclusive (it covers
columns x1..x2-1); :func:`place_labels` puts each label at the cheapest free place next to its box.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from monorarp.core.types import Box

#: Integer pixel rectangle ``(x1, y1, x2, y2)``, ``x2``/``y2`` exclusive (covers columns x1..x2-1).
Rect = tuple[int, int, int, int]


def rects_overlap(a: Rect, b: Rect) -> bool:
    """True when rectangles ``a`` and ``b`` share at least one pixel."""
    return a[0] < b[2] and b[0] < a[2] and a[1] < b[3] and b[1] < a[3]


def box_rect(box: Box) -> Rect:
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
