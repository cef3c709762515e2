"""KITTI-style 2-D average precision (pure maths, no files).

Per image and difficulty (:mod:`harness.scoring.kitti_difficulty`), KITTI object devkit's
``clean_data`` rules (valid, ignored and ``DontCare`` boxes), greedy matching by descending score,
interpolated precision sampled at 40 (``AP_R40``) and 11 (``AP_R11``) recall points, both as defined
and as the devkit samples them.
Values are fractions 0..1. The rules in full: docs/kitti.md (KITTI AP).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from harness.scoring.kitti_difficulty import DIFFICULTIES, passes
from monorarp.core.boxes import as_boxes, intersection, iou_matrix

NEIGHBOUR_CLASS = {"car": "van", "pedestrian": "person_sitting"}


def inter_over_first(a, b) -> np.ndarray:
    """(N, M) intersection area over the area of each box of ``a`` (the devkit's overlap with ignored regions).

    Not an IoU (:func:`monorarp.core.boxes.iou_matrix`): a detection inside a large DontCare
    region overlaps it fully even though their IoU is small.
    """
    a, b = as_boxes(a), as_boxes(b)
    area = (a[:, 2] - a[:, 0]) * (a[:, 3] - a[:, 1])
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(area[:, None] > 0, intersection(a[:, None, :], b[None, :, :]) / area[:, None], 0.0)


@dataclass
class ImageTruth:
    """One image's labels: types, boxes (N, 4) px, occlusion levels, truncation."""

    types: Sequence[str]
    boxes: np.ndarray
    occluded: np.ndarray
    truncated: np.ndarray


@dataclass
class ImageDetections:
    """One image's detections: boxes (M, 4) px, scores, class names."""

    boxes: np.ndarray
    scores: np.ndarray
    labels: Sequence[str]


def gt_status(truth: ImageTruth, cls: str, difficulty: str) -> tuple[np.ndarray, np.ndarray]:
    """``(status, dontcare_boxes)``: per box 0 valid, 1 ignored, -1 no part (module docstring)."""
    types = np.array([t.lower() for t in truth.types], dtype=object)
    cls = cls.lower()
    ok = passes(truth.boxes, truth.occluded, truth.truncated, difficulty) if len(types) else np.zeros(0, bool)
    of_cls = types == cls
    neighbour = types == NEIGHBOUR_CLASS.get(cls, "\0")
    status = np.where(of_cls & ok, 0, np.where(neighbour | of_cls, 1, -1)).astype(int)
    dc = as_boxes(truth.boxes)[types == "dontcare"] if len(types) else np.zeros((0, 4))
    return status, dc


def match_image(truth: ImageTruth, dets: ImageDetections, cls: str, difficulty: str, iou_threshold: float
                ) -> tuple[np.ndarray, int, int]:
    """``(outcome, n_valid, n_excused)``: per detection of the class (others: -2) 1 TP, 0 FP, -1 ignored, in
    the order of ``dets``; ``n_valid`` = valid ground-truth boxes not excused; ``n_excused`` the excused ones."""
    status, dc = gt_status(truth, cls, difficulty)
    gtb = as_boxes(truth.boxes)
    db = as_boxes(dets.boxes)
    scores = np.asarray(dets.scores, dtype=float).reshape(-1)
    of_cls = np.array([lbl.lower() == cls.lower() for lbl in dets.labels], dtype=bool)
    outcome = np.full(len(db), -2, dtype=int)
    too_small = (db[:, 3] - db[:, 1]) < DIFFICULTIES[difficulty][0]
    overlap = iou_matrix(db, gtb)
    dc_cover = inter_over_first(db, dc) if len(dc) else np.zeros((len(db), 0))
    taken = status < 0                                   # boxes of no part are never assigned
    excused = 0
    for j in np.argsort(-scores, kind="stable"):
        if not of_cls[j]:
            continue
        row = np.where(taken, -1.0, overlap[j]) if len(gtb) else np.zeros(0)
        valid = np.where(status == 0, row, -1.0)
        ign = np.where(status == 1, row, -1.0)
        if valid.size and valid.max() > iou_threshold:
            g = int(np.argmax(valid))
            taken[g] = True
            if too_small[j]:
                outcome[j], excused = -1, excused + 1
            else:
                outcome[j] = 1
        elif ign.size and ign.max() > iou_threshold:
            taken[int(np.argmax(ign))] = True
            outcome[j] = -1
        elif too_small[j] or (dc_cover.shape[1] and dc_cover[j].max() > iou_threshold):
            outcome[j] = -1
        else:
            outcome[j] = 0
    return outcome, int((status == 0).sum()) - excused, excused


def pr_curve(outcomes: Sequence[np.ndarray], scores: Sequence[np.ndarray], n_valid: int
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(thresholds, precision, recall)`` at each distinct score, from per-image outcomes (1 TP, 0 FP)."""
    o = np.concatenate([np.asarray(x).reshape(-1) for x in outcomes]) if outcomes else np.zeros(0, int)
    s = np.concatenate([np.asarray(x, dtype=float).reshape(-1) for x in scores]) if scores else np.zeros(0)
    keep = o >= 0
    o, s = o[keep], s[keep]
    order = np.argsort(-s, kind="stable")
    o, s = o[order], s[order]
    tp, fp = np.cumsum(o == 1), np.cumsum(o == 0)
    last = np.r_[np.flatnonzero(np.diff(s) != 0), len(s) - 1] if len(s) else np.zeros(0, int)
    tp, fp = tp[last], fp[last]
    with np.errstate(divide="ignore", invalid="ignore"):
        precision = tp / (tp + fp)
        recall = tp / n_valid if n_valid else np.full(len(tp), np.nan)
    return s[last], precision, recall


def interpolated_ap(precision: np.ndarray, recall: np.ndarray, points: np.ndarray) -> float:
    """Mean over ``points`` of the largest precision at recall >= each point (0 where none)."""
    p, r = np.asarray(precision, dtype=float), np.asarray(recall, dtype=float)
    if not np.isfinite(r).all():
        return float("nan")
    # Running maximum from the high-recall end; searchsorted finds the first curve point with r >= point.
    order = np.argsort(r, kind="stable")
    r, p = r[order], p[order]
    pmax = np.maximum.accumulate(p[::-1])[::-1] if p.size else p
    idx = np.searchsorted(r, np.asarray(points) - 1e-12, side="left")
    vals = np.where(idx < len(r), pmax[np.minimum(idx, max(len(r) - 1, 0))] if len(r) else 0.0, 0.0)
    return float(np.mean(vals))


def devkit_thresholds(tp_scores: np.ndarray, n_gt: int, n_points: int = 41) -> np.ndarray:
    """The devkit's ``get_thresholds``: scores of true positives at which recall passes (to the nearest)
    each of ``n_points`` evenly spaced recall samples (the first at recall ``1 / n_gt``)."""
    s = np.sort(np.asarray(tp_scores, dtype=float))[::-1]
    out, current = [], 0.0
    for i, score in enumerate(s):
        left = (i + 1) / n_gt
        right = (i + 2) / n_gt if i < len(s) - 1 else left
        if (right - current) < (current - left) and i < len(s) - 1:
            continue
        out.append(score)
        current += 1.0 / (n_points - 1.0)
    return np.array(out)


def devkit_sampled_ap(outcome: np.ndarray, scores: np.ndarray, n_gt: int) -> tuple[float, float]:
    """``(AP_R40, AP_R11)`` sampled as KITTI's devkit does (precision at :func:`devkit_thresholds`, made
    non-increasing, ``sum(p[1:41]) / 40`` and ``sum(p[0:41:4]) / 11``), from this module's matching."""
    o, s = np.asarray(outcome).reshape(-1), np.asarray(scores, dtype=float).reshape(-1)
    keep = o >= 0
    o, s = o[keep], s[keep]
    ths = devkit_thresholds(s[o == 1], n_gt)
    prec = np.zeros(41)
    if len(ths):
        order = np.argsort(-s, kind="stable")
        tp, fp = np.cumsum(o[order] == 1), np.cumsum(o[order] == 0)
        n_above = np.searchsorted(-s[order], -ths, side="right")       # detections with score >= threshold
        p = tp[n_above - 1] / np.maximum(tp[n_above - 1] + fp[n_above - 1], 1)
        prec[:len(p)] = np.maximum.accumulate(p[::-1])[::-1]
    return float(prec[1:].sum() / 40), float(prec[0::4].sum() / 11)


R40 = np.linspace(1.0 / 40, 1.0, 40)
R11 = np.linspace(0.0, 1.0, 11)


def average_precision(truths: Sequence[ImageTruth], detections: Sequence[ImageDetections], cls: str = "Car",
                      difficulty: str = "moderate", iou_threshold: float = 0.7) -> dict:
    """``ap_r40``, ``ap_r11`` (fractions; null without a valid box), the same sampled as the devkit does
    (``ap_r40_devkit``, ``ap_r11_devkit``), ``valid`` boxes, ``tp``/``fp`` at the lowest score and the
    detections ``ignored``, over a dataset (``truths[i]``, ``detections[i]``: image i)."""
    if len(truths) != len(detections):
        raise ValueError(f"{len(truths)} images of truth but {len(detections)} of detections")
    outcomes, scores, n_valid, n_excused = [], [], 0, 0
    for tr, de in zip(truths, detections):
        o, n, e = match_image(tr, de, cls, difficulty, iou_threshold)
        outcomes.append(o)
        scores.append(np.asarray(de.scores, dtype=float).reshape(-1))
        n_valid += n
        n_excused += e
    _, precision, recall = pr_curve(outcomes, scores, n_valid)
    all_o = np.concatenate(outcomes) if outcomes else np.zeros(0, int)
    all_s = np.concatenate(scores) if scores else np.zeros(0)
    nan = float("nan")
    dk40, dk11 = devkit_sampled_ap(all_o, all_s, n_valid + n_excused) if n_valid + n_excused else (nan, nan)
    return {"ap_r40": interpolated_ap(precision, recall, R40) if n_valid else nan,
            "ap_r11": interpolated_ap(precision, recall, R11) if n_valid else nan,
            "ap_r40_devkit": dk40, "ap_r11_devkit": dk11,
            "valid": n_valid, "tp": int((all_o == 1).sum()), "fp": int((all_o == 0).sum()),
            "ignored": int((all_o == -1).sum())}


def bootstrap_ap_r40(truths: Sequence[ImageTruth], detections: Sequence[ImageDetections], cls: str = "Car",
                     difficulty: str = "moderate", iou_threshold: float = 0.5, resamples: int = 400,
                     seed: int = 0) -> np.ndarray:
    """AP_R40 of ``resamples`` bootstrap resamples of the images (drawn with replacement, seeded; each image
    keeps its own matching): the sampling spread of :func:`average_precision`'s ``ap_r40`` over a set of
    images. NaN for a resample without a valid box."""
    per = [match_image(tr, de, cls, difficulty, iou_threshold) for tr, de in zip(truths, detections)]
    scores = [np.asarray(de.scores, dtype=float).reshape(-1) for de in detections]
    valid = np.array([n for _, n, _ in per], dtype=int)
    rng = np.random.default_rng(seed)
    out = np.full(resamples, np.nan)
    for b in range(resamples):
        idx = rng.integers(0, len(per), len(per)) if per else np.zeros(0, int)
        n = int(valid[idx].sum())
        if n:
            _, precision, recall = pr_curve([per[i][0] for i in idx], [scores[i] for i in idx], n)
            out[b] = interpolated_ap(precision, recall, R40)
    return out


def kitti_ap(truths: Sequence[ImageTruth], detections: Sequence[ImageDetections], cls: str = "Car",
             iou_thresholds: Sequence[float] = (0.7, 0.5)) -> dict:
    """``{"class", "iou_0.7": {"easy": {...}, "moderate": ..., "hard": ...}, "iou_0.5": ...}``."""
    out: dict = {"class": cls, "recall_points": "R40 (1/40..1) and R11 (0..1)"}
    for thr in iou_thresholds:
        out[f"iou_{thr:g}"] = {d: average_precision(truths, detections, cls, d, thr) for d in DIFFICULTIES}
    return out
