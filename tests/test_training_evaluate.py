"""Validation figures of training.evaluate on a hand-made set with known bottom-edge errors."""

from __future__ import annotations

import numpy as np
import pytest

from training.data import Dataset
from training.evaluate import figures


def test_bottom_edge_figures_with_and_without_boxes_cut_by_the_border():
    # one 640x360 image, three required vehicles; the last is cut by the image's bottom border
    truth = np.array([[100.0, 100.0, 160.0, 140.25],
                      [300.0, 120.0, 340.0, 150.5],
                      [400.0, 250.0, 639.5, 359.5]])
    boxes = np.column_stack([np.zeros(3), truth, np.zeros(3)])
    ds = Dataset(np.zeros((1, 192, 320, 3), np.uint8), boxes, np.array([[640, 360]]), {}, truth.copy())
    pred = truth.copy()
    pred[:, 3] += [0.1, -0.4, -0.9]                  # bottom-edge errors (px)
    out = figures([pred], [np.array([0.9, 0.8, 0.7])], ds)
    assert out["ap50"] == pytest.approx(1.0)
    assert out["bottom_edge_fine_count"] == 3 and out["bottom_edge_fine_abs_err_median_px"] == pytest.approx(0.4)
    assert out["bottom_edge_fine_count_uncut"] == 2
    assert out["bottom_edge_fine_abs_err_median_px_uncut"] == pytest.approx(0.25)
