"""Oracle detector: detections made from ground-truth boxes, with controllable noise.

Isolates what comes after detection (tracker, state, risk). With no noise the
detections are exactly the ground-truth boxes of the objects that are visible
enough (``visibility >= min_visibility``) and tall enough (``>= min_height_px``).

Noise (seeded per frame by ``(seed, frame index)``, so the same frame always
gives the same detections whatever the thread timing):

* ``jitter_px`` — Gaussian standard deviation (px) added to each box edge;
* ``miss_rate`` — probability that a detectable object is dropped;
* ``false_positives`` — Poisson mean of spurious boxes per frame, each sized
  like a 1.8 m x 1.5 m vehicle standing on the ground at a random image row
  below the horizon (from ``camera`` when given, else the middle row).

Feeding the truth: before each frame reaches :meth:`OracleDetector.detect`,
the harness calls :meth:`OracleDetector.set_truth` with that frame's truth record
and its image. ``detect`` looks the truth up by the image object's identity
(falling back to first-in-first-out order if the pipeline handed it a copy),
so the synchronous and the threaded runners see the same truth for each frame.
"""

from __future__ import annotations

import threading
from collections import OrderedDict

import numpy as np

from harness.world.truth import FrameTruth
from monorarp.core.camera import CameraModel
from monorarp.core.errors import UserError
from monorarp.core.types import Detection

VEHICLE_WIDTH_M = 1.8
VEHICLE_HEIGHT_M = 1.5


class OracleConfigError(UserError, ValueError):
    """An impossible oracle noise setting."""


class OracleDetector:
    """``detect(image)`` -> the ground-truth boxes of the frame registered with :meth:`set_truth`."""

    uses_camera = True   # the registry passes the run's camera
    uses_seed = True     # a sweep passes the run's seed
    uses_truth = True    # needs each frame's ground truth (set_truth): simulated runs only

    def __init__(self, min_visibility: float = 0.3, min_height_px: float = 4.0, jitter_px: float = 0.0,
                 miss_rate: float = 0.0, false_positives: float = 0.0, seed: int = 0,
                 camera: CameraModel | None = None, label: str = "car") -> None:
        problems = []
        if not 0 <= min_visibility <= 1:
            problems.append(f"min_visibility must be in [0, 1], got {min_visibility}")
        if not jitter_px >= 0:
            problems.append(f"jitter must be >= 0 px, got {jitter_px}")
        if not 0 <= miss_rate <= 1:
            problems.append(f"miss rate must be in [0, 1], got {miss_rate}")
        if not 0 <= false_positives <= 100:
            problems.append(f"false-positive rate must be in [0, 100] per frame, got {false_positives}")
        if problems:
            raise OracleConfigError("oracle detector: " + "; ".join(problems))
        self.min_visibility = float(min_visibility)
        self.min_height_px = float(min_height_px)
        self.jitter_px = float(jitter_px)
        self.miss_rate = float(miss_rate)
        self.false_positives = float(false_positives)
        self.seed = int(seed)
        self.camera = camera
        self.label = label
        self._lock = threading.Lock()
        self._pending: OrderedDict[object, tuple[np.ndarray | None, FrameTruth]] = OrderedDict()
        self._fifo = 0

    # ------------------------------------------------------------ truth feed
    def set_truth(self, truth: FrameTruth, image: np.ndarray | None = None) -> None:
        """Queue ``truth`` (the frame's :class:`~harness.world.truth.FrameTruth`) for the frame whose image is ``image``."""
        with self._lock:
            self._fifo += 1
            key = id(image) if image is not None else ("fifo", self._fifo)
            self._pending[key] = (image, truth)

    def _take(self, image: np.ndarray) -> FrameTruth:
        with self._lock:
            entry = self._pending.get(id(image))
            if entry is not None and entry[0] is image:
                del self._pending[id(image)]
                return entry[1]
            if not self._pending:
                raise RuntimeError("oracle detector: no ground truth queued for this frame (call set_truth first)")
            return self._pending.popitem(last=False)[1][1]

    # -------------------------------------------------------------- detection
    def detect(self, image: np.ndarray) -> list[Detection]:
        truth = self._take(image)
        h, w = image.shape[:2]
        return self.detections_for(truth, (w, h))

    __call__ = detect

    def detections_for(self, truth: FrameTruth, size: tuple[int, int]) -> list[Detection]:
        """The (noisy) detections of one frame's truth; ``size`` = image (width, height) in px."""
        w, h = size
        rng = np.random.default_rng([self.seed, truth.frame])
        objs = [o for o in truth.objects
                if o.visibility >= self.min_visibility and o.box[3] - o.box[1] >= self.min_height_px]
        boxes = np.array([o.box for o in objs], dtype=float).reshape(-1, 4)
        keep = rng.random(len(boxes)) >= self.miss_rate if self.miss_rate > 0 else np.ones(len(boxes), bool)
        boxes = boxes[keep]
        if self.jitter_px > 0 and len(boxes):
            boxes = boxes + rng.normal(0.0, self.jitter_px, boxes.shape)
            boxes = _clip(boxes, w, h)
        if self.false_positives > 0:
            fp = self._false_boxes(rng, int(rng.poisson(self.false_positives)), w, h)
            boxes = np.vstack([boxes, fp])
        return [Detection(box=tuple(float(v) for v in b), score=1.0, label=self.label) for b in boxes]

    def _false_boxes(self, rng: np.random.Generator, n: int, w: int, h: int) -> np.ndarray:
        """``n`` vehicle-sized boxes standing on the ground below the horizon."""
        if self.camera is not None:
            cam = self.camera.scaled(w, h) if (self.camera.width, self.camera.height) != (w, h) else self.camera
            horizon, fx, fy, height_m = cam.horizon_row, cam.fx, cam.fy, cam.height_m
        else:
            horizon, fx, fy, height_m = (h - 1) / 2, 0.8 * w, 0.8 * w, 1.3
        lo = min(horizon + 3.0, h - 1.5)
        bottom = rng.uniform(lo, h - 0.5, n)
        dist = height_m * fy / np.maximum(bottom - horizon, 1.0)      # equation 3 at that row, m
        bw = VEHICLE_WIDTH_M * fx / dist
        bh = VEHICLE_HEIGHT_M * fy / dist
        cx = rng.uniform(-0.5, w - 0.5, n)
        boxes = np.stack([cx - bw / 2, bottom - bh, cx + bw / 2, bottom], axis=1)
        return _clip(boxes, w, h)


def _clip(boxes: np.ndarray, w: int, h: int) -> np.ndarray:
    """Clip to the image (continuous coordinates -0.5..w-0.5) keeping at least 1 px per side."""
    b = boxes.copy()
    b[:, [0, 2]] = np.clip(b[:, [0, 2]], -0.5, w - 0.5)
    b[:, [1, 3]] = np.clip(b[:, [1, 3]], -0.5, h - 0.5)
    b[:, 2] = np.maximum(b[:, 2], np.minimum(b[:, 0] + 1.0, w - 0.5))
    b[:, 0] = np.minimum(b[:, 0], b[:, 2] - 1.0)
    b[:, 3] = np.maximum(b[:, 3], np.minimum(b[:, 1] + 1.0, h - 0.5))
    b[:, 1] = np.minimum(b[:, 1], b[:, 3] - 1.0)
    return b
