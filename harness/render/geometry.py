"""Pure geometry shared by the renderer and the ground truth (no rendering here).

Frames:

* **Road frame** (highway-env, :mod:`harness.world`): ``x`` along the road,
  ``y`` to the right of travel, heading from +x towards +y; the ground is z = 0.
  Left-handed with z up, so it is never used for 3-D rendering directly.
* **World frame W** (pyrender, right-handed): ``X = x``, ``Y = -y`` (left of
  travel), ``Z`` up; the ground is Z = 0. ``Render.light_direction`` is given in W.
* **Ego frame** and **camera frame**: :mod:`monorarp.camera`. The camera sits at
  ego centre + ``forward_offset_m`` along the ego heading + ``lateral_offset_m``
  to its right, ``height_m`` above the ground.
* **Vehicle model frame** (meshes): ``X`` forward, ``Y`` left, ``Z`` up, origin on
  the ground at the centre of the length x width footprint.

Footprint corner order (4, per vehicle, its own left/right): rear-left,
rear-right, front-right, front-left. 3-D box corner order (8): those four on the
ground (z = 0), then the same four at roof height.
"""

from __future__ import annotations

import numpy as np

from harness.world import VehicleState
from monorarp.camera import CameraModel

# Unit footprint corners (along, across-to-the-right) in half-lengths / half-widths.
_FOOT = np.array([[-1.0, -1.0], [-1.0, 1.0], [1.0, 1.0], [1.0, -1.0]])


def heading_axes(heading: np.ndarray | float) -> tuple[np.ndarray, np.ndarray]:
    """Road-frame unit vectors (..., 2): forward and right of a heading (rad)."""
    h = np.asarray(heading, dtype=float)
    c, s = np.cos(h), np.sin(h)
    return np.stack([c, s], axis=-1), np.stack([-s, c], axis=-1)


def camera_position_road(ego: VehicleState, camera: CameraModel) -> np.ndarray:
    """(2,) road-frame ground position of the camera (m)."""
    fwd, right = heading_axes(ego.heading)
    return np.array([ego.x, ego.y]) + camera.forward_offset_m * fwd + camera.lateral_offset_m * right


def road_to_ego_xy(points_xy: np.ndarray, ego: VehicleState, camera: CameraModel) -> np.ndarray:
    """(..., 2) road-frame ground points -> (..., 2) ego-frame (x right, y ahead), m."""
    fwd, right = heading_axes(ego.heading)
    d = np.asarray(points_xy, dtype=float) - camera_position_road(ego, camera)
    return np.stack([d @ right, d @ fwd], axis=-1)


def road_vectors_to_ego(vec_xy: np.ndarray, ego: VehicleState) -> np.ndarray:
    """(..., 2) road-frame vectors (e.g. velocities) -> (..., 2) ego-frame (x right, y ahead)."""
    fwd, right = heading_axes(ego.heading)
    v = np.asarray(vec_xy, dtype=float)
    return np.stack([v @ right, v @ fwd], axis=-1)


def footprint_corners_road(x, y, heading, length, width) -> np.ndarray:
    """(N, 4, 2) road-frame footprint corners (order in the module docstring)."""
    x, y, heading, length, width = (np.atleast_1d(np.asarray(a, dtype=float)) for a in (x, y, heading, length, width))
    fwd, right = heading_axes(heading)
    along = _FOOT[None, :, 0:1] * (length / 2)[:, None, None] * fwd[:, None, :]
    across = _FOOT[None, :, 1:2] * (width / 2)[:, None, None] * right[:, None, :]
    return np.stack([x, y], axis=-1)[:, None, :] + along + across


def vehicles_footprints_ego(vehicles: list[VehicleState] | tuple, ego: VehicleState, camera: CameraModel) -> np.ndarray:
    """(N, 4, 2) footprint corners of ``vehicles`` in the ego frame (m)."""
    if not vehicles:
        return np.zeros((0, 4, 2))
    arr = np.array([[v.x, v.y, v.heading, v.length, v.width] for v in vehicles], dtype=float)
    return road_to_ego_xy(footprint_corners_road(*arr.T), ego, camera)


def box_corners_ego(footprints_ego: np.ndarray, heights: np.ndarray, camera: CameraModel) -> np.ndarray:
    """(N, 8, 3) 3-D box corners in the ego frame: ground corners then roof corners."""
    n = footprints_ego.shape[0]
    ground = np.full((n, 4, 1), -camera.height_m)
    roof = ground + np.asarray(heights, dtype=float).reshape(n, 1, 1)
    return np.concatenate([np.concatenate([footprints_ego, ground], axis=-1),
                           np.concatenate([footprints_ego, roof], axis=-1)], axis=1)


# ------------------------------------------------------------------ world frame W
def road_to_world(points: np.ndarray) -> np.ndarray:
    """(..., 3) road-frame (x, y right, z up) -> W (X, Y left, Z up)."""
    p = np.array(points, dtype=float)
    p[..., 1] *= -1.0
    return p


def vehicle_pose_world(v: VehicleState) -> np.ndarray:
    """4x4 pose of a vehicle's model frame in W."""
    c, s = np.cos(-v.heading), np.sin(-v.heading)
    pose = np.eye(4)
    pose[:2, :2] = [[c, -s], [s, c]]
    pose[0, 3], pose[1, 3] = v.x, -v.y
    return pose


def camera_pose_world(ego: VehicleState, camera: CameraModel) -> np.ndarray:
    """4x4 pose (camera -> W) of the OpenGL camera (x right, y up, looking along -z)."""
    fwd, right = heading_axes(ego.heading)
    r_w_from_ego = np.array([[right[0], fwd[0], 0.0],
                             [-right[1], -fwd[1], 0.0],
                             [0.0, 0.0, 1.0]])
    r_w_from_cv = r_w_from_ego @ camera.R_cam_from_ego.T
    pose = np.eye(4)
    pose[:3, :3] = r_w_from_cv @ np.diag([1.0, -1.0, -1.0])
    cam = camera_position_road(ego, camera)
    pose[:3, 3] = (cam[0], -cam[1], camera.height_m)
    return pose
