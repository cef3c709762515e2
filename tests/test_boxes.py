"""The one IoU (monorarp.core.boxes) against independent references: a scalar loop and pixel counting."""

from __future__ import annotations

import numpy as np
import pytest

from monorarp.core.boxes import intersection, iou, iou_matrix

from tracking_helpers import iou_ref


def _random_boxes(rng: np.random.Generator, n: int) -> np.ndarray:
    xy = rng.uniform(0, 100, (n, 2))
    return np.hstack([xy, xy + rng.uniform(1, 40, (n, 2))])


def test_iou_matrix_matches_scalar_reference():
    rng = np.random.default_rng(0)
    a, b = _random_boxes(rng, 7), _random_boxes(rng, 5)
    ref = np.array([[iou_ref(x, y) for y in b] for x in a])
    np.testing.assert_allclose(iou_matrix(a, b), ref, atol=1e-12)


def _raster_iou(a, b, size=40):
    """IoU by counting pixels of integer-aligned boxes (independent reference)."""
    ma = np.zeros((size, size), bool)
    mb = np.zeros((size, size), bool)
    ma[a[1]:a[3], a[0]:a[2]] = True
    mb[b[1]:b[3], b[0]:b[2]] = True
    union = (ma | mb).sum()
    return (ma & mb).sum() / union if union else 0.0


def test_iou_matrix_matches_pixel_counting():
    rng = np.random.default_rng(1)
    boxes = []
    for _ in range(12):
        x = np.sort(rng.choice(40, 2, replace=False))
        y = np.sort(rng.choice(40, 2, replace=False))
        boxes.append((int(x[0]), int(y[0]), int(x[1]), int(y[1])))
    got = iou_matrix(boxes[:5], boxes[5:])
    ref = np.array([[_raster_iou(p, q) for q in boxes[5:]] for p in boxes[:5]])
    np.testing.assert_allclose(got, ref, atol=1e-12)


def test_closed_form_cases():
    assert iou_matrix([(0, 0, 10, 10)], [(5, 0, 15, 10)])[0, 0] == pytest.approx(1 / 3)
    assert iou_matrix([(0, 0, 10, 10)], [(0, 0, 10, 10)])[0, 0] == 1.0
    assert iou_matrix([(0, 0, 10, 10)], [(2, 2, 4, 4)])[0, 0] == pytest.approx(4 / 100)   # nested
    assert iou_matrix([(0, 0, 10, 10)], [(10, 0, 20, 10)])[0, 0] == 0.0                   # touching
    assert iou_matrix([(0, 0, 0, 5)], [(0, 0, 0, 5)])[0, 0] == 0.0                         # degenerate
    assert iou_matrix([(5, 5, 0, 0)], [(0, 0, 5, 5)])[0, 0] == 0.0                         # inverted


def test_empty_inputs():
    assert iou_matrix([], [(0, 0, 1, 1)]).shape == (0, 1)
    assert iou_matrix(np.zeros((3, 4)) + [0, 0, 1, 1], np.empty((0, 4))).shape == (3, 0)


def test_elementwise_iou_is_the_matrix_diagonal():
    rng = np.random.default_rng(2)
    a, b = _random_boxes(rng, 9), _random_boxes(rng, 9)
    np.testing.assert_array_equal(iou(a, b), np.diag(iou_matrix(a, b)))
    inter = intersection(a[:, None, :], b[None, :, :])
    ref = np.array([[max(0, min(x[2], y[2]) - max(x[0], y[0])) * max(0, min(x[3], y[3]) - max(x[1], y[1]))
                     for y in b] for x in a])
    np.testing.assert_allclose(inter, ref, atol=1e-9)
