"""Detections reused across sweep runs (harness/run/detection_memo.py): computed once per image history,
identical outputs with and without reuse, the detector's own time reported."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

import harness.run.runner
from harness.world.scenario import parse_scenario
from harness.run.detection_memo import DetectionMemo, ReplayingDetector, detector_identity
from monorarp.core.camera import CameraModel
from monorarp.detection.centernet import CenterNetDetector
from monorarp.pipeline.config import ComponentConfig
from monorarp.core.types import Detection, FrameResult
from test_render_cache import SCENARIO as TINY

SCENARIO = {**TINY, "camera": {"width": 320, "height": 192}}    # the net's input size: vehicles big enough to detect
CAMERA = CameraModel(width=320, height=192, fx=300.0, fy=300.0, cx=159.5, cy=95.5, height_m=1.3)
SAME_BYTES = ("per_frame.csv", "per_object.csv", "ground_truth.jsonl", "camera.json")


class Counting:
    """A stateful detector: its box depends on the image and on how many frames it has seen since reset."""

    def __init__(self) -> None:
        self.calls = 0
        self.seen = 0

    def reset(self) -> None:
        self.seen = 0

    def detect(self, image: np.ndarray) -> list[Detection]:
        self.calls += 1
        self.seen += 1
        return [Detection((float(image.sum()), float(self.seen), 10.0, 20.0), 0.9)]


class Pipe:
    def __init__(self, detector) -> None:
        self.detector = detector


def images(*values: int) -> list[np.ndarray]:
    return [np.full((4, 6, 3), v, np.uint8) for v in values]


def replaying(memo: DetectionMemo, inner=None, config=ComponentConfig(name="counting")) -> ReplayingDetector:
    pipe = Pipe(inner or Counting())
    wrapped = memo.attach(pipe, config, CAMERA)
    assert wrapped is pipe.detector
    return wrapped


def test_same_history_computed_once_and_results_equal():
    memo = DetectionMemo()
    a, b = replaying(memo), replaying(memo)
    first = [a.detect(im) for im in images(1, 2, 3)]
    b.reset()
    second = [b.detect(im) for im in images(1, 2, 3)]
    assert second == first and a.inner.calls == 3 and b.inner.calls == 0


def test_different_history_is_computed_again():
    memo = DetectionMemo()
    a, b = replaying(memo), replaying(memo)
    for im in images(1, 2, 3):
        a.detect(im)
    b.reset()
    out = [b.detect(im) for im in images(9, 2, 3)]   # frames 2 and 3 are the same images after another first one
    assert b.inner.calls == 3
    assert [d[0].box[1] for d in out] == [1.0, 2.0, 3.0]


def test_identity_covers_config_and_camera():
    cfg = ComponentConfig(name="centernet", kwargs={"fovea_zoom": 2.0})
    base = detector_identity(cfg, CAMERA)
    assert detector_identity(ComponentConfig(name="centernet", kwargs={"fovea_zoom": 2.5}), CAMERA) != base
    assert detector_identity(cfg, replace(CAMERA, pitch_rad=0.03)) != base
    assert detector_identity(ComponentConfig(name="centernet", kwargs={"fovea_zoom": 2.0}), CAMERA) == base
    memo = DetectionMemo()
    a = replaying(memo, config=cfg)
    b = replaying(memo, config=ComponentConfig(name="centernet", kwargs={"fovea_zoom": 2.5}))
    for im in images(1, 2):
        a.detect(im)
        b.detect(im)
    assert a.inner.calls == 2 and b.inner.calls == 2


def test_truth_fed_detectors_are_not_wrapped():
    class Oracle(Counting):
        def set_truth(self, truth, image) -> None: ...

    pipe = Pipe(Oracle())
    assert DetectionMemo().attach(pipe, ComponentConfig(name="oracle"), CAMERA) is None
    assert isinstance(pipe.detector, Oracle)


def test_lru_bound():
    memo = DetectionMemo(max_frames=2)
    a = replaying(memo)
    for im in images(1, 2, 3):
        a.detect(im)
    assert len(memo) == 2


def test_restore_timings_reports_the_detectors_own_time():
    """Both runs report the time the detector took when it ran (not the lookup's); total and wall follow."""
    memo = DetectionMemo()
    a, b = replaying(memo), replaying(memo)
    a.detect(images(1)[0])
    b.detect(images(1)[0])
    ra, rb = (FrameResult(index=0, t=0.0, detections=[], tracks=[], states={}, risk=None,
                          timings_ms={"detector": ms, "tracker": 1.0, "total": ms + 2.0}) for ms in (50.0, 0.01))
    wa, wb = a.restore_timings([ra], 1.0), b.restore_timings([rb], 1.0)
    own = ra.timings_ms["detector"]
    assert rb.timings_ms["detector"] == own and 0 < own < 50.0
    assert np.isclose(ra.timings_ms["total"], own + 2.0) and np.isclose(rb.timings_ms["total"], own + 2.0)
    assert np.isclose(wa, 1.0 + (own - 50.0) / 1e3) and np.isclose(wb, 1.0 + (own - 0.01) / 1e3)


def run_dir(tmp: Path, name: str, tracker: str, memo: DetectionMemo | None) -> Path:
    out = tmp / name
    harness.run.runner.run_scenario(parse_scenario(SCENARIO), {"detector": {"name": "centernet"}, "tracker": {"name": tracker}},
                             n_frames=5, out_dir=out, annotate=False, write_frames=False, detections=memo)
    return out


def test_runs_with_reuse_write_the_same_files(tmp_path, monkeypatch):
    """Two variants through one memo: the second never runs the net, and both write what they write without it."""
    calls: list[int] = []
    real = CenterNetDetector.detect

    def counting(self, image, **kw):
        out = real(self, image, **kw)
        calls.append(len(out))
        return out

    monkeypatch.setattr(CenterNetDetector, "detect", counting)
    memo = DetectionMemo()
    reused = [run_dir(tmp_path, f"memo_{t}", t, memo) for t in ("particle", "sort")]
    assert len(calls) == 5 and sum(calls) > 0                  # the second run took the first one's detections
    fresh = [run_dir(tmp_path, f"fresh_{t}", t, None) for t in ("particle", "sort")]
    assert len(calls) == 15
    for a, b in zip(reused, fresh):
        for name in SAME_BYTES:
            assert (a / name).read_bytes() == (b / name).read_bytes(), name
