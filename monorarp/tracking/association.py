"""Global (optimal) association of detections to tracks by box overlap.

Boxes are ``(x1, y1, x2, y2)`` in continuous pixel coordinates (see
:mod:`monorarp.core.types`). The cost of pairing is ``1 - IoU``; pairs below the IoU
gate are never made. The assignment minimises the total cost over all pairs at
once (Hungarian algorithm), so one track cannot steal a detection that another
track needs more -- unlike first-come greedy matching.
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import linear_sum_assignment

from monorarp.core.boxes import iou_matrix


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
