"""The run directory (harness/run/outputs.py): all or nothing, nothing at all without a directory."""

from __future__ import annotations

import json

import pytest

from harness.world.truth import FrameTruth
from harness.run.outputs import CAMERA_NAME, GROUND_TRUTH_NAME, METRICS_NAME, OUTPUT_NAMES, RunOutputs
from monorarp.core.camera import CameraModel

CAMERA = CameraModel.from_fov(64, 36, 70.0, 1.3, 0.0)
TRUTH = FrameTruth.from_json({"frame": 0, "t": 0.0, "ego": {"speed": 25.0}, "objects": []})


def test_without_a_directory_nothing_is_written(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    with RunOutputs(None, CAMERA, 15.0) as out:
        assert out.dir is None
        out.record_frame(None, TRUTH)
        out.write_scores({"frames": 1}, [], [])
    assert list(tmp_path.iterdir()) == []


def test_success_moves_the_directory_into_place(tmp_path):
    target = tmp_path / "run"
    with RunOutputs(target, CAMERA, 15.0, write_frames=False, annotate=False) as out:
        out.record_frame(None, TRUTH)
        out.write_scores({"frames": 1}, [], [])
        assert not target.exists()
    names = {p.name for p in target.iterdir()}
    assert names <= set(OUTPUT_NAMES)
    assert {CAMERA_NAME, GROUND_TRUTH_NAME, METRICS_NAME} <= names
    assert json.loads((target / GROUND_TRUTH_NAME).read_text()) == TRUTH.to_json()
    assert json.loads((target / CAMERA_NAME).read_text())["width"] == 64


def test_failure_leaves_nothing(tmp_path):
    target = tmp_path / "run"
    with pytest.raises(RuntimeError), RunOutputs(target, CAMERA, 15.0, write_frames=False, annotate=False) as out:
        out.record_frame(None, TRUTH)
        raise RuntimeError("boom")
    assert not target.exists()
    assert list(tmp_path.iterdir()) == []
