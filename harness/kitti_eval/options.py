"""The options of ``monorarp eval kitti`` (:class:`KittiEvalOptions`)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from monorarp.pipeline.config import REAL_WORLD_DETECTOR, PipelineConfig
from monorarp.state.config import REAL_FRAMES_STATE

#: ``--detector`` value that makes each frame's vehicle labels the detections (an oracle).
LABELS_DETECTOR = "labels"


@dataclass(frozen=True)
class KittiEvalOptions:
    detector: str = REAL_WORLD_DETECTOR               # registry name, .onnx path, or "labels"
    tracker: str = PipelineConfig().tracker.name      # tracking sequences only
    camera_height_m: float | None = None
    horizon_row: float | None = None
    fps: float | None = None          # tracking sequences; default: export.json's, else 10 Hz
    frames: int | None = None         # evaluate only the first N frames (all sequences together)
    state_kwargs: dict[str, Any] | None = None   # the state estimator's settings; None: the dataset's default
    score_threshold: float | None = None   # the detector's score threshold (0..1); None: its own (model card)

    def state_settings(self, rendered: bool) -> dict[str, Any]:
        """The state estimator's settings: :attr:`state_kwargs`, or by default the size prior
        (:data:`~monorarp.state.config.REAL_FRAMES_STATE`) on real frames, none on a ``rendered`` export's."""
        if self.state_kwargs is not None:
            return dict(self.state_kwargs)
        return {} if rendered else dict(REAL_FRAMES_STATE)
