"""Colour appearance for re-identification, checked against OpenCV's calcHist and compareHist."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from monorarp.tracking.appearance import BINS, bhattacharyya, colour_histograms


def _reference(image, box, inset=0.15):
    """cv2.calcHist over the same inner box (the crop rounding of colour_histograms), L1-normalised."""
    x1, y1, x2, y2 = box
    w, h = x2 - x1, y2 - y1
    c = (int(np.floor(x1 + inset * w + 0.5)), int(np.ceil(x2 - inset * w + 0.5)),
         int(np.floor(y1 + inset * h + 0.5)), int(np.ceil(y2 - inset * h + 0.5)))
    hsv = cv2.cvtColor(np.ascontiguousarray(image[c[2]:c[3], c[0]:c[1]]), cv2.COLOR_BGR2HSV)
    hist = cv2.calcHist([hsv], [0, 1, 2], None, list(BINS), [0, 180, 0, 256, 0, 256]).ravel()
    return hist.astype(float) / hist.sum()


def test_histograms_match_calchist_and_distances_match_comparehist():
    rng = np.random.default_rng(0)
    image = rng.integers(0, 256, (120, 200, 3), dtype=np.uint8)
    boxes = np.array([[10.0, 20.0, 60.0, 70.0], [55.5, 5.2, 150.3, 100.9], [120.0, 40.0, 199.5, 119.5]])
    hists = colour_histograms(image, boxes)
    for k, b in enumerate(boxes):
        assert hists[k] == pytest.approx(_reference(image, b), abs=1e-12)
    dist = bhattacharyya(hists, hists)
    for i in range(3):
        for j in range(3):
            ref = cv2.compareHist(hists[i].astype(np.float32), hists[j].astype(np.float32),
                                  cv2.HISTCMP_BHATTACHARYYA)
            assert dist[i, j] == pytest.approx(ref, abs=1e-5)
    assert np.diag(dist) == pytest.approx(0.0, abs=1e-6)


def test_same_paint_is_near_and_other_paint_is_far():
    image = np.full((100, 300, 3), 90, np.uint8)                    # grey road
    image[30:60, 20:60] = (30, 30, 200)                              # red car
    image[30:60, 120:160] = (30, 30, 200)                            # the same red car elsewhere
    image[30:60, 220:260] = (200, 80, 20)                            # a blue car
    h = colour_histograms(image, np.array([[20, 30, 60, 60], [120, 30, 160, 60], [220, 30, 260, 60]], float))
    d = bhattacharyya(h[:1], h)[0]
    assert d[1] == pytest.approx(0.0, abs=1e-9) and d[2] == pytest.approx(1.0)


def test_a_box_off_the_image_is_empty():
    image = np.full((100, 200, 3), 90, np.uint8)
    h = colour_histograms(image, np.array([[20.0, 20.0, 80.0, 50.0], [300.0, 0.0, 340.0, 20.0]]))
    assert h[0].sum() == pytest.approx(1.0) and not h[1].any()
    assert bhattacharyya(h[1:], h[:1])[0, 0] == 1.0
