"""The directory of one scored run: its file names and their writers, replaced as a whole on success.

:class:`RunOutputs` writes into ``out_dir`` (built beside it, moved into place only when the
run succeeded; on any failure nothing is left):

* ``metrics.json`` — :func:`harness.scoring.evaluate.evaluate` (nested; NaN -> null);
* ``per_object.csv`` — estimate and truth side by side per frame and object;
* ``per_frame.csv`` — per frame: ego speed estimate and truth, risk, its probability, the
  1/TTC baseline (when the run's risk is another estimator) and the risk label
  (:func:`harness.scoring.per_frame.frame_rows`);
* ``annotated.mp4`` — :func:`monorarp.app.display.draw_frame` on every frame (unless ``annotate=False``);
* ``frames.mp4``, ``camera.json``, ``ground_truth.jsonl`` — as ``monorarp render`` writes them
  (``frames.mp4`` only with ``write_frames=True``).
"""

from __future__ import annotations

from contextlib import ExitStack
from pathlib import Path
from typing import Any

from harness.world.truth import FrameTruth
from monorarp.core.camera import CameraModel
from monorarp.app.io import JsonlWriter, atomic_output_dir, write_json_atomic
from monorarp.core.types import FrameResult

METRICS_NAME = "metrics.json"
PER_OBJECT_NAME = "per_object.csv"
PER_FRAME_NAME = "per_frame.csv"
ANNOTATED_NAME = "annotated.mp4"
VIDEO_NAME = "frames.mp4"
CAMERA_NAME = "camera.json"
GROUND_TRUTH_NAME = "ground_truth.jsonl"
OUTPUT_NAMES = (METRICS_NAME, PER_OBJECT_NAME, PER_FRAME_NAME, ANNOTATED_NAME, VIDEO_NAME, CAMERA_NAME, GROUND_TRUTH_NAME)


class RunOutputs:
    """Context manager over the run directory ``out_dir`` (None: nothing is written, every call is a no-op).

    Entering opens the atomic directory and the writers and writes ``camera.json``; a clean
    exit moves the directory into place, an exception removes it.
    """

    def __init__(self, out_dir: str | Path | None, camera: CameraModel, fps: float, *,
                 write_frames: bool = True, annotate: bool = True) -> None:
        self.out_dir, self.camera, self.fps = out_dir, camera, fps
        self.write_frames, self.annotate_frames = write_frames, annotate
        self.dir: Path | None = None      # the temporary directory being filled, while entered
        self._stack = ExitStack()

    def __enter__(self) -> RunOutputs:
        from monorarp.app.video.writer import VideoWriter

        size = (self.camera.width, self.camera.height)
        with ExitStack() as stack:
            tmp = stack.enter_context(atomic_output_dir(self.out_dir, owned_names=OUTPUT_NAMES)) \
                if self.out_dir else None
            self._truth = stack.enter_context(JsonlWriter(tmp / GROUND_TRUTH_NAME)) if tmp else None
            self._frames = stack.enter_context(VideoWriter(tmp / VIDEO_NAME, self.fps, size)) \
                if tmp and self.write_frames else None
            self._annotated = stack.enter_context(VideoWriter(tmp / ANNOTATED_NAME, self.fps, size)) \
                if tmp and self.annotate_frames else None
            if tmp:
                write_json_atomic(tmp / CAMERA_NAME, self.camera.to_dict())
            self._stack = stack.pop_all()
        self.dir = tmp
        return self

    def __exit__(self, *exc_info: Any) -> bool | None:
        return self._stack.__exit__(*exc_info)

    def record_frame(self, image: Any, truth: FrameTruth) -> None:
        """Append one frame's truth to ``ground_truth.jsonl`` and its image (BGR) to ``frames.mp4``."""
        if self._truth is not None:
            self._truth.write(truth.to_json())
        if self._frames is not None:
            self._frames.write(image)

    def annotate(self, image: Any, res: FrameResult, truth: FrameTruth, warning_s: float) -> None:
        """Append the annotated display of ``res`` over ``image`` to ``annotated.mp4``."""
        if self._annotated is None:
            return
        from monorarp.app.display import draw_frame

        speed = res.ego_speed if res.ego_speed is not None else truth.ego.speed  # estimate, else true
        self._annotated.write(draw_frame(image, res, warning_s=warning_s, ego_speed=speed,
                                         truth_boxes=[o.box for o in truth.objects], legend=True))

    def write_scores(self, metrics: dict, records: list, frame_rows: list[dict]) -> None:
        """Write ``metrics.json``, ``per_object.csv`` and ``per_frame.csv``."""
        if self.dir is None:
            return
        from harness.scoring.evaluate import write_metrics   # here: the names above stay cheap
        from harness.scoring.per_frame import write_frame_csv
        from harness.scoring.records import write_csv

        write_metrics(metrics, self.dir / METRICS_NAME)
        write_csv(records, self.dir / PER_OBJECT_NAME)
        write_frame_csv(frame_rows, self.dir / PER_FRAME_NAME)
