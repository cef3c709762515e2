"""Which vehicles need an extra render to count their unoccluded, unbounded pixels.

``visibility`` = visible pixels / pixels the vehicle would cover if nothing hid it
and the image had no border. A vehicle whose projected 3-D box lies inside the
image and overlaps no nearer vehicle's projected box covers exactly its visible
pixels (its mesh lies inside its box), so its ratio is 1 without another render.
The others are drawn in a sub-window of the (virtual, unbounded) image plane
around their projected box where nothing can hide them (each vehicle one bit of
the pixel code, OR-ed, no depth test), with the same rasteriser and the principal
point shifted by whole pixels, so the pixel grid is the same as the image's.
The virtual canvas reaches one image size beyond each border; very large windows
are rendered at an integer downscale ``s`` and their count multiplied by s^2.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from monorarp.core.camera import CameraModel


@dataclass(frozen=True)
class Window:
    """A sub-window of the virtual image: full-resolution pixel columns x0.. and rows y0..,
    rendered as ``width`` x ``height`` pixels of ``scale`` x ``scale`` full-resolution pixels."""

    x0: int
    y0: int
    width: int
    height: int
    scale: int

    def intrinsics(self, camera: CameraModel) -> tuple[float, float, float, float]:
        """(fx, fy, cx, cy) of the window's own pixel grid (OpenCV convention)."""
        s = self.scale
        return (camera.fx / s, camera.fy / s,
                (camera.cx - self.x0 - (s - 1) / 2) / s, (camera.cy - self.y0 - (s - 1) / 2) / s)


def projected_boxes(corners_cam: np.ndarray, camera: CameraModel, znear: float) -> np.ndarray:
    """(N, 4) boxes [u0, v0, u1, v1] (px) of the projected 3-D boxes; +-inf when a corner
    lies closer than ``znear`` to the camera plane (the projection is then unbounded)."""
    n = corners_cam.shape[0]
    out = np.empty((n, 4))
    if n == 0:
        return out
    z = corners_cam[..., 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        uv = camera.project_cam(corners_cam)
    out[:, :2] = uv.min(axis=1)
    out[:, 2:] = uv.max(axis=1)
    near = (z <= znear).any(axis=1)
    out[near] = (-np.inf, -np.inf, np.inf, np.inf)
    return out


def needs_full_render(boxes: np.ndarray, corners_cam: np.ndarray, drawn: np.ndarray,
                      width: int, height: int, margin: float = 1.0) -> np.ndarray:
    """(N,) bool: vehicles that may be truncated by the border or hidden by another drawn vehicle."""
    n = boxes.shape[0]
    inside = ((boxes[:, 0] >= margin - 0.5) & (boxes[:, 1] >= margin - 0.5)
              & (boxes[:, 2] <= width - 0.5 - margin) & (boxes[:, 3] <= height - 0.5 - margin))
    z = corners_cam[..., 2]
    zmin, zmax = z.min(axis=1), z.max(axis=1)
    b = boxes
    overlap = ((b[:, None, 0] <= b[None, :, 2] + margin) & (b[None, :, 0] <= b[:, None, 2] + margin)
               & (b[:, None, 1] <= b[None, :, 3] + margin) & (b[None, :, 1] <= b[:, None, 3] + margin))
    # j can hide i only if some of j is nearer than some of i.
    can_hide = overlap & (zmin[None, :] < zmax[:, None]) & drawn[None, :] & ~np.eye(n, dtype=bool)
    return ~inside | can_hide.any(axis=1)


def boxes_touching(mask: np.ndarray, boxes: np.ndarray) -> np.ndarray:
    """(N,) bool: projected boxes ``[x0, y0, x1, y1]`` (px, pixel centres at integers) whose pixels
    (clipped to the image) hold any True of the (H, W) ``mask``; through an integral image."""
    h, w = mask.shape
    if not len(boxes) or not mask.any():
        return np.zeros(len(boxes), dtype=bool)
    ii = cv2.integral(np.ascontiguousarray(mask, dtype=bool).view(np.uint8), sdepth=cv2.CV_32S if h * w < 2 ** 31
                      else cv2.CV_64F)
    b = np.nan_to_num(np.asarray(boxes, dtype=float), nan=0.0, posinf=1e9, neginf=-1e9)
    x0 = np.clip(np.floor(b[:, 0] + 0.5), 0, w).astype(int)
    y0 = np.clip(np.floor(b[:, 1] + 0.5), 0, h).astype(int)
    x1 = np.clip(np.floor(b[:, 2] + 0.5) + 1, 0, w).astype(int)
    y1 = np.clip(np.floor(b[:, 3] + 0.5) + 1, 0, h).astype(int)
    ok = (x1 > x0) & (y1 > y0)
    total = ii[y1, x1] - ii[y0, x1] - ii[y1, x0] + ii[y0, x0]
    return ok & (total > 0)


def box_corners(bounds: np.ndarray) -> np.ndarray:
    """(N, 8, 3) corners of (N, 2, 3) axis-aligned boxes ``[[min xyz], [max xyz]]``."""
    b = np.asarray(bounds, dtype=float).reshape(-1, 2, 3)
    pick = np.array([[i >> 2 & 1, i >> 1 & 1, i & 1] for i in range(8)])          # (8, 3) of 0/1
    return np.where(pick[None] == 1, b[:, None, 1], b[:, None, 0])


def outside_view(corners_cam: np.ndarray, camera: CameraModel, znear: float, margin: float = 2.0) -> np.ndarray:
    """(N,) bool: convex hulls of (N, K, 3) points (camera frame, OpenCV axes, m) that lie wholly outside the
    view of ``camera`` (pinhole; pixel centres at integers): every point behind the near plane ``znear``, or
    every point beyond one side plane of the image (its border pushed out by ``margin`` px).

    Conservative: True means nothing of the hull projects into the image, so a mesh inside it draws no
    pixel; False may still draw none. The side planes pass through the camera centre, so the test holds
    for points behind the camera too."""
    c = np.asarray(corners_cam, dtype=float)
    x, y, z = c[..., 0], c[..., 1], c[..., 2]
    m = float(margin)
    planes = np.stack([z < znear,
                       camera.fx * x + (camera.cx + 0.5 + m) * z < 0,
                       -camera.fx * x + (camera.width - 0.5 + m - camera.cx) * z < 0,
                       camera.fy * y + (camera.cy + 0.5 + m) * z < 0,
                       -camera.fy * y + (camera.height - 0.5 + m - camera.cy) * z < 0])     # (5, N, K)
    return planes.all(axis=2).any(axis=0)


def full_window(box: np.ndarray, width: int, height: int, max_pixels: int) -> Window | None:
    """The sub-window around one projected box, clipped to the virtual canvas
    [-width, 2 width) x [-height, 2 height); None when it is empty."""
    x0 = max(math.floor(box[0]) - 1, -width) if np.isfinite(box[0]) else -width
    y0 = max(math.floor(box[1]) - 1, -height) if np.isfinite(box[1]) else -height
    x1 = min(math.ceil(box[2]) + 2, 2 * width) if np.isfinite(box[2]) else 2 * width
    y1 = min(math.ceil(box[3]) + 2, 2 * height) if np.isfinite(box[3]) else 2 * height
    if x1 <= x0 or y1 <= y0:
        return None
    area = (x1 - x0) * (y1 - y0)
    s = max(1, math.ceil(math.sqrt(area / max_pixels)))
    # Sizes rounded up to multiples of 32 px so the renderer's buffers are rarely reallocated.
    return Window(x0, y0, -(-math.ceil((x1 - x0) / s) // 32) * 32, -(-math.ceil((y1 - y0) / s) // 32) * 32, s)


_BITS = ((np.arange(256)[:, None] >> np.arange(8)) & 1).astype(np.int64)     # (256, 8): byte value -> its bits


def bit_counts(codes: np.ndarray, n: int) -> np.ndarray:
    """(n,) int64: how many pixels of the (h, w) uint32 ``codes`` have bit k set, k < n <= 24."""
    nz = codes[codes != 0]
    hist = np.stack([np.bincount((nz >> (8 * j)) & 0xFF, minlength=256) for j in range(3)])   # (3, 256)
    return (hist @ _BITS).ravel()[:n]


MAX_MEMBERS = 24
"""The most vehicles one sub-window pass counts: each is drawn as one bit of the 24-bit id code."""


def plan_full_renders(boxes: np.ndarray, indices, width: int, height: int, max_pixels: int,
                      max_members: int = MAX_MEMBERS) -> list[tuple[Window, list[int]]]:
    """Group vehicles ``indices`` into as few sub-window renders as possible.

    The pass draws member k as bit k, OR-ed into its pixels without a depth test
    (:meth:`harness.render.passes.Passes.ids` with ``overlay``), so members may overlap: each
    member's pixels are those it covers alone. Vehicles share a render when their joint window is
    a full-resolution one of at most ``max_pixels`` and ``max_members`` are not yet in it; a vehicle
    whose own window is coarser (scale > 1) gets a window of its own.
    """
    groups: list[tuple[np.ndarray, list[int]]] = []
    singles: list[tuple[Window, list[int]]] = []
    for i in indices:
        box = boxes[i]
        win = full_window(box, width, height, max_pixels)
        if win is None:
            continue
        if win.scale > 1:
            singles.append((win, [i]))
            continue
        for k, (ubox, members) in enumerate(groups):
            if len(members) >= max_members:
                continue
            joined = np.r_[np.minimum(ubox[:2], box[:2]), np.maximum(ubox[2:], box[2:])]
            jw = full_window(joined, width, height, max_pixels)
            if jw is not None and jw.scale == 1:
                groups[k] = (joined, members + [i])
                break
        else:
            groups.append((np.asarray(box, dtype=float), [i]))
    return [(full_window(ubox, width, height, max_pixels), members) for ubox, members in groups] + singles
