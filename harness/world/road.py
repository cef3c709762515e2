"""Where a scenario's road sits along absolute road ``x`` (m): the ego's start, and the scenario's
vertical profile and horizontal curves placed from the camera's position at t = 0. The simulator
places vehicles in this frame; the renderer and the ground truth bend the world with the same plan
and profile."""

from __future__ import annotations

from harness.world.road_plan import RoadPlan
from harness.world.road_profile import RoadProfile

EGO_START_X_M = 250.0
"""Ego centre at t = 0: far enough from the road start for vehicles placed up to 200 m behind."""


def road_profile(segments, camera_forward_offset_m: float, ego_x_m: float = EGO_START_X_M) -> RoadProfile | None:
    """A scenario's ``road.profile`` in absolute road ``x``: each ``start_m`` is measured from the
    camera at t = 0 (like a placed vehicle's ``distance_m``; ``ego_x_m``: the ego's centre then);
    None for a level road."""
    return RoadProfile.from_segments(segments, ego_x_m + camera_forward_offset_m)


def road_plan(curves, camera_forward_offset_m: float, ego_x_m: float = EGO_START_X_M) -> RoadPlan | None:
    """A scenario's ``road.curves`` in absolute road ``x`` (``start_m`` from the camera at t = 0, the ego's
    centre then at ``ego_x_m``); None: straight."""
    return RoadPlan.from_segments(curves, ego_x_m + camera_forward_offset_m)
