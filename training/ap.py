"""Detection metrics in plain numpy: IoU, greedy matching by score, average precision.

AP follows PASCAL VOC 2010+ / COCO-style all-point interpolation: detections of
all images sorted by score, each matched greedily to the unmatched ground-truth
box of its image with the highest IoU >= threshold; precision made monotone
(non-increasing) and integrated over recall. Detections whose best overlap is an
*ignored* ground-truth box (vehicles too occluded or too small to be required)
count neither as true nor as false positives.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from monorarp.core.boxes import iou_matrix


@dataclass
class Matches:
    """Per detection (all images, sorted by descending score): 1 = TP, 0 = FP, -1 = ignored."""

    outcome: np.ndarray
    scores: np.ndarray
    n_gt: int
    pairs: list[tuple[int, int, int]]  # (image index, detection index, gt index) of true positives


def match(dets: list[np.ndarray], scores: list[np.ndarray], gts: list[np.ndarray],
          iou_threshold: float, ignore: list[np.ndarray] | None = None) -> Matches:
    """Greedy score-ordered matching over a dataset.

    ``dets[i]`` (Ni, 4), ``scores[i]`` (Ni,), ``gts[i]`` (Mi, 4) for image i;
    ``ignore[i]`` (Ki, 4) boxes a detection may hit without penalty.
    """
    order_img, order_det, all_scores = [], [], []
    for i, s in enumerate(scores):
        s = np.asarray(s, dtype=np.float64).reshape(-1)
        order_img += [i] * len(s)
        order_det += list(range(len(s)))
        all_scores.append(s)
    sc = np.concatenate(all_scores) if all_scores else np.zeros(0)
    order = np.argsort(-sc, kind="stable")
    ious = [iou_matrix(d, g) for d, g in zip(dets, gts)]
    ign = [iou_matrix(d, ig) if ig is not None and len(ig) else None
           for d, ig in zip(dets, ignore or [None] * len(dets))]
    used = [np.zeros(len(np.asarray(g).reshape(-1, 4)), bool) for g in gts]
    outcome = np.zeros(len(order), dtype=np.int64)
    pairs = []
    for k, o in enumerate(order):
        i, d = order_img[o], order_det[o]
        row = ious[i][d] if ious[i].shape[1] else np.zeros(0)
        cand = np.where(used[i], -1.0, row)
        j = int(np.argmax(cand)) if cand.size else -1
        if j >= 0 and cand[j] >= iou_threshold:
            used[i][j] = True
            outcome[k] = 1
            pairs.append((i, d, j))
        elif ign[i] is not None and ign[i][d].max() >= iou_threshold:
            outcome[k] = -1
        else:
            outcome[k] = 0
    n_gt = int(sum(len(u) for u in used))
    return Matches(outcome, sc[order], n_gt, pairs)


def average_precision(m: Matches) -> float:
    """All-point interpolated AP from :func:`match` results (0 when there is no ground truth)."""
    keep = m.outcome >= 0
    tp = (m.outcome[keep] == 1).astype(np.float64)
    if m.n_gt == 0:
        return 0.0
    ctp = np.cumsum(tp)
    cfp = np.cumsum(1.0 - tp)
    recall = ctp / m.n_gt
    precision = ctp / np.maximum(ctp + cfp, 1e-12)
    mrec = np.concatenate([[0.0], recall, [recall[-1] if len(recall) else 0.0]])
    mpre = np.concatenate([[1.0], precision, [0.0]])
    mpre = np.maximum.accumulate(mpre[::-1])[::-1]
    return float(np.sum((mrec[1:] - mrec[:-1]) * mpre[1:]))


def ap_at(dets, scores, gts, iou_threshold: float, ignore=None) -> float:
    return average_precision(match(dets, scores, gts, iou_threshold, ignore))
