"""How the state estimator reads a box's distance from a measured road profile (pure maths).

:func:`contact_ground`: a box bottom row's ground distance (m), the flat-ground one wherever the
:class:`~monorarp.core.ground_profile.GroundProfile` agrees with it, and the one-sigma to add;
:func:`width_distance`: a vehicle's distance from its box width alone, the second reading where the
profile cannot see the road. Ego frame: :mod:`monorarp.core.camera`. The method and its measured
figures: docs/road_profile.md.
"""

from __future__ import annotations

import numpy as np

from monorarp.core.camera import CameraModel
from monorarp.core.ground_profile import GroundProfile


def width_distance(camera: CameraModel, boxes: np.ndarray, width_m: float = 1.8, length_m: float = 4.5) -> np.ndarray:
    """(M,) rear-face distance (m) of each box's vehicle from its width in the image (no ground used).

    A box across the centre column shows the rear face alone: ``d = f_x W / (x2 - x1)``. Beside it,
    the far edge is the rear outer corner at depth ``d`` and the near edge the front inner corner at
    ``d + L``: with ``a``, ``b`` the far and near edge's offsets from ``c_x`` over ``f_x`` (towards the
    vehicle's side), ``a d = X + W`` and ``b (d + L) = X`` give ``d = (W + b L) / (a - b)``
    (pitch neglected: ``Z_cam`` taken as ``d``). NaN where the edges give no positive distance.
    """
    b = np.asarray(boxes, dtype=float).reshape(-1, 4)
    x1, x2 = (b[:, 0] - camera.cx) / camera.fx, (b[:, 2] - camera.cx) / camera.fx
    right, left = x1 > 0, x2 < 0
    far = np.where(right, x2, np.where(left, -x1, 0.0))
    near = np.where(right, x1, np.where(left, -x2, 0.0))
    with np.errstate(divide="ignore", invalid="ignore"):
        d = np.where(right | left, (width_m + near * length_m) / (far - near), width_m / (x2 - x1))
    return np.where(np.isfinite(d) & (d > 0), d, np.nan)


def contact_ground(camera: CameraModel, profile: GroundProfile | None, rows: np.ndarray, edge_std_px: float,
                   gate_sigmas: float = 3.0, boxes: np.ndarray | None = None, width_m: float = 1.8,
                   width_std_m: float = 0.15, length_m: float = 4.5,
                   contact_offset_m: float = 0.95) -> tuple[np.ndarray, np.ndarray]:
    """Ground distance (m) of box bottom rows and the one-sigma (m) to add to the flat-ground one.

    Where the profile covers the row and agrees with the flat ground within ``gate_sigmas`` of its
    one-sigma: the flat-ground distance, nothing added. Where it disagrees: the profile's distance;
    added, its one-sigma and the larger sensitivity of the distance to the bottom edge's persistent
    error (``edge_std_px`` through the profile's metres per row beyond what the state estimator
    already counts, the flat ground's ``(Y^2 + h_c^2) / (h_c f_y)`` at the same distance). Outside
    the profile: below its nearest row (the near road the lines were measured on) the flat-ground
    distance; above its farthest row, where no line was followed, and within ``end_margin_px`` of it
    when the lines were lost there (``open_end``: the box may stand on road that is not seen), the
    distance and the grade it cannot see, ``Y^2 / h_c x fallback_grade_std`` (as
    :func:`monorarp.state.measurement.grade_gain`). There, given the ``boxes``, the vehicle's width
    is a second reading that needs no ground (:func:`width_distance`, ``width_m`` +- ``width_std_m`` and
    1 px of box width, + ``contact_offset_m`` to the contact line): more than two of its sigmas beyond,
    the vehicle stands behind the road's visible end (a crest): the width's distance and one-sigma;
    within two sigmas it bears the reading out: only their difference is added, not the grade.
    Without a profile: the flat ground.
    """
    rows = np.asarray(rows, dtype=float)
    flat = camera.ground_point_from_pixel(np.full_like(rows, camera.cx), rows)[:, 1]
    if profile is None:
        return flat, np.zeros_like(flat)
    d, sd, gain = profile.at(rows)
    with np.errstate(invalid="ignore"):
        inside = np.isfinite(d)
        differ = inside & ~(np.abs(d - flat) <= gate_sigmas * sd)
        Y = np.nan_to_num(d)
        flat_gain = (Y * Y + camera.height_m ** 2) / (camera.height_m * camera.fy)   # what d_y_std already has
        extra_gain = np.sqrt(np.maximum(np.nan_to_num(gain) ** 2 - flat_gain ** 2, 0.0))
    beyond = ~inside & (rows < profile.rows[0]) if profile.rows.size else np.ones_like(inside)
    y = np.where(differ, d, flat)
    add = np.where(differ, np.hypot(sd, extra_gain * edge_std_px), 0.0)
    at_end = np.zeros_like(inside)
    if profile.open_end and profile.rows.size:
        at_end = inside & (rows <= profile.rows[0] + profile.end_margin_px)
    unseen = beyond | at_end
    widened = np.where(unseen, np.hypot(add, y * y / camera.height_m * profile.fallback_grade_std), add)
    if boxes is None:
        return y, np.nan_to_num(widened, nan=0.0)
    b = np.asarray(boxes, dtype=float).reshape(-1, 4)
    d_w = width_distance(camera, b, width_m, length_m) + contact_offset_m
    sd_w = d_w * np.hypot(width_std_m / width_m, 1.0 / np.maximum(b[:, 2] - b[:, 0], 1.0))
    with np.errstate(invalid="ignore"):
        behind = unseen & (d_w > y + 2.0 * sd_w)                 # beyond the road's visible end
        agree = unseen & (np.abs(d_w - y) <= 2.0 * sd_w)          # the width bears the reading out
    y = np.where(behind, d_w, y)
    add = np.where(behind, sd_w, np.where(agree, np.hypot(add, d_w - y), widened))
    return y, np.nan_to_num(add, nan=0.0)
