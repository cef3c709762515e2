"""One scored run: simulate -> render -> ground truth -> pipeline -> score, written atomically.

:func:`run_scenario` composes the run's three parts: the frame feed (:mod:`harness.run.frame_feed`:
frames and truth in, preloaded or streamed), the scoring (:mod:`harness.run.scoring`) and the
run directory (:mod:`harness.run.outputs`: its files, written atomically).

Ego speed: an ego-speed stage is told the scenario's marking standard
(``road.markings``: stripe length, period, width) unless its kwargs set them, as a
user configures the pipeline for the road it drives on (the estimators' defaults
are US markings). The risk stage gets the frame's ego-speed estimate when it takes
one (Monte Carlo); with ``gps_speed=True`` it gets the true ego speed of the frame
(a GPS-like source) on frames without an estimate.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING

from harness.run import frame_feed
from harness.run.frame_feed import PRELOAD_BYTES, FrameFeed, GpsFallbackRisk, fits_in_memory, run_pipeline
from harness.run.outputs import RunOutputs
from harness.run.scoring import score_run
from harness.world.scenario import Scenario
from harness.scoring.evaluate import EvalConfig
from monorarp.app.io import to_jsonable
from monorarp.pipeline.config import ComponentConfig, PipelineConfig
from monorarp.pipeline.runner import Pipeline
from monorarp.pipeline.registry import uses
from monorarp.core.types import FrameResult

if TYPE_CHECKING:
    from harness.run.frame_cache import FrameCache
    from harness.run.detection_memo import DetectionMemo


# ---------------------------------------------------------------------------- pipeline
def describe(cfg: PipelineConfig) -> dict:
    """Component names and kwargs for ``metrics["config"]``."""
    comps = {k: getattr(cfg, k) for k in ("detector", "tracker", "state", "risk", "ego_speed", "warning", "horizon")}
    return {"components": {k: c.name for k, c in comps.items() if c is not None},
            "component_kwargs": {k: to_jsonable(c.kwargs) for k, c in comps.items() if c is not None and c.kwargs}}


def with_scenario_markings(cfg: PipelineConfig, scenario: Scenario) -> PipelineConfig:
    """``cfg`` with the ego-speed stage told the scenario's marking dimensions (unless its kwargs set them)."""
    if cfg.ego_speed is None:
        return cfg
    m = scenario.road.markings
    kw = {"stripe_length_m": m.stripe_length_m, "period_m": m.period_m, "marking_width_m": m.width_m,
          **cfg.ego_speed.kwargs}
    return cfg.model_copy(update={"ego_speed": ComponentConfig(name=cfg.ego_speed.name, kwargs=kw)})


# --------------------------------------------------------------------------------- run
def run_scenario(scenario: Scenario, pipeline_config: PipelineConfig | Mapping, n_frames: int | None = None,
                 out_dir: str | Path | None = None, threaded: bool = False, annotate: bool = True,
                 eval_config: EvalConfig = EvalConfig(), write_frames: bool = True,
                 preload_bytes: int = PRELOAD_BYTES, gps_speed: bool = False,
                 cache: FrameCache | None = None, detections: DetectionMemo | None = None) -> dict:
    """Simulate, render, run the pipeline and score ``scenario``; returns the metrics dict (NaN kept).

    ``n_frames`` defaults to the scenario's duration x fps. With ``out_dir`` the files of
    :mod:`harness.run.outputs` are written atomically. ``gps_speed``: a risk
    stage that takes the ego speed gets the true one on frames without an estimate.
    ``cache``: frames and truth come from this :class:`~harness.run.frame_cache.FrameCache`
    (rendered and stored on a miss); the outputs are identical either way. ``detections``: the
    detector's results are reused from (and kept in) this memo when an earlier run fed the same
    detector the same images (:mod:`harness.run.detection_memo`); identical outputs too.
    """
    cfg = pipeline_config if isinstance(pipeline_config, PipelineConfig) else \
        PipelineConfig.model_validate(pipeline_config)
    cfg = with_scenario_markings(cfg, scenario)
    camera = scenario.camera.model()

    pipeline = Pipeline.from_config(cfg, camera)     # bad component names / model files fail before any output
    replay = detections.attach(pipeline, cfg.detector, camera) if detections is not None else None
    true_speeds: dict[float, float] = {}
    if gps_speed and uses(pipeline.risk, "ego_speed"):
        pipeline.risk = GpsFallbackRisk(pipeline.risk, true_speeds)
    n = scenario.n_frames if n_frames is None else int(n_frames)
    # looked up on the module, so tests can count renders by patching harness.run.frame_feed.rendered_frames
    source = frame_feed.rendered_frames(scenario, n) if cache is None else cache.frames(scenario, n)
    preload = fits_in_memory(n, camera, preload_bytes)
    run_info = {"scenario": scenario.name, "seed": scenario.seed, "fps_scenario": scenario.fps,
                "camera": {"width": camera.width, "height": camera.height}, **describe(cfg),
                "threaded": bool(threaded), "fps_includes_render": not preload, "gps_speed": bool(gps_speed)}

    with RunOutputs(out_dir, camera, scenario.fps, write_frames=write_frames, annotate=annotate) as outputs:
        feed = FrameFeed(source, true_speeds, outputs.record_frame, getattr(pipeline.detector, "set_truth", None))

        def annotate_result(res: FrameResult) -> None:
            image, truth = feed.take(res.index)
            outputs.annotate(image, res, truth, eval_config.warning_threshold_s)

        results, wall = run_pipeline(pipeline, feed.frames(), preload, threaded, annotate_result)
        if replay is not None:
            wall = replay.restore_timings(results, wall)
        score = score_run([feed.truths[r.index] for r in results], results, cfg, pipeline, camera, eval_config,
                          wall, run_info, gps_speed)
        if outputs.dir:
            outputs.write_scores(score.metrics, score.records, score.frame_rows())
    return score.metrics
