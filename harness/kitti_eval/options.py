"""The options of ``monorarp eval kitti`` (:class:`KittiEvalOptions`)."""

from __future__ import annotations

from dataclasses import dataclass

from monorarp.pipeline.config import PipelineConfig

#: ``--detector`` value that makes each frame's vehicle labels the detections (an oracle).
LABELS_DETECTOR = "labels"


@dataclass(frozen=True)
class KittiEvalOptions:
    detector: str = PipelineConfig().detector.name    # registry name, .onnx path, or "labels"
    tracker: str = PipelineConfig().tracker.name      # tracking sequences only
    camera_height_m: float | None = None
    horizon_row: float | None = None
    fps: float | None = None          # tracking sequences; default: export.json's, else 10 Hz
    frames: int | None = None         # evaluate only the first N frames (all sequences together)
