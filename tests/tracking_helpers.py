"""Shared by the tracker tests: a scalar IoU reference and motmetrics scoring of a tracker on synthetic boxes."""

import motmetrics as mm
import numpy as np

from monorarp.core.types import Detection

DT = 1 / 30


def iou_ref(a, b) -> float:
    """Plain scalar IoU, the reference for the vectorised one."""
    w = max(0.0, min(a[2], b[2]) - max(a[0], b[0]))
    h = max(0.0, min(a[3], b[3]) - max(a[1], b[1]))
    inter = w * h
    union = (a[2] - a[0]) * (a[3] - a[1]) + (b[2] - b[0]) * (b[3] - b[1]) - inter
    return inter / union if union > 0 else 0.0


def box_at(cx, cy, w, h):
    return np.array([cx - w / 2, cy - h / 2, cx + w / 2, cy + h / 2])


def run(tracker, frames, images=None):
    """frames: list of (gt {id: box}, detections [Detection | box]) -> (motmetrics row, tracks per frame)."""
    acc = mm.MOTAccumulator(auto_id=True)
    outs = []
    for k, (gt, dets) in enumerate(frames):
        dets = [d if isinstance(d, Detection) else Detection(tuple(map(float, d))) for d in dets]
        tracks = tracker.update(None if images is None else images[k], dets, k * DT)
        outs.append(tracks)
        dist = np.array([[1 - iou_ref(g, tr.box) if iou_ref(g, tr.box) >= 0.5 else np.nan for tr in tracks]
                         for g in gt.values()]).reshape(len(gt), len(tracks))
        acc.update(list(gt), [tr.id for tr in tracks], dist)
    summ = mm.metrics.create().compute(acc, metrics=["mota", "idf1", "num_switches", "num_false_positives",
                                                     "num_misses"])
    return summ.iloc[0], outs
