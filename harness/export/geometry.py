"""Pure geometry of the dataset exports (no files here): KITTI boxes, calibration, truncation.

Frames are those of :mod:`monorarp.core.camera` (camera frame: OpenCV, x right, y down, z forward; ego
frame: x right, y ahead, z up) and of the ground truth's ``corners_cam``. KITTI's camera frame is
the pitched camera's own; the pitch and mounting go into ``Tr_velo_to_cam`` / ``Tr_imu_to_velo``,
and the rebuilt KITTI box misses only the pitch. In full: docs/formats.md (the pitched camera).
"""

from __future__ import annotations

import numpy as np

from monorarp.core import boxes
from monorarp.core.camera import CameraModel

#: Nearest depth (m) a box edge is kept at before it is projected (clipped there).
Z_NEAR_M = 0.1

#: Index of each of KITTI's 8 box corners (devkit order: x = +l/2, +l/2, -l/2, -l/2 and
#: z = +w/2, -w/2, -w/2, +w/2 in the object frame, ground then roof) among ``corners_cam``.
KITTI_CORNER_ORDER = np.array([3, 2, 1, 0, 7, 6, 5, 4])

#: The 12 edges of a box in ``corners_cam`` order.
BOX_EDGES = np.array([[0, 1], [1, 2], [2, 3], [3, 0], [4, 5], [5, 6], [6, 7], [7, 4],
                      [0, 4], [1, 5], [2, 6], [3, 7]])

#: Velodyne axes (x forward, y left, z up) -> ego axes (x right, y ahead, z up).
R_EGO_FROM_VELO = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])


# ------------------------------------------------------------------------ KITTI boxes
def kitti_box(corners_cam: np.ndarray) -> dict[str, np.ndarray]:
    """KITTI box parameters of (N, 8, 3) ``corners_cam`` boxes.

    Returns arrays ``h``, ``w``, ``l`` (N,), ``location`` (N, 3) = ground-face centre,
    ``rotation_y`` (N,) in [-pi, pi) and ``alpha`` (N,) = observation angle
    ``rotation_y - atan2(x, z)`` of the location, wrapped to [-pi, pi).
    """
    c = np.asarray(corners_cam, dtype=float).reshape(-1, 8, 3)
    length = np.linalg.norm(c[:, 3] - c[:, 0], axis=-1)
    width = np.linalg.norm(c[:, 1] - c[:, 0], axis=-1)
    height = np.linalg.norm(c[:, 4] - c[:, 0], axis=-1)
    location = c[:, :4].mean(axis=1)
    forward = (c[:, 3] - c[:, 0]) + (c[:, 2] - c[:, 1])
    rotation_y = wrap_angle(np.arctan2(-forward[:, 2], forward[:, 0]))
    alpha = wrap_angle(rotation_y - np.arctan2(location[:, 0], location[:, 2]))
    return {"h": height, "w": width, "l": length, "location": location, "rotation_y": rotation_y, "alpha": alpha}


def kitti_box_corners(h, w, l, location, rotation_y) -> np.ndarray:
    """(N, 8, 3) corners of KITTI boxes, as KITTI's devkit builds them (``compute_box_3d``).

    Object frame: x along the length, y down (0 on the ground, -h at the roof), z across;
    rotated by ``rotation_y`` about the camera's y axis and moved to ``location``.
    """
    h, w, l, ry = (np.atleast_1d(np.asarray(a, dtype=float)) for a in (h, w, l, rotation_y))
    loc = np.asarray(location, dtype=float).reshape(-1, 3)
    x = np.array([1, 1, -1, -1, 1, 1, -1, -1])[None, :] * (l[:, None] / 2)
    y = np.array([0, 0, 0, 0, -1, -1, -1, -1])[None, :] * h[:, None]
    z = np.array([1, -1, -1, 1, 1, -1, -1, 1])[None, :] * (w[:, None] / 2)
    c, s = np.cos(ry)[:, None], np.sin(ry)[:, None]
    return np.stack([c * x + s * z, y, -s * x + c * z], axis=-1) + loc[:, None, :]


def wrap_angle(a):
    """Angles wrapped to [-pi, pi)."""
    return (np.asarray(a, dtype=float) + np.pi) % (2 * np.pi) - np.pi


# ------------------------------------------------------------------------ calibration
def projection_matrix(camera: CameraModel) -> np.ndarray:
    """3x4 ``P = K [I | 0]``: camera-frame points to pixels (OpenCV pixel centres)."""
    return np.hstack([camera.K, np.zeros((3, 1))])


def velo_to_cam(camera: CameraModel) -> np.ndarray:
    """3x4 ``Tr_velo_to_cam``: a levelled frame at the camera (x forward, y left, z up) -> camera frame."""
    return np.hstack([camera.R_cam_from_ego @ R_EGO_FROM_VELO, np.zeros((3, 1))])


def imu_to_velo(camera: CameraModel) -> np.ndarray:
    """3x4 ``Tr_imu_to_velo``: the frame on the ground under the ego's centre (x forward, y left,
    z up) -> the levelled frame at the camera (a translation only)."""
    camera_in_imu = np.array([camera.forward_offset_m, -camera.lateral_offset_m, camera.height_m])
    return np.hstack([np.eye(3), -camera_in_imu[:, None]])


def calibration(camera: CameraModel) -> dict[str, np.ndarray]:
    """The KITTI object calibration matrices (names as in KITTI's ``calib/*.txt``)."""
    p = projection_matrix(camera)
    return {"P0": p, "P1": p, "P2": p, "P3": p, "R0_rect": np.eye(3),
            "Tr_velo_to_cam": velo_to_cam(camera), "Tr_imu_to_velo": imu_to_velo(camera)}


def project(P: np.ndarray, points: np.ndarray) -> np.ndarray:
    """(..., 3) points -> (..., 2) pixels through a 3x4 projection matrix."""
    p = np.asarray(points, dtype=float)
    h = p @ np.asarray(P, dtype=float)[:, :3].T + np.asarray(P, dtype=float)[:, 3]
    return h[..., :2] / h[..., 2:3]


# ------------------------------------------------------------------- projected extents
def projected_extent(corners_cam: np.ndarray, camera: CameraModel, z_near: float = Z_NEAR_M) -> np.ndarray:
    """(N, 4) ``[u0, v0, u1, v1]``: 2-D extent of each (N, 8, 3) box on the unbounded image plane.

    Edges are clipped at depth ``z_near`` first, so a box reaching behind the camera
    gets the extent of its visible part; a box wholly behind ``z_near`` gives NaN.
    """
    c = np.asarray(corners_cam, dtype=float).reshape(-1, 8, 3)
    a, b = c[:, BOX_EDGES[:, 0]], c[:, BOX_EDGES[:, 1]]                  # (N, 12, 3)
    za, zb = a[..., 2:3], b[..., 2:3]
    with np.errstate(divide="ignore", invalid="ignore"):
        s = np.clip((z_near - za) / (zb - za), 0.0, 1.0)
    a_in = za >= z_near
    b_in = zb >= z_near
    # Each edge keeps its endpoints in front of the near plane and, when it crosses the
    # plane, its crossing point in place of the endpoint behind it.
    cross = a + s * (b - a)
    pa = np.where(a_in, a, cross)
    pb = np.where(b_in, b, cross)
    used = (a_in | b_in)[..., 0]                                        # (N, 12)
    keep = np.concatenate([used, used], axis=1)                         # (N, 24)
    pts = np.concatenate([pa, pb], axis=1)                              # (N, 24, 3)
    uv = camera.project_cam(np.where(keep[..., None], pts, [0.0, 0.0, 1.0]))
    lo = np.where(keep[..., None], uv, np.inf).min(axis=1)
    hi = np.where(keep[..., None], uv, -np.inf).max(axis=1)
    out = np.concatenate([lo, hi], axis=1)
    out[~keep.any(axis=1)] = np.nan
    return out


def kitti_2d_box(extent: np.ndarray, visible_box, width: int, height: int) -> np.ndarray:
    """KITTI's 2-D box: the projected 3-D box ``extent`` ``[u0, v0, u1, v1]`` clipped to the image, so an
    occluded vehicle's box covers its hidden part too (KITTI's labels: median IoU 0.97 with their projected
    3-D boxes, largely occluded cars included); grown to hold ``visible_box`` (a mirror may reach past
    the 3-D box)."""
    v = np.asarray(visible_box, dtype=float)
    if not np.all(np.isfinite(extent)):
        return v
    return boxes.hull(boxes.clip_to_image(extent, width, height), v)


def truncation(extent: np.ndarray, width: int, height: int) -> np.ndarray:
    """(N,) share of each ``[u0, v0, u1, v1]`` extent's area outside the image (0 inside, 1 wholly out)."""
    e = np.asarray(extent, dtype=float).reshape(-1, 4)
    area = np.clip(e[:, 2] - e[:, 0], 0, None) * np.clip(e[:, 3] - e[:, 1], 0, None)
    iw = np.clip(np.minimum(e[:, 2], width - 0.5) - np.maximum(e[:, 0], -0.5), 0, None)
    ih = np.clip(np.minimum(e[:, 3], height - 0.5) - np.maximum(e[:, 1], -0.5), 0, None)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where(area > 0, 1.0 - iw * ih / area, 1.0)
    return np.clip(np.nan_to_num(t, nan=1.0), 0.0, 1.0)


def occlusion(visibility: np.ndarray, truncated: np.ndarray) -> np.ndarray:
    """(N,) share of each object's in-image part hidden by nearer vehicles.

    ``visibility`` (ground truth) = visible pixels / pixels on an unbounded image, which
    counts the border's cut too; the in-image share is taken as ``1 - truncated`` (the
    projected box's), so ``occlusion = 1 - visibility / (1 - truncated)``, clipped to 0..1
    (exact for untruncated objects).
    """
    v = np.asarray(visibility, dtype=float)
    inside = 1.0 - np.asarray(truncated, dtype=float)
    with np.errstate(divide="ignore", invalid="ignore"):
        occ = np.where(inside > 1e-9, 1.0 - v / inside, 0.0)
    return np.clip(occ, 0.0, 1.0)


#: Occlusion share below which an object is KITTI "fully visible" (0), and below which it
#: is "partly occluded" (1); above: "largely occluded" (2).
OCCLUSION_LEVELS = (0.1, 0.5)
#: Truncation share below which a KITTI-tracking object is "not truncated" (0), and below which
#: it is "partly truncated" (1); above: 2.
TRUNCATION_LEVELS = (1e-3, 0.5)


def levels(x: np.ndarray, thresholds: tuple[float, float]) -> np.ndarray:
    """(N,) integer level 0, 1 or 2 of ``x`` against two increasing thresholds."""
    return np.searchsorted(np.asarray(thresholds), np.asarray(x, dtype=float), side="right").astype(int)


def kitti_type(length: float, width: float, body: str | None = None) -> str:
    """KITTI class of a vehicle (:func:`harness.world.vehicles.kitti_type`): without a body type ``Truck`` for the
    renderer's trucks, else ``Car``; a fleet's body type by KITTI's convention (vans ``Van``, lorries and buses
    ``Truck``, every car, SUV and pickup ``Car``)."""
    from harness.world.vehicles import kitti_type as world_kitti_type

    return world_kitti_type(float(length), float(width), body)

