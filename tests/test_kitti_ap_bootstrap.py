"""The image bootstrap of KITTI's Car AP: each resample is the AP of the resampled images, recomputed."""

from __future__ import annotations

import numpy as np

from harness.scoring import kitti_ap as k


def _dataset(seed: int, n_images: int = 40):
    rng = np.random.default_rng(seed)
    truths, dets = [], []
    for _ in range(n_images):
        n = int(rng.integers(1, 6))
        xy = np.c_[rng.uniform(0, 1000, n), rng.uniform(100, 200, n)]
        boxes = np.c_[xy, xy[:, 0] + rng.uniform(30, 200, n), xy[:, 1] + rng.uniform(26, 120, n)]
        truths.append(k.ImageTruth(types=["Car"] * n, boxes=boxes, occluded=np.zeros(n, int), truncated=np.zeros(n)))
        hit = rng.random(n) < 0.7                                   # 70 % found, plus 0-2 false boxes
        fp = int(rng.integers(0, 3))
        fake = np.c_[rng.uniform(0, 1000, fp), rng.uniform(0, 100, fp)]
        fake = np.c_[fake, fake[:, 0] + 50, fake[:, 1] + 40]
        d = np.r_[boxes[hit] + rng.normal(0, 3, (hit.sum(), 4)), fake]
        sc = np.r_[rng.uniform(0.4, 1.0, hit.sum()), rng.uniform(0.0, 0.8, fp)]
        dets.append(k.ImageDetections(boxes=d, scores=sc, labels=["car"] * len(d)))
    return truths, dets


def test_each_resample_is_the_ap_of_the_resampled_images():
    truths, dets = _dataset(3)
    b = k.bootstrap_ap_r40(truths, dets, "Car", "moderate", 0.5, resamples=25, seed=7)
    rng = np.random.default_rng(7)
    for value in b:
        idx = rng.integers(0, len(truths), len(truths))
        ref = k.average_precision([truths[i] for i in idx], [dets[i] for i in idx], "Car", "moderate", 0.5)["ap_r40"]
        assert value == ref
    full = k.average_precision(truths, dets, "Car", "moderate", 0.5)["ap_r40"]
    assert 0.3 < full < 0.95 and b.std() > 0.005                 # a spread, around the full set's AP
    assert np.percentile(b, 2.5) < full < np.percentile(b, 97.5)
    assert np.array_equal(b, k.bootstrap_ap_r40(truths, dets, "Car", "moderate", 0.5, resamples=25, seed=7))
