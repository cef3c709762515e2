"""Frames and their truth into the pipeline: simulated and rendered (or cached), preloaded or streamed.

:func:`rendered_frames` simulates and renders a scenario; :class:`FrameFeed` hands each frame
to the pipeline while keeping its truth, passing it to an oracle detector and to the GPS-like
true-speed map of :class:`GpsFallbackRisk`; :func:`run_pipeline` runs the pipeline over the feed.

Timing: frames are rendered into memory first when they fit (:func:`fits_in_memory`, up to
``preload_bytes``), then the pipeline runs over them alone, so ``fps`` = frames / pipeline
wall time. Longer runs stream frames from the renderer into the pipeline; ``fps`` then
includes simulation and rendering (``metrics["config"]["fps_includes_render"]``).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterable, Iterator, Mapping
from typing import Any

from harness.world.scenario import Scenario
from harness.world.truth import FrameTruth
from monorarp.core.camera import CameraModel
from monorarp.pipeline.runner import Pipeline, run_sync, run_threaded
from monorarp.core.types import Frame, FrameResult, ObjectState, RiskEstimate

PRELOAD_BYTES = 1 << 30


def rendered_frames(scenario: Scenario, n_frames: int | None = None) -> Iterator[tuple[Frame, FrameTruth]]:
    """(Frame, truth record) of each simulated frame; the simulation is set up before the first yield."""
    from harness.world.ground_truth import frame_truth
    from harness.render.renderer import Renderer
    from harness.simulation.simulator import simulate

    worlds = simulate(scenario, n_frames=n_frames)
    first = next(worlds, None)   # raises scenario errors the simulation finds, before any rendering

    def gen() -> Iterator[tuple[Frame, FrameTruth]]:
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


class GpsFallbackRisk:
    """Risk stage wrapper: ``ego_speed`` = the pipeline's estimate, else the frame's true ego speed (GPS-like).

    ``speeds`` maps frame time (s) to the true ego speed (m/s); the harness fills it
    before the frame enters the pipeline.
    """

    uses_ego_speed = True

    def __init__(self, inner: Any, speeds: Mapping[float, float]) -> None:
        self.inner, self.speeds = inner, speeds

    def reset(self) -> None:
        if hasattr(self.inner, "reset"):
            self.inner.reset()

    def assess(self, states: dict[int, ObjectState], t: float, ego_speed: float | None = None) -> RiskEstimate:
        if ego_speed is None:
            ego_speed = self.speeds.get(t)
        return self.inner.assess(states, t, ego_speed=ego_speed)


def fits_in_memory(n_frames: int, camera: CameraModel, preload_bytes: int = PRELOAD_BYTES) -> bool:
    """Whether ``n_frames`` BGR images of ``camera``'s size take at most ``preload_bytes``."""
    return n_frames * camera.width * camera.height * 3 <= preload_bytes


class FrameFeed:
    """The frames of ``source`` for the pipeline, each one's truth kept until its result is out.

    Before a frame is yielded: its truth goes to ``truths`` (by frame index), its true ego
    speed to ``true_speeds`` (by frame time, s -> m/s), both to ``on_frame(image, truth)``, and
    truth and image to ``oracle`` (an oracle detector's ``set_truth``) when given.
    """

    def __init__(self, source: Iterable[tuple[Frame, FrameTruth]], true_speeds: dict[float, float],
                 on_frame: Callable[[Any, FrameTruth], None], oracle: Callable[[FrameTruth, Any], None] | None = None) -> None:
        self.source, self.true_speeds, self.on_frame, self.oracle = source, true_speeds, on_frame, oracle
        self.truths: dict[int, FrameTruth] = {}
        self.images: dict[int, Any] = {}

    def frames(self) -> Iterator[Frame]:
        for frame, truth in self.source:
            self.truths[frame.index] = truth
            self.true_speeds[frame.t] = truth.ego.speed
            self.images[frame.index] = frame.image
            self.on_frame(frame.image, truth)
            if self.oracle is not None:
                self.oracle(truth, frame.image)
            yield frame

    def take(self, index: int) -> tuple[Any, FrameTruth]:
        """(image, truth) of frame ``index``; the image is released."""
        return self.images.pop(index), self.truths[index]


def run_pipeline(pipeline: Pipeline, frames: Iterator[Frame], preload: bool, threaded: bool,
                 on_result: Callable[[FrameResult], None]) -> tuple[list[FrameResult], float]:
    """Results of ``pipeline`` (reset first) over ``frames`` and the wall time (s) of the run.

    ``preload``: the frames are all taken before the clock starts and ``on_result`` is called
    after it stops; else they stream in and ``on_result`` runs as each result comes out.
    """
    runner = run_threaded if threaded else run_sync
    pipeline.reset()
    input_frames = list(frames) if preload else frames
    results: list[FrameResult] = []
    t0 = time.perf_counter()
    for res in runner(pipeline, input_frames):
        results.append(res)
        if not preload:
            on_result(res)
    wall = time.perf_counter() - t0
    del input_frames
    if preload:
        for res in results:
            on_result(res)
    return results, wall
