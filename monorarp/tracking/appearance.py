"""Colour appearance of boxes, for re-identifying a vehicle after an occlusion.

A box's appearance is the normalised joint HSV histogram of its inner part (the box shrunk by
``inset`` of its size on every side, so the road and the neighbours at its edges weigh less):
``bins`` = (hue, saturation, value) bins over OpenCV's 8-bit HSV ranges (hue 0-179, saturation
and value 0-255). Two appearances are compared by the Bhattacharyya distance
``sqrt(1 - sum(sqrt(p * q)))`` (OpenCV's ``HISTCMP_BHATTACHARYYA`` on normalised histograms):
0 for identical histograms, 1 for disjoint ones.
"""

from __future__ import annotations

import cv2
import numpy as np

BINS = (6, 3, 3)


def colour_histograms(image: np.ndarray, boxes: np.ndarray, bins: tuple[int, int, int] = BINS,
                      inset: float = 0.15) -> np.ndarray:
    """(K, prod(bins)) L1-normalised HSV histograms of the BGR ``image`` inside (K, 4) ``boxes`` (px).

    A box with no pixel inside the image gets an all-zero row (distance 1 to everything).
    """
    boxes = np.asarray(boxes, dtype=float).reshape(-1, 4)
    out = np.zeros((len(boxes), int(np.prod(bins))))
    h, w = image.shape[:2]
    bw, bh = boxes[:, 2] - boxes[:, 0], boxes[:, 3] - boxes[:, 1]
    x1 = np.clip(np.floor(boxes[:, 0] + inset * bw + 0.5), 0, w).astype(int)
    x2 = np.clip(np.ceil(boxes[:, 2] - inset * bw + 0.5), 0, w).astype(int)
    y1 = np.clip(np.floor(boxes[:, 1] + inset * bh + 0.5), 0, h).astype(int)
    y2 = np.clip(np.ceil(boxes[:, 3] - inset * bh + 0.5), 0, h).astype(int)
    scale = np.array([180, 256, 256]) / np.array(bins)
    for k in np.flatnonzero((x2 > x1) & (y2 > y1)):
        hsv = cv2.cvtColor(np.ascontiguousarray(image[y1[k]:y2[k], x1[k]:x2[k]]), cv2.COLOR_BGR2HSV)
        idx = np.minimum((hsv.reshape(-1, 3) / scale).astype(int), np.array(bins) - 1)
        counts = np.bincount(np.ravel_multi_index(idx.T, bins), minlength=out.shape[1])
        out[k] = counts / counts.sum()
    return out


def bhattacharyya(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(K, M) Bhattacharyya distances between (K, B) and (M, B) normalised histograms (1: an empty one)."""
    bc = np.sqrt(np.asarray(a, float))[:, None, :] * np.sqrt(np.asarray(b, float))[None, :, :]
    return np.sqrt(np.clip(1.0 - bc.sum(axis=2), 0.0, 1.0))
