"""Ground-plane geometry of image rows, for a camera with no roll (pure maths, no I/O).

With no roll every image row ``v`` below the horizon is the image of one ground
line of constant longitudinal distance ``y(v)`` (ego frame, m), and along that
row the lateral ground coordinate is linear in ``u``:
``u = cx + x * s(v)`` with ``s(v)`` in px per metre. These two functions are all
the lane-speed estimators need to sample the road on the ground plane; they are
derived from :meth:`CameraModel.ground_point_from_pixel`, never re-implemented.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from monorarp.core.camera import CameraModel
from monorarp.core.errors import UserError


class EgoSpeedError(UserError, ValueError):
    """Impossible ego-speed estimator settings (names the parameter and the reason)."""


class EgoSpeedStageError(EgoSpeedError):
    """The pipeline's ego-speed stage cannot be built (:meth:`monorarp.pipeline.runner.Pipeline.from_config`): the
    message names the stage; a command adds its file and that ``--ego-speed none`` runs without it."""


def row_distance(camera: CameraModel, v: np.ndarray) -> np.ndarray:
    """Ground distance ahead ``y`` (m, ego frame) seen at continuous image rows ``v``; NaN above the horizon."""
    v = np.asarray(v, dtype=float)
    return camera.ground_point_from_pixel(np.full_like(v, camera.cx), v)[..., 1]


def row_of_distance(camera: CameraModel, y: np.ndarray) -> np.ndarray:
    """Continuous image row ``v`` where the ground at distance ``y`` (m ahead) appears."""
    y = np.asarray(y, dtype=float)
    pts = np.stack([np.zeros_like(y), y, np.full_like(y, -camera.height_m)], axis=-1)
    return camera.project_ego(pts)[..., 1]


def row_scale(camera: CameraModel, v: np.ndarray) -> np.ndarray:
    """Pixels per metre of lateral ground offset along image rows ``v`` (NaN above the horizon)."""
    v = np.asarray(v, dtype=float)
    p = camera.ground_point_from_pixel(np.full_like(v, camera.cx + 1.0), v)
    return 1.0 / p[..., 0]


@dataclass(frozen=True)
class GroundRows:
    """The integer image rows seeing the ground between ``y_near`` and ``y_far``, nearest first.

    ``v`` (rows, px), ``y`` (distance ahead, m), ``scale`` (px per lateral metre),
    ``dy_dv`` (m of ground per row, >0).
    """

    v: np.ndarray
    y: np.ndarray
    scale: np.ndarray
    dy_dv: np.ndarray

    @classmethod
    def build(cls, camera: CameraModel, y_near: float, y_far: float) -> "GroundRows":
        if not 0 < y_near < y_far:
            raise EgoSpeedError(f"ground range must satisfy 0 < near < far, got near={y_near} m, far={y_far} m")
        rows = np.arange(camera.height - 1, int(np.ceil(camera.horizon_row)), -1, dtype=float)
        y = row_distance(camera, rows)
        keep = np.isfinite(y) & (y >= y_near) & (y <= y_far)
        if keep.sum() < 8:
            raise EgoSpeedError(
                f"camera sees fewer than 8 image rows of ground between {y_near} m and {y_far} m "
                f"(horizon row {camera.horizon_row:.1f}, image height {camera.height}); check pitch and the range"
            )
        v = rows[keep]
        dy = np.abs(row_distance(camera, v - 0.5) - row_distance(camera, v + 0.5))
        return cls(v=v, y=y[keep], scale=row_scale(camera, v), dy_dv=dy)


def x_to_u(camera: CameraModel, x: np.ndarray, scale: np.ndarray) -> np.ndarray:
    """Column ``u`` of the lateral ground offset ``x`` (m) on rows with px-per-metre ``scale``."""
    return camera.cx + np.asarray(x) * scale


BGR_TO_GRAY = np.array([0.114, 0.587, 0.299], dtype=np.float32)


def to_gray(samples: np.ndarray) -> np.ndarray:
    """BGR samples (..., 3) or gray (...) -> float32 luma (ITU-R BT.601, as cv2.cvtColor)."""
    if samples.ndim >= 3 and samples.shape[-1] == 3:
        return samples.astype(np.float32) @ BGR_TO_GRAY
    return samples.astype(np.float32)
