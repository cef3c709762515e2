"""Track bookkeeping shared by the multi-object trackers (particle, SORT, ByteTrack).

A :class:`TrackBook` holds one row per track in parallel numpy columns: the
common ones (``ids``, ``age`` in frames, ``score`` of the last matched
detection, ``labels``) plus the columns a tracker declares for its own motion
model and track control (hit counts, misses, particles, ...). It hands out ids
(counting up from 0, never reused until :meth:`TrackBook.reset`), counts the
frames of the sequence, keeps the columns aligned when tracks are born or
deleted, and turns rows into the :class:`~monorarp.core.types.Track` records the
trackers output. The trackers keep only their motion model and association.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
import numpy.typing as npt

from monorarp.core.types import Detection, Track

_COMMON = {"ids": ((), np.int64), "age": ((), np.int64), "score": ((), np.float64)}


def detections_array(detections: Sequence[Detection]) -> tuple[np.ndarray, np.ndarray]:
    """Boxes (N, 4) (x1, y1, x2, y2) px and scores (N,) of ``detections``."""
    n = len(detections)
    return (np.array([d.box for d in detections], dtype=float).reshape(n, 4),
            np.array([d.score for d in detections], dtype=float))


class TrackBook:
    """Per-track columns; ``columns`` maps each extra column name to ``(shape of one row, dtype)``.

    Columns are attributes (``book.ids``, ``book.hits``...), numpy arrays with one row per track.
    """

    def __init__(self, **columns: tuple[tuple[int, ...], npt.DTypeLike]) -> None:
        self._columns = {**_COMMON, **columns}
        self.reset()

    def reset(self) -> None:
        """No tracks, no frames; ids start again from 0."""
        for name, (shape, dtype) in self._columns.items():
            setattr(self, name, np.empty((0, *shape), dtype=dtype))
        self.labels: list[str] = []
        self.next_id = 0
        self.frames = 0

    def __getattr__(self, name: str) -> Any:   # the columns (set in reset); for type checkers
        raise AttributeError(name)

    def __len__(self) -> int:
        return len(self.ids)

    def step(self) -> None:
        """A new frame: one more frame in the sequence, every track one frame older."""
        self.frames += 1
        self.age += 1

    def early(self, min_hits: int) -> bool:
        """In the sequence's first ``min_hits`` frames (tentative tracks are output then)."""
        return self.frames <= min_hits

    def add(self, scores: np.ndarray, labels: Sequence[str], **values: Any) -> None:
        """Start ``len(scores)`` tracks with new ids and age 0; columns not in ``values`` start at 0."""
        k = len(scores)
        if not k:
            return
        born = {"ids": np.arange(self.next_id, self.next_id + k), "score": scores, **values}
        for name, (shape, dtype) in self._columns.items():
            rows = np.broadcast_to(np.asarray(born.get(name, 0), dtype=dtype), (k, *shape))
            setattr(self, name, np.concatenate([getattr(self, name), rows]))
        self.labels.extend(labels)
        self.next_id += k

    def hit(self, rows: np.ndarray, scores: np.ndarray, labels: Sequence[str]) -> None:
        """Tracks ``rows`` took detections with these scores and labels."""
        self.score[rows] = scores
        for r, lab in zip(rows, labels):
            self.labels[r] = lab

    def keep(self, keep: np.ndarray) -> None:
        """Keep only the tracks where the boolean mask ``keep`` is true (the others are deleted)."""
        for name in self._columns:
            setattr(self, name, getattr(self, name)[keep])
        self.labels = [lab for lab, k in zip(self.labels, keep) if k]

    def tracks(self, rows: np.ndarray, boxes: np.ndarray, coasting: np.ndarray | None = None) -> list[Track]:
        """:class:`Track` records of ``rows`` with their (len(rows), 4) ``boxes`` (x1, y1, x2, y2) px."""
        out = []
        for k, i in enumerate(rows):
            b = boxes[k]
            out.append(Track(id=int(self.ids[i]), box=(float(b[0]), float(b[1]), float(b[2]), float(b[3])),
                             score=float(self.score[i]), label=self.labels[i], age=int(self.age[i]),
                             coasting=bool(coasting[k]) if coasting is not None else False))
        return out


class BookTracker:
    """Base of the trackers whose tracks live in a :class:`TrackBook` (``self._book``)."""

    _book: TrackBook

    @property
    def n_tracks(self) -> int:
        """Tracks held now (output or not)."""
        return len(self._book)
