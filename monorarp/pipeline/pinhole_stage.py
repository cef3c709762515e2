"""A lane-marking image stage (ego speed, horizon) on a camera with lens distortion.

The lane-marking stages (:mod:`monorarp.ego_speed`, :mod:`monorarp.horizon`) fit straight lines and back-project
rows and columns onto the road with the pinhole model. For a distorted camera (:mod:`monorarp.core.distortion`)
such a stage is built for the camera's *virtual pinhole camera* (:mod:`monorarp.state.pinhole_view`: the same
focal lengths and mounting, no distortion, a canvas holding every ray the image sees, its pixel ``(u, v)`` the
real camera's ideal pixel ``(u + x0, v + y0)``) and each frame is resampled onto that canvas before the stage
sees it: the view the state estimator works in. An ego speed (m/s) comes back as it is; a horizon reading's row
comes back as the real camera's ideal row (``+ y0``), the row its ``horizon_row`` and pitch use. A lane-width
road profile stays in canvas rows: the state estimator does not use one on a distorted camera.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace
from typing import Any

import numpy as np

from monorarp.core.camera import CameraModel
from monorarp.core.types import HorizonReading
from monorarp.state.pinhole_view import pinhole_view


def check_frame(image: np.ndarray, camera: CameraModel, stage: str) -> None:
    """Raise ValueError unless ``image`` is a (height, width[, 3]) array of ``camera``'s size."""
    if not isinstance(image, np.ndarray) or image.ndim not in (2, 3) or image.shape[:2] != (camera.height, camera.width):
        raise ValueError(f"{stage}: image of shape {getattr(image, 'shape', None)} does not match the camera's "
                         f"{camera.width}x{camera.height} (expected (height, width[, 3]) uint8)")


class PinholeImageStage:
    """``update(image, t)`` of the stage ``build(virtual camera)`` returns, fed each frame of the distorted
    ``camera`` resampled onto the virtual camera's canvas (module docstring); ``reset()`` passes through, as do
    the stage's other attributes."""

    def __init__(self, build: Callable[[CameraModel], Any], camera: CameraModel, kind: str) -> None:
        self.real, self.kind = camera, kind
        self.view = pinhole_view(camera, None)
        self.inner = build(self.view.virtual(camera))

    def update(self, image: np.ndarray, t: float) -> Any:
        check_frame(image, self.real, f"{self.kind} stage")
        out = self.inner.update(self.view.image(image), t)
        return replace(out, row=out.row + self.view.y0) if isinstance(out, HorizonReading) else out

    def reset(self) -> None:
        if hasattr(self.inner, "reset"):
            self.inner.reset()

    def __getattr__(self, name: str) -> Any:   # the stage's settings and diagnostics
        if name == "inner":
            raise AttributeError(name)
        return getattr(self.inner, name)
