"""`monorarp calibrate`: the camera estimated from synthetic lane markings drawn with a known camera."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from monorarp.app.cli import main
from monorarp.core.camera import CameraModel
from monorarp.horizon.calibration import CalibrationError, autocorrelation, calibrate, dash_period

LANE_W, STRIPE, PERIOD = 4.0, 3.05, 12.19


def _quad(cam: CameraModel, x0: float, x1: float, y0: float, y1: float) -> np.ndarray:
    pts = np.array([[x0, y0, -cam.height_m], [x1, y0, -cam.height_m], [x1, y1, -cam.height_m],
                    [x0, y1, -cam.height_m]])
    return np.round(cam.project_ego(pts) * 16).astype(np.int32)   # 4 fractional bits


def road_frame(cam: CameraModel, travelled_m: float) -> np.ndarray:
    """Grey asphalt with the ego lane's dashed lines at +-W/2 and solid lines a lane further out."""
    img = np.full((cam.height, cam.width, 3), 90, np.uint8)
    half = 0.075
    polys = []
    for x in (-1.5 * LANE_W, 1.5 * LANE_W):
        polys.append(_quad(cam, x - half, x + half, 2.0, 200.0))
    first = -(travelled_m % PERIOD)
    for x in (-0.5 * LANE_W, 0.5 * LANE_W):
        for k in range(20):
            y0 = first + k * PERIOD
            y1 = y0 + STRIPE
            if y1 > 2.0:
                polys.append(_quad(cam, x - half, x + half, max(y0, 2.0), y1))
    cv2.fillPoly(img, polys, (230, 230, 230), lineType=cv2.LINE_AA, shift=4)
    return img


def frames(cam: CameraModel, n: int = 40, step_m: float = 1.7) -> list[np.ndarray]:
    return [road_frame(cam, i * step_m) for i in range(n)]


CAMERAS = [CameraModel.from_fov(640, 360, 70.0, 1.3, math.radians(2.0)),
           CameraModel.from_fov(800, 450, 50.0, 1.7, math.radians(-1.0))]


@pytest.mark.parametrize("cam", CAMERAS, ids=["70deg-1.3m", "50deg-1.7m"])
def test_known_camera_recovered(cam: CameraModel) -> None:
    est = calibrate(frames(cam), lane_width_m=LANE_W)
    assert abs(est.focal_px.value / cam.fx - 1) < 0.05
    assert abs(est.horizon_row.value - cam.horizon_row) < 3.0
    assert abs(est.height_m.value / cam.height_m - 1) < 0.03
    assert 0 < est.focal_px.sigma < 0.05 * cam.fx


def test_height_given_measures_lane_width() -> None:
    cam = CAMERAS[0]
    est = calibrate(frames(cam), height_m=cam.height_m)
    assert est.height_given and est.height_m.value == cam.height_m
    assert abs(est.lane_width_m.value - LANE_W) < 0.12
    assert abs(est.focal_px.value / cam.fx - 1) < 0.05


def test_wrong_period_scales_the_focal_length() -> None:
    """The focal length is proportional to the stated stripe period (the only longitudinal scale; the pitch
    correction cos(pitch) moves it by < 1 %)."""
    cam = CAMERAS[0]
    imgs = frames(cam)
    a = calibrate(imgs, lane_width_m=LANE_W).focal_px.value
    b = calibrate(imgs, lane_width_m=LANE_W, stripe_period_m=2 * PERIOD).focal_px.value
    assert b / a == pytest.approx(2.0, rel=0.01)


def test_dash_period_of_a_square_wave_and_none_for_a_constant() -> None:
    x = ((np.arange(600) % 80) < 20).astype(float)
    assert dash_period(autocorrelation(x)) == pytest.approx(80, abs=0.5)
    assert dash_period(autocorrelation(np.ones(600) + 0.01 * np.linspace(0, 1, 600) ** 3)) is None


def test_solid_lines_only_refused() -> None:
    cam = CAMERAS[0]
    img = np.full((cam.height, cam.width, 3), 90, np.uint8)
    quads = [_quad(cam, x - 0.075, x + 0.075, 2.0, 200.0) for x in (-2.0, 2.0, -6.0, 6.0)]
    cv2.fillPoly(img, quads, (230, 230, 230), lineType=cv2.LINE_AA, shift=4)
    with pytest.raises(CalibrationError, match="dashed"):
        calibrate([img] * 20, lane_width_m=LANE_W)


def _write_video(path, imgs) -> None:
    h, w = imgs[0].shape[:2]
    out = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), 15.0, (w, h))
    for im in imgs:
        out.write(im)
    out.release()


def test_cli_writes_a_camera_file_video_reads(tmp_path, capsys) -> None:
    cam = CAMERAS[0]
    video = tmp_path / "clip.mp4"
    _write_video(video, frames(cam))
    out = tmp_path / "cam.yaml"
    assert main(["calibrate", str(video), "--out", str(out), "--lane-width", "4"]) == 0
    printed = capsys.readouterr().out
    assert "focal length" in printed and "horizon row" in printed and "+-" in printed
    got = CameraModel.load(out)
    assert abs(got.fx / cam.fx - 1) < 0.05
    assert abs(got.horizon_row - cam.horizon_row) < 3.0
    assert abs(got.height_m / cam.height_m - 1) < 0.03


def test_uniform_video_one_line_exit_2_nothing_written(tmp_path, capsys) -> None:
    video = tmp_path / "grey.mp4"
    _write_video(video, [np.full((360, 640, 3), 120, np.uint8)] * 10)
    out = tmp_path / "cam.yaml"
    assert main(["calibrate", str(video), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "lane" in err and "Traceback" not in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["grey.mp4"]
