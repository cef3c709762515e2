"""Particle tracker and association on synthetic detections, scored with motmetrics."""

from __future__ import annotations

import motmetrics as mm
import numpy as np
import pytest

from monorarp.registry import create
from monorarp.tracking import ParticleTracker
from monorarp.tracking.association import assign, associate_iou, iou_matrix
from monorarp.tracking.particle import systematic_resample
from monorarp.types import Detection

from tracking_helpers import DT, box_at, iou_ref, run  # noqa: F401


def test_iou_matrix_matches_scalar_reference():
    rng = np.random.default_rng(0)
    a = rng.uniform(0, 100, (7, 2)); a = np.hstack([a, a + rng.uniform(1, 40, (7, 2))])
    b = rng.uniform(0, 100, (5, 2)); b = np.hstack([b, b + rng.uniform(1, 40, (5, 2))])
    ref = np.array([[iou_ref(x, y) for y in b] for x in a])
    np.testing.assert_allclose(iou_matrix(a, b), ref, atol=1e-12)
    assert iou_matrix(a, np.empty((0, 4))).shape == (7, 0)


def test_global_assignment_where_greedy_swaps():
    """Track A overlaps both detections, B only d0. Greedy (A first, or best pair first) gives A d0 and
    leaves B unmatched; the optimal assignment gives A-d1, B-d0."""
    tracks = np.array([box_at(50, 50, 40, 40), box_at(30, 50, 40, 40)])   # A, B
    dets = np.array([box_at(42, 50, 40, 40), box_at(62, 50, 40, 40)])     # d0, d1
    iou = iou_matrix(tracks, dets)
    greedy_a = int(np.argmax(iou[0]))
    assert greedy_a == 0 and iou[1, 1] < 0.2                               # greedy strands B
    matches, un_t, un_d, _ = associate_iou(tracks, dets, min_iou=0.2)
    assert sorted(map(tuple, matches)) == [(0, 1), (1, 0)]
    assert len(un_t) == 0 and len(un_d) == 0


def test_assignment_gate():
    cost = np.array([[0.1, 0.95], [0.9, 0.97]])
    matches, un_r, un_c = assign(cost, max_cost=0.8)
    assert matches.tolist() == [[0, 0]] and un_r.tolist() == [1] and un_c.tolist() == [1]


def test_systematic_resampling_counts():
    """Systematic resampling draws particle i floor(N w_i) or ceil(N w_i) times, every row independently."""
    rng = np.random.default_rng(3)
    w = rng.random((6, 50)) ** 4
    w /= w.sum(axis=1, keepdims=True)
    idx = systematic_resample(w, rng)
    assert idx.shape == (6, 50) and idx.min() >= 0 and idx.max() < 50
    for row, wr in zip(idx, w):
        counts = np.bincount(row, minlength=50)
        assert np.all(counts >= np.floor(50 * wr) - 1e-9) and np.all(counts <= np.ceil(50 * wr) + 1e-9)


def test_two_vehicles_crossing_keep_ids():
    """A nearer (larger) vehicle passes in front of a farther one moving the other way."""
    frames = []
    for k in range(80):
        a = box_at(100 + 6 * k, 200, 80, 60)
        b = box_at(560 - 5 * k, 190, 50, 38)
        frames.append(({1: a, 2: b}, [a, b]))
    summ, outs = run(ParticleTracker(), frames)
    assert summ["num_switches"] == 0
    assert summ["mota"] > 0.97
    assert len({tr.id for o in outs for tr in o}) == 2


def test_occlusion_gap_same_id_after():
    frames = []
    for k in range(60):
        b = box_at(150 + 3 * k, 200, 60, 45)
        dets = [] if 25 <= k < 30 else [b]                                 # 5 missed frames
        frames.append(({1: b}, dets))
    tr = ParticleTracker(max_coast=10)
    summ, outs = run(tr, frames)
    ids = [o[0].id for o in outs]
    assert set(ids) == {0}
    assert [o[0].coasting for o in outs[25:30]] == [True] * 5 and not outs[30][0].coasting
    assert summ["num_switches"] == 0 and summ["mota"] > 0.98                # coasting boxes stay on target


def test_ids_stable_over_100_noisy_frames():
    rng = np.random.default_rng(7)
    starts = [(80, 210, 70, 55, 1.5), (220, 190, 40, 30, -0.5), (330, 185, 30, 23, 0.2),
              (450, 200, 60, 45, -1.2), (560, 195, 45, 34, 0.0)]
    frames = []
    for k in range(100):
        gt = {i: box_at(x + vx * k, y, w * (1 + 0.002 * k), h * (1 + 0.002 * k))
              for i, (x, y, w, h, vx) in enumerate(starts)}
        dets = [g + rng.normal(0, 1.0, 4) for g in gt.values() if rng.random() > 0.05]   # 1 px jitter, 5 % misses
        frames.append((gt, dets))
    summ, outs = run(ParticleTracker(), frames)
    assert summ["num_switches"] == 0
    assert summ["idf1"] > 0.97 and summ["mota"] > 0.95
    assert len({tr.id for o in outs for tr in o}) == 5


def test_false_positive_does_not_become_a_track():
    truth = box_at(200, 200, 60, 45)
    frames = []
    for k in range(30):
        dets = [truth]
        if k == 10:
            dets.append(box_at(500, 150, 30, 30))                          # one-frame false positive
        if k in (15, 16):
            dets.append(box_at(420, 250, 25, 25))                          # two-frame false positive
        frames.append(({1: truth}, dets))
    tracker = ParticleTracker(min_hits=2, max_coast=5)
    summ, outs = run(tracker, frames)
    fp_frames = [k for k, o in enumerate(outs) for tr in o if tr.id != 0]
    assert 10 not in fp_frames                                             # never confirmed
    assert len(fp_frames) <= 1 + 5                                         # confirmed at 16, coasts <= 5
    assert summ["num_switches"] == 0


def test_deletion_after_max_coast_and_ids_never_reused():
    b = box_at(300, 200, 50, 40)
    tracker = ParticleTracker(max_coast=4)
    seen = []
    for k in range(20):
        dets = [Detection(tuple(b))] if (k < 5 or k >= 15) else []
        seen.append([tr.id for tr in tracker.update(None, dets, k * DT)])
    assert seen[4] == [0]
    assert seen[5:9] == [[0]] * 4 and seen[9] == []                        # coasts 4 frames, then deleted
    assert tracker.n_tracks == 0 or 0 not in seen[15]
    assert 0 not in seen[16] and seen[16] == [1]                          # new object: a new id
    tracker.reset()
    assert tracker.update(None, [Detection(tuple(b))], 0.0)[0].id == 0    # reset starts again


def test_mean_output_follows_detections_and_is_deterministic():
    def once():
        tr = create("tracker", "particle", box_output="mean", seed=5)
        out = []
        for k in range(40):
            out = tr.update(None, [Detection(tuple(box_at(200 + 4 * k, 200, 60, 40)))], k * DT)
        return out[0].box
    a, b = once(), once()
    assert a == b
    np.testing.assert_allclose(a, box_at(200 + 4 * 39, 200, 60, 40), atol=1.5)


def test_bad_parameters():
    with pytest.raises(ValueError):
        ParticleTracker(box_output="median")
    with pytest.raises(ValueError):
        ParticleTracker(n_particles=0)
