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
from monorarp.tracking.bookkeeping import BookTracker, TrackBook, detections_array
from monorarp.tracking.kalman_box import BoxKalman
from monorarp.core.types import Detection, Track


class SortTracker(BookTracker):
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
        # streak: consecutive matched frames; since: frames since the last match
        self._book = TrackBook(streak=((), np.int64), since=((), np.int64))

    def _keep(self, keep: np.ndarray) -> None:
        self._kf.keep(keep)
        self._book.keep(keep)

    def update(self, image: np.ndarray | None, detections: Sequence[Detection], t: float) -> list[Track]:
        book = self._book
        book.step()
        dets = [d for d in detections if d.score >= self.score_threshold]
        boxes, scores = detections_array(dets)

        pred = self._kf.predict()
        # A track whose prediction is no longer a finite box is dropped (SORT's NaN check).
        finite = np.isfinite(pred).all(axis=1)
        if not finite.all():
            self._keep(finite)
            pred = pred[finite]
        book.since += 1
        book.streak[book.since > 1] = 0                   # missed the previous frame too

        matches, _, un_d, _ = associate_iou(pred, boxes, self.min_iou)
        rows, cols = matches[:, 0], matches[:, 1]
        self._kf.update(rows, boxes[cols])
        book.since[rows] = 0
        book.streak[rows] += 1
        book.hit(rows, scores[cols], [dets[c].label for c in cols])

        if len(un_d):
            self._kf.add(boxes[un_d])
            book.add(scores[un_d], [dets[i].label for i in un_d])   # streak 0 at birth, as SORT

        show = (book.since == 0) & ((book.streak >= self.min_hits) | book.early(self.min_hits))
        idx = np.flatnonzero(show)
        out = book.tracks(idx, self._kf.boxes()[idx])
        alive = book.since <= self.max_age
        if not alive.all():
            self._keep(alive)
        return out
