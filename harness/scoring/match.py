"""Per-frame assignment of estimated boxes to ground-truth boxes.

Boxes are ``(x1, y1, x2, y2)`` in continuous pixel coordinates (see
:mod:`monorarp.core.types`); area = (x2 - x1) * (y2 - y1). A pair may be matched
only when its IoU is at least ``min_iou``; among those, the assignment that
maximises the total IoU is chosen (Hungarian algorithm, not greedy).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from scipy.optimize import linear_sum_assignment

from monorarp.core.boxes import as_boxes, iou_matrix

MIN_IOU = 0.5


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


def intersection_over_gt(gt: Sequence[Sequence[float]] | np.ndarray,
                         est: Sequence[Sequence[float]] | np.ndarray) -> np.ndarray:
    """(N, M) area of each gt/est intersection divided by the gt box's area (0 for degenerate gt)."""
    a, b = as_boxes(gt), as_boxes(est)
    iw = np.clip(np.minimum(a[:, None, 2], b[None, :, 2]) - np.maximum(a[:, None, 0], b[None, :, 0]), 0, None)
    ih = np.clip(np.minimum(a[:, None, 3], b[None, :, 3]) - np.maximum(a[:, None, 1], b[None, :, 1]), 0, None)
    area = np.clip(a[:, 2] - a[:, 0], 0, None) * np.clip(a[:, 3] - a[:, 1], 0, None)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(area[:, None] > 0, iw * ih / area[:, None], 0.0)


def split_ignored(gt_boxes: np.ndarray, counted: np.ndarray, est_boxes: np.ndarray,
                  min_iou: float = MIN_IOU, ignore_cover: float | None = None,
                  est_out_of_range: np.ndarray | None = None) -> tuple[list[tuple[int, int, float]], np.ndarray]:
    """Match ``est`` against *all* GT boxes, then set aside estimates that must not be penalised.

    ``counted``: boolean mask over ``gt_boxes``; False marks objects that are
    neither to be found nor to be penalised (too occluded, out of range).
    An estimate is set aside when (MOTChallenge's distractor rule) the
    Hungarian assignment at ``min_iou`` gives it an ignored object, or, when it
    has no counted object at IoU >= ``min_iou`` at all, if it covers at least
    ``ignore_cover`` of an ignored object's (visible) box (e.g. a track coasting
    on the whole vehicle while only a sliver is visible), or if
    ``est_out_of_range`` flags it (nuScenes-style range filter on predictions).
    Returns (matches with counted GT, boolean mask over ``est_boxes`` of the
    estimates set aside).
    """
    counted = np.asarray(counted, dtype=bool)
    gt_boxes, est_boxes = as_boxes(gt_boxes), as_boxes(est_boxes)
    matches = match_boxes(gt_boxes, est_boxes, min_iou)
    ignored_est = np.zeros(len(est_boxes), dtype=bool)
    kept = []
    for g, e, iou in matches:
        if counted[g]:
            kept.append((g, e, iou))
        else:
            ignored_est[e] = True
    free = np.ones(len(est_boxes), dtype=bool)
    free[[e for _, e, _ in kept]] = False
    free &= ~ignored_est
    if free.any():
        near_counted = (iou_matrix(gt_boxes[counted], est_boxes) >= min_iou).any(axis=0)
        candidates = free & ~near_counted
        if ignore_cover is not None and (~counted).any():
            covered = (intersection_over_gt(gt_boxes[~counted], est_boxes) >= ignore_cover).any(axis=0)
            ignored_est |= candidates & covered
        if est_out_of_range is not None:
            ignored_est |= candidates & np.asarray(est_out_of_range, dtype=bool)
    return kept, ignored_est
