"""A distorted camera's boxes and image, seen in its ideal pinhole canvas (what the state geometry assumes).

Equations 3 and 4 and every rule of :mod:`monorarp.state.geometry` hold for pinhole pixels. For a camera with
lens distortion (:mod:`monorarp.core.distortion`) the state estimator works on a *virtual pinhole camera*: the
same focal lengths, no distortion, and a canvas large enough to hold every ray the distorted image sees
(``canvas``; for barrel distortion larger than the image), the principal point shifted by whole pixels.

A box of the distorted image becomes the largest axis-aligned box inside its undistorted outline
(:func:`ideal_boxes`): for a vehicle whose pinhole silhouette is box-like, its pinhole box. With radial
distortion the distorted box touches the silhouette where a side's curve comes nearest the image centre
(barrel) or at its ends (pincushion); undistorting each side and keeping its innermost point finds that
place in both cases. A side within ``border_tol_px`` of the real image's border is put on the canvas's
border, so "cut by the border" keeps meaning the real image's border. Boxes ``(x1, y1, x2, y2)`` px,
continuous pixel coordinates (:mod:`monorarp.core.camera`).
"""

from __future__ import annotations

import functools
import math
from dataclasses import replace

import numpy as np

from monorarp.core.camera import CameraModel
from monorarp.core.distortion import ZERO, ideal_bounds
from monorarp.state.measurement import plausible_boxes

_EDGE_SAMPLES = 17


@functools.lru_cache(maxsize=16)
def _canvas(width: int, height: int, fx: float, fy: float, cx: float, cy: float, k: tuple, margin: int
            ) -> tuple[int, int, int, int]:
    """``(x0, y0, canvas width, canvas height)``: the ideal pixels ``x0 .. x0 + w - 1`` (whole pixels) hold
    the rays of the distorted image with ``margin`` px to spare."""
    u0, v0, u1, v1 = ideal_bounds(width, height, fx, fy, cx, cy, k)
    x0, y0 = math.floor(u0) - margin, math.floor(v0) - margin
    return x0, y0, math.ceil(u1) + margin - x0 + 1, math.ceil(v1) + margin - y0 + 1


class PinholeView:
    """The virtual pinhole camera of a distorted ``camera`` and the boxes and images in it."""

    def __init__(self, camera: CameraModel, border_tol_px: float | None) -> None:
        self.real, self.tol = camera, border_tol_px
        self.margin = int(math.ceil(border_tol_px or 0.0)) + 2
        c = camera
        self.x0, self.y0, *self.size = _canvas(c.width, c.height, c.fx, c.fy, c.cx, c.cy, c.distortion, self.margin)
        self.camera = self.virtual(c)
        self._maps: tuple[np.ndarray, np.ndarray] | None = None

    def virtual(self, camera: CameraModel) -> CameraModel:
        """The virtual pinhole camera of ``camera`` (this view's intrinsics and distortion; its own mounting)."""
        return replace(camera, width=self.size[0], height=self.size[1], cx=camera.cx - self.x0, cy=camera.cy - self.y0,
                       distortion=ZERO)

    def boxes(self, boxes: np.ndarray) -> np.ndarray:
        """(M, 4) boxes of the distorted image -> (M, 4) boxes of the virtual camera (NaN rows stay NaN, and so
        become boxes that are no measurement: :func:`~monorarp.state.measurement.plausible_boxes`)."""
        c = self.real
        b = plausible_boxes(c, np.asarray(boxes, dtype=float).reshape(-1, 4))   # beyond 10 image sizes: NaN
        x1, y1, x2, y2 = b.T
        t = np.linspace(0.0, 1.0, _EDGE_SAMPLES)
        # each side's samples, with the point of it nearest the principal point
        us = np.concatenate([x1[:, None] + (x2 - x1)[:, None] * t, np.clip(c.cx, x1, x2)[:, None]], axis=1)
        vs = np.concatenate([y1[:, None] + (y2 - y1)[:, None] * t, np.clip(c.cy, y1, y2)[:, None]], axis=1)
        n = us.shape[1]
        with np.errstate(invalid="ignore"):
            top = c.undistort_pixels(np.stack([us, np.repeat(y1[:, None], n, 1)], -1))[..., 1].max(axis=1)
            bottom = c.undistort_pixels(np.stack([us, np.repeat(y2[:, None], n, 1)], -1))[..., 1].min(axis=1)
            left = c.undistort_pixels(np.stack([np.repeat(x1[:, None], n, 1), vs], -1))[..., 0].max(axis=1)
            right = c.undistort_pixels(np.stack([np.repeat(x2[:, None], n, 1), vs], -1))[..., 0].min(axis=1)
            out = np.stack([left - self.x0, top - self.y0, right - self.x0, bottom - self.y0], axis=1)
            if self.tol is not None:       # a side on the real border: on the canvas's border
                v = self.camera
                tol = self.tol
                out[:, 0] = np.where(x1 <= -0.5 + tol, np.minimum(out[:, 0], -0.5), out[:, 0])
                out[:, 1] = np.where(y1 <= -0.5 + tol, np.minimum(out[:, 1], -0.5), out[:, 1])
                out[:, 2] = np.where(x2 >= c.width - 0.5 - tol, np.maximum(out[:, 2], v.width - 0.5), out[:, 2])
                out[:, 3] = np.where(y2 >= c.height - 0.5 - tol, np.maximum(out[:, 3], v.height - 0.5), out[:, 3])
        return out

    def image(self, image: np.ndarray) -> np.ndarray:
        """The distorted frame resampled (bilinear) onto the virtual camera's canvas (0 outside the real image)."""
        import cv2

        if self._maps is None:
            v = self.camera
            uu, vv = np.meshgrid(np.arange(v.width, dtype=float) + self.x0, np.arange(v.height, dtype=float) + self.y0)
            d = self.real.distort_pixels(np.stack([uu, vv], axis=-1))
            self._maps = (d[..., 0].astype(np.float32), d[..., 1].astype(np.float32))
        return cv2.remap(image, *self._maps, interpolation=cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT)


def pinhole_view(camera: CameraModel, border_tol_px: float | None) -> PinholeView:
    """The :class:`PinholeView` of a distorted ``camera``, cached by its intrinsics and distortion (a per-frame
    pitch from the horizon stage reuses it: :meth:`PinholeView.virtual`)."""
    c = camera
    return _cached_view(replace(c, height_m=1.0, pitch_rad=0.0, roll_rad=0.0, lateral_offset_m=0.0,
                                forward_offset_m=0.0), border_tol_px)


@functools.lru_cache(maxsize=16)
def _cached_view(camera: CameraModel, border_tol_px: float | None) -> PinholeView:
    return PinholeView(camera, border_tol_px)
