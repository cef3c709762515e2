"""The pipeline: detector -> tracker -> state estimator -> risk estimator (Table I).

Stage contracts are the Protocols of :mod:`monorarp.core.types` (any object with those methods
works; built-ins are named in :mod:`monorarp.pipeline.catalogue` and built by :mod:`monorarp.pipeline.registry`):
detector, optional ego_speed (m/s), optional horizon (none = the calibrated horizon; the state
estimator gets each frame's reading as ``horizon=``), tracker, state, risk (gets the frame's
ego-speed estimate as ``ego_speed=``, m/s or None, same frame in both runners), optional warning
(the forward-collision warning decision, :mod:`monorarp.warning.fcw`).

Two runners give identical outputs on offline input: :func:`run_sync` (one
thread, frame after frame) and :func:`run_threaded` (each stage on its own
thread, joined by bounded FIFO queues as in the paper, so stages of successive
frames overlap). Time per stage and frame is recorded in ms
(``time.perf_counter``) under ``detector``, ``ego_speed``, ``tracker``,
``state``, ``risk``, ``warning`` and ``total`` (``ego_speed``/``warning`` are 0 when there is no such
stage; ``total`` is the whole ``process`` call in the synchronous runner and
the sum of the stages in the threaded one).
"""

from __future__ import annotations

import queue
import threading
import time
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from monorarp.core.camera import CameraModel
from monorarp.pipeline import registry
from monorarp.pipeline.config import ComponentConfig, PipelineConfig
from monorarp.pipeline.detectors import build_detector
from monorarp.pipeline.pinhole_stage import PinholeImageStage
from monorarp.core.types import (Detection, Detector, EgoSpeedEstimator, Frame, FrameResult, HorizonReading, HorizonStage,
                            ObjectState, RiskEstimate, RiskEstimator, StateEstimator, Track, Tracker, WarningStage,
                            WarningState, strong)


@dataclass
class _Record:
    """One frame's working record on its way through the stages (filled stage by stage)."""

    frame: Frame
    timings: dict[str, float] = field(default_factory=dict)   # stage -> ms
    detections: list[Detection] = field(default_factory=list)
    ego_speed: float | None = None
    horizon: HorizonReading | None = None
    tracks: list[Track] = field(default_factory=list)
    states: dict[int, ObjectState] = field(default_factory=dict)
    risk: RiskEstimate | None = None
    warning: WarningState = field(default_factory=WarningState)

    def timed(self, key: str, fn: Callable, *args: Any, **kwargs: Any) -> Any:
        """``fn(*args, **kwargs)``, its time recorded under ``key`` (ms)."""
        t0 = time.perf_counter()
        out = fn(*args, **kwargs)
        self.timings[key] = (time.perf_counter() - t0) * 1e3
        return out

    def result(self) -> FrameResult:
        f = self.frame
        return FrameResult(index=f.index, t=f.t, detections=strong(self.detections), tracks=self.tracks,
                           states=self.states, risk=self.risk, ego_speed=self.ego_speed,
                           timings_ms=self.timings, warning=self.warning, horizon=self.horizon)


class Pipeline:
    """One frame in, one :class:`FrameResult` out; see the module docstring for stage interfaces."""

    def __init__(self, detector: Detector, tracker: Tracker, state: StateEstimator, risk: RiskEstimator,
                 ego_speed: EgoSpeedEstimator | None = None, warning: WarningStage | None = None,
                 horizon: HorizonStage | None = None) -> None:
        self.detector, self.tracker, self.state, self.risk, self.ego_speed = detector, tracker, state, risk, ego_speed
        self.warning, self.horizon = warning, horizon

    @classmethod
    def from_config(cls, config: PipelineConfig | dict, camera: CameraModel | None = None) -> "Pipeline":
        """Build every stage through the registry (:func:`monorarp.pipeline.registry.build`).

        ``camera`` is passed to every component whose factory declares ``uses_camera = True``
        (the state estimator; the risk estimator, for its mounting offsets; ...) unless its
        kwargs already set one.
        """
        cfg = config if isinstance(config, PipelineConfig) else PipelineConfig.model_validate(config)
        cfg.validate_names()   # unknown names fail before any model is loaded
        from monorarp.lanes.geometry import EgoSpeedError, EgoSpeedStageError

        def build(kind: str, comp: ComponentConfig | None) -> Any:
            return None if comp is None else registry.build(kind, comp.name, comp.kwargs, camera)

        def build_lane_stage(kind: str, comp: ComponentConfig | None) -> Any:
            """A lane-marking stage; on a distorted camera, in its virtual pinhole view (:mod:`.pinhole_stage`)."""
            if (comp is not None and camera is not None and camera.distorted and "camera" not in comp.kwargs
                    and registry.uses(registry.get_factory(kind, comp.name), "camera")):
                return PinholeImageStage(lambda cam: registry.build(kind, comp.name, comp.kwargs, cam), camera, kind)
            return build(kind, comp)

        def build_ego_speed() -> Any:   # e.g. a camera that sees too little road: say which stage fails
            try:
                return build_lane_stage("ego_speed", cfg.ego_speed)
            except EgoSpeedError as e:
                raise EgoSpeedStageError(f"ego-speed stage {cfg.ego_speed.name!r} (lane-marking ego-speed "
                                         f"estimator) cannot run: {e}") from None

        return cls(detector=build_detector(cfg.detector, camera), tracker=build("tracker", cfg.tracker),
                   state=build("state", cfg.state), risk=build("risk", cfg.risk),
                   ego_speed=build_ego_speed(), warning=build("warning", cfg.warning),
                   horizon=build_lane_stage("horizon", cfg.horizon))

    def reset(self) -> None:
        """Start a new sequence: every stateful stage forgets its history."""
        for stage in (self.detector, self.tracker, self.state, self.risk, self.ego_speed, self.warning, self.horizon):
            if hasattr(stage, "reset"):
                stage.reset()

    # The stage steps, shared by both runners. Each takes and returns the frame's
    # working record and records its own time.
    def detect(self, image: np.ndarray) -> list[Detection]:
        """The detector's detections of ``image``, weak ones too when the tracker takes them and
        the detector gives them (``uses_weak_detections`` on both)."""
        weak = registry.uses(self.tracker, "weak_detections") and registry.uses(self.detector, "weak_detections")
        return list(self.detector.detect(image, weak=True) if weak else self.detector.detect(image))

    def _detect(self, rec: _Record) -> _Record:
        rec.detections = rec.timed("detector", self.detect, rec.frame.image)
        return rec

    def _ego_speed(self, rec: _Record) -> _Record:
        if self.ego_speed is None:
            rec.ego_speed, rec.timings["ego_speed"] = None, 0.0
        else:
            rec.ego_speed = rec.timed("ego_speed", self.ego_speed.update, rec.frame.image, rec.frame.t)
        return rec

    def _horizon(self, rec: _Record) -> _Record:
        # only with a horizon stage: without one the timings keep their keys and the record has none
        rec.horizon = rec.timed("horizon", self.horizon.update, rec.frame.image, rec.frame.t)
        return rec

    def _track(self, rec: _Record) -> _Record:
        f = rec.frame
        dets = tracker_input(self.tracker, rec.detections)
        rec.tracks = list(rec.timed("tracker", self.tracker.update, f.image, dets, f.t))
        return rec

    def _state(self, rec: _Record) -> _Record:
        extra = {"image": rec.frame.image} if registry.uses(self.state, "image") else {}
        rec.states = dict(rec.timed("state", self.state.update, rec.tracks, rec.frame.t, horizon=rec.horizon, **extra))
        return rec

    def _risk(self, rec: _Record) -> _Record:
        rec.risk = rec.timed("risk", self.risk.assess, rec.states, rec.frame.t, ego_speed=rec.ego_speed)
        return rec

    def _warn(self, rec: _Record) -> _Record:
        if self.warning is None:
            rec.warning, rec.timings["warning"] = WarningState(), 0.0
        else:
            rec.warning = rec.timed("warning", self.warning.update, rec.states, rec.risk, rec.frame.t,
                                    ego_speed=rec.ego_speed)
        return rec

    @property
    def steps(self) -> list[Callable[[_Record], _Record]]:
        horizon = [self._horizon] if self.horizon is not None else []
        return [self._detect, self._ego_speed, *horizon, self._track, self._state, self._risk, self._warn]

    def process(self, frame: Frame) -> FrameResult:
        """Run every stage on one frame."""
        t0 = time.perf_counter()
        rec = _Record(frame)
        for step in self.steps:
            rec = step(rec)
        rec.timings["total"] = (time.perf_counter() - t0) * 1e3
        return rec.result()


def tracker_input(tracker: Tracker, detections: list[Detection]) -> list[Detection]:
    """What ``tracker`` is given of a frame's detections: all, weak ones too, if it declares
    ``uses_weak_detections``; otherwise the strong ones."""
    return detections if registry.uses(tracker, "weak_detections") else strong(detections)


# --------------------------------------------------------------------------- runners
def run_sync(pipeline: Pipeline, frames: Iterable[Frame]) -> Iterator[FrameResult]:
    """Process frames one after the other on the calling thread."""
    for frame in frames:
        yield pipeline.process(frame)


@dataclass(frozen=True)
class _Failure:
    """Travels down the queues in place of a record when a stage (or the source) raised."""

    error: BaseException


_END = object()  # end of input


def run_threaded(pipeline: Pipeline, frames: Iterable[Frame], queue_size: int = 4) -> Iterator[FrameResult]:
    """Process frames with one thread per stage joined by bounded queues; results in input order.

    An exception in any stage (or in the frame source) is re-raised in the
    caller; closing the iterator early stops every thread.
    """
    stop = threading.Event()
    steps = pipeline.steps
    queues = [queue.Queue(maxsize=queue_size) for _ in range(len(steps) + 1)]

    def put(q: queue.Queue, item: Any) -> bool:
        while not stop.is_set():
            try:
                q.put(item, timeout=0.05)
                return True
            except queue.Full:
                continue
        return False

    def get(q: queue.Queue) -> Any:
        while not stop.is_set():
            try:
                return q.get(timeout=0.05)
            except queue.Empty:
                continue
        return _END

    def source() -> None:
        try:
            for frame in frames:
                if not put(queues[0], _Record(frame)):
                    return
        except BaseException as e:  # noqa: BLE001 - handed to the caller
            put(queues[0], _Failure(e))
            return
        put(queues[0], _END)

    def worker(step: Callable[[_Record], _Record], q_in: queue.Queue, q_out: queue.Queue) -> None:
        while True:
            item = get(q_in)
            if item is _END or isinstance(item, _Failure):
                put(q_out, item)
                return
            try:
                item = step(item)
            except BaseException as e:  # noqa: BLE001 - handed to the caller
                put(q_out, _Failure(e))
                return
            if not put(q_out, item):
                return

    threads = [threading.Thread(target=source, name="monorarp-source", daemon=True)]
    threads += [threading.Thread(target=worker, args=(s, queues[i], queues[i + 1]), daemon=True,
                                 name=f"monorarp-{s.__name__.lstrip('_')}") for i, s in enumerate(steps)]
    for th in threads:
        th.start()
    try:
        while True:
            item = get(queues[-1])
            if item is _END:
                return
            if isinstance(item, _Failure):
                raise item.error
            t = item.timings
            t["total"] = sum(t.values())
            yield item.result()
    finally:
        stop.set()
        for th in threads:
            th.join(timeout=1.0)
