"""The frame feed (harness/run/frame_feed.py): truth bookkeeping, oracle hand-off, preload vs streaming."""

from __future__ import annotations

import numpy as np

from harness.world.truth import FrameTruth
from harness.run.frame_feed import FrameFeed, fits_in_memory, run_pipeline
from monorarp.core.camera import CameraModel
from monorarp.core.types import Frame

TRUTHS = [FrameTruth.from_json({"frame": i, "t": i / 10, "ego": {"speed": 20.0 + i}, "objects": []}) for i in range(3)]


def _source(events):
    for truth in TRUTHS:
        events.append(("made", truth.frame))
        yield Frame(index=truth.frame, t=truth.t, image=np.zeros((2, 2, 3), np.uint8)), truth


def _frames(events):
    return (frame for frame, _ in _source(events))


class _Pipeline:
    def __init__(self, events):
        self.events = events

    def reset(self):
        self.events.append(("reset",))

    def process(self, frame):
        self.events.append(("processed", frame.index))
        return frame


def test_truth_speed_and_oracle_before_the_frame_enters():
    events, speeds = [], {}
    feed = FrameFeed(_source(events), speeds, lambda image, truth: events.append(("recorded", truth.frame)),
                     lambda truth, image: events.append(("oracle", truth.frame)))
    for frame in feed.frames():
        events.append(("yielded", frame.index))
    assert events[:4] == [("made", 0), ("recorded", 0), ("oracle", 0), ("yielded", 0)]
    assert speeds == {0.0: 20.0, 0.1: 21.0, 0.2: 22.0}
    image, truth = feed.take(1)
    assert truth is TRUTHS[1] and 1 not in feed.images and 1 in feed.truths


def test_preload_takes_every_frame_first_and_reports_after():
    events = []
    results, wall = run_pipeline(_Pipeline(events), _frames(events), preload=True, threaded=False,
                                 on_result=lambda r: events.append(("result", r.index)))
    assert [r.index for r in results] == [0, 1, 2] and wall >= 0.0
    assert events[0] == ("reset",)
    assert [e[0] for e in events[1:]] == ["made"] * 3 + ["processed"] * 3 + ["result"] * 3


def test_streaming_reports_each_result_as_it_comes():
    events = []
    run_pipeline(_Pipeline(events), _frames(events), preload=False, threaded=False,
                 on_result=lambda r: events.append(("result", r.index)))
    assert events[1:4] == [("made", 0), ("processed", 0), ("result", 0)]


def test_fits_in_memory():
    cam = CameraModel.from_fov(100, 10, 70.0, 1.3, 0.0)
    assert fits_in_memory(10, cam, 100 * 10 * 3 * 10)
    assert not fits_in_memory(11, cam, 100 * 10 * 3 * 10)
