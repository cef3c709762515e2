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


def crossing_frames(n=80):
    """A nearer (larger) vehicle passing in front of a farther one moving the other way, detected exactly."""
    frames = []
    for k in range(n):
        a = box_at(100 + 6 * k, 200, 80, 60)
        b = box_at(560 - 5 * k, 190, 50, 38)
        frames.append(({1: a, 2: b}, [a, b]))
    return frames


NOISY_STARTS = [(80, 210, 70, 55, 1.5), (220, 190, 40, 30, -0.5), (330, 185, 30, 23, 0.2),
                (450, 200, 60, 45, -1.2), (560, 195, 45, 34, 0.0)]


def noisy_vehicle_frames(seed=7, n=100, miss_rate=0.05, jitter=1.0):
    """Five vehicles (slowly growing boxes), each detected with `jitter` px noise and missed at `miss_rate`."""
    rng = np.random.default_rng(seed)
    frames = []
    for k in range(n):
        gt = {i: box_at(x + vx * k, y, w * (1 + 0.002 * k), h * (1 + 0.002 * k))
              for i, (x, y, w, h, vx) in enumerate(NOISY_STARTS)}
        dets = [g + rng.normal(0, jitter, 4) for g in gt.values() if rng.random() > miss_rate]
        frames.append((gt, dets))
    return frames


def ids_with_gap(tracker, box, n, gap):
    """Track ids output per frame for one still `box` over `n` frames, undetected in frames gap[0] <= k < gap[1]."""
    seen = []
    for k in range(n):
        dets = [] if gap[0] <= k < gap[1] else [Detection(tuple(box))]
        seen.append([t.id for t in tracker.update(None, dets, k * DT)])
    return seen
