"""Alternative trackers: SORT, ByteTrack (synthetic detections, motmetrics) and OpenCV's KCF/CSRT/MOSSE/MedianFlow
(synthetic textured image sequences)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from monorarp.pipeline.registry import create
from monorarp.tracking.bytetrack import ByteTracker
from monorarp.tracking.opencv import OpenCVMultiTracker
from monorarp.tracking.sort import SortTracker
from monorarp.tracking.kalman_box import BoxKalman, boxes_to_z, x_to_boxes
from monorarp.tracking.opencv import box_to_rect, inside_fraction, rect_to_box
from monorarp.core.types import Detection

from tracking_helpers import (DT, box_at, crossing_frames, ids_with_gap, iou_ref,  # noqa: F401
                              noisy_vehicle_frames, run)


# ------------------------------------------------------------------------------------------- Kalman
def test_box_kalman_matches_textbook_filter():
    """Batched filter (Joseph form, solve) against a plain one-track filter written out here (inverse, (I-KH)P)."""
    F = np.eye(7); F[0, 4] = F[1, 5] = F[2, 6] = 1
    H = np.eye(4, 7)
    R = np.diag([1, 1, 10, 10.0]); Q = np.diag([1, 1, 1, 1, 0.01, 0.01, 1e-4])
    rng = np.random.default_rng(1)
    truth = [box_at(100 + 3 * k, 80 + k, 40 + 0.5 * k, 30 + 0.4 * k) for k in range(15)]
    meas = [b + rng.normal(0, 1.0, 4) for b in truth]
    kf = BoxKalman()
    kf.add(np.array([meas[0], meas[0] + 50]))          # a second track that is never updated
    w, h = meas[0][2] - meas[0][0], meas[0][3] - meas[0][1]
    x = np.array([meas[0][0] + w / 2, meas[0][1] + h / 2, w * h, w / h, 0, 0, 0.0])
    P = np.diag([10, 10, 10, 10, 1e4, 1e4, 1e4])
    for z_box in meas[1:]:
        kf.predict()
        kf.update(np.array([0]), z_box[None])
        x, P = F @ x, F @ P @ F.T + Q
        w, h = z_box[2] - z_box[0], z_box[3] - z_box[1]
        z = np.array([z_box[0] + w / 2, z_box[1] + h / 2, w * h, w / h])
        K = P @ H.T @ np.linalg.inv(H @ P @ H.T + R)
        x, P = x + K @ (z - H @ x), (np.eye(7) - K @ H) @ P
    np.testing.assert_allclose(kf.x[0], x, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(kf.P[0], P, rtol=1e-6, atol=1e-6)
    np.testing.assert_allclose(x_to_boxes(kf.x[:1])[0], truth[-1], atol=2.5)
    np.testing.assert_allclose(x_to_boxes(boxes_to_z(np.array(truth))), truth, atol=1e-9)


# ------------------------------------------------------------------------------------------- SORT / ByteTrack
@pytest.mark.parametrize("name", ["sort", "bytetrack"])
def test_crossing_vehicles_keep_ids(name):
    summ, outs = run(create("tracker", name), crossing_frames())
    assert summ["num_switches"] == 0 and summ["mota"] > 0.97 and summ["idf1"] > 0.97
    assert len({tr.id for o in outs for tr in o}) == 2


@pytest.mark.parametrize("name", ["sort", "bytetrack"])
def test_five_noisy_vehicles_100_frames(name):
    frames = noisy_vehicle_frames(seed=7, miss_rate=0.05)                           # 5 % misses
    tracker = SortTracker(max_age=3) if name == "sort" else ByteTracker()
    summ, outs = run(tracker, frames)
    assert summ["num_switches"] == 0 and summ["idf1"] > 0.9 and summ["mota"] > 0.85
    assert len({tr.id for o in outs for tr in o}) == 5


def test_sort_occlusion_gap_and_min_hits():
    """5 missed frames inside max_age keep the id; as in SORT's reference code, the track is output again
    once its hit streak reaches min_hits (3 matched frames after the gap)."""
    frames = []
    for k in range(60):
        b = box_at(150 + 3 * k, 200, 60, 45)
        frames.append(({1: b}, [] if 25 <= k < 30 else [b]))
    summ, outs = run(SortTracker(max_age=6, min_hits=3), frames)
    assert {tr.id for o in outs for tr in o} == {0}
    present = [bool(o) for o in outs]
    assert present[:25] == [True] * 25 and present[25:32] == [False] * 7 and all(present[32:])
    # a second object appearing later is output only from its (min_hits + 1)-th frame (streak 0 at birth)
    tr = SortTracker(min_hits=3)
    seen = []
    for k in range(10):
        dets = [Detection(tuple(box_at(100, 100, 40, 30)))]
        if k >= 5:
            dets.append(Detection(tuple(box_at(300, 120, 40, 30))))
        seen.append(sorted(t.id for t in tr.update(None, dets, k * DT)))
    assert seen[4] == [0] and seen[5:8] == [[0]] * 3 and seen[8] == [0, 1]


def test_sort_track_dies_after_max_age_and_id_not_reused():
    b = box_at(300, 200, 50, 40)
    tr = SortTracker(max_age=2, min_hits=1)
    seen = ids_with_gap(tr, b, 12, (4, 7))
    assert seen[3] == [0] and seen[4:7] == [[]] * 3
    assert seen[7] == [] and seen[8] == [1] and seen[11] == [1]       # new id, output once matched again
    tr.reset()
    assert tr.update(None, [Detection(tuple(b))], 0.0)[0].id == 0


def occluded_low_score_frames():
    """One vehicle whose detection score drops to 0.3 for 8 frames (partly occluded), then recovers."""
    frames = []
    for k in range(50):
        b = box_at(120 + 4 * k, 150, 60, 45)
        score = 0.3 if 20 <= k < 28 else 0.9
        frames.append(({1: b}, [Detection(tuple(map(float, b)), score=score)]))
    return frames


def test_bytetrack_second_association_recovers_what_sort_drops():
    frames = occluded_low_score_frames()
    summ_b, outs_b = run(ByteTracker(high_thresh=0.5, low_thresh=0.1), frames)
    assert summ_b["num_misses"] == 0 and summ_b["num_switches"] == 0 and summ_b["mota"] == 1.0
    assert {t.id for o in outs_b for t in o} == {0}
    assert [o[0].score for o in outs_b[20:28]] == [0.3] * 8          # the low-score boxes carried the track
    summ_s, outs_s = run(SortTracker(score_threshold=0.5, max_age=1, min_hits=3), frames)
    assert all(not o for o in outs_s[20:28])                        # dropped while the score is low
    assert summ_s["num_misses"] >= 8
    assert len({t.id for o in outs_s for t in o}) == 2              # and comes back under a new id
    # Without the second association (low detections discarded) ByteTrack would lose them too.
    summ_n, _ = run(ByteTracker(high_thresh=0.5, low_thresh=0.5), frames)
    assert summ_n["num_misses"] >= 8


def test_bytetrack_low_scores_never_start_tracks_and_lost_buffer():
    tr = ByteTracker()
    for k in range(10):
        assert tr.update(None, [Detection(tuple(box_at(100, 100, 40, 30)), score=0.4)], k * DT) == []
    assert tr.n_tracks == 0

    def ids(track_buffer):
        tr = ByteTracker(track_buffer=track_buffer)
        seen = []
        for k in range(30):
            b = box_at(100 + 2 * k, 100, 40, 30)
            dets = [] if 8 <= k < 18 else [Detection(tuple(b), score=0.9)]    # 10 frames unseen
            seen.append([t.id for t in tr.update(None, dets, k * DT)])
        return seen

    long_buf, short_buf = ids(30), ids(5)
    assert long_buf[7] == [0] and long_buf[8:18] == [[]] * 10 and long_buf[18] == [0]   # re-activated
    assert short_buf[18] == [] and short_buf[19] == [1]       # removed; new id once confirmed


# ------------------------------------------------------------------------------------------- OpenCV
def test_rect_conventions():
    box = (9.5, 4.5, 19.5, 14.5)                               # pixel columns/rows 10..19 / 5..14
    assert box_to_rect(box, integer=True) == (10, 5, 10, 10)
    assert rect_to_box((10, 5, 10, 10)) == box
    assert box_to_rect(box, integer=False) == (10.0, 5.0, 10.0, 10.0)
    # Independent check: draw the rectangle as OpenCV fills it and take its tight pixel box.
    img = np.zeros((30, 40), np.uint8)
    x, y, w, h = box_to_rect((3.2, 7.9, 21.4, 18.3), integer=True)
    cv2.rectangle(img, (x, y), (x + w - 1, y + h - 1), 255, thickness=-1)
    rows, cols = np.nonzero(img)
    drawn = (cols.min() - 0.5, rows.min() - 0.5, cols.max() + 0.5, rows.max() + 0.5)
    assert drawn == rect_to_box((x, y, w, h))
    np.testing.assert_allclose(drawn, (3.2, 7.9, 21.4, 18.3), atol=0.5)
    assert inside_fraction((-10.5, 0, 9.5, 10), 100, 100) == pytest.approx(0.5)


def textured_sequence(n=30, size=(320, 180), seed=0):
    """Two textured rectangles over a textured background: A moves from frame 0, B appears at frame 12.

    Returns images and the true boxes {name: (x1, y1, x2, y2) or None} per frame.
    """
    w, h = size
    rng = np.random.default_rng(seed)
    bg = cv2.GaussianBlur(rng.integers(0, 256, (h, w, 3), dtype=np.uint8), (0, 0), 3.0)
    bg = cv2.normalize(bg, None, 60, 160, cv2.NORM_MINMAX)
    tex = {name: cv2.normalize(cv2.GaussianBlur(rng.integers(0, 256, (sh, sw, 3), dtype=np.uint8), (0, 0), 3.0),
                               None, 0, 255, cv2.NORM_MINMAX)
           for name, (sw, sh) in {"A": (56, 40), "B": (48, 36)}.items()}
    images, truths = [], []
    for k in range(n):
        img = bg.copy()
        boxes = {}
        for name, (x0, y0, vx, vy, start) in {"A": (40, 60, 3, 1, 0), "B": (230, 110, -2, -1, 12)}.items():
            if k < start:
                boxes[name] = None
                continue
            x, y = x0 + vx * (k - start), y0 + vy * (k - start)
            th, tw = tex[name].shape[:2]
            img[y:y + th, x:x + tw] = tex[name]
            boxes[name] = (x - 0.5, y - 0.5, x + tw - 0.5, y + th - 0.5)
        images.append(img)
        truths.append(boxes)
    return images, truths


@pytest.mark.parametrize("name", ["kcf", "csrt", "mosse", "medianflow"])
def test_opencv_tracker_follows_and_new_object_gets_new_id(name):
    images, truths = textured_sequence()
    tracker = create("tracker", name)
    centre = lambda b: np.array([(b[0] + b[2]) / 2, (b[1] + b[3]) / 2])   # noqa: E731
    for k, (img, boxes) in enumerate(zip(images, truths)):
        dets = []
        if k == 0:
            dets = [Detection(boxes["A"])]                                   # initialised from a detection
        if k == 12:
            dets = [Detection(boxes["A"]), Detection(boxes["B"])]            # A overlaps its tracker: no new one
        tracks = {t.id: t for t in tracker.update(img, dets, k * DT)}
        assert 0 in tracks, f"frame {k}: lost A"
        assert np.abs(centre(tracks[0].box) - centre(boxes["A"])).max() <= 4.0, f"frame {k}: {tracks[0].box}"
        if k >= 12:
            assert set(tracks) == {0, 1}
            assert np.abs(centre(tracks[1].box) - centre(boxes["B"])).max() <= 4.0, f"frame {k}: B"
            assert tracks[1].coasting == (k != 12)
        else:
            assert set(tracks) == {0}
    assert tracker.n_tracks == 2
    tracker.reset()
    assert tracker.update(images[0], [Detection(truths[0]["A"])], 0.0)[0].id == 0


class _Scripted:
    """Stand-in OpenCV tracker replaying a script of (ok, rect) answers."""

    def __init__(self, script):
        self.script = list(script)

    def init(self, image, rect):
        return None

    def update(self, image):
        return self.script.pop(0)


def test_opencv_drops_failed_and_drifted_trackers_and_reinit():
    img = np.zeros((100, 200, 3), np.uint8)
    scripts = iter([[(False, (0, 0, 0, 0))],                                # fails at once
                    [(True, (150, 40, 30, 20)), (True, (195, 40, 30, 20))],  # drifts right, out
                    [(True, (20, 60, 30, 20))] * 5])
    mt = OpenCVMultiTracker("kcf")
    mt._create = lambda: _Scripted(next(scripts))
    dets = [Detection((9.5, 9.5, 39.5, 29.5)), Detection((139.5, 39.5, 169.5, 59.5)),
            Detection((19.5, 59.5, 49.5, 79.5))]
    assert [t.id for t in mt.update(img, dets, 0.0)] == [0, 1, 2]
    assert [t.id for t in mt.update(img, [], DT)] == [1, 2]                # 0 failed
    out = mt.update(img, [], 2 * DT)
    assert [t.id for t in out] == [2] and out[0].coasting                  # 1 left the image (1/6 inside)
    # periodic re-initialisation from the matched detection (off by default)
    calls = []

    class Counting(_Scripted):
        def init(self, image, rect):
            calls.append(rect)

    mt = OpenCVMultiTracker("kcf", reinit_every=2)
    mt._create = lambda: Counting([(True, (20, 60, 30, 20))] * 10)
    for k in range(6):
        mt.update(img, [Detection((19.5, 59.5, 49.5, 79.5))], k * DT)
    assert len(calls) == 1 + 2                                             # init, then at frames 2 and 4
    mt = OpenCVMultiTracker("kcf", max_unmatched=1)
    mt._create = lambda: _Scripted([(True, (20, 60, 30, 20))] * 10)
    mt.update(img, [Detection((19.5, 59.5, 49.5, 79.5))], 0.0)
    assert [len(mt.update(img, [], k * DT)) for k in (1, 2)] == [1, 0]


def test_bad_parameters():
    with pytest.raises(ValueError):
        OpenCVMultiTracker("boosting")
    with pytest.raises(ValueError):
        ByteTracker(high_thresh=0.2, low_thresh=0.5)
    with pytest.raises(ValueError):
        SortTracker(min_iou=1.5)
