"""SORT (Bewley et al. 2016, "Simple Online and Realtime Tracking").

Each frame: every track's Kalman filter (:mod:`monorarp.tracking.kalman_box`)
predicts its box; detections with ``score >= score_threshold`` are matched to
the predictions by the Hungarian algorithm on IoU (pairs below ``min_iou``
never match, :func:`monorarp.tracking.association.associate_iou`); matched
filters are corrected; every unmatched detection starts a new track; a track
unmatched for more than ``max_age`` frames is deleted.

Output (as SORT's reference code): the tracks matched or born in this frame
whose hit streak (consecutive matched frames after the one that created it) is
at least ``min_hits`` -- or any such track during the first ``min_hits`` frames
of a sequence -- with the filter's posterior box. Unmatched tracks are not output (SORT has no coasting output).
Ids count up from 0 and are never reused until :meth:`SortTracker.reset`.
Defaults are the reference code's (``max_age=1, min_hits=3, min_iou=0.3``).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from monorarp.tracking.association import associate_iou
from monorarp.tracking.kalman_box import BoxKalman
from monorarp.types import Detection, Track


def detections_array(detections: Sequence[Detection]) -> tuple[np.ndarray, np.ndarray]:
    """Boxes (N, 4) and scores (N,) of ``detections``."""
    n = len(detections)
    return (np.array([d.box for d in detections], dtype=float).reshape(n, 4),
            np.array([d.score for d in detections], dtype=float))


def to_tracks(ids, boxes, scores, labels, ages, coasting=None) -> list[Track]:
    """Rows of arrays -> :class:`Track` records."""
    out = []
    for i in range(len(ids)):
        b = boxes[i]
        out.append(Track(id=int(ids[i]), box=(float(b[0]), float(b[1]), float(b[2]), float(b[3])),
                         score=float(scores[i]), label=labels[i], age=int(ages[i]),
                         coasting=bool(coasting[i]) if coasting is not None else False))
    return out


class SortTracker:
    """SORT; ``update(image, detections, t) -> list[Track]`` (``image`` and ``t`` unused: one step per call).

    Parameters:
        max_age: frames a track survives without a matched detection.
        min_hits: consecutive matched frames before a track is output.
        min_iou: association gate (IoU of predicted box and detection).
        score_threshold: detections below this score are discarded.
    """

    def __init__(self, max_age: int = 1, min_hits: int = 3, min_iou: float = 0.3,
                 score_threshold: float = 0.0) -> None:
        if max_age < 0 or min_hits < 0:
            raise ValueError(f"need max_age >= 0 and min_hits >= 0, got {max_age}, {min_hits}")
        if not 0.0 <= min_iou <= 1.0:
            raise ValueError(f"min_iou must be in [0, 1], got {min_iou}")
        self.max_age, self.min_hits = int(max_age), int(min_hits)
        self.min_iou, self.score_threshold = float(min_iou), float(score_threshold)
        self.reset()

    def reset(self) -> None:
        """Forget every track; ids start again from 0."""
        self._kf = BoxKalman()
        self._ids = np.empty(0, dtype=np.int64)
        self._streak = np.empty(0, dtype=np.int64)        # consecutive matched frames
        self._since = np.empty(0, dtype=np.int64)         # frames since the last match
        self._age = np.empty(0, dtype=np.int64)
        self._score = np.empty(0)
        self._labels: list[str] = []
        self._next_id = 0
        self._frames = 0

    @property
    def n_tracks(self) -> int:
        return len(self._ids)

    def _keep(self, keep: np.ndarray) -> None:
        self._kf.keep(keep)
        for name in ("_ids", "_streak", "_since", "_age", "_score"):
            setattr(self, name, getattr(self, name)[keep])
        self._labels = [lab for lab, k in zip(self._labels, keep) if k]

    def update(self, image: np.ndarray | None, detections: Sequence[Detection], t: float) -> list[Track]:
        self._frames += 1
        dets = [d for d in detections if d.score >= self.score_threshold]
        boxes, scores = detections_array(dets)

        pred = self._kf.predict()
        self._age += 1
        # A track whose prediction is no longer a finite box is dropped (SORT's NaN check).
        finite = np.isfinite(pred).all(axis=1)
        if not finite.all():
            self._keep(finite)
            pred = pred[finite]
        self._since += 1
        self._streak[self._since > 1] = 0                 # missed the previous frame too

        matches, _, un_d, _ = associate_iou(pred, boxes, self.min_iou)
        rows, cols = matches[:, 0], matches[:, 1]
        self._kf.update(rows, boxes[cols])
        self._since[rows] = 0
        self._streak[rows] += 1
        self._score[rows] = scores[cols]
        for r, c in zip(rows, cols):
            self._labels[r] = dets[c].label

        if len(un_d):
            k = len(un_d)
            self._kf.add(boxes[un_d])
            self._ids = np.concatenate([self._ids, np.arange(self._next_id, self._next_id + k)])
            self._next_id += k
            self._streak = np.concatenate([self._streak, np.zeros(k, dtype=np.int64)])   # as SORT: 0 at birth
            self._since = np.concatenate([self._since, np.zeros(k, dtype=np.int64)])
            self._age = np.concatenate([self._age, np.zeros(k, dtype=np.int64)])
            self._score = np.concatenate([self._score, scores[un_d]])
            self._labels.extend(dets[i].label for i in un_d)

        show = (self._since == 0) & ((self._streak >= self.min_hits) | (self._frames <= self.min_hits))
        idx = np.flatnonzero(show)
        out = to_tracks(self._ids[idx], self._kf.boxes()[idx], self._score[idx],
                        [self._labels[i] for i in idx], self._age[idx])
        alive = self._since <= self.max_age
        if not alive.all():
            self._keep(alive)
        return out
