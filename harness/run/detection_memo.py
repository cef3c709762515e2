"""Detections reused by the runs of a sweep that feed the same detector the same frames.

Sweep variants often differ only after the detector (the paper's tracker against KCF on the
same frames): their detector sees the same images in the same order and so returns the same
detections. A :class:`DetectionMemo` (one per worker process) keeps each frame's detections
under a digest of the detector's configuration, the camera and every image since the pipeline
was reset, up to and including this one; a run whose detector would see exactly that history
takes the detections instead of running the detector. Keyed on the images' bytes, not on
names, so a hit is the same computation whatever made the frames (cache off, cold or warm);
keyed on the whole history, so a detector that keeps state between frames is reused only for
the same sequence from its reset. Detectors fed the ground truth (``uses_truth``, the oracle)
are never wrapped.

Timing: each frame's ``detector`` time (ms) is the detector's own, measured when it ran (in
this run or in the earlier run that computed it); :meth:`ReplayingDetector.restore_timings`
puts it back into the results after the run, adjusting ``total`` and the run's wall time, so
``runtime_ms.*`` and ``fps`` read as if the detector had run (without the digests' cost).
"""

from __future__ import annotations

import hashlib
import json
import time
from collections import OrderedDict
from collections.abc import Sequence
from typing import Any

import numpy as np

from monorarp.core.camera import CameraModel
from monorarp.app.io import to_jsonable
from monorarp.pipeline import registry
from monorarp.pipeline.config import ComponentConfig
from monorarp.core.types import Detection, FrameResult, strong

MAX_FRAMES = 20_000   # frames kept (least recently used dropped): a few MB


class DetectionMemo:
    """Detections (and the detector's ms) by history digest, least recently used dropped beyond ``max_frames``."""

    def __init__(self, max_frames: int = MAX_FRAMES) -> None:
        self.max_frames = max_frames
        self._entries: OrderedDict[bytes, tuple[tuple[Detection, ...], float]] = OrderedDict()

    def __len__(self) -> int:
        return len(self._entries)

    def get(self, key: bytes) -> tuple[tuple[Detection, ...], float] | None:
        hit = self._entries.get(key)
        if hit is not None:
            self._entries.move_to_end(key)
        return hit

    def put(self, key: bytes, detections: tuple[Detection, ...], ms: float) -> None:
        self._entries[key] = (detections, ms)
        self._entries.move_to_end(key)
        while len(self._entries) > self.max_frames:
            self._entries.popitem(last=False)

    def attach(self, pipeline: Any, config: ComponentConfig, camera: CameraModel) -> "ReplayingDetector | None":
        """Wrap ``pipeline.detector`` (built from ``config`` for ``camera``) to reuse detections; None when it
        takes the ground truth (left as it is)."""
        if getattr(pipeline.detector, "uses_truth", False) or hasattr(pipeline.detector, "set_truth"):
            return None
        pipeline.detector = ReplayingDetector(pipeline.detector, self, detector_identity(config, camera))
        return pipeline.detector


def detector_identity(config: ComponentConfig, camera: CameraModel) -> bytes:
    """Digest of what the detector's output depends on besides the images: its name, kwargs and the camera."""
    text = json.dumps({"detector": config.name, "kwargs": to_jsonable(config.kwargs), "camera": camera.to_dict()},
                      sort_keys=True)
    return hashlib.sha256(text.encode()).digest()


def image_digest(image: np.ndarray) -> bytes:
    """sha256 of an image's shape, dtype and pixels (~0.45 ms for 640x360 BGR)."""
    h = hashlib.sha256(f"{image.shape}{image.dtype}".encode())
    h.update(np.ascontiguousarray(image).data)
    return h.digest()


class ReplayingDetector:
    """``detect(image)`` of the wrapped detector, or its earlier result for the same history (see module doc)."""

    def __init__(self, inner: Any, memo: DetectionMemo, identity: bytes) -> None:
        self.inner, self.memo, self.identity = inner, memo, identity
        self._history = identity
        self._own_ms: list[float] = []      # per detect() call since reset: the detector's own time

    def reset(self) -> None:
        if hasattr(self.inner, "reset"):
            self.inner.reset()
        self._history = self.identity
        self._own_ms = []

    @property
    def uses_weak_detections(self) -> bool:
        return registry.uses(self.inner, "weak_detections")

    def detect(self, image: np.ndarray, weak: bool = False) -> list[Detection]:
        """The inner detector's detections (weak ones too when asked), computed once per history:
        kept with the weak ones (when it gives them), so a run that takes none shares them."""
        self._history = hashlib.sha256(self._history + image_digest(image)).digest()
        hit = self.memo.get(self._history)
        if hit is None:
            t0 = time.perf_counter()
            dets = tuple(self.inner.detect(image, weak=True) if self.uses_weak_detections else self.inner.detect(image))
            ms = (time.perf_counter() - t0) * 1e3
            self.memo.put(self._history, dets, ms)
            hit = (dets, ms)
        self._own_ms.append(hit[1])
        return list(hit[0]) if weak else strong(hit[0])

    __call__ = detect

    def restore_timings(self, results: Sequence[FrameResult], wall_s: float) -> float:
        """Set each result's ``detector`` ms to the detector's own (``total`` adjusted); returns ``wall_s`` adjusted."""
        if len(results) != len(self._own_ms):
            raise RuntimeError(f"detection replay: {len(results)} results for {len(self._own_ms)} detector calls")
        shift_ms = 0.0
        for res, own in zip(results, self._own_ms):
            d = own - res.timings_ms["detector"]
            res.timings_ms["detector"] = own
            res.timings_ms["total"] += d
            shift_ms += d
        return wall_s + shift_ms / 1e3
