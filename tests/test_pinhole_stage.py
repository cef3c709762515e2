"""The lane-marking stages on a distorted camera (monorarp.pipeline.pinhole_stage): run in the virtual pinhole view,
they read a barrel lens's frames as well as a pinhole camera's; read as a pinhole, they do not."""

from __future__ import annotations

import os

os.environ.setdefault("PYOPENGL_PLATFORM", "egl")

import numpy as np  # noqa: E402
import pytest  # noqa: E402

from harness.run.frame_feed import rendered_frames  # noqa: E402
from harness.world.scenario import parse_scenario  # noqa: E402
from monorarp.ego_speed.ground_track import GroundTrackEgoSpeed  # noqa: E402
from monorarp.horizon.stages import OnlineHorizon  # noqa: E402
from monorarp.pipeline.pinhole_stage import PinholeImageStage  # noqa: E402
from monorarp.pipeline.runner import Pipeline  # noqa: E402

BARREL = [-0.22, 0.05, 0.0008, -0.0005, 0.0]
N = 60


def _scenario(distortion):
    cam = {"width": 640, "height": 360, "hfov_deg": 70, "pitch_deg": 2.0}
    if distortion is not None:
        cam["distortion"] = distortion
    return parse_scenario({"name": "lens", "seed": 1, "fps": 15, "duration_s": 5.0, "camera": cam,
                           "road": {"lanes": 4}, "traffic": {"vehicles_count": 3},
                           "ego": {"lane": 1, "speed_mps": 25.0, "behaviour": "idm"}})


def _speed_errors(stage, frames):
    err = []
    for f, truth in frames:
        v = stage.update(f.image, f.t)
        if v is not None:
            err.append(abs(v - truth.ego.speed) / truth.ego.speed)
    return np.array(err)


@pytest.fixture(scope="module")
def lens():
    """The barrel lens camera and its rendered frames with truth (simple look, 640x360, 4 s)."""
    s = _scenario(BARREL)
    return s.camera.model(), list(rendered_frames(s, N))


def test_ego_speed_in_the_pinhole_view(lens):
    camera, frames = lens
    assert camera.distorted
    wrapped = _speed_errors(PinholeImageStage(GroundTrackEgoSpeed, camera, "ego_speed"), frames)
    as_pinhole = _speed_errors(GroundTrackEgoSpeed(camera.pinhole), frames)
    assert len(wrapped) >= N // 2
    assert np.median(wrapped) < 0.01                   # the pinhole camera's figure (0.4 % on highway_cruise)
    assert np.median(as_pinhole) > 2 * np.median(wrapped)


def test_online_horizon_row_is_the_real_cameras_ideal_row(lens):
    camera, frames = lens
    wrapped = PinholeImageStage(OnlineHorizon, camera, "horizon")
    rows = [wrapped.update(f.image, f.t) for f, _ in frames]
    measured = np.array([r.row for r in rows if r.source == "vanishing_point"])
    assert len(measured) >= N // 2
    assert abs(np.median(measured) - camera.horizon_row) < 1.0   # px, on the real camera's ideal rows
    naive = OnlineHorizon(camera.pinhole)
    raw = [naive.update(f.image, f.t) for f, _ in frames]
    raw_rows = np.array([r.row for r in raw if r.source == "vanishing_point"])
    assert len(raw_rows) == 0 or abs(np.median(raw_rows) - camera.horizon_row) > 2 * abs(
        np.median(measured) - camera.horizon_row)


def test_pipeline_builds_lane_stages_in_the_pinhole_view(lens):
    camera, frames = lens
    cfg = {"detector": {"name": "oracle"}, "ego_speed": {"name": "ground_track"}, "horizon": {"name": "online"}}
    p = Pipeline.from_config(cfg, camera)
    assert isinstance(p.ego_speed, PinholeImageStage) and isinstance(p.horizon, PinholeImageStage)
    assert p.ego_speed.camera.width > camera.width and not p.ego_speed.camera.distorted  # the canvas, a pinhole
    pin = Pipeline.from_config(cfg, camera.pinhole)
    assert isinstance(pin.ego_speed, GroundTrackEgoSpeed) and isinstance(pin.horizon, OnlineHorizon)
    with pytest.raises(ValueError, match="does not match the camera's 640x360"):
        p.ego_speed.update(np.zeros((10, 10, 3), np.uint8), 0.0)
