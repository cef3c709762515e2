"""The pipeline on a video file or webcam: predictions and an annotated video.

Output directory (written atomically: built in a temporary directory beside
it and renamed into place only when the whole input was processed; a previous
run of this command there is replaced, anything else is refused):

* ``predictions.jsonl`` -- one strict-JSON object per frame::

      {"frame": 0, "t": 0.0,
       "tracks": [{"id": 1, "box": [x1, y1, x2, y2], "coasting": false,
                   "d_x": -3.6, "d_y": 21.4, "v_x": 0.1, "v_y": -2.0, "ttc": 10.7}],
       "risk": 0.093, "risk_kind": "inverse_ttc",
       "ego_speed": 24.8, "ego_speed_source": "estimate"}

  ``t`` is the frame's timestamp (s; :mod:`monorarp.app.video.source`). Boxes in
  px (:mod:`monorarp.core.types` convention); ``d_x``, ``d_y`` (m), ``v_x``, ``v_y``
  (m/s) in the ego frame, null for a track without a state yet; ``ttc`` (s)
  null when not on a collision course. ``risk`` per ``risk_kind``
  (``inverse_ttc``: 1/s; ``probability``: 0..1). ``ego_speed`` (m/s): the
  ego-speed estimator's value (source ``estimate``), else the ``--speed``
  given (``given``), else null.
* ``annotated.mp4`` -- :func:`monorarp.app.display.draw_frame` on every frame,
  H.264 at the source's frame rate (omitted with ``write_video=False``).
* ``run.json`` -- input, camera used (after any scaling), components, frame
  count, timestamps range and mean per-stage times (ms).
"""

from __future__ import annotations

import os
import sys
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import TextIO

import cv2
import numpy as np

from monorarp.core.camera import CameraError, CameraModel
from monorarp.app.common_options import check_frames
from monorarp.app.options import REAL_FRAMES, default_pipeline_config
from monorarp.detection.model_file import is_model_path
from monorarp.core.errors import UserError
from monorarp.app.io import JsonlWriter, atomic_output_dir, write_json_atomic
from monorarp.pipeline.config import ComponentConfig, PipelineConfig
from monorarp.pipeline.runner import Pipeline, run_sync, run_threaded
from monorarp.pipeline.registry import get_factory, uses
from monorarp.core.types import Frame, FrameResult
from monorarp.app.video.source import VideoInfo, VideoSource
from monorarp.warning.thresholds import TTC_CUE_THRESHOLD_S

OUTPUT_NAMES = ("predictions.jsonl", "annotated.mp4", "run.json")
FALLBACK_FPS = 30.0   # annotated video rate when the source reports none (e.g. some webcams)
WINDOW = "monorarp"


class DisplayError(UserError, RuntimeError):
    """``--display`` asked for where no window can be shown."""


@dataclass(frozen=True)
class VideoRunOptions:
    """The pipeline (default: what ``monorarp video`` runs without options) and the run loop's settings."""

    pipeline: PipelineConfig = field(default_factory=lambda: default_pipeline_config(REAL_FRAMES))
    speed_mps: float | None = None      # known ego speed (GPS), m/s: the Monte Carlo risk's when it sets none
    threaded: bool = False
    max_frames: int | None = None
    write_video: bool = True
    display: bool = False
    warning_s: float = TTC_CUE_THRESHOLD_S   # display: TTC (s) drawn as a warning


@dataclass(frozen=True)
class VideoRunSummary:
    out_dir: Path | None
    frames: int
    t_first: float | None
    t_last: float | None
    wall_s: float                  # whole loop: decode, pipeline, drawing, encoding, writing
    pipeline_ms_mean: float | None
    camera: CameraModel
    camera_scaled: bool

    @property
    def fps(self) -> float:
        """Frames per second of wall time over the whole loop."""
        return self.frames / self.wall_s if self.wall_s > 0 else float("nan")


# --------------------------------------------------------------------------- checks
def check_display() -> None:
    """Raise :class:`DisplayError` unless OpenCV has a GUI backend and a screen exists."""
    gui = _opencv_gui()
    if gui is None:
        raise DisplayError("--display needs OpenCV built with GUI support; this one has none "
                           "(opencv-contrib-python-headless): run without --display and open annotated.mp4")
    if sys.platform.startswith("linux") and not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
        raise DisplayError("--display needs a screen, but neither DISPLAY nor WAYLAND_DISPLAY is set")


def _opencv_gui() -> str | None:
    """OpenCV's GUI backend name from its build information, None for a headless build."""
    for line in cv2.getBuildInformation().splitlines():
        key, _, value = line.strip().partition(":")
        if key.strip() == "GUI":
            value = value.strip()
            return None if not value or value.upper() == "NONE" else value
    return None


#: Pixels each side of a resized video may differ from one common scale of the camera file's image
#: (a resize rounds each side to whole, often even, pixels).
RESIZE_TOL_PX = 1.0


def is_resize(camera: CameraModel, width: int, height: int) -> bool:
    """Whether a ``width`` x ``height`` image is ``camera``'s resized by one scale for both sides, each side
    rounded to within :data:`RESIZE_TOL_PX` (1920x1080 -> 960x540 or 854x480: yes; 640x480 -> 960x540: no)."""
    lo = max((width - RESIZE_TOL_PX) / camera.width, (height - RESIZE_TOL_PX) / camera.height)
    hi = min((width + RESIZE_TOL_PX) / camera.width, (height + RESIZE_TOL_PX) / camera.height)
    return lo <= hi


def camera_for(camera: CameraModel, info: VideoInfo, log: TextIO | None | str = "stderr") -> tuple[CameraModel, bool]:
    """``camera`` at the video's resolution: scaled when the video is a resize of the camera file's image (with a
    note on ``log``: ``"stderr"`` = the current ``sys.stderr``, None = silent); :class:`CameraError` when the
    shapes differ beyond a resize's rounding (:func:`is_resize`: a crop or a stretch, which scaling cannot fit)."""
    log = sys.stderr if log == "stderr" else log
    if (camera.width, camera.height) == (info.width, info.height):
        return camera, False
    if not is_resize(camera, info.width, info.height):
        raise CameraError(
            f"{info.name}: the video is {info.width}x{info.height} (aspect {info.width / info.height:.3f}) but the "
            f"camera file is {camera.width}x{camera.height} (aspect {camera.width / camera.height:.3f}): no resize "
            "turns one into the other, so its intrinsics do not fit the video; make a camera file of the video's "
            f"size, width {info.width} and height {info.height} with fx/fy/cx/cy or hfov_deg for that image "
            "(docs/formats.md), then find its horizon_row with monorarp calibrate-horizon INPUT --camera FILE")
    if log is not None:
        print(f"note: the video is {info.width}x{info.height} but the camera file is "
              f"{camera.width}x{camera.height}: intrinsics scaled to the video", file=log)
    return camera.scaled(info.width, info.height), True


# ------------------------------------------------------------------------- pipeline
def with_given_speed(config: PipelineConfig, speed_mps: float | None) -> PipelineConfig:
    """``config`` with a known ego speed (m/s) given to the Monte Carlo risk, unless its kwargs set one."""
    if config.risk.name != "monte_carlo" or speed_mps is None or "ego_speed_mps" in config.risk.kwargs:
        return config
    risk = ComponentConfig(name=config.risk.name, kwargs={**config.risk.kwargs, "ego_speed_mps": speed_mps})
    return config.model_copy(update={"risk": risk})


# --------------------------------------------------------------------------- records
def _num(x: float | None) -> float | None:
    return None if x is None or not np.isfinite(x) else float(x)


def prediction_record(result: FrameResult, given_speed: float | None = None) -> dict:
    """The ``predictions.jsonl`` object of one frame (module docstring)."""
    tracks = []
    for tr in result.tracks:
        st = result.states.get(tr.id)
        tracks.append({
            "id": int(tr.id), "box": [float(v) for v in tr.box], "coasting": bool(tr.coasting),
            "d_x": None if st is None else _num(st.d_x), "d_y": None if st is None else _num(st.d_y),
            "v_x": None if st is None else _num(st.v_x), "v_y": None if st is None else _num(st.v_y),
            "ttc": _num(result.risk.ttc.get(tr.id)),
        })
    if result.ego_speed is not None and np.isfinite(result.ego_speed):
        speed, source = float(result.ego_speed), "estimate"
    elif given_speed is not None:
        speed, source = float(given_speed), "given"
    else:
        speed, source = None, None
    w = result.warning
    return {"frame": int(result.index), "t": float(result.t), "tracks": tracks,
            "risk": _num(result.risk.risk), "risk_kind": getattr(result.risk, "kind", "inverse_ttc"),
            "ego_speed": speed, "ego_speed_source": source,
            "warning": {"active": bool(w.active), "track_id": w.track_id, "ttc": _num(w.ttc),
                        "episode": w.episode, "onset_t": _num(w.onset_t)}}


# ------------------------------------------------------------------------------ run
def _refuse_truth_detector(name: str) -> None:
    """A detector that reads the simulation's ground truth (``uses_truth``) has none on a video."""
    if not is_model_path(name) and uses(get_factory("detector", name), "truth"):
        raise UserError(f"--detector {name}: needs the simulation's ground truth, which a video does not have "
                        "(it runs in monorarp run, sweep, bench and scorecard)")


def run_video(input_spec: str | int | Path, camera: CameraModel | str | Path, out_dir: str | Path | None,
              options: VideoRunOptions = VideoRunOptions(), *, log: TextIO | None | str = "stderr",
              on_frame: Callable[[FrameResult, np.ndarray | None], None] | None = None) -> VideoRunSummary:
    """Run the pipeline on ``input_spec`` (file path, or webcam index as int / digit string).

    ``camera``: a :class:`CameraModel` or the path of a camera file. ``out_dir``
    None writes nothing (e.g. display only). Every check (display, camera,
    input decodes, component names, model files, output location) happens
    before anything is written; any error leaves no output directory behind.
    For a webcam, Ctrl-C ends the capture and keeps what was recorded; with
    ``display``, the keys q and Esc end any input early, keeping the output.
    """
    if options.display:
        check_display()
    cam = camera if isinstance(camera, CameraModel) else CameraModel.load(camera)
    check_frames(options.max_frames)
    if options.speed_mps is not None and not (np.isfinite(options.speed_mps) and options.speed_mps >= 0):
        raise UserError(f"--speed must be a non-negative speed in m/s, got {options.speed_mps}")
    with VideoSource(input_spec) as source:
        cam, scaled = camera_for(cam, source.info, log)
        _refuse_truth_detector(options.pipeline.detector.name)   # after the input's own errors, as names are
        pipeline = Pipeline.from_config(with_given_speed(options.pipeline, options.speed_mps), cam)
        if out_dir is None:
            return _loop(source, pipeline, cam, scaled, options, None, on_frame)
        with atomic_output_dir(out_dir, owned_names=OUTPUT_NAMES) as tmp:
            summary = _loop(source, pipeline, cam, scaled, options, tmp, on_frame)
        return VideoRunSummary(**{**summary.__dict__, "out_dir": Path(out_dir)})


def _loop(source: VideoSource, pipeline: Pipeline, cam: CameraModel, scaled: bool, options: VideoRunOptions,
          out: Path | None, on_frame: Callable | None) -> VideoRunSummary:
    from monorarp.app.display import draw_frame
    from monorarp.app.video.writer import VideoWriter

    info = source.info
    fps = info.fps or FALLBACK_FPS
    runner = run_threaded if options.threaded else run_sync
    images: dict[int, np.ndarray] = {}

    def remember(frames: Iterator[Frame]) -> Iterator[Frame]:
        for f in frames:   # images for drawing; popped as soon as their result arrives
            images[f.index] = f.image
            yield f

    writer = VideoWriter(out / "annotated.mp4", fps, (info.width, info.height)) \
        if out is not None and options.write_video else None
    preds = JsonlWriter(out / "predictions.jsonl") if out is not None else None
    draw = writer is not None or options.display or on_frame is not None
    n, t_first, t_last = 0, None, None
    timings: dict[str, float] = {}
    t0 = time.perf_counter()
    results = runner(pipeline, remember(source.frames(options.max_frames)))
    try:
        try:
            for res in results:
                image = images.pop(res.index)
                annotated = draw_frame(image, res, warning_s=options.warning_s,
                                       ego_speed=res.ego_speed if res.ego_speed is not None else options.speed_mps
                                       ) if draw else None
                if preds is not None:
                    preds.write(prediction_record(res, options.speed_mps))
                if writer is not None:
                    writer.write(annotated)
                if on_frame is not None:
                    on_frame(res, annotated)
                n += 1
                t_first = res.t if t_first is None else t_first
                t_last = res.t
                for k, v in res.timings_ms.items():
                    timings[k] = timings.get(k, 0.0) + v
                if options.display:
                    cv2.imshow(WINDOW, annotated)
                    if cv2.waitKey(1) & 0xFF in (ord("q"), 27):   # q or Esc: stop early, keep the output
                        break
        except KeyboardInterrupt:   # a webcam run ends with Ctrl-C and keeps its output
            if not info.is_webcam:
                raise
        finally:
            results.close()
        wall = time.perf_counter() - t0
        if writer is not None:
            writer.close()
        if preds is not None:
            preds.close()
    except BaseException:
        if writer is not None:
            writer.close()
        if preds is not None:
            preds.abort()
        raise
    finally:
        if options.display:
            cv2.destroyAllWindows()
    if n == 0:
        raise UserError(f"{info.name}: no frame was processed")
    means = {k: v / n for k, v in timings.items()}
    summary = VideoRunSummary(out_dir=out, frames=n, t_first=t_first, t_last=t_last, wall_s=wall,
                              pipeline_ms_mean=means.get("total"), camera=cam, camera_scaled=scaled)
    if out is not None:
        cfg = options.pipeline
        write_json_atomic(out / "run.json", {
            "input": info.name, "webcam": info.is_webcam,
            "video": {"width": info.width, "height": info.height, "fps": info.fps,
                      "frame_count": info.frame_count},
            "camera": cam.to_dict(), "camera_scaled": scaled,
            "components": {**{k: getattr(cfg, k).name for k in ("detector", "tracker", "state", "risk")},
                           "ego_speed": None if cfg.ego_speed is None else cfg.ego_speed.name},
            "speed_mps": options.speed_mps, "threaded": options.threaded,
            "frames": n, "t_first": t_first, "t_last": t_last,
            "timings_ms_mean": means, "wall_s": wall, "frames_per_s": summary.fps,
        })
    return summary

