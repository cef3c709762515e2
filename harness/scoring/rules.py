"""The scoring rules: their settings (:class:`EvalConfig`) and which objects and predictions count.

A ground-truth object *counts* (must be found, is scored) when visible enough and within range;
a prediction whose bottom edge meets the ground beyond the range is set aside (nuScenes' range
filter on predictions). The rules in full: docs/metrics.md.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from harness.scoring.match import MIN_IOU
from harness.world.truth import ObjectTruth
from monorarp.core.boxes import as_boxes
from monorarp.core.camera import CameraModel
from monorarp.warning.thresholds import TTC_CUE_THRESHOLD_S


@dataclass(frozen=True)
class EvalConfig:
    """Settings of the scoring rules (written to ``metrics.json``'s ``scoring``, in this order)."""

    warning_threshold_s: float = TTC_CUE_THRESHOLD_S   # TTC warning: TTC below this (s)
    min_iou: float = MIN_IOU                            # a box pair matches at IoU >= this
    min_visibility: float = 0.3                         # a GT object counts at visibility >= this (0..1)
    max_range_m: float = 80.0                           # ... and at d_long <= this (m)
    ignore_cover: float | None = 0.5                    # set-aside rule (harness.scoring.match.split_ignored)
    risk_horizon_s: float = 10.0                        # risk label window (s)
    near_miss_ttc_s: float = 1.0                        # a true TTC below this is a near miss (s)


def counted_mask(objects: Sequence[ObjectTruth], cfg: EvalConfig) -> np.ndarray:
    """Which GT objects count (visibility and range rule of the module docstring).

    An object carrying its own ``counted`` flag (a labelled dataset whose labels say what must be
    found, e.g. KITTI's difficulty levels) uses it in place of the visibility rule; range still applies.
    """
    return np.array([(o.counted if o.counted is not None else o.visibility >= cfg.min_visibility)
                     and o.d_long <= cfg.max_range_m for o in objects], dtype=bool)


def ground_range(boxes: np.ndarray, camera: CameraModel) -> np.ndarray:
    """(N,) forward distance (m) at which each box's bottom edge meets the ground; NaN at or above the horizon."""
    b = as_boxes(boxes)
    return camera.ground_point_from_pixel(np.full(len(b), camera.cx), b[:, 3])[:, 1]


def out_of_range(boxes: np.ndarray, camera: CameraModel | None, max_range_m: float) -> np.ndarray | None:
    """Boxes whose bottom edge meets the ground beyond ``max_range_m`` (or never); None without a camera."""
    if camera is None:
        return None
    return ~(ground_range(boxes, camera) <= max_range_m)
