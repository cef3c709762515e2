"""Global (optimal) association of detections to tracks by box overlap.

Boxes are ``(x1, y1, x2, y2)`` in continuous pixel coordinates (see
:mod:`monorarp.types`). The cost of pairing is ``1 - IoU``; pairs below the IoU
gate are never made. The assignment minimises the total cost over all pairs at
once (Hungarian algorithm), so one track cannot steal a detection that another
track needs more -- unlike first-come greedy matching.
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import linear_sum_assignment


def iou_matrix(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(A, 4) and (B, 4) boxes -> (A, B) intersection over union, 0 for empty boxes."""
    a = np.asarray(a, dtype=float).reshape(-1, 4)
    b = np.asarray(b, dtype=float).reshape(-1, 4)
    ix1 = np.maximum(a[:, None, 0], b[None, :, 0])
    iy1 = np.maximum(a[:, None, 1], b[None, :, 1])
    ix2 = np.minimum(a[:, None, 2], b[None, :, 2])
    iy2 = np.minimum(a[:, None, 3], b[None, :, 3])
    inter = np.clip(ix2 - ix1, 0.0, None) * np.clip(iy2 - iy1, 0.0, None)
    area_a = np.clip(a[:, 2] - a[:, 0], 0.0, None) * np.clip(a[:, 3] - a[:, 1], 0.0, None)
    area_b = np.clip(b[:, 2] - b[:, 0], 0.0, None) * np.clip(b[:, 3] - b[:, 1], 0.0, None)
    union = area_a[:, None] + area_b[None, :] - inter
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(union > 0.0, inter / union, 0.0)


def assign(cost: np.ndarray, max_cost: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Minimum-total-cost assignment of rows to columns, gated by ``max_cost``.

    Returns ``(matches, unmatched_rows, unmatched_cols)``: ``matches`` is an
    (M, 2) int array of (row, col) pairs, each with ``cost <= max_cost``.
    Gated pairs are excluded *before* solving, so a forbidden pair never
    displaces an allowed one.
    """
    cost = np.asarray(cost, dtype=float)
    n_rows, n_cols = cost.shape
    if n_rows == 0 or n_cols == 0:
        return np.empty((0, 2), dtype=int), np.arange(n_rows), np.arange(n_cols)
    allowed = cost <= max_cost
    big = 1e6  # finite stand-in for "forbidden"; any allowed pair costs <= max_cost << big
    rows, cols = linear_sum_assignment(np.where(allowed, cost, big))
    keep = allowed[rows, cols]
    rows, cols = rows[keep], cols[keep]
    free_rows, free_cols = np.ones(n_rows, dtype=bool), np.ones(n_cols, dtype=bool)
    free_rows[rows], free_cols[cols] = False, False
    un_rows, un_cols = np.flatnonzero(free_rows), np.flatnonzero(free_cols)
    return np.stack([rows, cols], axis=1).astype(int), un_rows, un_cols


def associate_iou(track_boxes: np.ndarray, det_boxes: np.ndarray, min_iou: float = 0.2):
    """Match predicted track boxes to detection boxes; see :func:`assign`.

    Returns ``(matches, unmatched_tracks, unmatched_detections, iou)``.
    """
    iou = iou_matrix(track_boxes, det_boxes)
    matches, un_t, un_d = assign(1.0 - iou, 1.0 - min_iou)
    return matches, un_t, un_d, iou
