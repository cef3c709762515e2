"""Renderer: determinism, camera pose (horizon), lane markings and silhouettes where
cv2.projectPoints puts them, pixel-centre convention, sensor noise/blur switches."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from harness.world.geometry import vehicle_pose_world
from harness.render.meshes import vehicle_trimesh
from harness.render.renderer import Renderer
from harness.render.shading import SKY_RGB
from harness.world.scenario import parse_scenario
from harness.world.state import VehicleState, WorldState

LANE_W = 3.7


def _scenario(**render):
    return parse_scenario({
        "name": "r", "seed": 11,
        "road": {"lanes": 3, "lane_width_m": LANE_W, "markings": {"stripe_length_m": 3.0, "period_m": 12.0, "width_m": 0.3}},
        "camera": {"width": 320, "height": 180, "hfov_deg": 70, "height_m": 1.4, "pitch_deg": 3.0,
                   "forward_offset_m": 0.5, "lateral_offset_m": 0.0},
        "render": render,
    })


EGO = VehicleState(0, 100.0, LANE_W, 0.0, 25.0, 25.0, 0.0, 1, 5.0, 2.0)
CARS = (VehicleState(1, 118.0, LANE_W, 0.0, 20.0, 20.0, 0.0, 1, 4.6, 1.9),
        VehicleState(2, 125.0, 0.0, 0.02, 22.0, 22.0, 0.4, 0, 4.4, 1.8),
        VehicleState(3, 150.0, 2 * LANE_W, 0.0, 22.0, 22.0, 0.0, 2, 12.0, 2.5))


@pytest.fixture(scope="module")
def renderer():
    with Renderer(_scenario()) as r:
        yield r


def _world(vehicles=CARS, frame=4):
    return WorldState(frame, frame / 15, EGO, tuple(vehicles))


def _ego_to_pixel(cam, p_ego):
    uv, _ = cv2.projectPoints(cam.ego_to_cam(np.asarray(p_ego, float)).reshape(-1, 1, 3),
                              np.zeros(3), np.zeros(3), cam.K, None)
    return uv.reshape(-1, 2)


def test_deterministic(renderer):
    a = renderer.render(_world())
    b = renderer.render(_world())
    with Renderer(_scenario()) as other:
        c = other.render(_world())
    for f in (b, c):
        assert f.image.tobytes() == a.image.tobytes()
        assert np.array_equal(f.id_mask, a.id_mask)
        assert f.full_pixels == a.full_pixels
    assert a.image.shape == (180, 320, 3) and a.image.dtype == np.uint8
    assert a.id_mask.dtype == np.int32 and set(np.unique(a.id_mask)) <= {-1, 1, 2, 3}


def test_sky_above_horizon_road_below(renderer):
    frame = renderer.render(_world(vehicles=()))
    cam = renderer.camera
    col = cam.width // 2
    sky_bgr = np.round(np.array(SKY_RGB[::-1]) * 255)
    column = frame.image[:, col].astype(int)
    is_sky = np.abs(column - sky_bgr).max(axis=1) <= 2
    h = cam.horizon_row
    assert is_sky[: math.floor(h - 1) + 1].all()
    assert not is_sky[math.ceil(h + 1):].any()
    below = column[math.ceil(h + 1):]
    # Road surface: grey (channels within a few levels of each other).
    assert (np.ptp(below[-40:], axis=1) <= 6).all()
    assert (frame.id_mask == -1).all()


def test_dashed_marking_where_projected(renderer):
    frame = renderer.render(_world(vehicles=()))
    cam = renderer.camera
    gray = cv2.cvtColor(frame.image, cv2.COLOR_BGR2GRAY).astype(int)
    cam_x = EGO.x + cam.forward_offset_m
    for boundary_y in (0.5 * LANE_W, 1.5 * LANE_W):       # left and right lines of the ego lane
        for k in (9, 10):                                  # stripes starting at x = 108, 120 m
            stripe_mid = k * 12.0 + 1.5
            gap_mid = k * 12.0 + 7.5
            pts = [[boundary_y - EGO.y, x - cam_x, -cam.height_m] for x in (stripe_mid, gap_mid)]
            (us, vs), (ug, vg) = _ego_to_pixel(cam, pts)
            assert gray[round(vs), round(us)] > 170, (boundary_y, k)
            assert gray[round(vg), round(ug)] < 110, (boundary_y, k)


def test_silhouette_pixel_centres_match_opencv(renderer):
    """The first/last covered column and row of each silhouette = ceil/floor of the extreme
    projected mesh vertex (pixel centres at integer coordinates, OpenCV convention)."""
    frame = renderer.render(_world())
    cam = renderer.camera
    checked = 0
    for v in CARS:
        tm = vehicle_trimesh(v.length, v.width, (0, 0, 0))
        pose = vehicle_pose_world(v)
        pw = tm.vertices @ pose[:3, :3].T + pose[:3, 3]           # world W: Y = -road y
        cam_x, cam_y = EGO.x + cam.forward_offset_m, EGO.y
        p_ego = np.stack([-pw[:, 1] - cam_y, pw[:, 0] - cam_x, pw[:, 2] - cam.height_m], axis=1)
        uv = _ego_to_pixel(cam, p_ego)
        rows, cols = np.nonzero(frame.id_mask == v.id)
        for value, got, rnd in ((uv[:, 0].min(), cols.min(), math.ceil), (uv[:, 0].max(), cols.max(), math.floor),
                                (uv[:, 1].min(), rows.min(), math.ceil), (uv[:, 1].max(), rows.max(), math.floor)):
            if abs(value - round(value)) > 0.05:                    # unambiguous
                assert got == rnd(value), (v.id, value, got)
                checked += 1
    assert checked >= 8


def test_noise_and_blur_only_when_enabled():
    world = _world()
    with Renderer(_scenario()) as plain_r:
        plain = plain_r.render(world)
    with Renderer(_scenario(noise_std=4.0)) as noisy_r:
        n1, n2 = noisy_r.render(world), noisy_r.render(world)
        n_next = noisy_r.render(_world(frame=5))
    with Renderer(_scenario(blur_px=1.5)) as blur_r:
        blurred = blur_r.render(world)
    assert n1.image.tobytes() == n2.image.tobytes()                 # seeded per frame
    assert n1.image.tobytes() != plain.image.tobytes()
    diff = n1.image.astype(float) - plain.image.astype(float)
    assert 2.5 < diff.std() < 5.5
    assert not np.array_equal(n_next.image - n1.image, np.zeros_like(n1.image))
    assert blurred.image.tobytes() != plain.image.tobytes()
    assert np.abs(cv2.Laplacian(blurred.image, cv2.CV_64F)).mean() < np.abs(cv2.Laplacian(plain.image, cv2.CV_64F)).mean()
    for f in (n1, blurred):
        assert np.array_equal(f.id_mask, plain.id_mask)
