"""One scored run: simulate -> render -> ground truth -> pipeline -> score, written atomically.

:func:`run_scenario` writes into ``out_dir`` (replaced as a whole only when the
run succeeded; on any failure nothing is left):

* ``metrics.json`` — :func:`harness.scoring.evaluate.evaluate` (nested; NaN -> null);
* ``per_object.csv`` — estimate and truth side by side per frame and object;
* ``per_frame.csv`` — per frame: ego speed estimate and truth, risk, its probability, the
  1/TTC baseline (when the run's risk is another estimator) and the risk label
  (:func:`harness.scoring.evaluate.frame_rows`);
* ``annotated.mp4`` — :func:`monorarp.display.draw_frame` on every frame (unless ``annotate=False``);
* ``frames.mp4``, ``camera.json``, ``ground_truth.jsonl`` — as ``monorarp render`` writes them
  (``frames.mp4`` only with ``write_frames=True``).

Ego speed: an ego-speed stage is told the scenario's marking standard
(``road.markings``: stripe length, period, width) unless its kwargs set them, as a
user configures the pipeline for the road it drives on (the estimators' defaults
are US markings). The risk stage gets the frame's ego-speed estimate when it takes
one (Monte Carlo); with ``gps_speed=True`` it gets the true ego speed of the frame
(a GPS-like source) on frames without an estimate.

Timing: frames are rendered into memory first (up to ``preload_bytes``), then
the pipeline runs over them alone, so ``fps`` = frames / pipeline wall time.
Longer runs stream frames from the renderer into the pipeline; ``fps`` then
includes simulation and rendering (``metrics["config"]["fps_includes_render"]``).
"""

from __future__ import annotations

import time
from collections.abc import Iterator, Mapping
from contextlib import ExitStack
from pathlib import Path
from typing import TYPE_CHECKING, Any

from harness.scenario import Scenario
from harness.scoring.evaluate import EvalConfig, evaluate, frame_rows, jsonable, write_frame_csv, write_metrics
from harness.scoring.records import write_csv
from harness.scoring.tables import summary_table  # noqa: F401  (re-exported for callers)
from monorarp.camera import CameraModel
from monorarp.pipeline import ComponentConfig, Pipeline, PipelineConfig, run_sync, run_threaded
from monorarp.registry import build
from monorarp.types import Frame, FrameResult, ObjectState, RiskEstimate

if TYPE_CHECKING:
    from harness.frame_cache import FrameCache

METRICS_NAME = "metrics.json"
PER_OBJECT_NAME = "per_object.csv"
PER_FRAME_NAME = "per_frame.csv"
ANNOTATED_NAME = "annotated.mp4"
VIDEO_NAME = "frames.mp4"
CAMERA_NAME = "camera.json"
GROUND_TRUTH_NAME = "ground_truth.jsonl"
OUTPUT_NAMES = (METRICS_NAME, PER_OBJECT_NAME, PER_FRAME_NAME, ANNOTATED_NAME, VIDEO_NAME, CAMERA_NAME, GROUND_TRUTH_NAME)
PRELOAD_BYTES = 1 << 30


# ---------------------------------------------------------------------------- pipeline
def describe(cfg: PipelineConfig) -> dict:
    """Component names and kwargs for ``metrics["config"]``."""
    comps = {k: getattr(cfg, k) for k in ("detector", "tracker", "state", "risk", "ego_speed", "warning", "horizon")}
    return {"components": {k: c.name for k, c in comps.items() if c is not None},
            "component_kwargs": {k: jsonable(c.kwargs) for k, c in comps.items() if c is not None and c.kwargs}}


def with_scenario_markings(cfg: PipelineConfig, scenario: Scenario) -> PipelineConfig:
    """``cfg`` with the ego-speed stage told the scenario's marking dimensions (unless its kwargs set them)."""
    if cfg.ego_speed is None:
        return cfg
    m = scenario.road.markings
    kw = {"stripe_length_m": m.stripe_length_m, "period_m": m.period_m, "marking_width_m": m.width_m,
          **cfg.ego_speed.kwargs}
    return cfg.model_copy(update={"ego_speed": ComponentConfig(name=cfg.ego_speed.name, kwargs=kw)})


class GpsFallbackRisk:
    """Risk stage wrapper: ``ego_speed`` = the pipeline's estimate, else the frame's true ego speed (GPS-like).

    ``speeds`` maps frame time (s) to the true ego speed (m/s); the harness fills it
    before the frame enters the pipeline.
    """

    def __init__(self, inner: Any, speeds: Mapping[float, float]) -> None:
        self.inner, self.speeds = inner, speeds

    def reset(self) -> None:
        if hasattr(self.inner, "reset"):
            self.inner.reset()

    def assess(self, states: dict[int, ObjectState], t: float, ego_speed: float | None = None) -> RiskEstimate:
        if ego_speed is None:
            ego_speed = self.speeds.get(t)
        return self.inner.assess(states, t, ego_speed=ego_speed)


def baseline_ttc_risk(results: list[FrameResult], camera: CameraModel) -> list[RiskEstimate] | None:
    """The paper's 1/TTC risk on the same states, when the run's risk estimator is another one (else None)."""
    if all(r.risk.kind == "inverse_ttc" for r in results):
        return None
    ttc = build("risk", "ttc", camera=camera)
    return [ttc.assess(r.states, r.t) for r in results]


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
                 preload_bytes: int = PRELOAD_BYTES, gps_speed: bool = False,
                 cache: FrameCache | None = None) -> dict:
    """Simulate, render, run the pipeline and score ``scenario``; returns the metrics dict (NaN kept).

    ``n_frames`` defaults to the scenario's duration x fps. With ``out_dir`` the
    files of the module docstring are written atomically. ``gps_speed``: a risk
    stage that takes the ego speed gets the true one on frames without an estimate.
    ``cache``: frames and truth come from this :class:`~harness.frame_cache.FrameCache`
    (rendered and stored on a miss); the outputs are identical either way.
    """
    cfg = pipeline_config if isinstance(pipeline_config, PipelineConfig) else \
        PipelineConfig.model_validate(pipeline_config)
    cfg = with_scenario_markings(cfg, scenario)
    camera = scenario.camera.model()
    import harness.oracle  # noqa: F401  (registers the "oracle" detector)

    pipeline = Pipeline.from_config(cfg, camera)     # bad component names / model files fail before any output
    true_speeds: dict[float, float] = {}
    from monorarp.pipeline import _takes_ego_speed

    if gps_speed and _takes_ego_speed(pipeline.risk):
        pipeline.risk = GpsFallbackRisk(pipeline.risk, true_speeds)
    n = scenario.n_frames if n_frames is None else int(n_frames)
    source = rendered_frames(scenario, n) if cache is None else cache.frames(scenario, n)
    preload = n * camera.width * camera.height * 3 <= preload_bytes
    run_info = {"scenario": scenario.name, "seed": scenario.seed, "fps_scenario": scenario.fps,
                "camera": {"width": camera.width, "height": camera.height}, **describe(cfg),
                "threaded": bool(threaded), "fps_includes_render": not preload, "gps_speed": bool(gps_speed)}

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
                true_speeds[frame.t] = float(truth["ego"]["speed"])
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
        baseline = baseline_ttc_risk(results, camera)
        metrics, records = evaluate(ordered, results, eval_config, wall_time_s=wall, run_info=run_info,
                                    camera=camera, baseline_risk=baseline,
                                    ego_speed_method=None if cfg.ego_speed is None else cfg.ego_speed.name,
                                    fcw_threshold_s=getattr(pipeline.warning, "ttc_threshold_s", None))
        metrics["risk"]["ego_speed_sources"] = _ego_speed_sources(results, pipeline, gps_speed)
        if tmp:
            write_metrics(metrics, tmp / METRICS_NAME)
            write_csv(records, tmp / PER_OBJECT_NAME)
            write_frame_csv(frame_rows(ordered, results, eval_config, baseline), tmp / PER_FRAME_NAME)
    return metrics


def _ego_speed_sources(results: list[FrameResult], pipeline: Pipeline, gps_speed: bool) -> dict[str, int] | None:
    """Frames whose risk stage got the ego speed from the estimator / the true speed / its own setting.

    None when the risk stage takes no ego speed (the 1/TTC risk works on relative velocities).
    """
    from monorarp.pipeline import _takes_ego_speed

    if not _takes_ego_speed(pipeline.risk):
        return None
    n_est = sum(r.ego_speed is not None for r in results)
    rest = len(results) - n_est
    return {"estimator": n_est, "gps": rest if gps_speed else 0, "risk_default": 0 if gps_speed else rest}
