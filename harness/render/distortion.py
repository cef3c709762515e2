"""The lens of a distorted scenario camera: a pinhole render on a wider canvas, warped to the distorted image.

With ``camera.distortion`` set (:mod:`monorarp.core.distortion`) the renderer draws its passes with a pinhole
camera of the same focal lengths on a *canvas* that holds every ray the distorted image sees (for barrel
distortion, ``k1 < 0``, the distorted image's corners look beyond the pinhole frame: the canvas is larger; for
pincushion smaller), the principal point shifted by whole pixels, and :class:`LensWarp` resamples them onto
the image: the colour pass (and the ray-length factor of the fog) bilinearly, the id pass and the depth
buffer by nearest neighbour, so every image pixel holds exactly one vehicle id (the one the ray through its
centre meets in the pinhole pass, to within the canvas's pixel grid). Image-space effects and the sensor
then run on the distorted image. A lens needing a canvas over :data:`MAX_FIELD_RATIO` times the image's width
or height (a strong barrel lens near its fold) is refused with a one-line :class:`LensError`.

``visibility`` stays the share of the vehicle's unbounded pinhole pixels that the image sees: each
vehicle's unoccluded count (in canvas pixels) is scaled by its ratio of image pixels to canvas pixels
inside the image's field (:meth:`LensWarp.full_pixels`).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Mapping
from dataclasses import dataclass, replace

import cv2
import numpy as np

from monorarp.core.camera import CameraModel
from monorarp.core.distortion import ZERO, ideal_bounds
from monorarp.core.errors import UserError

#: the canvas at most this many times the image's width and height
MAX_FIELD_RATIO = 2.0
_MARGIN_PX = 2


class LensError(UserError, ValueError):
    """A lens the renderer cannot draw."""


@dataclass(frozen=True)
class LensWarp:
    """Canvas ``x0 .. x0 + width - 1`` x ``y0 .. y0 + height - 1`` (ideal pixels) and the maps onto the image."""

    x0: int
    y0: int
    width: int
    height: int
    map_x: np.ndarray        # (H, W) float32: canvas column of each image pixel's ray
    map_y: np.ndarray
    nearest_index: np.ndarray   # (H * W,) flat canvas index nearest each image pixel's ray
    inside: np.ndarray       # (height, width) bool: canvas pixels whose ray the image sees

    def canvas(self, camera: CameraModel) -> CameraModel:
        """The pinhole camera the passes are drawn with: ``camera``'s pose and focal lengths on the canvas."""
        return replace(camera, width=self.width, height=self.height, cx=camera.cx - self.x0,
                       cy=camera.cy - self.y0, distortion=ZERO)

    def linear(self, image: np.ndarray) -> np.ndarray:
        """A canvas-sized image (colour uint8, or float32) resampled bilinearly onto the distorted image."""
        return cv2.remap(image, self.map_x, self.map_y, interpolation=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)

    def nearest(self, image: np.ndarray) -> np.ndarray:
        """A canvas-sized (H', W') array resampled by nearest neighbour (exact values: ids, depths)."""
        h, w = self.map_x.shape
        return image.reshape(-1, *image.shape[2:])[self.nearest_index].reshape(h, w, *image.shape[2:])

    def full_pixels(self, full: Mapping[int, float], canvas_ids: np.ndarray, image_ids: np.ndarray
                    ) -> dict[int, float]:
        """Unoccluded pixel counts (canvas pixels, ``full``) as image pixels, so that image count / count is
        the canvas's visible share inside the image's field; ``canvas_ids``, ``image_ids``: the id passes."""
        inside = np.bincount((canvas_ids[self.inside] + 1).ravel())
        seen = np.bincount((image_ids + 1).ravel())
        out = {}
        for vid, n in full.items():
            k = vid + 1
            n_in = inside[k] if k < len(inside) else 0
            n_img = seen[k] if k < len(seen) else 0
            out[vid] = float(n) * float(n_img) / float(n_in) if n_in > 0 and n_img > 0 else float(n)
        return out


@functools.lru_cache(maxsize=8)
def _warp(width: int, height: int, fx: float, fy: float, cx: float, cy: float, k: tuple) -> LensWarp:
    cam = CameraModel(width, height, fx, fy, cx, cy, 1.0, distortion=k)
    u0, v0, u1, v1 = ideal_bounds(width, height, fx, fy, cx, cy, k)
    x0, y0 = math.floor(u0) - _MARGIN_PX, math.floor(v0) - _MARGIN_PX
    w, h = math.ceil(u1) + _MARGIN_PX - x0 + 1, math.ceil(v1) + _MARGIN_PX - y0 + 1
    if w > MAX_FIELD_RATIO * width or h > MAX_FIELD_RATIO * height:
        raise LensError(f"camera distortion {list(k)}: its image sees rays over {w}x{h} px of the pinhole image "
                        f"plane, more than {MAX_FIELD_RATIO:g} times the {width}x{height} image the renderer draws "
                        "it from; use a milder lens (smaller |k1|)")
    uu, vv = np.meshgrid(np.arange(width, dtype=float), np.arange(height, dtype=float))
    ideal = cam.undistort_pixels(np.stack([uu, vv], axis=-1))
    mx, my = ideal[..., 0] - x0, ideal[..., 1] - y0
    ix = np.clip(np.floor(mx + 0.5), 0, w - 1).astype(np.int64)
    iy = np.clip(np.floor(my + 0.5), 0, h - 1).astype(np.int64)
    cu, cv = np.meshgrid(np.arange(w, dtype=float) + x0, np.arange(h, dtype=float) + y0)
    seen = cam.distort_pixels(np.stack([cu, cv], axis=-1))
    inside = ((seen[..., 0] >= -0.5) & (seen[..., 0] < width - 0.5) & (seen[..., 1] >= -0.5)
              & (seen[..., 1] < height - 0.5))
    return LensWarp(x0, y0, w, h, mx.astype(np.float32), my.astype(np.float32), (iy * w + ix).ravel(), inside)


def lens_warp(camera: CameraModel) -> LensWarp | None:
    """The (cached) :class:`LensWarp` of ``camera``'s lens; None for a pinhole camera."""
    if not camera.distorted:
        return None
    c = camera
    return _warp(c.width, c.height, c.fx, c.fy, c.cx, c.cy, c.distortion)
