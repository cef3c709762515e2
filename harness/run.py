"""One scored run: simulate -> render -> ground truth -> pipeline -> score, written atomically.

:func:`run_scenario` writes into ``out_dir`` (replaced as a whole only when the
run succeeded; on any failure nothing is left):

* ``metrics.json`` — :func:`harness.scoring.evaluate.evaluate` (nested; NaN -> null);
* ``per_object.csv`` — estimate and truth side by side per frame and object;
* ``annotated.mp4`` — :func:`monorarp.display.draw_frame` on every frame (unless ``annotate=False``);
* ``frames.mp4``, ``camera.json``, ``ground_truth.jsonl`` — as ``monorarp render`` writes them
  (``frames.mp4`` only with ``write_frames=True``).

Timing: frames are rendered into memory first (up to ``preload_bytes``), then
the pipeline runs over them alone, so ``fps`` = frames / pipeline wall time.
Longer runs stream frames from the renderer into the pipeline; ``fps`` then
includes simulation and rendering (``metrics["config"]["fps_includes_render"]``).
"""

from __future__ import annotations

import inspect
import time
from collections.abc import Iterator, Mapping
from contextlib import ExitStack
from pathlib import Path
from typing import Any

from harness.scenario import Scenario
from harness.scoring.evaluate import EvalConfig, evaluate, jsonable, write_metrics
from harness.scoring.records import write_csv
from harness.scoring.tables import summary_table  # noqa: F401  (re-exported for callers)
from monorarp.camera import CameraModel
from monorarp.pipeline import Pipeline, PipelineConfig, run_sync, run_threaded
from monorarp.registry import get_factory
from monorarp.types import Frame, FrameResult

METRICS_NAME = "metrics.json"
PER_OBJECT_NAME = "per_object.csv"
ANNOTATED_NAME = "annotated.mp4"
VIDEO_NAME = "frames.mp4"
CAMERA_NAME = "camera.json"
GROUND_TRUTH_NAME = "ground_truth.jsonl"
OUTPUT_NAMES = (METRICS_NAME, PER_OBJECT_NAME, ANNOTATED_NAME, VIDEO_NAME, CAMERA_NAME, GROUND_TRUTH_NAME)
PRELOAD_BYTES = 1 << 30


# ---------------------------------------------------------------------------- pipeline
def _instantiate(factory: Any, kwargs: Mapping, camera: CameraModel) -> Any:
    kwargs = dict(kwargs)
    try:
        takes_camera = "camera" in inspect.signature(factory).parameters
    except (TypeError, ValueError):
        takes_camera = False
    if takes_camera and "camera" not in kwargs:
        kwargs["camera"] = camera
    return factory(**kwargs)


def build_pipeline(config: PipelineConfig | Mapping, camera: CameraModel) -> Pipeline:
    """A :class:`Pipeline` from ``config``; the detector may also be an ``.onnx`` path or ``"oracle"``.

    Every component name is resolved before anything is built, so an unknown
    name is reported before a model is loaded. ``camera`` is passed to every
    factory that takes a ``camera`` argument. Raises
    :class:`~monorarp.errors.UserError` for unknown names or unusable model files.
    """
    import harness.oracle  # noqa: F401  (registers the "oracle" detector)
    from monorarp.detection import load_detector

    cfg = config if isinstance(config, PipelineConfig) else PipelineConfig.model_validate(config)
    onnx = cfg.detector.name.lower().endswith(".onnx")
    stages = {"detector": None if onnx else cfg.detector, "tracker": cfg.tracker, "state": cfg.state,
              "risk": cfg.risk, "ego_speed": cfg.ego_speed}
    factories = {k: get_factory(k, c.name) for k, c in stages.items() if c is not None}
    built = {k: _instantiate(f, stages[k].kwargs, camera) for k, f in factories.items()}
    if onnx:
        built["detector"] = load_detector(cfg.detector.name, **cfg.detector.kwargs)
    return Pipeline(detector=built["detector"], tracker=built["tracker"], state=built["state"],
                    risk=built["risk"], ego_speed=built.get("ego_speed"))


def describe(cfg: PipelineConfig) -> dict:
    """Component names and kwargs for ``metrics["config"]``."""
    comps = {k: getattr(cfg, k) for k in ("detector", "tracker", "state", "risk", "ego_speed")}
    return {"components": {k: c.name for k, c in comps.items() if c is not None},
            "component_kwargs": {k: jsonable(c.kwargs) for k, c in comps.items() if c is not None and c.kwargs}}


# ------------------------------------------------------------------------------ frames
def rendered_frames(scenario: Scenario, n_frames: int | None = None) -> Iterator[tuple[Frame, dict]]:
    """(Frame, truth dict) of each simulated frame; the simulation is set up before the first yield."""
    from harness.ground_truth import frame_truth
    from harness.render import Renderer
    from harness.simulation import simulate

    worlds = simulate(scenario, n_frames=n_frames)
    first = next(worlds, None)   # raises scenario errors the simulation finds, before any rendering

    def gen() -> Iterator[tuple[Frame, dict]]:
        if first is None:
            return
        with Renderer(scenario) as renderer:
            for world in _chain(first, worlds):
                rendered = renderer.render(world)
                truth = frame_truth(world, renderer.camera, rendered)
                yield Frame(index=int(world.frame), t=float(world.t), image=rendered.image), truth

    return gen()


def _chain(first, rest):
    yield first
    yield from rest


# --------------------------------------------------------------------------------- run
def run_scenario(scenario: Scenario, pipeline_config: PipelineConfig | Mapping, n_frames: int | None = None,
                 out_dir: str | Path | None = None, threaded: bool = False, annotate: bool = True,
                 eval_config: EvalConfig = EvalConfig(), write_frames: bool = True,
                 preload_bytes: int = PRELOAD_BYTES) -> dict:
    """Simulate, render, run the pipeline and score ``scenario``; returns the metrics dict (NaN kept).

    ``n_frames`` defaults to the scenario's duration x fps. With ``out_dir`` the
    files of the module docstring are written atomically.
    """
    cfg = pipeline_config if isinstance(pipeline_config, PipelineConfig) else \
        PipelineConfig.model_validate(pipeline_config)
    camera = scenario.camera.model()
    pipeline = build_pipeline(cfg, camera)     # bad component names / model files fail before any output
    n = scenario.n_frames if n_frames is None else int(n_frames)
    source = rendered_frames(scenario, n)
    preload = n * camera.width * camera.height * 3 <= preload_bytes
    run_info = {"scenario": scenario.name, "seed": scenario.seed, "fps_scenario": scenario.fps,
                "camera": {"width": camera.width, "height": camera.height}, **describe(cfg),
                "threaded": bool(threaded), "fps_includes_render": not preload}

    from harness.output import JsonlWriter, atomic_output_dir, write_json_atomic
    from harness.video import VideoWriter
    from monorarp.display import draw_frame

    with ExitStack() as stack:
        tmp = stack.enter_context(atomic_output_dir(out_dir, owned_names=OUTPUT_NAMES)) if out_dir else None
        truth_out = stack.enter_context(JsonlWriter(tmp / GROUND_TRUTH_NAME)) if tmp else None
        frames_video = stack.enter_context(VideoWriter(tmp / VIDEO_NAME, scenario.fps, (camera.width, camera.height))) \
            if tmp and write_frames else None
        annotated = stack.enter_context(VideoWriter(tmp / ANNOTATED_NAME, scenario.fps,
                                                    (camera.width, camera.height))) if tmp and annotate else None
        if tmp:
            write_json_atomic(tmp / CAMERA_NAME, camera.to_dict())

        truths: dict[int, dict] = {}
        images: dict[int, Any] = {}
        oracle = getattr(pipeline.detector, "set_truth", None)

        def frames() -> Iterator[Frame]:
            for frame, truth in source:
                truths[frame.index] = truth
                images[frame.index] = frame.image
                if truth_out is not None:
                    truth_out.write(truth)
                if frames_video is not None:
                    frames_video.write(frame.image)
                if oracle is not None:
                    oracle(truth, frame.image)
                yield frame

        def annotate_result(res: FrameResult) -> None:
            image = images.pop(res.index)
            if annotated is not None:
                truth = truths[res.index]
                speed = res.ego_speed if res.ego_speed is not None else truth["ego"]["speed"]  # estimate, else true
                annotated.write(draw_frame(image, res, warning_s=eval_config.warning_threshold_s, ego_speed=speed,
                                           truth_boxes=[o["box"] for o in truth["objects"]]))

        runner = run_threaded if threaded else run_sync
        pipeline.reset()
        input_frames = list(frames()) if preload else frames()
        results: list[FrameResult] = []
        t0 = time.perf_counter()
        for res in runner(pipeline, input_frames):
            results.append(res)
            if not preload:
                annotate_result(res)
        wall = time.perf_counter() - t0
        del input_frames
        if preload:
            for res in results:
                annotate_result(res)

        ordered = [truths[r.index] for r in results]
        metrics, records = evaluate(ordered, results, eval_config, wall_time_s=wall, run_info=run_info,
                                    camera=camera)
        if tmp:
            write_metrics(metrics, tmp / METRICS_NAME)
            write_csv(records, tmp / PER_OBJECT_NAME)
    return metrics
