"""Exact per-frame ground truth: the :class:`~harness.world.truth.FrameTruth` record of each frame.

Distances (m), velocities (m/s) and TTC (s) in the ego frame of :mod:`monorarp.core.camera` (road-aligned
with a moving camera), boxes (px) and 3-D corners (m) in the frame's true camera; one object per
vehicle with at least one visible pixel, sorted by id. Every field's definition:
docs/formats.md (``ground_truth.jsonl``); the moving camera's ``camera`` block: docs/camera_motion.md.

On a road with a vertical profile (``world.profile``) the ego frame is the ego body's (parallel to
the road under the ego, :mod:`harness.world.geometry`), boxes and corners come from the same 3-D
placement the renderer draws, velocities are 3-D (a vehicle at ``x`` climbs at ``slope(x) vx``),
and ``s_long`` is the along-road arc length from the camera's foot point (the camera minus its
height along the ego's up axis) to the middle of the rear face's ground edge: docs/road_profile.md.

On a curved road (``world.plan``) the same holds with the ego frame yawed with the ego's body;
``s_long`` is then measured along the road at the camera foot point's lateral offset and ``s_lat``
is the rear face middle's lateral road offset minus the foot point's; ``ego.speed`` is the ego's
horizontal speed in the bent world (``1 - kappa y`` times the simulation's along a lane at ``y``;
``ego.x``, ``y``, ``heading`` stay road-frame). ``ttc`` on a curved road is
that of the unbent simulation (road-frame footprints and velocities: each vehicle keeps its speed
along its lane), since a straight-ahead constant-velocity extrapolation in the ego frame would see
the next lane's cars cross the ego's path: docs/road_curves.md.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import replace

import numpy as np

from harness.world.geometry import (ego_frame_world, road_vectors_to_ego, vehicle_corners_ego,
                                     vehicles_footprints_ego)
from harness.world.vehicles import vehicle_height
from harness.world.road_plan import path_length
from harness.world.truth import CameraTruth, EgoTruth, FrameTruth, ObjectTruth
from harness.world.state import WorldState
from monorarp.core.camera import CameraModel
from monorarp.risk.ttc import HORIZON_S, ego_extent, time_to_collision


def pixel_boxes(id_mask: np.ndarray) -> dict[int, tuple[list[float], int]]:
    """Tight pixel box ``[x1, y1, x2, y2]`` and pixel count of every id >= 0 in the mask."""
    flat = np.flatnonzero(id_mask.ravel() >= 0)
    if flat.size == 0:
        return {}
    ids = id_mask.ravel()[flat]
    order = np.argsort(ids, kind="stable")
    ids, flat = ids[order], flat[order]
    rows, cols = np.divmod(flat, id_mask.shape[1])
    starts = np.flatnonzero(np.r_[True, ids[1:] != ids[:-1]])
    counts = np.diff(np.r_[starts, ids.size])
    r0, r1 = np.minimum.reduceat(rows, starts), np.maximum.reduceat(rows, starts)
    c0, c1 = np.minimum.reduceat(cols, starts), np.maximum.reduceat(cols, starts)
    return {int(i): ([c0[k] - 0.5, r0[k] - 0.5, c1[k] + 0.5, r1[k] + 0.5], int(counts[k]))
            for k, i in enumerate(ids[starts])}


def frame_truth(world: WorldState, camera: CameraModel, id_mask, full_pixels: Mapping[int, float] | None = None,
                horizon_s: float = HORIZON_S) -> FrameTruth:
    """The ground-truth record of one frame.

    ``id_mask`` is the renderer's id pass, or the :class:`~harness.render.renderer.RenderedFrame`
    itself (then ``full_pixels`` comes from it). ``full_pixels`` (id -> unoccluded
    pixel count) is required for ``visibility``.
    """
    nominal = camera
    if hasattr(id_mask, "id_mask"):
        full_pixels = id_mask.full_pixels if full_pixels is None else full_pixels
        camera = getattr(id_mask, "camera", None) or camera    # the true camera of a moving mount
        id_mask = id_mask.id_mask
    if full_pixels is None:
        raise ValueError("frame_truth needs full_pixels (RenderedFrame.full_pixels) to compute visibility")
    ego = world.ego
    visible = pixel_boxes(np.asarray(id_mask))
    vehicles = [v for v in world.vehicles if v.id in visible]
    vehicles.sort(key=lambda v: v.id)
    speed = float(ego.speed) if world.plan is None else float(np.hypot(    # the bent lane's stretch: 1 - kappa y
        ego.vx * (1 - float(world.plan.curvature(ego.x)) * ego.y), ego.vy))
    ego_truth = EgoTruth(speed=speed, x=float(ego.x), y=float(ego.y), heading=float(ego.heading),
                         lane=int(ego.lane), crashed=bool(ego.crashed))
    pose = None
    if camera is not nominal:
        from harness.world.camera_motion import pose_record

        pose = CameraTruth(**pose_record(camera, nominal))
    record = FrameTruth(frame=int(world.frame), t=float(world.t), ego=ego_truth, camera=pose)
    if not vehicles:
        return record
    heights = np.array([vehicle_height(v.length, v.width, v.body) for v in vehicles])
    corners_ego = vehicle_corners_ego(vehicles, ego, camera, heights, world.profile, world.plan)   # (N, 8, 3)
    foot = corners_ego[:, :4, :2]                                                # (N, 4, 2)
    corners_cam = camera.ego_to_cam(corners_ego)                                 # (N, 8, 3)
    centres = foot.mean(axis=1)                                                  # footprint centres
    if world.profile is None and world.plan is None:
        v_rel = road_vectors_to_ego(np.array([[v.vx - ego.vx, v.vy - ego.vy] for v in vehicles]), ego)
        s_long = s_lat = [None] * len(vehicles)
    else:
        v_rel, s_long, s_lat = _road_motion(world, vehicles, camera, corners_ego)
    ex, ey = ego_extent(ego.length, ego.width, camera.forward_offset_m, camera.lateral_offset_m)
    # on a curve, TTC is the unbent simulation's: constant velocities along the lanes, not straight ahead
    ttc_foot, ttc_v = (foot, v_rel) if world.plan is None else (
        vehicles_footprints_ego(vehicles, ego, camera),
        road_vectors_to_ego(np.array([[v.vx - ego.vx, v.vy - ego.vy] for v in vehicles]), ego))
    ttc = time_to_collision(ttc_foot[..., 0].min(1), ttc_foot[..., 0].max(1), ttc_foot[..., 1].min(1),
                            ttc_foot[..., 1].max(1), ttc_v[:, 0], ttc_v[:, 1], ex, ey, horizon_s)
    objects = []
    for k, v in enumerate(vehicles):
        box, n_visible = visible[v.id]
        full = float(full_pixels.get(v.id, n_visible))
        objects.append(ObjectTruth(
            id=int(v.id),
            name=v.name,
            box=tuple(float(b) for b in box),
            visibility=float(min(1.0, n_visible / full)) if full > 0 else 0.0,
            d_long=float(foot[k, :, 1].min()),
            d_lat=float(centres[k, 0]),
            v_long=float(v_rel[k, 1]),
            v_lat=float(v_rel[k, 0]),
            ttc=None if np.isnan(ttc[k]) else float(ttc[k]),
            lane_rel=int(v.lane - ego.lane),
            corners_cam=tuple(map(tuple, corners_cam[k].round(6).tolist())),
            length=float(v.length),
            width=float(v.width),
            body=v.body,
            crashed=bool(v.crashed),
            s_long=s_long[k],
            s_lat=s_lat[k],
        ))
    return replace(record, objects=tuple(objects))


def _road_motion(world: WorldState, vehicles: list, camera: CameraModel,
                 corners_ego: np.ndarray) -> tuple[np.ndarray, list[float], list[float | None]]:
    """On a profiled and/or curved road: (N, 2) ego-frame relative velocities (x right, y ahead; m/s),
    each vehicle's along-road distance ``s_long`` (m) from the camera's foot point to the middle of its
    rear face's ground edge, and (curved road only) its along-road lateral offset ``s_lat`` (m, + right)."""
    profile, plan, ego = world.profile, world.plan, world.ego
    cam_w, r_w_from_ego = ego_frame_world(ego, camera, profile, plan)

    def velocity_w(v) -> np.ndarray:
        if plan is None:
            return np.array([v.vx, -v.vy, float(profile.slope(v.x)) * v.vx])
        th, along = float(plan.theta(v.x)), 1 - float(plan.curvature(v.x)) * v.y   # (x, y) -> P stretch
        vx, vy = v.vx * along * math.cos(th) - v.vy * math.sin(th), v.vx * along * math.sin(th) + v.vy * math.cos(th)
        return np.array([vx, -vy, 0.0 if profile is None else float(profile.slope(v.x)) * v.vx])

    v_rel = np.array([(velocity_w(v) - velocity_w(ego)) @ r_w_from_ego for v in vehicles])[:, :2]
    rear_w = cam_w + corners_ego[:, :2].mean(axis=1) @ r_w_from_ego.T   # rear face, ground, W
    foot_w = cam_w - camera.height_m * r_w_from_ego[:, 2]
    if plan is None:
        return v_rel, [float(s) for s in profile.arc_length(foot_w[0], rear_w[:, 0])], [None] * len(vehicles)
    x1, y1 = plan.from_plane(np.stack([rear_w[:, 0], -rear_w[:, 1]], axis=-1))
    x0, y0 = plan.from_plane(np.array([foot_w[0], -foot_w[1]]))
    s_long = path_length(plan, profile, x0, x1, y0)
    return v_rel, [float(s) for s in s_long], [float(s) for s in y1 - y0]
