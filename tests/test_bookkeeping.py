"""TrackBook: ids, aligned columns through births and deletions, frames, Track records."""

from __future__ import annotations

import numpy as np

from monorarp.tracking.bookkeeping import TrackBook, detections_array
from monorarp.core.types import Detection


def test_ids_count_up_and_columns_stay_aligned():
    book = TrackBook(hits=((), np.int64), hist=((3, 2), np.float64))
    book.add(np.array([0.9, 0.8]), ["car", "truck"], hits=1)
    book.step()
    book.add(np.array([0.7]), ["bus"], hist=np.ones((1, 3, 2)))
    assert book.ids.tolist() == [0, 1, 2] and book.age.tolist() == [1, 1, 0]
    assert book.hits.tolist() == [1, 1, 0] and book.hist.shape == (3, 3, 2) and book.hist[2].sum() == 6
    book.keep(np.array([True, False, True]))
    assert book.ids.tolist() == [0, 2] and book.labels == ["car", "bus"] and book.hist[1].sum() == 6
    book.add(np.array([0.5]), ["car"])
    assert book.ids.tolist() == [0, 2, 3]           # ids are never reused
    book.hit(np.array([1]), np.array([0.25]), ["van"])
    assert book.score.tolist() == [0.9, 0.25, 0.5] and book.labels[1] == "van"
    book.reset()
    assert len(book) == 0 and book.frames == 0 and book.hist.shape == (0, 3, 2)
    book.add(np.array([0.5]), ["car"])
    assert book.ids.tolist() == [0]


def test_frames_early_and_track_records():
    book = TrackBook()
    assert book.early(0)                             # frame 0: before the first update
    book.step()
    assert book.early(1) and not book.early(0)
    book.step()
    assert not book.early(1)
    book.add(np.array([0.6, 0.4]), ["car", "car"])
    book.step()
    tracks = book.tracks(np.array([1]), np.array([[1.0, 2.0, 3.0, 4.0]]), coasting=np.array([True]))
    assert len(tracks) == 1
    t = tracks[0]
    assert (t.id, t.box, t.score, t.label, t.age, t.coasting) == (1, (1.0, 2.0, 3.0, 4.0), 0.4, "car", 1, True)
    assert book.tracks(np.array([0]), np.zeros((1, 4)))[0].coasting is False


def test_detections_array():
    boxes, scores = detections_array([Detection(box=(1, 2, 3, 4), score=0.5, label="car")])
    assert boxes.tolist() == [[1, 2, 3, 4]] and scores.tolist() == [0.5]
    boxes, scores = detections_array([])
    assert boxes.shape == (0, 4) and scores.shape == (0,)
