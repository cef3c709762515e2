"""Estimated ego-frame states -> the road-frame scene a rollout starts from (pure maths).

Ego frame (:mod:`monorarp.core.camera`): origin at the camera, ``x`` lateral (+ right),
``y`` longitudinal (+ ahead); ``d_y`` is the distance to a vehicle's rear face,
``d_x`` the lateral offset of its centre, velocities are relative to the ego.

Rollout road frame (:mod:`monorarp.risk.monte_carlo.rollout`): ``x`` along the road with
the ego's centre at 0, ``y`` across it (+ right) with the ego's lane centre at 0
(the ego is assumed centred in its lane); lane ``round(y / lane_width)``.
The road is assumed straight and aligned with the ego's heading.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Geometry:
    """Sizes (m) and camera mounting on the ego (m)."""

    vehicle_length_m: float = 4.5
    vehicle_width_m: float = 1.8
    ego_length_m: float = 4.5
    ego_width_m: float = 1.8
    camera_forward_offset_m: float = 0.0   # camera ahead of the ego's centre
    camera_lateral_offset_m: float = 0.0   # camera right of the ego's centre
    lane_width_m: float = 3.7


@dataclass(frozen=True)
class Noise:
    """Standard deviations of the initial-state noise (state-estimator error)."""

    position_m: float = 0.3          # longitudinal, plus position_rel * distance
    position_rel: float = 0.03
    lateral_m: float = 0.2
    speed_mps: float = 0.5           # relative speed, plus speed_rel * distance (m/s per m)
    speed_rel: float = 0.01
    ego_speed_mps: float = 0.3       # common to every vehicle of a rollout (absolute speeds = ego + relative)


def road_positions(d_x: np.ndarray, d_y: np.ndarray, geo: Geometry) -> tuple[np.ndarray, np.ndarray]:
    """Centres (x along the road, y across) of vehicles at ego-frame (d_x, d_y), relative to the ego's centre."""
    x = d_y + geo.camera_forward_offset_m + geo.vehicle_length_m / 2.0
    y = d_x + geo.camera_lateral_offset_m
    return x, y


def lane_of(y: np.ndarray, lane_width_m: float) -> np.ndarray:
    """Lane index (ego's lane = 0, + right) of lateral positions ``y`` (m)."""
    return np.rint(np.asarray(y) / lane_width_m).astype(int)


def lane_range(lanes: np.ndarray, lanes_left: int | None, lanes_right: int | None) -> tuple[int, int]:
    """Allowed lane indices: given counts of lanes left/right of the ego, else those spanned by ``lanes`` and 0."""
    lo = -lanes_left if lanes_left is not None else min(0, int(lanes.min(initial=0)))
    hi = lanes_right if lanes_right is not None else max(0, int(lanes.max(initial=0)))
    return lo, hi
