"""ByteTrack-style tracker (Zhang et al. 2022, "ByteTrack: Multi-Object Tracking by Associating Every
Detection Box"), with SORT's box Kalman filter (:mod:`monorarp.tracking.kalman_box`).

Each frame (following the reference ``BYTETracker.update``):

1. detections are split by score: *high* ``score > high_thresh``, *low*
   ``low_thresh < score <= high_thresh`` (lower ones are discarded);
2. every track's filter predicts (a lost track's area rate is zeroed first);
3. **first association**: confirmed tracks, tracked and lost, against the high
   detections (Hungarian on ``1 - IoU``, IoU >= ``match_iou``; with
   ``fuse_score`` the IoU is multiplied by the detection score as in the
   reference code); a matched lost track is re-activated with its old id;
4. **second association**: the confirmed tracks still unmatched and currently
   tracked against the *low* detections (IoU >= ``second_iou``, no score
   fusion); tracks still unmatched become *lost*;
5. unconfirmed tracks (born last frame) against the remaining high detections
   (IoU >= ``unconfirmed_iou``); matched ones are confirmed, the others removed;
6. remaining high detections with ``score >= new_track_thresh`` start tracks,
   unconfirmed except in a sequence's first frame;
7. lost tracks unmatched for more than ``track_buffer`` frames are removed; a
   tracked/lost pair with IoU > 0.85 keeps only the older one.

Output: confirmed tracks matched in this frame, with the filter's posterior box.
Ids count up from 0, one per started track, never reused until :meth:`ByteTracker.reset`.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from monorarp.core.boxes import iou_matrix
from monorarp.tracking.association import assign
from monorarp.tracking.bookkeeping import BookTracker, TrackBook, detections_array
from monorarp.tracking.kalman_box import BoxKalman
from monorarp.core.types import Detection, Track

TRACKED, LOST = 0, 1
DUPLICATE_IOU = 0.85


def _match(track_boxes: np.ndarray, det_boxes: np.ndarray, min_iou: float, det_scores: np.ndarray | None = None):
    """Hungarian matching on ``1 - IoU`` (or ``1 - IoU * score``) gated at ``min_iou``."""
    sim = iou_matrix(track_boxes, det_boxes)
    if det_scores is not None and sim.size:
        sim = sim * det_scores[None, :]
    return assign(1.0 - sim, 1.0 - min_iou)


class ByteTracker(BookTracker):
    """ByteTrack; ``update(image, detections, t) -> list[Track]`` (``image``, ``t`` unused: one step per call).

    Parameters (see the module docstring): ``high_thresh``, ``low_thresh``,
    ``new_track_thresh`` (scores); ``match_iou``, ``second_iou``,
    ``unconfirmed_iou`` (IoU gates); ``track_buffer`` (frames a lost track is
    kept; the reference's 30 at 30 fps); ``fuse_score`` (reference default True).
    """

    def __init__(self, high_thresh: float = 0.5, low_thresh: float = 0.1, new_track_thresh: float | None = None,
                 match_iou: float = 0.2, second_iou: float = 0.5, unconfirmed_iou: float = 0.3,
                 track_buffer: int = 30, fuse_score: bool = True) -> None:
        if not 0.0 <= low_thresh <= high_thresh:
            raise ValueError(f"need 0 <= low_thresh <= high_thresh, got {low_thresh}, {high_thresh}")
        if track_buffer < 0:
            raise ValueError(f"track_buffer must be >= 0 frames, got {track_buffer}")
        self.high_thresh, self.low_thresh = float(high_thresh), float(low_thresh)
        self.new_track_thresh = float(high_thresh + 0.1 if new_track_thresh is None else new_track_thresh)
        self.match_iou, self.second_iou, self.unconfirmed_iou = float(match_iou), float(second_iou), float(unconfirmed_iou)
        self.track_buffer = int(track_buffer)
        self.fuse_score = bool(fuse_score)
        self.reset()

    def reset(self) -> None:
        """Forget every track; ids start again from 0."""
        self._kf = BoxKalman()
        # state: TRACKED or LOST; active: confirmed; start / end: frame of birth / of the last match
        self._book = TrackBook(state=((), np.int64), active=((), bool), start=((), np.int64), end=((), np.int64))

    def _keep(self, keep: np.ndarray) -> None:
        self._kf.keep(keep)
        self._book.keep(keep)

    def _hit(self, rows: np.ndarray, boxes: np.ndarray, scores: np.ndarray, labels: list[str]) -> None:
        """Correct tracks ``rows`` with their matched detections: tracked, confirmed, seen now."""
        book = self._book
        self._kf.update(rows, boxes)
        book.state[rows] = TRACKED
        book.active[rows] = True
        book.end[rows] = book.frames
        book.hit(rows, scores, labels)

    def update(self, image: np.ndarray | None, detections: Sequence[Detection], t: float) -> list[Track]:
        book = self._book
        book.step()
        boxes, scores = detections_array(detections)
        labels = [d.label for d in detections]
        high = np.flatnonzero(scores > self.high_thresh)
        low = np.flatnonzero((scores > self.low_thresh) & (scores <= self.high_thresh))

        self._kf.x[book.state == LOST, 6] = 0.0
        pred = self._kf.predict()

        # first association: confirmed tracks (tracked or lost) vs high detections
        pool = np.flatnonzero(book.active)
        m, un_p, un_h = _match(pred[pool], boxes[high], self.match_iou, scores[high] if self.fuse_score else None)
        rows, cols = pool[m[:, 0]], high[m[:, 1]]
        self._hit(rows, boxes[cols], scores[cols], [labels[c] for c in cols])

        # second association: still-tracked leftovers vs low detections; unmatched ones become lost
        rest = pool[un_p]
        rest = rest[book.state[rest] == TRACKED]
        m2, un_r, _ = _match(pred[rest], boxes[low], self.second_iou)
        rows, cols = rest[m2[:, 0]], low[m2[:, 1]]
        self._hit(rows, boxes[cols], scores[cols], [labels[c] for c in cols])
        book.state[rest[un_r]] = LOST

        # unconfirmed tracks vs the remaining high detections; unmatched ones are removed
        left = high[un_h]
        unconf = np.flatnonzero(~book.active)
        m3, un_u, un_l = _match(pred[unconf], boxes[left], self.unconfirmed_iou,
                                scores[left] if self.fuse_score else None)
        rows, cols = unconf[m3[:, 0]], left[m3[:, 1]]
        self._hit(rows, boxes[cols], scores[cols], [labels[c] for c in cols])
        keep = np.ones(self.n_tracks, dtype=bool)
        keep[unconf[un_u]] = False
        # lost tracks past the buffer are removed
        keep &= ~((book.state == LOST) & (book.frames - book.end > self.track_buffer))
        self._keep(keep)

        # new tracks from confident unmatched high detections
        new = left[un_l]
        new = new[scores[new] >= self.new_track_thresh]
        if len(new):
            self._kf.add(boxes[new])
            book.add(scores[new], [labels[i] for i in new], state=TRACKED, active=book.frames == 1,
                     start=book.frames, end=book.frames)

        self._remove_duplicates()
        show = np.flatnonzero((book.state == TRACKED) & book.active)
        return book.tracks(show, self._kf.boxes()[show])

    def _remove_duplicates(self) -> None:
        """A tracked and a lost track with IoU > 0.85: drop the one that started later (reference rule)."""
        book = self._book
        tracked = np.flatnonzero((book.state == TRACKED) & book.active)
        lost = np.flatnonzero(book.state == LOST)
        if not len(tracked) or not len(lost):
            return
        boxes = self._kf.boxes()
        pairs = np.argwhere(iou_matrix(boxes[tracked], boxes[lost]) > DUPLICATE_IOU)
        if not len(pairs):
            return
        keep = np.ones(self.n_tracks, dtype=bool)
        for a, b in pairs:
            i, j = tracked[a], lost[b]
            if book.frames - book.start[i] > book.frames - book.start[j]:
                keep[j] = False
            else:
                keep[i] = False
        self._keep(keep)
