"""Trackers: detections in, boxes with stable ids out (the paper's section IV-B).

Built-in trackers (kind ``"tracker"``, declared in :mod:`monorarp.catalogue`): ``particle``
(the paper's), ``kcf``, ``csrt``, ``mosse``, ``medianflow`` (OpenCV, :mod:`.opencv`),
``sort`` and ``bytetrack`` (Kalman filter + optimal assignment).
"""

from monorarp.tracking.bytetrack import ByteTracker
from monorarp.tracking.opencv import CSRTTracker, KCFTracker, MedianFlowTracker, MOSSETracker, OpenCVMultiTracker
from monorarp.tracking.particle import ParticleTracker
from monorarp.tracking.sort import SortTracker

__all__ = ["ByteTracker", "CSRTTracker", "KCFTracker", "MOSSETracker", "MedianFlowTracker", "OpenCVMultiTracker",
           "ParticleTracker", "SortTracker"]
