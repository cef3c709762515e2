"""Particle tracker and association on synthetic detections, scored with motmetrics."""

from __future__ import annotations

import numpy as np
import pytest

from monorarp.pipeline.registry import create
from monorarp.tracking.particle import ParticleTracker
from monorarp.core.boxes import iou_matrix
from monorarp.tracking.association import assign, associate_iou
from monorarp.tracking.particle import systematic_resample
from monorarp.core.types import Detection

from tracking_helpers import (DT, box_at, crossing_frames, ids_with_gap, iou_ref,  # noqa: F401
                              noisy_vehicle_frames, run)


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
    frames = crossing_frames(80)
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
    frames = noisy_vehicle_frames(seed=7, miss_rate=0.05, jitter=1.0)              # 1 px jitter, 5 % misses
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
    tracker = ParticleTracker(max_coast=4, max_lost=0)
    seen = ids_with_gap(tracker, b, 20, (5, 15))
    assert seen[4] == [0]
    assert seen[5:9] == [[0]] * 4 and seen[9] == []                        # coasts 4 frames, then deleted
    assert tracker.n_tracks == 0 or 0 not in seen[15]
    assert 0 not in seen[16] and seen[16] == [1]                          # new object: a new id
    tracker.reset()
    assert tracker.update(None, [Detection(tuple(b))], 0.0)[0].id == 0    # reset starts again


# ---------------------------------------------------------------- dense traffic (issue 8)
# A far car half hidden behind a nearer one is missed by the detector for many frames in a row
# (dense_traffic: gaps of 5-30 frames). These cases isolate what the tracker does about it.

def test_coasting_box_stays_on_a_small_far_vehicle():
    """A 14 x 10 px car moving 1.5 px/frame, detections with 0.7 px jitter, 12 frames undetected:
    the coasting box must stay on it (IoU >= 0.5 every frame). The velocity is fitted to the last
    detections; differencing consecutive posterior means (the old model) drifts off within a few frames."""
    rng = np.random.default_rng(11)
    frames = []
    for k in range(60):
        b = box_at(300 + 1.5 * k, 200 + 0.2 * k, 14, 10)
        dets = [] if 30 <= k < 42 else [b + rng.normal(0, 0.7, 4)]
        frames.append(({1: b}, dets))
    summ, outs = run(ParticleTracker(max_coast=12), frames)
    coast = [(o[0], frames[k][0][1]) for k, o in enumerate(outs) if 30 <= k < 42]
    assert all(tr.coasting and tr.id == 0 for tr, _ in coast) and len(coast) == 12
    assert min(iou_ref(tr.box, g) for tr, g in coast) >= 0.5
    assert summ["num_misses"] == 0 and summ["num_false_positives"] == 0 and summ["num_switches"] == 0


def test_vehicle_lost_for_two_seconds_gets_its_id_back():
    """Undetected for 30 frames (> max_coast): not output meanwhile, but kept and predicted, so
    it is re-identified on its predicted box when it is detected again (the old tracker deleted it
    after max_coast and gave the same vehicle a new id)."""
    frames = []
    for k in range(80):
        b = box_at(200 + 1.0 * k, 180, 30, 20)
        frames.append(({1: b}, [] if 20 <= k < 50 else [b]))
    tracker = ParticleTracker()
    summ, outs = run(tracker, frames)
    assert all(not o for o in outs[20 + tracker.max_coast:50])                # lost: not output
    assert {tr.id for o in outs for tr in o} == {0}                           # ... and the same id after
    assert summ["num_switches"] == 0 and summ["num_false_positives"] == 0


def test_track_hidden_behind_a_nearer_vehicle_is_not_output():
    """A far car (small box, bottom edge high) passes behind a near one (large box, bottom edge low);
    once its predicted box is covered by the near car's detection it is not output (no ghost on
    the near car), yet kept, and it keeps its id when it comes out on the other side."""
    frames = []
    for k in range(70):
        near = box_at(300, 220, 120, 80)                                      # y 180..260
        far = box_at(180 + 4 * k, 200, 30, 20)                                # y 190..210, crosses x 240..360
        hidden = far[0] >= near[0] and far[2] <= near[2]                       # inside the near car's box
        gt = {1: near} if hidden else {1: near, 2: far}
        frames.append((gt, [near] if hidden else [near, far]))
    summ, outs = run(ParticleTracker(), frames)
    hidden_frames = [k for k, (gt, _) in enumerate(frames) if 2 not in gt]
    assert len(hidden_frames) >= 15
    assert all(len(outs[k]) == 1 for k in hidden_frames)                    # only the near car
    assert len({tr.id for o in outs for tr in o}) == 2                        # the far car keeps its id
    assert summ["num_false_positives"] == 0 and summ["num_switches"] == 0


def test_second_box_on_a_tracked_vehicle_starts_no_track():
    """A detector without NMS puts a second, shifted box on a vehicle for a few frames (IoU ~0.7 with
    the first): it must not become a second track that later takes the vehicle's id."""
    frames = []
    for k in range(40):
        b = box_at(300 - 3 * k, 200, 90, 50)
        dets = [b]
        if 10 <= k < 16:
            dets.append(b + np.array([-12.0, 0, -12.0, 0]))                   # the same car, shifted
        frames.append(({1: b}, dets))
    summ, outs = run(ParticleTracker(), frames)
    assert {tr.id for o in outs for tr in o} == {0}
    assert summ["num_false_positives"] == 0 and summ["num_switches"] == 0


def test_track_leaving_the_view_is_not_coasted_off_the_image():
    """A passing car leaves through the right border: its last detection touches the border while it
    moves outwards, so it is not output coasting after it has gone (needs the image, for its width)."""
    image = np.zeros((360, 640, 3), np.uint8)
    frames = []
    for k in range(30):
        b = box_at(560 + 6 * k, 250, 100, 70)
        b = np.array([b[0], b[1], min(b[2], 639.5), b[3]])                     # the detector clips to the image
        visible = b[0] < 639.5 - 8
        frames.append(({1: b} if visible else {}, [b] if visible else []))
    summ, outs = run(ParticleTracker(), frames, images=[image] * len(frames))
    assert summ["num_false_positives"] == 0
    gone = [k for k, (gt, _) in enumerate(frames) if not gt]
    assert gone and all(not outs[k] for k in gone)


def test_fit_velocity_is_least_squares_slope():
    from monorarp.tracking.particle import fit_velocity
    rng = np.random.default_rng(0)
    z = rng.normal(size=(4, 10, 4))
    t = rng.uniform(0, 1, (4, 10))
    t[0, 3:] = np.nan; z[0, 3:] = 0.0                                         # 3 of 10 slots filled
    t[1, 1:] = np.nan; z[1, 1:] = 0.0                                         # one: no slope
    v = fit_velocity(z, t)
    for i in (0, 2, 3):
        ok = ~np.isnan(t[i])
        np.testing.assert_allclose(v[i], np.polyfit(t[i, ok], z[i, ok], 1)[0], atol=1e-9)
    assert np.all(v[1] == 0.0)


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
    with pytest.raises(ValueError):
        ParticleTracker(vel_window=1)
    with pytest.raises(ValueError):
        ParticleTracker(max_lost=-1)
    for bad in ({"reid_distance": 0.0}, {"reid_distance": 1.5}, {"reid_gate": 0.0}):
        with pytest.raises(ValueError, match=next(iter(bad))):
            ParticleTracker(**bad)


# ------------------------------------------------------------ weak detections (second association pass)
def test_weak_detection_extends_a_track_but_never_starts_one():
    trk = ParticleTracker(seed=0, min_hits=2)
    car, ghost = (100.0, 100.0, 140.0, 130.0), (300.0, 100.0, 330.0, 125.0)
    for k in range(3):
        trk.update(None, [Detection(car, 0.9)], k * DT)
    tid = {t.id for t in trk.update(None, [Detection(car, 0.9)], 3 * DT)}
    for k in range(4, 30):                     # the car only weakly seen; a weak box elsewhere
        out = trk.update(None, [Detection(car, 0.35, weak=True), Detection(ghost, 0.35, weak=True)], k * DT)
        assert {t.id for t in out} == tid      # past max_coast (10) too: the weak boxes keep it matched
        assert all(t.coasting for t in out)    # but measure nothing: output as coasting (no state update)
    out = trk.update(None, [Detection(car, 0.9)], 30 * DT)
    assert {t.id for t in out} == tid and not out[0].coasting
    plain = ParticleTracker(seed=0, min_hits=2)
    for k in range(4):
        plain.update(None, [Detection(car, 0.9)], k * DT)
    for k in range(4, 30):                     # the same frames given no detection: coasts, then is dropped
        out = plain.update(None, [], k * DT)
    assert out == []


def test_strong_detection_wins_over_a_weak_one_that_overlaps_more():
    """A single pass would give the track the weak box (IoU 1.0 beats 0.6); the second-pass rule gives it the
    strong one, and the weak box starts nothing."""
    trk = ParticleTracker(seed=0, min_hits=1, meas_noise=0.02)
    car = (100.0, 100.0, 140.0, 130.0)
    for k in range(5):
        trk.update(None, [Detection(car, 0.9)], k * DT)
    shifted = (108.0, 100.0, 148.0, 130.0)     # IoU 0.67 with the car's box
    assert iou_matrix(np.array([car]), np.array([shifted]))[0, 0] == pytest.approx(32 / 48)
    out = trk.update(None, [Detection(car, 0.40, weak=True), Detection(shifted, 0.9)], 5 * DT)
    assert len(out) == 1 and out[0].box == pytest.approx(shifted)
    single = ParticleTracker(seed=0, min_hits=1, meas_noise=0.02)   # both strong: the closer box wins
    for k in range(5):
        single.update(None, [Detection(car, 0.9)], k * DT)
    out = single.update(None, [Detection(car, 0.40), Detection(shifted, 0.9)], 5 * DT)
    assert out[0].box == pytest.approx(car)


def test_min_score_makes_low_scoring_detections_weak():
    trk = ParticleTracker(seed=0, min_hits=1, min_score=0.5)
    assert trk.update(None, [Detection((10.0, 10.0, 50.0, 40.0), 0.4)], 0.0) == []
    assert len(trk.update(None, [Detection((10.0, 10.0, 50.0, 40.0), 0.6)], DT)) == 1


def _painted(boxes_colours, shape=(240, 400)):
    """A grey image with each (box, BGR colour) painted in, later ones in front."""
    image = np.full((*shape, 3), 90, np.uint8)
    for b, colour in boxes_colours:
        x1, y1, x2, y2 = (int(round(v)) for v in b)
        image[y1:y2, x1:x2] = colour
        image[y1:y1 + (y2 - y1) // 3, x1:x2] = (25, 25, 25)            # a dark rear window
    return image


def _reappearing(colour_after):
    """A red car tracked 20 frames (+1 px/frame), unseen 30, then seen 60 px behind its predicted box
    (IoU 0 with it, so only appearance can re-identify it), painted ``colour_after``."""
    red = (30, 30, 200)
    frames, images = [], []
    for k in range(70):
        if k < 20:
            b = box_at(100 + k, 150, 30, 20)
            frames.append(({1: b}, [b]))
            images.append(_painted([(b, red)]))
        elif k < 50:
            frames.append(({}, []))
            images.append(_painted([]))
        else:
            b = box_at(90, 150, 30, 20)
            frames.append(({1: b}, [b]))
            images.append(_painted([(b, colour_after)]))
    return frames, images


def test_lost_vehicle_is_reidentified_by_its_colour_not_by_a_differently_coloured_one():
    frames, images = _reappearing((30, 30, 200))
    _, outs = run(ParticleTracker(), frames, images)
    assert {tr.id for o in outs for tr in o} == {0}                           # the red car keeps id 0
    _, outs = run(ParticleTracker(reid_distance=None), frames, images)
    assert {tr.id for o in outs[50:] for tr in o} == {1}                      # off: a new id
    frames, images = _reappearing((200, 80, 20))                              # a blue car there instead
    _, outs = run(ParticleTracker(), frames, images)
    assert {tr.id for o in outs[50:] for tr in o} == {1}
    _, outs = run(ParticleTracker(), *_reappearing((30, 30, 200))[:1])        # no image: no appearance
    assert {tr.id for o in outs[50:] for tr in o} == {1}


def test_reidentified_track_forgets_its_old_motion():
    """After re-identification the particles restart at the detection with no velocity: coasting on
    (the car unseen again), its box stays where the car was seen, instead of drifting back along the
    line the least-squares velocity would draw through the old and the new positions."""
    frames, images = _reappearing((30, 30, 200))
    frames = frames[:51] + [({}, [])] * 6
    images = images[:51] + [images[50]] * 6
    _, outs = run(ParticleTracker(box_output="mean"), frames, images)
    assert [tr.id for tr in outs[50]] == [0] and all(tr.coasting for tr in outs[56])
    assert outs[56][0].box == pytest.approx(tuple(box_at(90, 150, 30, 20)), abs=2.0)


def test_lost_track_found_again_by_overlap_forgets_its_old_motion():
    """A far car's box shrinks 0.5 px/frame while tracked (a fitted size velocity), then it is unseen
    for 30 frames, so its lost track's predicted box keeps shrinking (to about half). Detected again
    where it is, overlapping that prediction (IoU ~0.5, no image: not re-identification), the track
    restarts at the detection: coasting on, its box stays on the car. Before, the particles stayed
    around the shrunken prediction and the coasting box was 20 px tall, not 30 (dense_traffic seed 2,
    car 23, frames 246-256)."""
    def seen(k):                                       # bottom edge fixed at y 200
        h = 40.0 - 0.5 * min(k, 20)
        return box_at(150, 200 - h / 2, 30, h)
    frames = [({1: seen(k)}, [seen(k)]) for k in range(20)] + [({}, [])] * 30
    frames += [({1: seen(20)}, [seen(20)])] + [({1: seen(20)}, [])] * 6
    _, outs = run(ParticleTracker(), frames)
    assert [tr.id for tr in outs[50]] == [0] and all(tr.coasting for tr in outs[56])
    assert outs[56][0].box == pytest.approx(tuple(seen(20)), abs=2.0)


def test_track_only_a_weak_box_supports_is_not_output_on_a_nearer_detected_vehicle():
    """A box on a near car's window is tracked while strong; when it turns weak, its track is judged as
    a coasting one (not output: it lies inside the near car's strong, nearer box)."""
    near, window = (0.0, 0.0, 100.0, 100.0), (60.0, 20.0, 80.0, 40.0)
    trk = ParticleTracker(seed=0, min_hits=1)
    for k in range(3):
        out = trk.update(None, [Detection(near, 0.9), Detection(window, 0.9)], k * DT)
    assert len(out) == 2
    out = trk.update(None, [Detection(near, 0.9), Detection(window, 0.35, weak=True)], 3 * DT)
    assert [tr.box for tr in out] == [pytest.approx(near)]
    alone = ParticleTracker(seed=0, min_hits=1)                            # no near car: still output
    for k in range(3):
        alone.update(None, [Detection(window, 0.9)], k * DT)
    out = alone.update(None, [Detection(window, 0.35, weak=True)], 3 * DT)
    assert len(out) == 1 and out[0].coasting
