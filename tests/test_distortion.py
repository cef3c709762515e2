"""Lens distortion of the camera model (monorarp.core.distortion), against OpenCV's projectPoints / undistortPoints."""

from __future__ import annotations

import json
import math

import cv2
import numpy as np
import pytest

from monorarp.core.camera import CameraError, CameraModel
from monorarp.state.pinhole_view import pinhole_view

LENSES = [(-0.25, 0.07, 0.0, 0.0, 0.0), (-0.18, 0.03, 0.0012, -0.0008, -0.004), (0.12, -0.02, -0.001, 0.0015, 0.0),
          (0.0, 0.0, 0.002, 0.001, 0.0)]


def _camera(k=None, **kw):
    return CameraModel.from_fov(640, 360, 70.0, 1.3, math.radians(2.0), distortion=k or (0.0,) * 5, **kw)


def _pixels(cam, n=2000, seed=0):
    rng = np.random.default_rng(seed)
    return np.stack([rng.uniform(-0.5, cam.width - 0.5, n), rng.uniform(-0.5, cam.height - 0.5, n)], axis=1)


@pytest.mark.parametrize("k", LENSES)
def test_projection_matches_opencv(k):
    cam = _camera(k)
    rng = np.random.default_rng(1)
    ideal = np.stack([rng.uniform(-40, cam.width + 40, 2000), rng.uniform(-20, cam.height + 20, 2000)], axis=1)
    pts = np.concatenate([(ideal - [cam.cx, cam.cy]) / [cam.fx, cam.fy], np.ones((len(ideal), 1))], axis=1)
    pts *= rng.uniform(2.0, 80.0, (len(pts), 1))
    ref, _ = cv2.projectPoints(pts.reshape(-1, 1, 3), np.zeros(3), np.zeros(3), cam.K, np.array(k))
    assert np.abs(cam.project_cam(pts) - ref.reshape(-1, 2)).max() < 1e-6
    assert np.abs(cam.distort_pixels(ideal) - ref.reshape(-1, 2)).max() < 1e-6


@pytest.mark.parametrize("k", LENSES)
def test_undistort_matches_opencv_and_round_trips(k):
    cam = _camera(k)
    uv = _pixels(cam)
    ideal = cam.undistort_pixels(uv)
    crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 500, 1e-15)
    ref = cv2.undistortPoints(uv.reshape(-1, 1, 2), cam.K, np.array(k), None, None, cam.K, crit).reshape(-1, 2)
    assert np.abs(ideal - ref).max() < 1e-4
    assert np.abs(cam.distort_pixels(ideal) - uv).max() < 1e-3


def test_zero_distortion_is_the_pinhole_exactly():
    cam = _camera()
    assert not cam.distorted and cam.pinhole is cam
    rng = np.random.default_rng(2)
    p = rng.uniform([-5, -2, 2], [5, 2, 60], (500, 3))
    z = p[:, 2]
    old = np.stack([cam.fx * p[:, 0] / z + cam.cx, cam.fy * p[:, 1] / z + cam.cy], axis=-1)
    assert cam.project_cam(p).tobytes() == old.tobytes()
    u, v = _pixels(cam).T
    rays = cam.cam_to_ego(np.stack([(u - cam.cx) / cam.fx, (v - cam.cy) / cam.fy, np.ones_like(u)], axis=-1))
    with np.errstate(divide="ignore", invalid="ignore"):
        old_g = rays * np.where(-rays[:, 2] > 1e-12, cam.height_m / -rays[:, 2], np.nan)[:, None]
    assert np.array_equal(cam.ground_point_from_pixel(u, v), old_g, equal_nan=True)
    assert "distortion" not in cam.to_dict()


def test_ground_point_from_a_distorted_pixel():
    k = LENSES[1]
    cam = _camera(k)
    rng = np.random.default_rng(3)
    ground = np.stack([rng.uniform(-6, 6, 300), rng.uniform(4, 60, 300), np.full(300, -cam.height_m)], axis=1)
    uv, _ = cv2.projectPoints(cam.ego_to_cam(ground).reshape(-1, 1, 3), np.zeros(3), np.zeros(3), cam.K, np.array(k))
    uv = uv.reshape(-1, 2)
    inside = (uv[:, 0] > 0) & (uv[:, 0] < cam.width - 1) & (uv[:, 1] > 0) & (uv[:, 1] < cam.height - 1)
    back = cam.ground_point_from_pixel(uv[inside, 0], uv[inside, 1])
    assert inside.sum() > 100
    assert np.abs(back - ground[inside]).max() < 1e-6
    # the pinhole reading of the same pixels is off: the undistortion is what makes it right
    naive = cam.pinhole.ground_point_from_pixel(uv[inside, 0], uv[inside, 1])
    assert np.abs(naive - ground[inside]).max() > 0.5


def test_camera_file_round_trip_and_old_files(tmp_path):
    k = LENSES[1]
    cam = _camera(k)
    path = tmp_path / "camera.json"
    cam.save(path)
    assert json.loads(path.read_text())["distortion"] == list(k)
    assert CameraModel.load(path) == cam
    old = _camera().to_dict()                    # a file of before the key existed
    assert CameraModel.from_dict(old) == _camera()
    four = CameraModel.from_dict({**old, "distortion": [-0.2, 0.05, 0.0, 0.0]})
    assert four.distortion == (-0.2, 0.05, 0.0, 0.0, 0.0)
    assert CameraModel.from_dict({**old, "distortion": None}) == _camera()
    (tmp_path / "cam.yaml").write_text("width: 640\nheight: 360\nhfov_deg: 70\nheight_m: 1.3\n"
                                       "distortion: [-0.2, 0.05, 0.001, 0.0, 0.0]\n")
    assert CameraModel.load(tmp_path / "cam.yaml").distortion == (-0.2, 0.05, 0.001, 0.0, 0.0)


@pytest.mark.parametrize("value, words", [
    ([-0.4, 0.0, 0.0, 0.0, 0.0], "folds the image back"),
    ([0.0, 0.0, 0.3, 0.0, 0.0], "cannot be inverted"),
    ([-0.2, 0.0, 0.0], "distortion must be a list"),
    (["a", 0, 0, 0, 0], "distortion[0] must be a number"),
    ([float("nan"), 0, 0, 0, 0], "distortion[0] must be finite"),
    ("-0.2", "distortion must be a list"),
])
def test_impossible_lens_is_one_line(value, words):
    d = {**_camera().to_dict(), "distortion": value}
    with pytest.raises(CameraError) as e:
        CameraModel.from_dict(d, source="cam.json")
    msg = str(e.value)
    assert words in msg and "\n" not in msg and msg.startswith("cam.json")


def test_projection_far_outside_the_image_does_not_fold_back():
    cam = _camera(LENSES[0])
    x = np.linspace(0.0, 8.0, 400)              # along a ray direction, out to 83 deg off axis
    uv = cam.distort_pixels(np.stack([cam.cx + x * cam.fx, np.full_like(x, cam.cy)], axis=1))
    assert (np.diff(uv[:, 0]) > 0).all()
    back = cam.undistort_pixels(uv)
    assert np.abs(back[:, 0] - (cam.cx + x * cam.fx)).max() < 1e-6


def test_pinhole_view_recovers_a_pinhole_rectangle():
    """A rectangle of the pinhole image, distorted (densely, cv2.projectPoints), boxed: its inscribed box of the
    undistorted outline is the rectangle again."""
    for k in LENSES[:3]:
        cam = _camera(k)
        view = pinhole_view(cam, 4.0)
        for rect in ([40.0, 200.0, 150.0, 300.0], [300.0, 150.0, 340.0, 190.0], [480.0, 20.0, 600.0, 120.0]):
            x1, y1, x2, y2 = rect
            t = np.linspace(0, 1, 400)
            edge = np.concatenate([np.stack([x1 + (x2 - x1) * t, np.full_like(t, y)], 1) for y in (y1, y2)]
                                  + [np.stack([np.full_like(t, x), y1 + (y2 - y1) * t], 1) for x in (x1, x2)])
            pts = np.concatenate([(edge - [cam.cx, cam.cy]) / [cam.fx, cam.fy], np.ones((len(edge), 1))], axis=1)
            d, _ = cv2.projectPoints(pts.reshape(-1, 1, 3), np.zeros(3), np.zeros(3), cam.K, np.array(k))
            d = d.reshape(-1, 2)
            box = np.array([[d[:, 0].min(), d[:, 1].min(), d[:, 0].max(), d[:, 1].max()]])
            got = view.boxes(box)[0] + [view.x0, view.y0, view.x0, view.y0]
            assert np.abs(got - rect).max() < 0.05, (k, rect, got)
            assert view.camera.distortion == (0.0,) * 5 and view.camera.fx == cam.fx
