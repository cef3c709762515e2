"""Per-frame assignment of estimated boxes to ground-truth boxes.

Boxes are ``(x1, y1, x2, y2)`` in continuous pixel coordinates (see
:mod:`monorarp.types`); area = (x2 - x1) * (y2 - y1). A pair may be matched
only when its IoU is at least ``min_iou``; among those, the assignment that
maximises the total IoU is chosen (Hungarian algorithm, not greedy).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from scipy.optimize import linear_sum_assignment

MIN_IOU = 0.5


def as_boxes(boxes: Sequence[Sequence[float]] | np.ndarray) -> np.ndarray:
    """Any sequence of 4-tuples -> float (N, 4) array (empty gives shape (0, 4))."""
    arr = np.asarray(boxes, dtype=float)
    return arr.reshape(-1, 4)


def iou_matrix(a: Sequence[Sequence[float]] | np.ndarray, b: Sequence[Sequence[float]] | np.ndarray) -> np.ndarray:
    """(N, M) intersection over union of every box of ``a`` with every box of ``b``.

    Degenerate boxes (zero or negative area) have IoU 0 with everything.
    """
    a, b = as_boxes(a), as_boxes(b)
    ix1 = np.maximum(a[:, None, 0], b[None, :, 0])
    iy1 = np.maximum(a[:, None, 1], b[None, :, 1])
    ix2 = np.minimum(a[:, None, 2], b[None, :, 2])
    iy2 = np.minimum(a[:, None, 3], b[None, :, 3])
    inter = np.clip(ix2 - ix1, 0, None) * np.clip(iy2 - iy1, 0, None)
    area_a = np.clip(a[:, 2] - a[:, 0], 0, None) * np.clip(a[:, 3] - a[:, 1], 0, None)
    area_b = np.clip(b[:, 2] - b[:, 0], 0, None) * np.clip(b[:, 3] - b[:, 1], 0, None)
    union = area_a[:, None] + area_b[None, :] - inter
    with np.errstate(divide="ignore", invalid="ignore"):
        iou = np.where(union > 0, inter / union, 0.0)
    return iou


def match_boxes(gt: Sequence[Sequence[float]] | np.ndarray, est: Sequence[Sequence[float]] | np.ndarray,
                min_iou: float = MIN_IOU) -> list[tuple[int, int, float]]:
    """Hungarian assignment of ``est`` boxes to ``gt`` boxes with IoU >= ``min_iou``.

    Returns ``(gt_index, est_index, iou)`` triples sorted by ``gt_index``.
    """
    iou = iou_matrix(gt, est)
    if iou.size == 0:
        return []
    feasible = iou >= min_iou
    if not feasible.any():
        return []
    # Infeasible pairs get a cost no feasible assignment can beat; dropped afterwards.
    cost = np.where(feasible, 1.0 - iou, 1.0 + iou.shape[0] + iou.shape[1])
    rows, cols = linear_sum_assignment(cost)
    keep = feasible[rows, cols]
    return [(int(r), int(c), float(iou[r, c])) for r, c in zip(rows[keep], cols[keep])]


def split_ignored(gt_boxes: np.ndarray, counted: np.ndarray, est_boxes: np.ndarray,
                  min_iou: float = MIN_IOU) -> tuple[list[tuple[int, int, float]], np.ndarray]:
    """Match ``est`` against *all* GT boxes, then set aside what matched ignored GT.

    ``counted``: boolean mask over ``gt_boxes``; False marks objects that are
    neither to be found nor to be penalised (too occluded, out of range).
    Returns (matches with counted GT, boolean mask over ``est_boxes`` of the
    estimates that matched an *ignored* GT and so must not count as false
    positives). This is the MOTChallenge treatment of distractors.
    """
    counted = np.asarray(counted, dtype=bool)
    matches = match_boxes(gt_boxes, est_boxes, min_iou)
    ignored_est = np.zeros(len(as_boxes(est_boxes)), dtype=bool)
    kept = []
    for g, e, iou in matches:
        if counted[g]:
            kept.append((g, e, iou))
        else:
            ignored_est[e] = True
    return kept, ignored_est
