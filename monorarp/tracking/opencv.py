"""OpenCV single-object trackers (KCF, CSRT, MOSSE, MedianFlow) run as one multi-object tracker.

As in the paper (section V-B), each OpenCV tracker follows its object in the image by itself and
needs the detector only to be initialised, for every new object; boxes are continuous
``(x1, y1, x2, y2)`` pixels, converted from and to OpenCV's ``(x, y, w, h)``. Each frame's steps
and the box conventions: docs/tracking.md.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import cv2
import numpy as np

from monorarp.core.boxes import clip_to_image
from monorarp.tracking.association import associate_iou
from monorarp.core.types import Detection, Track

#: algorithm -> (factory attribute path, takes float rectangles)
ALGORITHMS: dict[str, tuple[str, bool]] = {
    "kcf": ("TrackerKCF_create", False),
    "csrt": ("TrackerCSRT_create", False),
    "mosse": ("legacy.TrackerMOSSE_create", True),
    "medianflow": ("legacy.TrackerMedianFlow_create", True),
}
MIN_SIDE_PX = 4.0   # boxes smaller than this (after clipping) cannot start a tracker


def _factory(algorithm: str) -> Callable[[], object]:
    path, _ = ALGORITHMS[algorithm]
    obj = cv2
    for part in path.split("."):
        obj = getattr(obj, part, None)
        if obj is None:
            raise RuntimeError(f"this OpenCV build ({cv2.__version__}) has no cv2.{path}; "
                               "install opencv-contrib-python-headless")
    return obj


def box_to_rect(box: Sequence[float], integer: bool) -> tuple:
    """Continuous ``(x1, y1, x2, y2)`` -> OpenCV ``(x, y, w, h)``; ``integer`` rounds to the pixel grid."""
    x1, y1, x2, y2 = (float(v) for v in box)
    if integer:
        x, y = int(round(x1 + 0.5)), int(round(y1 + 0.5))
        return x, y, max(1, int(round(x2 + 0.5)) - x), max(1, int(round(y2 + 0.5)) - y)
    return x1 + 0.5, y1 + 0.5, x2 - x1, y2 - y1


def rect_to_box(rect: Sequence[float]) -> tuple[float, float, float, float]:
    """OpenCV ``(x, y, w, h)`` -> continuous ``(x1, y1, x2, y2)``."""
    x, y, w, h = (float(v) for v in rect)
    return x - 0.5, y - 0.5, x + w - 0.5, y + h - 0.5


def inside_fraction(box: Sequence[float], width: int, height: int) -> float:
    """Fraction of ``box``'s area inside the image (continuous extent -0.5 .. size - 0.5); 0 for empty boxes."""
    x1, y1, x2, y2 = box
    area = max(0.0, x2 - x1) * max(0.0, y2 - y1)
    if area <= 0:
        return 0.0
    iw = max(0.0, min(x2, width - 0.5) - max(x1, -0.5))
    ih = max(0.0, min(y2, height - 0.5) - max(y1, -0.5))
    return iw * ih / area


def clip_box(box: Sequence[float], width: int, height: int) -> tuple[float, float, float, float]:
    return tuple(float(v) for v in clip_to_image(box, width, height))


@dataclass
class _Object:
    id: int
    tracker: object
    box: tuple[float, float, float, float]
    score: float
    label: str
    age: int = 0
    since_init: int = 0
    unmatched: int = 0


class OpenCVMultiTracker:
    """Multi-object tracker made of one OpenCV tracker per object; see the module docstring.

    Parameters:
        algorithm: ``"kcf"``, ``"csrt"``, ``"mosse"`` or ``"medianflow"``.
        min_iou: IoU above which a detection belongs to an existing tracker.
        min_score: detections below this score never start a tracker.
        min_inside: a tracker whose box has less than this fraction inside the image is dropped.
        reinit_every: re-initialise a matched tracker from its detection every this many frames (None: never).
        max_unmatched: drop a tracker after this many frames with no matching detection (None: never).
    """

    algorithm: str = "kcf"

    def __init__(self, algorithm: str | None = None, min_iou: float = 0.3, min_score: float = 0.0,
                 min_inside: float = 0.5, reinit_every: int | None = None, max_unmatched: int | None = None) -> None:
        algorithm = algorithm or self.algorithm
        if algorithm not in ALGORITHMS:
            raise ValueError(f"unknown OpenCV tracker {algorithm!r}; choose from {', '.join(ALGORITHMS)}")
        if reinit_every is not None and reinit_every < 1:
            raise ValueError(f"reinit_every must be >= 1 frame or None, got {reinit_every}")
        if max_unmatched is not None and max_unmatched < 0:
            raise ValueError(f"max_unmatched must be >= 0 frames or None, got {max_unmatched}")
        self.algorithm = algorithm
        self._create = _factory(algorithm)
        self._float_rects = ALGORITHMS[algorithm][1]
        self.min_iou, self.min_score, self.min_inside = float(min_iou), float(min_score), float(min_inside)
        self.reinit_every, self.max_unmatched = reinit_every, max_unmatched
        self.reset()

    def reset(self) -> None:
        """Forget every object; ids start again from 0."""
        self._objects: list[_Object] = []
        self._next_id = 0

    @property
    def n_tracks(self) -> int:
        return len(self._objects)

    def _init(self, image: np.ndarray, box: Sequence[float]) -> tuple[object, tuple] | None:
        """A new OpenCV tracker on ``box`` (clipped to the image), or None if it cannot start."""
        h, w = image.shape[:2]
        box = clip_box(box, w, h)
        if box[2] - box[0] < MIN_SIDE_PX or box[3] - box[1] < MIN_SIDE_PX:
            return None
        rect = box_to_rect(box, integer=not self._float_rects)
        tracker = self._create()
        try:
            ok = tracker.init(image, rect)
        except cv2.error:
            return None
        if ok is False:                     # legacy trackers return a flag, the others None
            return None
        return tracker, box if self._float_rects else rect_to_box(rect)

    def update(self, image: np.ndarray, detections: Sequence[Detection], t: float) -> list[Track]:
        """Advance every tracker on ``image`` (BGR uint8) and start trackers for new detections."""
        if image is None:
            raise ValueError("OpenCV trackers need the image")
        h, w = image.shape[:2]
        alive: list[_Object] = []
        for obj in self._objects:
            try:
                ok, rect = obj.tracker.update(image)
            except cv2.error:
                ok = False
            if not ok:
                continue
            box = rect_to_box(rect)
            if inside_fraction(box, w, h) < self.min_inside:
                continue
            obj.box, obj.age, obj.since_init = box, obj.age + 1, obj.since_init + 1
            alive.append(obj)
        self._objects = alive

        n = len(detections)
        det_boxes = np.array([d.box for d in detections], dtype=float).reshape(n, 4)
        tr_boxes = np.array([o.box for o in alive], dtype=float).reshape(len(alive), 4)
        matches, _, un_d, _ = associate_iou(tr_boxes, det_boxes, self.min_iou)
        matched = np.zeros(len(alive), dtype=bool)
        for r, c in matches:
            obj, det = alive[r], detections[c]
            matched[r] = True
            obj.unmatched, obj.score, obj.label = 0, det.score, det.label
            if self.reinit_every is not None and obj.since_init >= self.reinit_every:
                started = self._init(image, det.box)
                if started is not None:
                    obj.tracker, obj.box = started
                    obj.since_init = 0
        for r in np.flatnonzero(~matched):
            alive[r].unmatched += 1
        if self.max_unmatched is not None:
            keep = [o.unmatched <= self.max_unmatched for o in alive]
            self._objects = [o for o, k in zip(alive, keep) if k]
            matched = matched[np.array(keep, dtype=bool)] if len(keep) else matched

        out = [self._track(o, coasting=not m) for o, m in zip(self._objects, matched)]
        for c in un_d:
            det = detections[c]
            if det.score < self.min_score:
                continue
            started = self._init(image, det.box)
            if started is None:
                continue
            obj = _Object(id=self._next_id, tracker=started[0], box=started[1], score=det.score, label=det.label)
            self._next_id += 1
            self._objects.append(obj)
            out.append(self._track(obj, coasting=False))
        return out

    @staticmethod
    def _track(o: _Object, coasting: bool) -> Track:
        return Track(id=o.id, box=tuple(float(v) for v in o.box), score=float(o.score), label=o.label,
                     coasting=coasting, age=o.age)


class KCFTracker(OpenCVMultiTracker):
    """Kernelized Correlation Filter (``cv2.TrackerKCF_create``), the paper's comparison tracker."""

    algorithm = "kcf"


class CSRTTracker(OpenCVMultiTracker):
    """Discriminative correlation filter with channel and spatial reliability (``cv2.TrackerCSRT_create``)."""

    algorithm = "csrt"


class MOSSETracker(OpenCVMultiTracker):
    """Minimum Output Sum of Squared Error filter (``cv2.legacy.TrackerMOSSE_create``)."""

    algorithm = "mosse"


class MedianFlowTracker(OpenCVMultiTracker):
    """Median Flow, forward-backward Lucas-Kanade (``cv2.legacy.TrackerMedianFlow_create``)."""

    algorithm = "medianflow"
