"""The oracle detector: exact ground-truth boxes without noise, seeded and order-independent noise."""

from __future__ import annotations

import threading

import numpy as np
import pytest

from harness.run.oracle import OracleConfigError, OracleDetector
from harness.world.truth import EgoTruth, FrameTruth, ObjectTruth
from monorarp.core.camera import CameraModel

W, H = 320, 180


def _truth(frame: int, n: int = 6) -> FrameTruth:
    rng = np.random.default_rng(frame + 100)
    objs = []
    for i in range(n):
        x1, y1 = rng.uniform(0, 250), rng.uniform(60, 140)
        w, h = rng.uniform(5, 60), rng.uniform(3, 40)
        objs.append(ObjectTruth(id=i + 1, box=(x1, y1, x1 + w, min(y1 + h, H - 0.5)),
                                visibility=float(rng.choice([0.1, 0.29, 0.3, 0.8, 1.0])),
                                d_long=20.0, d_lat=0.0, v_long=0.0, v_lat=0.0))
    return FrameTruth(frame=frame, t=frame / 15, ego=EgoTruth(speed=20.0), objects=tuple(objs))


def _img() -> np.ndarray:
    return np.zeros((H, W, 3), np.uint8)


def test_noise_free_boxes_are_exactly_the_visible_ground_truth():
    det = OracleDetector(min_visibility=0.3, min_height_px=4.0)
    for f in range(5):
        truth = _truth(f)
        img = _img()
        det.set_truth(truth, img)
        boxes = [d.box for d in det.detect(img)]
        want = [o.box for o in truth.objects if o.visibility >= 0.3 and o.box[3] - o.box[1] >= 4.0]
        assert boxes == want


def test_truth_follows_the_image_not_the_call_order():
    det = OracleDetector(jitter_px=1.0, seed=5)
    imgs = [_img() for _ in range(3)]
    for f, img in enumerate(imgs):
        det.set_truth(_truth(f), img)
    out = {f: det.detect(imgs[f]) for f in (2, 0, 1)}           # out of order
    ref = OracleDetector(jitter_px=1.0, seed=5)
    for f in range(3):
        assert out[f] == ref.detections_for(_truth(f), (W, H))   # same seed + frame -> same noise
    with pytest.raises(RuntimeError):
        det.detect(_img())                                      # nothing queued


def test_copied_image_falls_back_to_fifo_order():
    det = OracleDetector()
    a, b = _img(), _img()
    det.set_truth(_truth(0), a)
    det.set_truth(_truth(1), b)
    first = det.detect(a.copy())
    assert first == det.detections_for(_truth(0), (W, H))


def test_noise_statistics_match_settings():
    det = OracleDetector(min_visibility=0.0, min_height_px=0.0, jitter_px=2.0, seed=1)
    truths = [_truth(f, 10) for f in range(200)]
    diffs = []
    for tr in truths:
        got = np.array([d.box for d in det.detections_for(tr, (1000, 1000))])
        diffs.append(got - np.array([o.box for o in tr.objects]))
    d = np.concatenate(diffs).ravel()
    assert abs(d.mean()) < 0.1 and d.std() == pytest.approx(2.0, rel=0.05)

    miss = OracleDetector(min_visibility=0.0, min_height_px=0.0, miss_rate=0.25, seed=2)
    kept = sum(len(miss.detections_for(tr, (W, H))) for tr in truths) / (10 * len(truths))
    assert kept == pytest.approx(0.75, abs=0.03)

    cam = CameraModel.from_fov(W, H, 70.0, 1.3, pitch_rad=np.radians(2))
    fp = OracleDetector(false_positives=1.5, seed=3, camera=cam)
    empty = [FrameTruth(frame=f, t=0.0, ego=EgoTruth(speed=20.0)) for f in range(2000)]
    boxes = [d.box for tr in empty for d in fp.detections_for(tr, (W, H))]
    assert len(boxes) / 2000 == pytest.approx(1.5, rel=0.06)  # Poisson mean; sd of the estimate 1.8 %
    b = np.array(boxes)
    assert (b[:, 3] > cam.horizon_row).all()                              # standing below the horizon
    assert (b[:, 2] > b[:, 0]).all() and (b[:, 3] > b[:, 1]).all()
    assert (b[:, [0, 1]] >= -0.5).all() and (b[:, 2] <= W - 0.5).all() and (b[:, 3] <= H - 0.5).all()


def test_thread_safe_feeding():
    det = OracleDetector(jitter_px=0.5, seed=9)
    imgs = [_img() for _ in range(50)]
    for f, img in enumerate(imgs):
        det.set_truth(_truth(f), img)
    out: dict[int, list] = {}

    def work(fs):
        for f in fs:
            out[f] = det.detect(imgs[f])

    threads = [threading.Thread(target=work, args=(range(k, 50, 4),)) for k in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert all(out[f] == det.detections_for(_truth(f), (W, H)) for f in range(50))


def test_bad_settings_are_user_errors():
    with pytest.raises(OracleConfigError, match="miss rate"):
        OracleDetector(miss_rate=1.5)
    with pytest.raises(OracleConfigError, match="jitter"):
        OracleDetector(jitter_px=-1)
