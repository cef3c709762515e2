"""Independent synthetic dashcam frames of a straight road with painted lane lines (tests/benchmarks only).

The road is drawn directly: each painted stripe is a ground-plane rectangle in
the ego frame, its corners projected with ``CameraModel.project_ego`` and filled
with ``cv2.fillConvexPoly`` on a 4x supersampled canvas, then area-averaged down
(so edges carry sub-pixel coverage). ``fillConvexPoly`` rounds vertices to whole
pixels and fills inclusively, which grows a polygon by half a pixel on every
side; polygons are shrunk by that half (sub)pixel first, so painted areas are
unbiased. Road frame: ``s`` along the road (m), lateral positions in metres to
the right of the camera.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np

from monorarp.core.camera import CameraModel


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
    extras: list = field(default_factory=list)            # extra ground quads on the road [(x0, x1, s0, s1, gray)]
    riders: list = field(default_factory=list)            # ground quads moving with the ego [(x0, x1, y0, y1, gray)]


SS = 4   # supersampling factor


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]


def shrink_quads(quads: np.ndarray, d: float) -> tuple[np.ndarray, np.ndarray]:
    """Undo the growth of cv2.fillConvexPoly's inclusive scan conversion on convex polygons (N, V, 2).

    The fill covers each scanline from round(x_left) to round(x_right) inclusive and
    rows from round(y_top) to round(y_bottom): it grows a polygon by ``d`` = half a
    pixel horizontally at its sides and vertically at horizontal edges. Each edge
    line is moved back inwards by that much. Returns the polygons and a mask of
    those that stay convex with the same orientation (thinner ones must be dropped).
    """
    e = np.roll(quads, -1, axis=1) - quads                         # edge i: vertex i -> i+1
    area2 = _cross(quads, np.roll(quads, -1, axis=1)).sum(axis=1)
    length = np.linalg.norm(e, axis=-1)
    ok = (np.abs(area2) > 1e-9) & (length > 1e-9).all(axis=1)
    n = np.stack([-e[..., 1], e[..., 0]], axis=-1) * np.sign(area2)[:, None, None]
    n = n / np.where(length > 1e-9, length, 1.0)[..., None]
    horizontal = np.abs(e[..., 1]) < 1e-9
    p = quads + (d * np.where(horizontal, 1.0, np.abs(n[..., 0])))[..., None] * n   # on each moved edge line
    ea, pa = np.roll(e, 1, axis=1), np.roll(p, 1, axis=1)           # edge i-1 meets edge i at vertex i
    den = _cross(ea, e)
    ok &= (np.abs(den) > 1e-12).all(axis=1)
    s = _cross(p - pa, e) / np.where(np.abs(den) > 1e-12, den, 1.0)
    out = pa + s[..., None] * ea
    turns = _cross(np.roll(out, -1, 1) - out, np.roll(out, -2, 1) - np.roll(out, -1, 1))
    ok &= (np.sign(turns) == np.sign(area2)[:, None]).all(axis=1)
    return out, ok


def _fill_all(canvas: np.ndarray, camera: CameraModel, rects: list[tuple[float, float, float, float, int]]) -> None:
    """Paint ego-frame ground rectangles ``(x0, x1, y0, y1, gray)`` onto the supersampled canvas."""
    if not rects:
        return
    r = np.array(rects, dtype=float)
    x = r[:, [0, 1, 1, 0]]
    y = r[:, [2, 2, 3, 3]]
    p3 = np.stack([x, y, np.full_like(x, -camera.height_m)], axis=-1)
    uv = camera.project_ego(p3) * SS + (SS - 1) / 2.0               # pixel centres of the fine canvas
    uv, ok = shrink_quads(uv, 0.5)
    pts = np.round(uv * 16).astype(np.int32)
    for q, keep, gray in zip(pts, ok, r[:, 4]):
        if keep:
            cv2.fillConvexPoly(canvas, q, int(gray), cv2.LINE_8, 4)


def render_road(camera: CameraModel, s: float, road: RoadSpec, rng: np.random.Generator | None = None) -> np.ndarray:
    """BGR uint8 frame with the camera at road position ``s`` (m)."""
    h, w = camera.height, camera.width
    canvas = np.full((h * SS, w * SS), road.road_gray, dtype=np.uint8)
    canvas[: int(np.ceil((camera.horizon_row + 0.5) * SS))] = road.sky_gray
    near = 0.8
    rects = []
    for x, dashed, phase in zip(road.lines_x, road.dashed, road.phases_m):
        x0, x1 = x - road.width_m / 2, x + road.width_m / 2
        if not dashed:
            rects.append((x0, x1, near, road.far_m, road.paint_gray))
            continue
        k0 = int(np.floor((s + near - phase) / road.period_m)) - 1
        k1 = int(np.ceil((s + road.far_m - phase) / road.period_m))
        for k in range(k0, k1 + 1):
            y0 = phase + k * road.period_m - s
            y1 = y0 + road.stripe_length_m
            y0, y1 = max(y0, near), min(y1, road.far_m)
            if y1 > y0:
                rects.append((x0, x1, y0, y1, road.paint_gray))
    for x0, x1, s0, s1, gray in road.extras:
        y0, y1 = max(s0 - s, near), min(s1 - s, road.far_m)
        if y1 > y0:
            rects.append((x0, x1, y0, y1, gray))
    _fill_all(canvas, camera, rects)
    _fill_all(canvas, camera, [(x0, x1, max(y0, near), y1, g) for x0, x1, y0, y1, g in road.riders])
    img = cv2.resize(canvas, (w, h), interpolation=cv2.INTER_AREA)
    if road.blur_px > 0:
        img = cv2.GaussianBlur(img, (0, 0), road.blur_px)
    if road.noise_std > 0:
        rng = rng or np.random.default_rng(0)
        noise = rng.standard_normal(img.shape, dtype=np.float32) * np.float32(road.noise_std)
        img = np.clip(img + noise, 0, 255).astype(np.uint8)
    return cv2.cvtColor(img, cv2.COLOR_GRAY2BGR)


def true_stripe_ends(camera: CameraModel, s: float, road: RoadSpec, y_min: float, y_max: float):
    """Exact stripe ends of the dashed lines in ``[y_min, y_max]`` (m ahead): list of (x, y, kind 0=near/1=far)."""
    out = []
    for x, dashed, phase in zip(road.lines_x, road.dashed, road.phases_m):
        if not dashed:
            continue
        k0 = int(np.floor((s + y_min - phase) / road.period_m)) - 1
        k1 = int(np.ceil((s + y_max - phase) / road.period_m)) + 1
        for k in range(k0, k1 + 1):
            y0 = phase + k * road.period_m - s
            for y, kind in ((y0, 0), (y0 + road.stripe_length_m, 1)):
                if y_min <= y <= y_max:
                    out.append((x, y, kind))
    return out


def sequence(camera: CameraModel, speed_mps: float, fps: float, n_frames: int, road: RoadSpec | None = None,
             s0: float = 0.0, seed: int = 0, times: np.ndarray | None = None):
    """Yield ``(t, image, speed)``: constant ``speed_mps``, frame k at ``times[k]`` (default k / fps)."""
    road = road or RoadSpec()
    rng = np.random.default_rng(seed)
    ts = np.arange(n_frames) / fps if times is None else np.asarray(times, dtype=float)
    for t in ts:
        yield float(t), render_road(camera, s0 + speed_mps * t, road, rng), speed_mps
