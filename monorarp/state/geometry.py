"""Geometry of the state estimator (section IV-C): ego-frame distances from a box and the camera.

Pure functions of a :class:`~monorarp.core.camera.CameraModel` and ``(M, 4)`` boxes ``(x1, y1, x2, y2)``
(continuous pixel coordinates): equation 3 (``d_y``, m, to the rear face) with the contact-line
correction, equation 4 (``d_x``, m, + right, to the centre), the near-edge terms and the border
flags of boxes cut by the image border. Ego frame: :mod:`monorarp.core.camera`. The reasoning behind
each rule: docs/state_estimation.md.
"""

from __future__ import annotations

import numpy as np

from monorarp.core.boxes import BORDER_TOL_PX, area, intersection
from monorarp.core.camera import CameraModel


# --------------------------------------------------------------------- the paper's formulas
def eq3_distance(bottom_row, horizon_row: float, height_m: float, focal_px: float) -> np.ndarray:
    """Equation 3: ``d_y = h_c F / (bottom_row - horizon_row)`` (m); NaN at or above the horizon."""
    d_b = np.asarray(bottom_row, dtype=float) - horizon_row
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(d_b > 0, height_m * focal_px / d_b, np.nan)


def eq4_lateral(d_y, d_e, focal_px: float, width_m: float) -> np.ndarray:
    """Equation 4 with sign: ``d_x = d_y d_e / F - sign(d_e) W_r / 2`` (m, + right).

    ``d_e``: signed column of the far edge minus the centre column (px).
    """
    d_e = np.asarray(d_e, dtype=float)
    return np.asarray(d_y, dtype=float) * d_e / focal_px - np.sign(d_e) * width_m / 2


# ------------------------------------------------------------------------- measurement
def fragments(boxes: np.ndarray, cover: float = 0.9, width_ratio: float = 1.5,
              bottom_px: float = 3.0) -> np.ndarray:
    """(M,) bool: box i lies over ``cover`` of its area inside another box at least ``width_ratio``
    times as wide whose bottom edge is within ``bottom_px`` of its own. Both then touch the ground
    on the same row, at the same distance, where two vehicles cannot overlap in the image: box i
    is a part of the other vehicle. Boxes (M, 4) ``(x1, y1, x2, y2)`` px."""
    b = np.asarray(boxes, dtype=float).reshape(-1, 4)
    inside = intersection(b[:, None, :], b[None, :, :]) >= cover * np.maximum(area(b), 1e-9)[:, None]
    width = b[:, 2] - b[:, 0]
    wider = width[None, :] >= width_ratio * np.maximum(width, 1e-9)[:, None]
    level = np.abs(b[:, None, 3] - b[None, :, 3]) <= bottom_px
    return (inside & wider & level & ~np.eye(len(b), dtype=bool)).any(axis=1)


def border_flags(camera: CameraModel, boxes: np.ndarray, tol_px: float | None = 1.0) -> np.ndarray:
    """(M, 3) booleans: the box's left edge, right edge, bottom edge touches the image border.

    "Touches": within ``tol_px`` of the border (continuous coordinates: the image spans
    -0.5 .. width - 0.5); boxes reaching beyond the image count too. ``tol_px=None``: never.
    """
    b = np.asarray(boxes, dtype=float).reshape(-1, 4)
    if tol_px is None:
        return np.zeros((len(b), 3), dtype=bool)
    return np.stack([b[:, 0] <= -0.5 + tol_px, b[:, 2] >= camera.width - 0.5 - tol_px,
                     b[:, 3] >= camera.height - 0.5 - tol_px], axis=1)


def box_distance(camera: CameraModel, boxes: np.ndarray, contact_offset_m: float = 0.95,
                 ground_clearance_m: float = 0.17, border_tol_px: float | None = BORDER_TOL_PX,
                 ground_y: np.ndarray | None = None) -> np.ndarray:
    """(M,) ``d_y`` (m) of each box's rear face from its bottom edge (equation 3 + contact-line correction).

    NaN for boxes not below the horizon and for boxes whose bottom edge touches the
    image's bottom border (truncated: their real bottom edge is out of view). ``ground_y`` (M,):
    the ground distance (m) of each bottom row from elsewhere (a measured road profile,
    :func:`monorarp.state.ground_contact.contact_ground`); None: the flat ground's.
    """
    b = np.asarray(boxes, dtype=float).reshape(-1, 4)
    v_b = b[:, 3]
    y_g = camera.ground_point_from_pixel(np.full_like(v_b, camera.cx), v_b)[:, 1] if ground_y is None \
        else np.asarray(ground_y, dtype=float)   # ground distance of the ray
    d_y = np.maximum(y_g - contact_offset_m, y_g * (1.0 - ground_clearance_m / camera.height_m))
    return np.where(border_flags(camera, b, border_tol_px)[:, 2], np.nan, d_y)


def hidden_sides(boxes: np.ndarray, tol_px: float = 2.0) -> np.ndarray:
    """(M, 2) bool: box i's left, right side is the edge of a nearer vehicle in front of it, not its own.

    A nearer box (bottom edge lower in the image by over 1 px) that spans box i's bottom row and reaches
    across one of its sides, to within ``tol_px`` of it, without holding the whole box: box i ends where
    the nearer vehicle begins. Only one side counts: where both are such edges, neither does.
    """
    b = np.asarray(boxes, dtype=float).reshape(-1, 4)
    i, j = b[:, None, :], b[None, :, :]
    front = (j[..., 3] > i[..., 3] + 1.0) & (j[..., 1] < i[..., 3])
    left = front & (j[..., 0] < i[..., 0]) & (i[..., 0] <= j[..., 2] + tol_px) & (j[..., 2] < i[..., 2])
    right = front & (j[..., 2] > i[..., 2]) & (i[..., 2] >= j[..., 0] - tol_px) & (j[..., 0] > i[..., 0])
    out = np.stack([left.any(axis=1), right.any(axis=1)], axis=1)
    return out & ~out[:, ::-1]


def lateral_terms(camera: CameraModel, boxes: np.ndarray, vehicle_width_m: float = 1.8,
                  vehicle_length_m: float = 4.5, ground_clearance_m: float = 0.17,
                  border_tol_px: float | None = BORDER_TOL_PX, hidden: np.ndarray | None = None) -> np.ndarray:
    """(M, 3) ``(a, b, c)`` with ``d_x = a (d_y + b) + c`` (m) for each box; NaN row: not measurable.

    Equation 4 is linear in the distance ``d_y``, so the box gives these terms and any
    ``d_y`` (measured, or the filter's when the bottom edge is cut) gives ``d_x``.
    Far edge (rear outer corner) when it is inside the image; otherwise the near edge
    (front inner corner, ``b = L + ...``); see docs/state_estimation.md. ``hidden`` (M, 2) bool: the
    left, right side is not the vehicle's own (:func:`hidden_sides`) and counts as cut.
    """
    b = np.asarray(boxes, dtype=float).reshape(-1, 4)
    x1, y1, x2, v_b = b.T
    cut_l, cut_r, _ = border_flags(camera, b, border_tol_px).T
    if hidden is not None:
        cut_l, cut_r = cut_l | hidden[:, 0], cut_r | hidden[:, 1]
    cx, half = camera.cx, vehicle_width_m / 2
    right, left = x1 > cx, x2 < cx
    straddle = ~right & ~left
    # Default: far edge (or the centre of a straddling box) on the rear-face plane y = d_y.
    u = np.where(right, x2, np.where(left, x1, (x1 + x2) / 2))
    c = np.where(right, -half, np.where(left, half, 0.0))
    # Straddling with one side cut: the other side is a rear corner.
    one_cut = straddle & (cut_l ^ cut_r)
    u = np.where(one_cut, np.where(cut_l, x2, x1), u)
    c = np.where(one_cut, np.where(cut_l, -half, half), c)
    # Row of the edge's extreme point: pitched down, the rear face's top corner; otherwise its bottom.
    v_e = y1 if camera.pitch_rad > 0 else v_b
    rays = camera.cam_to_ego(np.stack([(u - cx) / camera.fx, (v_e - camera.cy) / camera.fy,
                                       np.ones_like(u)], axis=-1))
    with np.errstate(divide="ignore", invalid="ignore"):
        a = rays[:, 0] / rays[:, 1]
    far = np.stack([a, np.zeros_like(a), c], axis=1)
    # Beside the centre line with the far edge cut: the near edge instead.
    near = (right & cut_r) | (left & cut_l)
    out = np.where(near[:, None], near_edge_terms(camera, b, vehicle_width_m, vehicle_length_m,
                                                  ground_clearance_m), far)
    out[straddle & cut_l & cut_r] = np.nan
    return out


def near_edge_terms(camera: CameraModel, boxes: np.ndarray, vehicle_width_m: float = 1.8,
                    vehicle_length_m: float = 4.5, ground_clearance_m: float = 0.17) -> np.ndarray:
    """(M, 3) lateral terms (see :func:`lateral_terms`) from each box's *near* edge; NaN for straddling boxes.

    The near edge of a vehicle beside the centre line is its inner side's front lower corner,
    on the plane ``y = d_y + L`` at height ``ground_clearance_m``: ``x = (u - c_x) / f_x Z_cam``.
    """
    b = np.asarray(boxes, dtype=float).reshape(-1, 4)
    x1, x2 = b[:, 0], b[:, 2]
    right, left = x1 > camera.cx, x2 < camera.cx
    R = camera.R_cam_from_ego                                        # Z_cam = R[2,1] y + R[2,2] z
    z_corner = -camera.height_m + ground_clearance_m                 # ego frame: origin at the camera
    a = (np.where(right, x1, x2) - camera.cx) / camera.fx * R[2, 1]
    bb = np.full_like(a, vehicle_length_m + R[2, 2] * z_corner / R[2, 1])
    c = np.where(right, vehicle_width_m / 2, -vehicle_width_m / 2)
    out = np.stack([a, bb, c], axis=1)
    out[~(right | left)] = np.nan
    return out


def contact_line_cut(camera: CameraModel, boxes: np.ndarray, d_x: np.ndarray, d_y: np.ndarray,
                     vehicle_width_m: float = 1.8, contact_offset_m: float = 0.95,
                     border_tol_px: float | None = BORDER_TOL_PX) -> np.ndarray:
    """(M,) True where the far edge is cut and the rear contact line's inner end is out of view.

    Then no part of the tyres' contact line is in the image and the box's bottom edge is some
    other point of the vehicle's underside at the border: equation 3 does not apply.
    """
    b = np.asarray(boxes, dtype=float).reshape(-1, 4)
    cut_l, cut_r, _ = border_flags(camera, b, border_tol_px).T
    right, left = b[:, 0] > camera.cx, b[:, 2] < camera.cx
    x_in = d_x - np.sign(d_x) * vehicle_width_m / 2
    pts = np.stack([x_in, d_y + contact_offset_m, np.full_like(d_y, -camera.height_m)], axis=-1)
    with np.errstate(divide="ignore", invalid="ignore"):
        u = camera.project_ego(pts)[:, 0]
    tol = 0.0 if border_tol_px is None else border_tol_px
    return (right & cut_r & ~(u < camera.width - 0.5 - tol)) | (left & cut_l & ~(u > -0.5 + tol))


def lateral_from_terms(terms: np.ndarray, d_y: np.ndarray) -> np.ndarray:
    """``d_x = a (d_y + b) + c`` (m) for (M, 3) :func:`lateral_terms` and (M,) distances."""
    return terms[:, 0] * (np.asarray(d_y, dtype=float) + terms[:, 1]) + terms[:, 2]


def measure_boxes(camera: CameraModel, boxes: np.ndarray, vehicle_width_m: float = 1.8,
                  contact_offset_m: float = 0.95, ground_clearance_m: float = 0.17,
                  vehicle_length_m: float = 4.5, border_tol_px: float | None = BORDER_TOL_PX) -> np.ndarray:
    """(M, 4) boxes -> (M, 2) ``(d_x, d_y)`` in the ego frame (m).

    NaN where a box does not give the value: not below the horizon, bottom edge on the
    image border or contact line out of view (both NaN), both sides on the border (``d_x`` NaN). ``border_tol_px=None``
    treats every box as whole. The geometry: docs/state_estimation.md.
    """
    b = np.asarray(boxes, dtype=float).reshape(-1, 4)
    d_y = box_distance(camera, b, contact_offset_m, ground_clearance_m, border_tol_px)
    terms = lateral_terms(camera, b, vehicle_width_m, vehicle_length_m, ground_clearance_m, border_tol_px)
    d_x = lateral_from_terms(terms, d_y)
    gone = contact_line_cut(camera, b, d_x, d_y, vehicle_width_m, contact_offset_m, border_tol_px)
    return np.where(gone[:, None], np.nan, np.stack([d_x, d_y], axis=1))


def occluded(boxes: np.ndarray, min_overlap: float) -> np.ndarray:
    """(M,) bool: box i is overlapped, over more than ``min_overlap`` of its area, by another box whose
    bottom edge is lower in the image (a nearer vehicle, in front of it)."""
    b = np.asarray(boxes, dtype=float).reshape(-1, 4)
    covered = intersection(b[:, None, :], b[None, :, :]) > min_overlap * np.maximum(area(b), 1e-9)[:, None]
    front = b[None, :, 3] > b[:, None, 3]
    return (covered & front).any(axis=1)


def too_narrow(camera: CameraModel, boxes: np.ndarray, d_y: np.ndarray, width_m: float) -> np.ndarray:
    """(M,) bool: box narrower (px) than ``width_m`` would be at its distance ``d_y`` (m; 0.1 m at least);
    False where ``d_y`` is NaN."""
    b = np.asarray(boxes, dtype=float).reshape(-1, 4)
    with np.errstate(invalid="ignore"):
        return (b[:, 2] - b[:, 0]) * np.maximum(d_y, 0.1) < camera.fx * width_m
