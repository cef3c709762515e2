"""Trackers: detections in, boxes with stable ids out (the paper's section IV-B).

Importing this package registers the built-in trackers with
:mod:`monorarp.registry` (kind ``"tracker"``): ``particle`` (the paper's),
``kcf``, ``csrt``, ``mosse``, ``medianflow`` (OpenCV, :mod:`.opencv`),
``sort`` and ``bytetrack`` (Kalman filter + optimal assignment).
"""

from monorarp.tracking import association, bytetrack, opencv, particle, sort  # noqa: F401  (runs @register)
