"""Independent synthetic dashcam frames of a straight road with painted lane lines (tests/benchmarks only).

The road is drawn directly: each painted stripe is a ground-plane rectangle in
the ego frame, its corners projected with ``CameraModel.project_ego`` and filled
with ``cv2.fillConvexPoly`` (anti-aliased, 1/16 px vertex precision). Road frame:
``s`` along the road (m), lateral positions in metres to the right of the camera.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np

from monorarp.camera import CameraModel


def default_camera(width: int = 640, height: int = 360) -> CameraModel:
    """The scenario schema's default dashcam: 70 deg HFOV, 1.3 m high, pitched 2 deg down."""
    return CameraModel.from_fov(width, height, 70.0, 1.3, np.radians(2.0), 0.0, 0.5)


@dataclass
class RoadSpec:
    """Lane lines (lateral position from the camera, m; dashed or solid) and paint."""

    lines_x: tuple[float, ...] = (-6.0, -2.0, 2.0, 6.0)
    dashed: tuple[bool, ...] = (False, True, True, False)
    stripe_length_m: float = 3.05
    period_m: float = 12.19
    width_m: float = 0.15
    phases_m: tuple[float, ...] = (0.0, 1.3, 4.1, 0.0)   # road position of the first dash start, per line
    road_gray: int = 70
    paint_gray: int = 215
    sky_gray: int = 160
    noise_std: float = 0.0
    blur_px: float = 0.0
    far_m: float = 120.0
    extras: list = field(default_factory=list)            # extra ground quads [(x0, x1, s0, s1, gray)]


def _quad(camera: CameraModel, x0: float, x1: float, y0: float, y1: float) -> np.ndarray:
    pts = np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]], dtype=float)
    p3 = np.concatenate([pts, np.full((4, 1), -camera.height_m)], axis=1)
    return np.round(camera.project_ego(p3) * 16).astype(np.int32)


def render_road(camera: CameraModel, s: float, road: RoadSpec, rng: np.random.Generator | None = None) -> np.ndarray:
    """BGR uint8 frame with the camera at road position ``s`` (m)."""
    h, w = camera.height, camera.width
    img = np.full((h, w, 3), road.road_gray, dtype=np.uint8)
    hz = int(np.floor(camera.horizon_row))
    img[: hz + 1] = road.sky_gray
    near = 0.8
    for x, dashed, phase in zip(road.lines_x, road.dashed, road.phases_m):
        x0, x1 = x - road.width_m / 2, x + road.width_m / 2
        if not dashed:
            cv2.fillConvexPoly(img, _quad(camera, x0, x1, near, road.far_m), (road.paint_gray,) * 3, cv2.LINE_AA, 4)
            continue
        k0 = int(np.floor((s + near - phase) / road.period_m)) - 1
        k1 = int(np.ceil((s + road.far_m - phase) / road.period_m))
        for k in range(k0, k1 + 1):
            y0 = phase + k * road.period_m - s
            y1 = y0 + road.stripe_length_m
            y0, y1 = max(y0, near), min(y1, road.far_m)
            if y1 > y0:
                cv2.fillConvexPoly(img, _quad(camera, x0, x1, y0, y1), (road.paint_gray,) * 3, cv2.LINE_AA, 4)
    for x0, x1, s0, s1, gray in road.extras:
        y0, y1 = max(s0 - s, near), min(s1 - s, road.far_m)
        if y1 > y0:
            cv2.fillConvexPoly(img, _quad(camera, x0, x1, y0, y1), (gray,) * 3, cv2.LINE_AA, 4)
    if road.blur_px > 0:
        img = cv2.GaussianBlur(img, (0, 0), road.blur_px)
    if road.noise_std > 0:
        rng = rng or np.random.default_rng(0)
        img = np.clip(img + rng.normal(0.0, road.noise_std, img.shape), 0, 255).astype(np.uint8)
    return img


def sequence(camera: CameraModel, speed_mps: float, fps: float, n_frames: int, road: RoadSpec | None = None,
             s0: float = 0.0, seed: int = 0, times: np.ndarray | None = None):
    """Yield ``(t, image, speed)``: constant ``speed_mps``, frame k at ``times[k]`` (default k / fps)."""
    road = road or RoadSpec()
    rng = np.random.default_rng(seed)
    ts = np.arange(n_frames) / fps if times is None else np.asarray(times, dtype=float)
    for t in ts:
        yield float(t), render_road(camera, s0 + speed_mps * t, road, rng), speed_mps
