"""Trackers: detections in, boxes with stable ids out (the paper's section IV-B).

Importing this package registers the built-in trackers with
:mod:`monorarp.registry` (kind ``"tracker"``).
"""

from monorarp.tracking import association, particle  # noqa: F401  (runs @register)
from monorarp.tracking.particle import ParticleTracker

__all__ = ["ParticleTracker", "association", "particle"]
