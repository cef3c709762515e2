"""Axis-aligned box overlap: the one IoU of the project.

Boxes are ``(x1, y1, x2, y2)`` in continuous pixel coordinates (see
:mod:`monorarp.core.types`): width ``x2 - x1``, no ``+1`` (KITTI's devkit counts the
same way). A box with zero or negative width or height has area 0 and IoU 0
with everything.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

Boxes = Sequence[Sequence[float]] | np.ndarray
#: A box edge this close to the image border (px) is taken as cut by it (detection and state stages).
BORDER_TOL_PX = 4.0


def as_boxes(boxes: Boxes) -> np.ndarray:
    """Any sequence of 4-tuples -> float (N, 4) array (empty gives shape (0, 4))."""
    return np.asarray(boxes, dtype=float).reshape(-1, 4)


def area(b: np.ndarray) -> np.ndarray:
    """(..., 4) boxes -> (...) area in px^2, 0 for degenerate boxes."""
    return np.clip(b[..., 2] - b[..., 0], 0.0, None) * np.clip(b[..., 3] - b[..., 1], 0.0, None)


def intersection(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Intersection area (px^2) of (..., 4) boxes ``a`` with broadcastable ``b``."""
    iw = np.clip(np.minimum(a[..., 2], b[..., 2]) - np.maximum(a[..., 0], b[..., 0]), 0.0, None)
    ih = np.clip(np.minimum(a[..., 3], b[..., 3]) - np.maximum(a[..., 1], b[..., 1]), 0.0, None)
    return iw * ih


def clip_to_image(b: Boxes, width: int, height: int) -> np.ndarray:
    """(..., 4) boxes clipped to a ``width`` x ``height`` image (its edges at -0.5 and ``width - 0.5``; an
    empty result has x2 <= x1 or y2 <= y1)."""
    b = np.array(b, dtype=float)
    b[..., :2] = np.maximum(b[..., :2], -0.5)
    b[..., 2:] = np.minimum(b[..., 2:], [width - 0.5, height - 0.5])
    return b


def hull(a: Boxes, b: Boxes) -> np.ndarray:
    """The smallest box holding both (..., 4) boxes ``a`` and broadcastable ``b``."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    return np.concatenate([np.minimum(a[..., :2], b[..., :2]), np.maximum(a[..., 2:], b[..., 2:])], axis=-1)


def iou(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Element-wise IoU of (..., 4) boxes ``a`` with broadcastable ``b``."""
    inter = intersection(a, b)
    union = area(a) + area(b) - inter
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(union > 0.0, inter / union, 0.0)


def iou_matrix(a: Boxes, b: Boxes) -> np.ndarray:
    """(N, 4) and (M, 4) boxes -> (N, M) intersection over union."""
    a, b = as_boxes(a), as_boxes(b)
    return iou(a[:, None, :], b[None, :, :])
