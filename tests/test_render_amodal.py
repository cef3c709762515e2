"""Amodal boxes (harness/render/amodal.py): each vehicle's box as if nothing hid it, clipped to the image."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from harness.render.amodal import clip_box, window_silhouette_boxes, window_silhouette_outline
from harness.simulation.simulator import simulate
from harness.world.ground_truth import frame_truth
from harness.world.scenario import Scenario


def _street(camera: dict | None = None) -> Scenario:
    return Scenario.model_validate({
        "name": "street", "seed": 4, "duration_s": 2.0, "fps": 5,
        "camera": {"width": 640, "height": 360, "hfov_deg": 70, **(camera or {})},
        "road": {"lanes": 2, "lane_width_m": 3.25, "shoulder_width_m": 2.3, "street": {"parked_per_100m": 14}},
        "traffic": {"vehicles_count": 6, "speed_range_mps": [8, 12]}, "ego": {"lane": 1, "speed_mps": 10.0}})


def _visible_box(mask: np.ndarray) -> np.ndarray:
    ys, xs = np.nonzero(mask)
    return np.array([xs.min() - 0.5, ys.min() - 0.5, xs.max() + 0.5, ys.max() + 0.5])


def test_window_silhouette_box_and_outline_agree_on_a_known_mask():
    codes = np.zeros((6, 8), np.uint32)
    codes[1:4, 2:5] = 1
    codes[5, 7] = 2
    boxes = window_silhouette_boxes(codes, x0=10, y0=20, scale=2, n_members=2)
    assert np.allclose(boxes[0], [10 + 4 - 0.5, 20 + 2 - 0.5, 10 + 10 - 0.5, 20 + 8 - 0.5])
    assert np.allclose(boxes[1], [10 + 14 - 0.5, 20 + 10 - 0.5, 10 + 16 - 0.5, 20 + 12 - 0.5])
    pts = window_silhouette_outline(codes, 0, 10, 20, 2)
    assert np.allclose(np.r_[pts.min(0), pts.max(0)], boxes[0])
    assert clip_box(np.array([-5.0, 2.0, 3.0, 9.0]), 4, 4) is not None
    assert clip_box(np.array([-9.0, 2.0, -1.0, 9.0]), 4, 4) is None


@pytest.mark.parametrize("camera", [None, {"distortion": [-0.25, 0.05, 0.0, 0.0, 0.0]}])
def test_amodal_boxes_hold_the_visible_pixels_and_lie_in_the_projected_3d_box(camera):
    """Each amodal box contains the vehicle's visible pixels and lies inside the cv2.projectPoints box of its
    3-D corners (with the lens's distortion coefficients), clipped to the image; the hidden parked cars get a
    box larger than their visible part. Turning the boxes on changes no pixel."""
    from harness.render.renderer import Renderer

    sc = _street(camera)
    world = list(simulate(sc, 1))[0]
    cam = sc.camera.model()
    with Renderer(sc) as r:
        plain = r.render(world)
        r.amodal = True
        fr = r.render(world)
    assert np.array_equal(plain.image, fr.image) and np.array_equal(plain.id_mask, fr.id_mask)
    assert plain.amodal_boxes == {}
    truth = {o.id: o for o in frame_truth(world, cam, fr).objects}
    k = np.array([[cam.fx, 0, cam.cx], [0, cam.fy, cam.cy], [0, 0, 1]], float)
    dist = None if camera is None else np.array(camera["distortion"], float)
    grown = 0
    tol = 1e-9 if camera is None else 1.0     # a lens resamples the id pass to the nearest canvas pixel
    for vid in np.unique(fr.id_mask[fr.id_mask >= 0]):
        vis = _visible_box(fr.id_mask == vid)
        box = fr.amodal_boxes.get(int(vid), vis)
        assert np.all(box[:2] <= vis[:2] + tol) and np.all(box[2:] >= vis[2:] - tol)
        corners = np.array(truth[int(vid)].corners_cam, float)
        if corners[:, 2].min() < 0.5:
            continue
        px, _ = cv2.projectPoints(corners, np.zeros(3), np.zeros(3), k, dist)
        px = px.reshape(-1, 2)
        proj = clip_box(np.r_[px.min(0), px.max(0)], cam.width, cam.height)
        assert np.all(box[:2] >= proj[:2] - 1 - tol) and np.all(box[2:] <= proj[2:] + 1 + tol), (vid, box, proj)
        grown += bool(np.any(np.abs(box - vis) > 2.0))
    assert grown >= 2
