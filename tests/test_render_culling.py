"""The realistic look's speed-ups change nothing: view culling (checked against cv2.projectPoints), the id
pass limited to a region, and the renderer with its culling switched off giving the same frames and truth."""

from __future__ import annotations

import dataclasses

import cv2
import numpy as np
import pytest

from harness.render import visibility
from harness.render.renderer import Renderer, _seg_colour
from harness.world.scenario import parse_scenario
from harness.world.state import VehicleState, WorldState
from monorarp.core.camera import CameraModel

LANE_W = 3.6
CAM = CameraModel(320, 180, 250.0, 250.0, 159.5, 89.5, 1.4)
EGO = VehicleState(0, 100.0, LANE_W, 0.0, 25.0, 25.0, 0.0, 1, 5.0, 2.0)
CARS = (VehicleState(1, 118.0, LANE_W, 0.0, 20.0, 20.0, 0.0, 1, 4.6, 1.9),
        VehicleState(2, 103.0, 0.0, 0.0, 22.0, 22.0, 0.0, 0, 4.4, 1.8),        # beside: cut by the border
        VehicleState(3, 150.0, 2 * LANE_W, 0.0, 22.0, 22.0, 0.2, 2, 12.0, 2.5))


def _scenario(look="realistic", **camera):
    return parse_scenario({"name": "cull", "seed": 5, "road": {"lanes": 3, "lane_width_m": LANE_W},
                           "camera": {"width": 320, "height": 180, "hfov_deg": 70, **camera},
                           "render": {"look": look}})


def _lands_inside(points_cam: np.ndarray, camera: CameraModel, znear: float) -> np.ndarray:
    """(N,) bool: points (camera frame, OpenCV) in front of ``znear`` projecting inside the image."""
    front = points_cam[:, 2] > znear
    uv = np.full((len(points_cam), 2), -1e9)
    if front.any():
        uv[front] = cv2.projectPoints(points_cam[front].reshape(-1, 1, 3), np.zeros(3), np.zeros(3), camera.K,
                                      None)[0].reshape(-1, 2)
    return front & (uv[:, 0] >= -0.5) & (uv[:, 0] <= camera.width - 0.5) & (uv[:, 1] >= -0.5) \
        & (uv[:, 1] <= camera.height - 0.5)


def test_box_corners_are_the_eight_min_max_combinations():
    c = visibility.box_corners(np.array([[[0.0, 1.0, 2.0], [3.0, 5.0, 7.0]]]))[0]
    assert c.shape == (8, 3)
    assert {tuple(p) for p in c} == {(x, y, z) for x in (0, 3) for y in (1, 5) for z in (2, 7)}


def test_outside_view_never_culls_a_box_with_a_point_in_the_image():
    rng = np.random.default_rng(0)
    lo = rng.uniform([-60, -20, -30], [60, 20, 80], (400, 3))
    boxes = np.stack([lo, lo + rng.uniform(0.2, 15.0, (400, 3))], axis=1)             # (N, 2, 3)
    out = visibility.outside_view(visibility.box_corners(boxes), CAM, 0.05, margin=0.0)
    assert 0.2 < out.mean() < 0.9                                                      # both kinds are tested
    t = rng.uniform(size=(400, 3000, 3))
    pts = boxes[:, None, 0] + t * (boxes[:, None, 1] - boxes[:, None, 0])              # points inside each box
    seen = np.array([_lands_inside(p, CAM, 0.05).any() for p in pts])
    assert not (out & seen).any()                                                      # culled: nothing seen
    # a box straddling the camera (corners behind it) but reaching into the view is kept
    assert not visibility.outside_view(visibility.box_corners(np.array([[[-1, -1, -5], [1, 1, 30]]])), CAM, 0.05)[0]
    # behind the camera, or wholly beyond one side plane: culled
    assert visibility.outside_view(visibility.box_corners(np.array([[[-50, -5, -40], [50, 5, -1]]])), CAM, 0.05)[0]
    assert visibility.outside_view(visibility.box_corners(np.array([[[40, -5, 10], [60, 5, 20]]])), CAM, 0.05)[0]


def test_id_pass_in_a_region_is_the_whole_pass_there_and_zero_elsewhere():
    with Renderer(_scenario("simple")) as r:
        r.render(WorldState(3, 0.2, EGO, CARS))
        seg = {e.node: _seg_colour(vid + 1) for vid, e in r._vehicles.items() if e.node.mesh.is_visible}
        with r._gl():
            r._passes.update(r._scene)
            whole = r._passes.ids(r._scene, 320, 180, seg)[::-1].copy()
            part = r._passes.ids(r._scene, 320, 180, seg, region=(100, 40, 250, 170))[::-1]
            empty = r._passes.ids(r._scene, 320, 180, seg, region=(50, 50, 50, 90))
    assert whole[40:170, 100:250].any()
    assert np.array_equal(part[40:170, 100:250], whole[40:170, 100:250])
    part[40:170, 100:250] = 0
    assert not part.any() and not empty.any()


@pytest.mark.parametrize("camera", [{}, {"distortion": [-0.3, 0.1, 0.0, 0.0, 0.0]}])
def test_culling_changes_no_pixel_and_no_truth(camera, monkeypatch):
    worlds = [WorldState(k, k / 15, dataclasses.replace(EGO, x=EGO.x + 2.0 * k), CARS) for k in range(3)]
    with Renderer(_scenario(**camera)) as r:
        got = [r.render(w) for w in worlds]
        n_drawn = sum(n.mesh.is_visible for n in r._scene.mesh_nodes)
    monkeypatch.setattr(Renderer, "_cull_outside_view", lambda self, cam_pose, c: None)
    with Renderer(_scenario(**camera)) as r:
        want = [r.render(w) for w in worlds]
        n_all = sum(n.mesh.is_visible for n in r._scene.mesh_nodes)
    assert n_drawn < n_all                                                      # something was culled
    for a, b in zip(got, want):
        assert np.array_equal(a.image, b.image)
        assert np.array_equal(a.id_mask, b.id_mask)
        assert a.full_pixels == b.full_pixels
