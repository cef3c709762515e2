"""Pipeline runners: threaded and synchronous give identical outputs; timings; errors propagate."""

from __future__ import annotations

import threading

import numpy as np
import pytest

from monorarp.core.camera import CameraModel
from monorarp.pipeline.config import PipelineConfig
from monorarp.pipeline.runner import Pipeline, run_sync, run_threaded
from monorarp.pipeline import registry
from monorarp.risk.estimators import TTCRiskEstimator
from monorarp.state.estimator import StateEstimator
from monorarp.tracking.particle import ParticleTracker
from monorarp.core.types import Detection, Frame, RiskEstimate

CAM = CameraModel.from_fov(320, 180, 60.0, 1.3)


class FakeDetector:
    """Two vehicles from the frame index (encoded in the image's first pixel), with seeded jitter."""

    def __init__(self, fail_at: int | None = None) -> None:
        self.fail_at = fail_at

    def detect(self, image: np.ndarray) -> list[Detection]:
        k = int(image[0, 0, 0])
        if k == self.fail_at:
            raise RuntimeError(f"detector failed on frame {k}")
        rng = np.random.default_rng(k)
        ahead = 30.0 - 0.2 * k
        v_b = CAM.horizon_row + CAM.fy * CAM.height_m / (ahead + 0.95)
        w = CAM.fx * 1.8 / ahead
        boxes = [(CAM.cx - w / 2, v_b - w * 0.8, CAM.cx + w / 2, v_b),
                 (60.0 + k, 100.0, 100.0 + k, 130.0)]
        dets = [Detection(tuple(np.array(b) + rng.normal(0, 0.3, 4)), 0.9) for b in boxes]
        return dets if k % 7 != 3 else dets[:1]           # some misses, so tracks coast


def frames(n: int):
    for k in range(n):
        img = np.zeros((CAM.height, CAM.width, 3), np.uint8)
        img[0, 0, 0] = k
        yield Frame(index=k, t=k / 30.0, image=img)


def make(detector=None, tracker=None) -> Pipeline:
    return Pipeline(detector or FakeDetector(), tracker or ParticleTracker(seed=1), StateEstimator(CAM),
                    TTCRiskEstimator())


def strip(r):
    return (r.index, r.t, r.detections, r.tracks, r.states, r.risk, r.ego_speed)


def test_threaded_equals_sync():
    sync = list(run_sync(make(), frames(40)))
    threaded = list(run_threaded(make(), frames(40), queue_size=2))
    assert [r.index for r in threaded] == list(range(40))
    assert [strip(r) for r in threaded] == [strip(r) for r in sync]
    assert any(r.states for r in sync) and any(r.risk.risk > 0 for r in sync)   # the comparison is not vacuous


def test_timings_recorded():
    for runner in (run_sync, run_threaded):
        for r in runner(make(), frames(5)):
            assert set(r.timings_ms) == {"detector", "ego_speed", "tracker", "state", "risk", "warning", "total"}
            assert all(v >= 0 for v in r.timings_ms.values())
            assert r.timings_ms["total"] >= r.timings_ms["tracker"]


class Boom(ParticleTracker):
    def update(self, image, detections, t):
        if t > 4 / 30.0:
            raise ValueError("tracker exploded")
        return super().update(image, detections, t)


@pytest.mark.parametrize("pipe, exc", [(lambda: make(tracker=Boom()), ValueError),
                                       (lambda: make(detector=FakeDetector(fail_at=6)), RuntimeError)])
def test_stage_exception_propagates(pipe, exc):
    before = threading.active_count()
    with pytest.raises(exc):
        list(run_threaded(pipe(), frames(50)))
    with pytest.raises(exc):
        list(run_sync(pipe(), frames(50)))
    assert threading.active_count() <= before


def test_source_exception_propagates():
    def bad():
        yield from frames(3)
        raise OSError("video ended badly")
    with pytest.raises(OSError):
        list(run_threaded(make(), bad()))


def test_early_close_stops_threads():
    before = threading.active_count()
    it = run_threaded(make(), frames(200), queue_size=1)
    assert next(it).index == 0
    it.close()
    assert threading.active_count() <= before


def test_from_config_builds_through_registry(request):
    registry.add("detector", "_test_fake", FakeDetector)
    request.addfinalizer(lambda: registry.remove("detector", "_test_fake"))
    cfg = PipelineConfig.model_validate({"detector": {"name": "_test_fake"},
                                         "state": {"name": "geometric", "kwargs": {"velocity": "difference"}}})
    p = Pipeline.from_config(cfg, CAM)
    assert isinstance(p.tracker, ParticleTracker) and p.state.config.velocity == "difference"
    assert isinstance(p.risk, TTCRiskEstimator)
    r = p.process(next(frames(1)))
    assert r.index == 0 and len(r.detections) == 2
    with pytest.raises(Exception):
        PipelineConfig.model_validate({"detector": {"name": "x"}, "trackerr": {"name": "particle"}})


class FakeEgoSpeed:
    def update(self, image, t):
        return 20.0 + t


def test_ego_speed_stage_runs_in_both_runners():
    def build():
        p = make()
        p.ego_speed = FakeEgoSpeed()
        return p
    for runner in (run_sync, run_threaded):
        res = list(runner(build(), frames(4)))
        assert [r.ego_speed for r in res] == [20.0 + k / 30.0 for k in range(4)]


class RecordingRisk:
    """Risk stage that takes the ego speed: records what it got and returns it as the risk."""

    def __init__(self) -> None:
        self.got: list[tuple[float, float | None]] = []

    def assess(self, states, t, ego_speed=None):
        from monorarp.core.types import RiskEstimate

        self.got.append((t, ego_speed))
        return RiskEstimate(risk=0.0 if ego_speed is None else ego_speed, kind="probability")


class SlowEgoSpeed(FakeEgoSpeed):
    """None on the first frame (no estimate yet), then 20 + t, with a jittered delay."""

    def update(self, image, t):
        import time

        time.sleep(0.001 * (int(image[0, 0, 0]) % 3))
        return None if t == 0.0 else 20.0 + t


def test_risk_stage_gets_the_same_frames_ego_speed_in_both_runners():
    for runner in (run_sync, run_threaded):
        p = make()
        p.ego_speed, p.risk = SlowEgoSpeed(), RecordingRisk()
        res = list(runner(p, frames(12)))
        expected = [None] + [20.0 + k / 30.0 for k in range(1, 12)]
        assert [e for _, e in p.risk.got] == expected
        assert [r.risk.risk for r in res] == [0.0] + expected[1:]


def test_monte_carlo_threaded_equals_sync_with_ego_speed():
    from monorarp.risk.monte_carlo.estimator import MonteCarloRisk

    def build():
        p = make()
        p.ego_speed, p.risk = FakeEgoSpeed(), MonteCarloRisk(n_rollouts=50, seed=2)
        return p
    sync = list(run_sync(build(), frames(15)))
    threaded = list(run_threaded(build(), frames(15), queue_size=2))
    assert [strip(r) for r in sync] == [strip(r) for r in threaded]
    # The ego speed reaches it as the assess() argument (not its configured or fallback speed).
    p = build()
    list(run_sync(p, frames(3)))
    assert p.risk.ego_speed_source == "argument"


def test_ttc_risk_takes_the_ego_speed_and_ignores_it():
    with_speed = make()
    with_speed.ego_speed = FakeEgoSpeed()
    assert [strip(r)[:6] for r in run_sync(with_speed, frames(20))] == \
        [strip(r)[:6] for r in run_sync(make(), frames(20))]


def test_every_stage_is_called_with_the_uniform_keywords():
    """The state stage gets ``horizon=`` and the risk stage ``ego_speed=`` even without those stages."""
    calls = []

    class State:
        def update(self, tracks, t, *, horizon):
            calls.append(("horizon", horizon))
            return {}

    class Risk:
        def assess(self, states, t, *, ego_speed):
            calls.append(("ego_speed", ego_speed))
            return RiskEstimate(0.0)

    for runner in (run_sync, run_threaded):
        calls.clear()
        list(runner(Pipeline(FakeDetector(), ParticleTracker(seed=1), State(), Risk()), frames(2)))
        assert sorted(calls) == [("ego_speed", None)] * 2 + [("horizon", None)] * 2


class WeakDetector(FakeDetector):
    """FakeDetector plus one weak box per frame when asked for weak detections."""

    uses_weak_detections = True

    def detect(self, image: np.ndarray, weak: bool = False) -> list[Detection]:
        extra = [Detection((200.0, 90.0, 230.0, 110.0), 0.35, weak=True)]
        return super().detect(image) + (extra if weak else [])


class RecordingTracker:
    """Records what it is given; outputs nothing."""

    def __init__(self) -> None:
        self.given: list[list[Detection]] = []

    def reset(self) -> None:
        self.given = []

    def update(self, image, detections, t):
        self.given.append(list(detections))
        return []


class WeakRecordingTracker(RecordingTracker):
    uses_weak_detections = True


def test_weak_detections_reach_only_a_tracker_that_takes_them():
    for tracker, wants in ((RecordingTracker(), False), (WeakRecordingTracker(), True)):
        results = list(run_sync(make(WeakDetector(), tracker), frames(5)))
        assert all(any(d.weak for d in given) == wants for given in tracker.given)
        assert all(not any(d.weak for d in r.detections) and len(r.detections) >= 1 for r in results)
    plain = RecordingTracker()                         # a detector without weak detections is never asked
    list(run_sync(make(FakeDetector(), WeakRecordingTracker()), frames(3)))
    list(run_sync(make(FakeDetector(), plain), frames(3)))
    assert all(not any(d.weak for d in g) for g in plain.given)
