"""Pure geometry shared by the renderer and the ground truth (no rendering here).

Frames:

* **Road frame** (highway-env, :mod:`harness.world.state`): ``x`` along the road,
  ``y`` to the right of travel, heading from +x towards +y; the ground is z = 0.
  Left-handed with z up, so it is never used for 3-D rendering directly.
* **World frame W** (pyrender, right-handed): ``X = x``, ``Y = -y`` (left of
  travel), ``Z`` up; the ground is Z = 0. ``Render.light_direction`` is given in W.
* **Ego frame** and **camera frame**: :mod:`monorarp.core.camera`. The camera sits at
  ego centre + ``forward_offset_m`` along the ego heading + ``lateral_offset_m``
  to its right, ``height_m`` above the ground.
* **Vehicle model frame** (meshes): ``X`` forward, ``Y`` left, ``Z`` up, origin on
  the ground at the centre of the length x width footprint.

With a vertical road profile (:mod:`harness.world.road_profile`) the ground is ``Z = z(X)``: each
vehicle's model frame (the ego's body frame too) sits at ``(x, -y, z(x))``, its ``Z`` along the
road's normal there and ``X`` along its heading in the road's tangent plane (pitched by
``atan(slope(x))``); the ego frame and the camera ride on the ego's body frame, so the camera's
pose relative to the road under the ego stays the calibrated one. With a horizontal plan
(:mod:`harness.world.road_plan`) the origin is at ``plan.to_plane(x, y)`` and the yaw is the road's heading
``theta(x)`` plus the vehicle's own heading. Without a profile and a plan (None) every function here
computes exactly what it did on the level straight road.

Footprint corner order (4, per vehicle, its own left/right): rear-left,
rear-right, front-right, front-left. 3-D box corner order (8): those four on the
ground (z = 0), then the same four at roof height.
"""

from __future__ import annotations

import numpy as np

from harness.world.road_plan import RoadPlan
from harness.world.road_profile import RoadProfile
from harness.world.state import VehicleState
from monorarp.core.camera import CameraModel

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


def vehicle_corners_ego(vehicles, ego: VehicleState, camera: CameraModel, heights: np.ndarray,
                        profile: RoadProfile | None = None, plan: RoadPlan | None = None) -> np.ndarray:
    """(N, 8, 3) 3-D box corners of ``vehicles`` in the ego frame (m), on the level straight road or
    on ``profile`` and/or ``plan``."""
    if profile is None and plan is None:
        return box_corners_ego(vehicles_footprints_ego(vehicles, ego, camera), heights, camera)
    if not vehicles:
        return np.zeros((0, 8, 3))
    arr = np.array([[v.x, v.y, v.heading, v.length, v.width] for v in vehicles], dtype=float)
    origin, rot = body_frames_world(arr[:, 0], arr[:, 1], arr[:, 2], profile, plan)
    foot = np.stack([_FOOT[:, 0] * arr[:, 3:4] / 2, -_FOOT[:, 1] * arr[:, 4:5] / 2], axis=-1)   # model X, Y
    model = np.concatenate([np.concatenate([foot, np.zeros((len(arr), 4, 1))], axis=-1),
                            np.concatenate([foot, np.broadcast_to(np.reshape(heights, (-1, 1, 1)),
                                                                  (len(arr), 4, 1))], axis=-1)], axis=1)
    world = origin[:, None, :] + np.einsum("nij,nkj->nki", rot, model)
    return world_to_ego(world, ego, camera, profile, plan)


# ------------------------------------------------------------------ world frame W
def body_frames_world(x, y, heading, profile: RoadProfile | None,
                      plan: RoadPlan | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Model frames on the profiled and/or curved road: origins (N, 3) in W and rotations (N, 3, 3)
    W <- model (columns: forward, left, up), for road-frame centres ``x``, ``y`` (m) and headings (rad)."""
    x, y, h = (np.atleast_1d(np.asarray(a, dtype=float)) for a in (x, y, heading))
    if plan is None:
        s = profile.slope(x)
        up = np.stack([-s, np.zeros_like(s), np.ones_like(s)], axis=-1)
        f0 = np.stack([np.cos(h), -np.sin(h), np.zeros_like(h)], axis=-1)
        origin = np.stack([x, -y, profile.z(x)], axis=-1)
    else:
        th, p = plan.theta(x), plan.to_plane(x, y)
        # slope along the lane at offset y, which advances (1 - kappa y) per unit x
        s = np.zeros_like(x) if profile is None else profile.slope(x) / (1 - plan.curvature(x) * y)
        up = np.stack([-s * np.cos(th), s * np.sin(th), np.ones_like(s)], axis=-1)
        f0 = np.stack([np.cos(th + h), -np.sin(th + h), np.zeros_like(h)], axis=-1)
        origin = np.stack([p[:, 0], -p[:, 1], np.zeros_like(x) if profile is None else profile.z(x)], axis=-1)
    up /= np.linalg.norm(up, axis=-1, keepdims=True)
    fwd = f0 - np.sum(f0 * up, axis=-1, keepdims=True) * up
    fwd /= np.linalg.norm(fwd, axis=-1, keepdims=True)
    return origin, np.stack([fwd, np.cross(up, fwd), up], axis=-1)


def ego_frame_world(ego: VehicleState, camera: CameraModel, profile: RoadProfile | None,
                    plan: RoadPlan | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The ego frame on the profiled and/or curved road: its origin (the camera, (3,) in W) and
    rotation W <- ego (columns: right, ahead, up of the ego's body)."""
    origin, rot = body_frames_world(ego.x, ego.y, ego.heading, profile, plan)
    fwd, left, up = rot[0].T
    cam = origin[0] + camera.forward_offset_m * fwd - camera.lateral_offset_m * left + camera.height_m * up
    return cam, np.stack([-left, fwd, up], axis=-1)


def world_to_ego(points_w: np.ndarray, ego: VehicleState, camera: CameraModel, profile: RoadProfile | None,
                 plan: RoadPlan | None = None) -> np.ndarray:
    """(..., 3) points in W -> (..., 3) ego frame (x right, y ahead, z up of the ego's body; origin at the camera)."""
    cam, rot = ego_frame_world(ego, camera, profile, plan)
    return (np.asarray(points_w, dtype=float) - cam) @ rot


def road_to_world(points: np.ndarray) -> np.ndarray:
    """(..., 3) road-frame (x, y right, z up) -> W (X, Y left, Z up)."""
    p = np.array(points, dtype=float)
    p[..., 1] *= -1.0
    return p


def vehicle_pose_world(v: VehicleState, profile: RoadProfile | None = None, plan: RoadPlan | None = None) -> np.ndarray:
    """4x4 pose of a vehicle's model frame in W."""
    pose = np.eye(4)
    if profile is not None or plan is not None:
        origin, rot = body_frames_world(v.x, v.y, v.heading, profile, plan)
        pose[:3, :3], pose[:3, 3] = rot[0], origin[0]
        return pose
    c, s = np.cos(-v.heading), np.sin(-v.heading)
    pose[:2, :2] = [[c, -s], [s, c]]
    pose[0, 3], pose[1, 3] = v.x, -v.y
    return pose


def camera_pose_world(ego: VehicleState, camera: CameraModel, profile: RoadProfile | None = None,
                      plan: RoadPlan | None = None) -> np.ndarray:
    """4x4 pose (camera -> W) of the OpenGL camera (x right, y up, looking along -z)."""
    if profile is not None or plan is not None:
        cam_w, r_w_from_ego = ego_frame_world(ego, camera, profile, plan)
    else:
        fwd, right = heading_axes(ego.heading)
        r_w_from_ego = np.array([[right[0], fwd[0], 0.0],
                                 [-right[1], -fwd[1], 0.0],
                                 [0.0, 0.0, 1.0]])
        cam = camera_position_road(ego, camera)
        cam_w = (cam[0], -cam[1], camera.height_m)
    r_w_from_cv = r_w_from_ego @ camera.R_cam_from_ego.T
    pose = np.eye(4)
    pose[:3, :3] = r_w_from_cv @ np.diag([1.0, -1.0, -1.0])
    pose[:3, 3] = cam_w
    return pose
