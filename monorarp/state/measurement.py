"""The state estimator's measurements: track boxes -> distance ``d_y``, lateral terms and ``d_y``'s one-sigma.

Built on the pure box geometry of :mod:`monorarp.state.geometry` (equations 3 and 4, border flags):
which boxes are measurements at all (:func:`plausible_boxes`), a box too narrow for a whole vehicle
beside a side border taken as cut by it (:func:`border_cut_boxes`), the per-track near-edge offset
that keeps the lateral reading steady when a box's far edge leaves the view (:class:`NearEdgeOffsets`),
the nearest distance a box cut by the bottom border can still be at (:func:`near_limit_m`), and the
one-sigma of ``d_y`` from the errors the filter cannot see (:func:`distance_std`). Ego frame
(m, + right, + ahead): :mod:`monorarp.core.camera`; boxes ``(x1, y1, x2, y2)`` px. The reasoning:
docs/state_estimation.md.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from monorarp.core.boxes import BORDER_TOL_PX
from monorarp.core.camera import CameraModel
from monorarp.state.geometry import (border_flags, box_distance, contact_line_cut, hidden_sides, lateral_from_terms,
                                     lateral_terms, near_edge_terms, too_narrow)


def border_tolerance(setting: float | str | None, width: int) -> float | None:
    """The border tolerance (px) of ``StateConfig.border_tol_px`` for an image ``width`` px wide:
    ``"auto"`` is :data:`~monorarp.core.boxes.BORDER_TOL_PX` per 640 px of width; None: never."""
    if setting == "auto":
        setting = BORDER_TOL_PX * width / 640.0
    return None if setting is None else float(setting)


def plausible_boxes(camera: CameraModel, boxes: np.ndarray) -> np.ndarray:
    """(M, 4) boxes (px) with every row that has a coordinate beyond 10 image sizes set to NaN.

    Such a box is no measurement (a broken detector or tracker): taken at face value, its
    distance (~1e300 m) overflows the filter's covariance. NaN rows are predicted / held.
    """
    limit = 10.0 * max(camera.width, camera.height)
    bad = ~(np.abs(boxes) <= limit).all(axis=1)
    return np.where(bad[:, None], np.nan, boxes)


def border_cut_boxes(camera: CameraModel, boxes: np.ndarray, border_tol_px: float | None,
                     min_vehicle_width_m: float, near_border_frac: float, contact_offset_m: float,
                     ground_clearance_m: float) -> np.ndarray:
    """(M, 4) boxes (px) with a far edge that stops short of the side border extended to it
    where the box is too narrow to be a whole vehicle.

    Beside the centre line, within ``near_border_frac`` of the frame width from the border on
    its far side, a box narrower than ``min_vehicle_width_m`` at its distance (equation 3)
    cannot hold a whole vehicle: the vehicle runs out of view and the detector's box stops a
    few detector pixels short of the border (at 1920x1080, 20-30 px). Taken at face value its
    far edge puts a next-lane car 2 m inside the ego's lane. ``border_tol_px`` None or
    ``min_vehicle_width_m`` 0: the boxes as given.
    """
    if border_tol_px is None or min_vehicle_width_m <= 0 or len(boxes) == 0:
        return boxes
    b = boxes.copy()
    with np.errstate(invalid="ignore"):
        d_y = box_distance(camera, b, contact_offset_m, ground_clearance_m, border_tol_px)
        narrow = too_narrow(camera, b, d_y, min_vehicle_width_m)
        near = near_border_frac * camera.width
        right = (b[:, 0] > camera.cx) & (b[:, 2] >= camera.width - 0.5 - near) & narrow
        left = (b[:, 2] < camera.cx) & (b[:, 0] <= -0.5 + near) & narrow
    b[right, 2] = np.maximum(b[right, 2], camera.width - 0.5)
    b[left, 0] = np.minimum(b[left, 0], -0.5)
    return b


def near_limit_m(camera: CameraModel, border_tol_px: float | None, contact_offset_m: float,
                 ground_clearance_m: float) -> float:
    """Distance (m) to a rear face whose contact line lies on the lowest row not taken as the border's.

    A box whose bottom edge is within ``border_tol_px`` of the bottom border is cut: its vehicle
    is nearer than this.
    """
    row = camera.height - 0.5 - (border_tol_px or 0.0)
    box = np.array([[camera.cx - 1.0, row - 1.0, camera.cx + 1.0, row]])
    d = box_distance(camera, box, contact_offset_m, ground_clearance_m, None)[0]
    return max(float(d), 0.0)


def inward_clipped(offset: float, right: bool, max_inward_m: float | None) -> float:
    """A learnt near-edge offset (m), moving the vehicle towards the centre line by at most
    ``max_inward_m`` (None: no limit); ``right``: the vehicle is right of the centre line.

    The near-edge model (assumed length 4.5 m, width 1.8 m) reads a longer or wider vehicle too
    far in, which the offset corrects outwards (a truck: 1 m or more); only a vehicle shorter
    and narrower than any car could need more than ~0.3 m inwards.
    """
    if max_inward_m is None:
        return offset
    return max(offset, -max_inward_m) if right else min(offset, max_inward_m)


class NearEdgeOffsets:
    """Per track, the offset (m) between its far-edge and near-edge lateral readings; ``readings``
    gives each box's ``d_y`` and lateral terms with it applied.

    While a box beside the centre line is whole, the offset (from the vehicle's true length and width
    differing from the assumed ones) is learnt per track (running mean); once the far edge is cut, the
    near-edge reading is shifted by it (:func:`inward_clipped` to ``max_inward_m``), so switching edges
    makes no jump (which would read as lateral velocity). It is learnt only from boxes whose sides both
    lie ``learn_margin_px`` or more inside the image (None: the border tolerance).
    """

    def __init__(self, learn_margin_px: float | None = None, max_inward_m: float | None = 0.3) -> None:
        self.learn_margin_px, self.max_inward_m = learn_margin_px, max_inward_m
        self.offsets: dict[int, float] = {}

    def reset(self) -> None:
        """Forget every track."""
        self.offsets = {}

    def forget(self, track_id: int) -> None:
        """Forget one track."""
        self.offsets.pop(track_id, None)

    def readings(self, camera: CameraModel, ids: Sequence[int], boxes: np.ndarray, ground_y: np.ndarray | None,
                 vehicle_width_m: float, vehicle_length_m: float, contact_offset_m: float,
                 ground_clearance_m: float, border_tol_px: float | None,
                 hidden_tol_px: float | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Measured ``d_y`` (M,; NaN where the box gives none) and the lateral terms (M, 3) of
        :func:`~monorarp.state.geometry.lateral_terms`, per track calibrated, of the (M, 4) ``boxes``
        of tracks ``ids``. ``ground_y``: each bottom row's ground distance (m) from a measured road
        profile (:func:`monorarp.state.ground_contact.contact_ground`); None: the flat ground's.
        ``hidden_tol_px``: a side that is a nearer box's edge (:func:`~monorarp.state.geometry.hidden_sides`,
        this tolerance) counts as cut, as a border does; None: never."""
        d_y = box_distance(camera, boxes, contact_offset_m, ground_clearance_m, border_tol_px, ground_y)
        hidden = None if hidden_tol_px is None else hidden_sides(boxes, hidden_tol_px)
        terms = lateral_terms(camera, boxes, vehicle_width_m, vehicle_length_m, ground_clearance_m, border_tol_px,
                              hidden)
        near = near_edge_terms(camera, boxes, vehicle_width_m, vehicle_length_m, ground_clearance_m)
        flags = border_flags(camera, boxes, border_tol_px)
        if hidden is not None:
            flags[:, :2] |= hidden
        whole = ~flags[:, 0] & ~flags[:, 1] & np.isfinite(near[:, 0]) & np.isfinite(d_y)
        if self.learn_margin_px is not None:
            whole &= ~border_flags(camera, boxes, self.learn_margin_px)[:, :2].any(axis=1)
        right, left = boxes[:, 0] > camera.cx, boxes[:, 2] < camera.cx
        uses_near = (right & flags[:, 1]) | (left & flags[:, 0])
        offset = lateral_from_terms(terms, d_y) - lateral_from_terms(near, d_y)
        for j, i in enumerate(ids):
            if whole[j]:
                old = self.offsets.get(i)
                self.offsets[i] = offset[j] if old is None else old + 0.3 * (offset[j] - old)
            elif uses_near[j] and i in self.offsets:
                terms[j, 2] += inward_clipped(self.offsets[i], right[j], self.max_inward_m)
        gone = contact_line_cut(camera, boxes, lateral_from_terms(terms, d_y), d_y, vehicle_width_m,
                                contact_offset_m, border_tol_px)
        return np.where(gone, np.nan, d_y), terms


def horizon_gain(camera: CameraModel, d_y: np.ndarray, contact_offset_m: float) -> np.ndarray:
    """``|d d_y / d row|`` (m/px): distance change per pixel of horizon-row error.

    The contact line's ground distance ``Y = d_y + contact_offset_m`` seen at depression
    angle ``a`` below the horizon (``Y = h_c cot a``) changes by ``(Y^2 + h_c^2) / h_c`` per
    radian, and one row is ``1 / fy`` rad near the principal point.
    """
    Y = np.asarray(d_y, dtype=float) + contact_offset_m
    h = camera.height_m
    return (Y * Y + h * h) / (h * camera.fy)


def grade_gain(camera: CameraModel, d_y: np.ndarray, contact_offset_m: float) -> np.ndarray:
    """``|d d_y / d grade|`` (m per unit rise/run): distance change per unit of road grade.

    A ground that rises with grade ``g`` from the camera's foot point (``z = g y``) meets the ray
    of depression angle ``a`` at ``Y = h_c / (tan a + g)``; the flat reading is ``h_c / tan a``,
    so ``dY/dg = -Y^2 / h_c`` at ``g = 0`` (``Y = d_y + contact_offset_m``, the contact line).
    """
    Y = np.asarray(d_y, dtype=float) + contact_offset_m
    return Y * Y / camera.height_m


def distance_std(camera: CameraModel, d_y: np.ndarray, filter_std: np.ndarray, horizon_std_px: float,
                 side_cut: np.ndarray | None, edge_std_px: float, border_edge_std_px: float,
                 contact_offset_std_m: float, grade_std: float, contact_offset_m: float) -> np.ndarray:
    """One-sigma of ``d_y`` (m): the filter's (``filter_std``); the horizon row's (``horizon_std_px``) and
    the box bottom edge's persistent error (``edge_std_px``, ``border_edge_std_px`` where ``side_cut``),
    both through :func:`horizon_gain` (the distance reads their difference); the contact line's
    (``contact_offset_std_m``); the road grade's (``grade_std``, through :func:`grade_gain`). In quadrature."""
    edge = np.where(side_cut, border_edge_std_px, edge_std_px) if side_cut is not None else edge_std_px
    px = np.hypot(horizon_std_px, edge)
    var = filter_std ** 2 + (horizon_gain(camera, d_y, contact_offset_m) * px) ** 2 + contact_offset_std_m ** 2
    if grade_std > 0:
        var = var + (grade_gain(camera, d_y, contact_offset_m) * grade_std) ** 2
    return np.sqrt(var)
