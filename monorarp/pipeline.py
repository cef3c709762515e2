"""The pipeline: detector -> tracker -> state estimator -> risk estimator (Table I).

Stage interfaces (any object with these methods works; built-ins come from
:mod:`monorarp.registry`):

* detector  ``detect(image) -> list[Detection]``
* ego_speed ``update(image, t) -> float | None`` (optional; m/s)
* horizon   ``update(image, t) -> HorizonReading`` (optional, :mod:`monorarp.horizon`): the
  frame's horizon row; a state estimator whose ``update`` takes a ``horizon`` keyword gets it
  (none = the calibrated horizon)
* tracker   ``update(image, detections, t) -> list[Track]``
* state     ``update(tracks, t) -> dict[int, ObjectState]``
* risk      ``assess(states, t) -> RiskEstimate``; when it takes an ``ego_speed``
  keyword (m/s or None), it gets the frame's ego-speed estimate (same frame, both runners)
* warning   ``update(states, risk, t) -> WarningState`` (optional): the forward-collision
  warning decision, episodes with hysteresis (:mod:`monorarp.warning`)

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
from dataclasses import dataclass
from typing import Any

from pydantic import BaseModel, ConfigDict, Field

from monorarp.camera import CameraModel
from monorarp import registry
from monorarp.types import Frame, FrameResult, WarningState


class ComponentConfig(BaseModel):
    """A component chosen by registry name, with its constructor keyword arguments."""

    model_config = ConfigDict(extra="forbid")
    name: str
    kwargs: dict[str, Any] = Field(default_factory=dict)


class PipelineConfig(BaseModel):
    """Which component fills each stage: the one place of every stage's default. ``ego_speed``, ``warning``
    and ``horizon`` are optional (None = no such stage; no horizon stage = the calibrated horizon). The
    detector is a registered name or an ``.onnx`` path (:func:`monorarp.detection.build_detector`)."""

    model_config = ConfigDict(extra="forbid")
    detector: ComponentConfig = ComponentConfig(name="centernet")
    tracker: ComponentConfig = ComponentConfig(name="particle")
    state: ComponentConfig = ComponentConfig(name="geometric")
    risk: ComponentConfig = ComponentConfig(name="ttc")
    ego_speed: ComponentConfig | None = None
    warning: ComponentConfig | None = ComponentConfig(name="fcw")
    horizon: ComponentConfig | None = None

    def stages(self) -> dict[str, ComponentConfig]:
        """The configured stages by kind (absent optional stages left out), in pipeline order."""
        return {k: c for k in type(self).model_fields if (c := getattr(self, k)) is not None}

    def validate_names(self) -> "PipelineConfig":
        """Raise :class:`~monorarp.registry.UnknownComponentError` (one line, naming the kind and the
        available names) for any unknown component name, before anything is built; returns ``self``."""
        from monorarp.detection import is_model_path

        for kind, comp in self.stages().items():
            if not (kind == "detector" and is_model_path(comp.name)):
                registry.get_factory(kind, comp.name)
        return self


class Pipeline:
    """One frame in, one :class:`FrameResult` out; see the module docstring for stage interfaces."""

    def __init__(self, detector: Any, tracker: Any, state: Any, risk: Any, ego_speed: Any = None,
                 warning: Any = None, horizon: Any = None) -> None:
        self.detector, self.tracker, self.state, self.risk, self.ego_speed = detector, tracker, state, risk, ego_speed
        self.warning, self.horizon = warning, horizon

    @classmethod
    def from_config(cls, config: PipelineConfig | dict, camera: CameraModel | None = None) -> "Pipeline":
        """Build every stage through the registry (:func:`monorarp.registry.build`).

        ``camera`` is passed to every component whose factory takes a ``camera``
        parameter (the state estimator; the risk estimator, for its mounting
        offsets) unless its kwargs already set one.
        """
        cfg = config if isinstance(config, PipelineConfig) else PipelineConfig.model_validate(config)
        cfg.validate_names()   # unknown names fail before any model is loaded
        from monorarp.detection import build_detector

        def build(kind: str, comp: ComponentConfig | None) -> Any:
            return None if comp is None else registry.build(kind, comp.name, comp.kwargs, camera)

        return cls(detector=build_detector(cfg.detector, camera), tracker=build("tracker", cfg.tracker),
                   state=build("state", cfg.state), risk=build("risk", cfg.risk),
                   ego_speed=build("ego_speed", cfg.ego_speed), warning=build("warning", cfg.warning),
                   horizon=build("horizon", cfg.horizon))

    def reset(self) -> None:
        """Start a new sequence: every stateful stage forgets its history."""
        for stage in (self.detector, self.tracker, self.state, self.risk, self.ego_speed, self.warning, self.horizon):
            if hasattr(stage, "reset"):
                stage.reset()

    # The six stage steps, shared by both runners. Each takes and returns the
    # frame's working record (a dict), and records its own time.
    def _detect(self, rec: dict) -> dict:
        rec["detections"] = list(_timed(rec, "detector", self.detector.detect, rec["frame"].image))
        return rec

    def _ego_speed(self, rec: dict) -> dict:
        if self.ego_speed is None:
            rec["ego_speed"], rec["timings"]["ego_speed"] = None, 0.0
        else:
            rec["ego_speed"] = _timed(rec, "ego_speed", self.ego_speed.update, rec["frame"].image, rec["frame"].t)
        return rec

    def _horizon(self, rec: dict) -> dict:
        # only with a horizon stage: without one the timings keep their keys and the record has none
        rec["horizon"] = _timed(rec, "horizon", self.horizon.update, rec["frame"].image, rec["frame"].t)
        return rec

    def _track(self, rec: dict) -> dict:
        f = rec["frame"]
        rec["tracks"] = list(_timed(rec, "tracker", self.tracker.update, f.image, rec["detections"], f.t))
        return rec

    def _state(self, rec: dict) -> dict:
        reading = rec.get("horizon")
        if reading is not None and _takes(self.state.update, "horizon"):
            rec["states"] = dict(_timed(rec, "state", lambda tr, t: self.state.update(tr, t, horizon=reading),
                                        rec["tracks"], rec["frame"].t))
        else:
            rec["states"] = dict(_timed(rec, "state", self.state.update, rec["tracks"], rec["frame"].t))
        return rec

    def _risk(self, rec: dict) -> dict:
        if _takes_ego_speed(self.risk):   # e.g. the Monte Carlo estimator: absolute speeds need the ego's
            rec["risk"] = _timed(rec, "risk", lambda s, t: self.risk.assess(s, t, ego_speed=rec["ego_speed"]),
                                 rec["states"], rec["frame"].t)
        else:
            rec["risk"] = _timed(rec, "risk", self.risk.assess, rec["states"], rec["frame"].t)
        return rec

    def _warn(self, rec: dict) -> dict:
        if self.warning is None:
            rec["warning"], rec["timings"]["warning"] = WarningState(), 0.0
        else:
            rec["warning"] = _timed(rec, "warning", self.warning.update, rec["states"], rec["risk"], rec["frame"].t)
        return rec

    @property
    def steps(self) -> list[Callable[[dict], dict]]:
        horizon = [self._horizon] if self.horizon is not None else []
        return [self._detect, self._ego_speed, *horizon, self._track, self._state, self._risk, self._warn]

    def process(self, frame: Frame) -> FrameResult:
        """Run every stage on one frame."""
        t0 = time.perf_counter()
        rec = _new_record(frame)
        for step in self.steps:
            rec = step(rec)
        rec["timings"]["total"] = (time.perf_counter() - t0) * 1e3
        return _result(rec)


_TAKES_EGO_SPEED: dict[type, bool] = {}
_TAKES: dict[tuple[Any, str], bool] = {}


def _takes(method: Any, parameter: str) -> bool:
    """Does the bound ``method`` accept keyword ``parameter``? (cached per function)"""
    key = (getattr(method, "__func__", method), parameter)
    if key not in _TAKES:
        _TAKES[key] = registry.takes(method, parameter)
    return _TAKES[key]


def _takes_ego_speed(risk: Any) -> bool:
    """Does ``risk.assess`` accept an ``ego_speed`` keyword? (cached per class)"""
    cls = type(risk)
    if cls not in _TAKES_EGO_SPEED:
        _TAKES_EGO_SPEED[cls] = registry.takes(risk.assess, "ego_speed")
    return _TAKES_EGO_SPEED[cls]


def _timed(rec: dict, key: str, fn: Callable, *args: Any) -> Any:
    t0 = time.perf_counter()
    out = fn(*args)
    rec["timings"][key] = (time.perf_counter() - t0) * 1e3
    return out


def _new_record(frame: Frame) -> dict:
    return {"frame": frame, "timings": {}}


def _result(rec: dict) -> FrameResult:
    f = rec["frame"]
    return FrameResult(index=f.index, t=f.t, detections=rec["detections"], tracks=rec["tracks"],
                       states=rec["states"], risk=rec["risk"], ego_speed=rec["ego_speed"],
                       timings_ms=rec["timings"], warning=rec["warning"], horizon=rec.get("horizon"))


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
                if not put(queues[0], _new_record(frame)):
                    return
        except BaseException as e:  # noqa: BLE001 - handed to the caller
            put(queues[0], _Failure(e))
            return
        put(queues[0], _END)

    def worker(step: Callable[[dict], dict], q_in: queue.Queue, q_out: queue.Queue) -> None:
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
            t = item["timings"]
            t["total"] = sum(t.values())
            yield _result(item)
    finally:
        stop.set()
        for th in threads:
            th.join(timeout=1.0)
