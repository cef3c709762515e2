"""The cameras of a KITTI dataset: one per calibration and image size (from ``P2`` and, for a
``monorarp export``, the mounting it holds), checked against the images; and the export's manifest
(``export.json``: frame rate, camera), checked."""

from __future__ import annotations

import math
import threading
from pathlib import Path

import numpy as np

from harness.kitti_eval import geometry as geo
from harness.kitti_eval.options import KittiEvalOptions
from harness.kitti_eval.reader import KittiInputError, Sample
from monorarp.core.camera import CameraError, CameraModel
from monorarp.core.readers import MAX_CONFIG_BYTES, read_json

MANIFEST_NAME = "export.json"


def read_manifest(root: Path) -> dict:
    """``export.json`` of a ``monorarp export`` dataset at ``root`` (for KITTI's ``DIR/training`` layout, also in
    ``DIR``); {} when there is none. One that is there is checked, as its ``fps`` sets the frame times and its
    ``camera`` the image size: a JSON object whose ``fps``, when present, is a positive number and whose
    ``camera``, when present, is a camera (:meth:`CameraModel.from_dict`); :class:`KittiInputError` naming
    the file and field otherwise."""
    places = [root / MANIFEST_NAME] + ([root.parent / MANIFEST_NAME] if root.name == "training" else [])
    p = next((p for p in places if p.exists()), None)
    if p is None:
        return {}
    data = read_json(p, "export manifest", KittiInputError, MAX_CONFIG_BYTES)
    if not isinstance(data, dict):
        raise KittiInputError(f"{p}: {MANIFEST_NAME} must hold a JSON object, got {type(data).__name__}")
    if "fps" in data:
        fps = data["fps"]
        if isinstance(fps, bool) or not isinstance(fps, (int, float)) or not (math.isfinite(fps) and fps > 0):
            raise KittiInputError(f"{p}: field fps must be a positive number (frames per second), got {fps!r:.60}")
    if "camera" in data:
        try:
            CameraModel.from_dict(data["camera"], source=f"{p}: field camera")
        except CameraError as e:
            raise KittiInputError(str(e)) from None
    return data


class Cameras:
    """Camera (and label offset) per calibration and image size, checked against the images (thread-safe)."""

    def __init__(self, opts: KittiEvalOptions, manifest: dict) -> None:
        self.opts = opts
        self.lock = threading.Lock()
        cam = manifest.get("camera")          # checked by read_manifest
        self.size = (int(cam["width"]), int(cam["height"])) if cam else None
        self.cache: dict[tuple, tuple[CameraModel, np.ndarray, dict]] = {}

    def get(self, sample: Sample, width: int, height: int) -> tuple[CameraModel, np.ndarray, dict]:
        if self.size is not None and (width, height) != tuple(self.size):
            raise KittiInputError(f"{sample.image}: {width}x{height} image, but the dataset's camera (export.json) "
                                  f"is {self.size[0]}x{self.size[1]}: image of another size than the calibration")
        key = (str(sample.calib_path), width, height)
        with self.lock:
            return self._get(key, sample, width, height)

    def _get(self, key: tuple, sample: Sample, width: int, height: int) -> tuple[CameraModel, np.ndarray, dict]:
        if key not in self.cache:
            try:
                K, _ = geo.intrinsics(sample.calib["P2"])
            except ValueError as e:
                raise KittiInputError(f"{sample.calib_path}: {e}") from None
            if not (0 <= K[0, 2] <= width - 1 and 0 <= K[1, 2] <= height - 1):
                raise KittiInputError(f"{sample.image}: {width}x{height} image, but the principal point of "
                                      f"{sample.calib_path} ({K[0, 2]:.1f}, {K[1, 2]:.1f}) lies outside it: image "
                                      "of another size than the calibration")
            self.cache[key] = geo.camera_from_calib(sample.calib, width, height, self.opts.camera_height_m,
                                                    self.opts.horizon_row, where=str(sample.calib_path))
        return self.cache[key]
