"""A distorted scenario camera end to end: the renderer's warped frames and truth, and the pipeline's distances."""

from __future__ import annotations

import os
from pathlib import Path

os.environ.setdefault("PYOPENGL_PLATFORM", "egl")

import cv2  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402
import yaml  # noqa: E402

from harness.render.distortion import LensError, lens_warp  # noqa: E402
from harness.render.meshes import vehicle_trimesh  # noqa: E402
from harness.render.renderer import Renderer  # noqa: E402
from harness.world.geometry import vehicle_pose_world  # noqa: E402
from harness.world.ground_truth import frame_truth  # noqa: E402
from harness.world.scenario import parse_scenario  # noqa: E402
from harness.world.state import VehicleState, WorldState  # noqa: E402
from monorarp.core.boxes import iou  # noqa: E402
from monorarp.core.camera import CameraModel  # noqa: E402

BARREL = [-0.22, 0.05, 0.0008, -0.0005, 0.0]
LANE_W = 3.7
EGO = VehicleState(0, 100.0, LANE_W, 0.0, 25.0, 25.0, 0.0, 1, 5.0, 2.0)
CARS = (VehicleState(1, 118.0, LANE_W, 0.0, 20.0, 20.0, 0.0, 1, 4.6, 1.9),
        VehicleState(2, 108.0, 0.0, 0.02, 22.0, 22.0, 0.4, 0, 4.4, 1.8),        # near, left: far off axis
        VehicleState(3, 111.0, 2 * LANE_W, 0.0, 22.0, 22.0, 0.0, 2, 12.0, 2.5),  # a truck, near, right
        VehicleState(4, 150.0, 2 * LANE_W, 0.0, 22.0, 22.0, 0.0, 2, 4.5, 1.8))
EDGES = [(0, 1), (1, 2), (2, 3), (3, 0), (4, 5), (5, 6), (6, 7), (7, 4), (0, 4), (1, 5), (2, 6), (3, 7)]


def _scenario(distortion=None, **extra):
    cam = {"width": 320, "height": 180, "hfov_deg": 70, "height_m": 1.4, "pitch_deg": 3.0, "forward_offset_m": 0.5}
    if distortion is not None:
        cam["distortion"] = distortion
    return parse_scenario({"name": "lens", "seed": 11, "camera": cam, **extra,
                           "road": {"lanes": 3, "lane_width_m": LANE_W,
                                    "markings": {"stripe_length_m": 3.0, "period_m": 12.0, "width_m": 0.3}}})


def _project(cam, pts_cam):
    uv, _ = cv2.projectPoints(np.asarray(pts_cam, float).reshape(-1, 1, 3), np.zeros(3), np.zeros(3), cam.K,
                              np.array(cam.distortion))
    return uv.reshape(-1, 2)


def _dense_edges(p, pairs, n=80):
    t = np.linspace(0.0, 1.0, n)[None, :, None]
    a, b = p[[i for i, _ in pairs]], p[[j for _, j in pairs]]
    return (a[:, None] * (1 - t) + b[:, None] * t).reshape(-1, 3)


@pytest.fixture(scope="module")
def frames():
    world = WorldState(4, 4 / 15, EGO, CARS)
    out = {}
    for name, k in (("pinhole", None), ("barrel", BARREL)):
        with Renderer(_scenario(k)) as r:
            fr = r.render(world)
            out[name] = (r.camera, fr, frame_truth(world, r.camera, fr))
    return out


def test_truth_boxes_are_the_distorted_projection(frames):
    """Each id-mask box against cv2.projectPoints (with the distortion) of the vehicle: its mesh's edges,
    densely, within a pixel; the projection of its 3-D box's edges (the truth's corners) holds it."""
    cam, fr, truth = frames["barrel"]
    assert fr.image.shape == (180, 320, 3) and fr.id_mask.shape == (180, 320)
    by_id = {v.id: v for v in CARS}
    checked, pinhole_miss = 0, 0.0
    for o in truth.objects:
        v = by_id[o.id]
        tm = vehicle_trimesh(v.length, v.width, (0, 0, 0))
        pose = vehicle_pose_world(v)
        pw = _dense_edges(tm.vertices, tm.edges_unique.tolist()) @ pose[:3, :3].T + pose[:3, 3]
        p_ego = np.stack([-pw[:, 1] - EGO.y, pw[:, 0] - (EGO.x + cam.forward_offset_m), pw[:, 2] - cam.height_m], 1)
        uv = _project(cam, cam.ego_to_cam(p_ego))
        ext = np.array([uv[:, 0].min(), uv[:, 1].min(), uv[:, 0].max(), uv[:, 1].max()])
        clipped = np.clip(ext, -0.5, [cam.width - 0.5, cam.height - 0.5] * 2)
        assert np.abs(np.array(o.box) - clipped).max() <= 1.0, (o.id, o.box, ext)
        uv0 = _project(cam.pinhole, cam.ego_to_cam(p_ego))          # the same without the lens: off
        ext0 = np.clip([uv0[:, 0].min(), uv0[:, 1].min(), uv0[:, 0].max(), uv0[:, 1].max()], -0.5,
                       [cam.width - 0.5, cam.height - 0.5] * 2)
        pinhole_miss = max(pinhole_miss, np.abs(np.array(o.box) - ext0).max())
        box3d = _project(cam, _dense_edges(np.array(o.corners_cam), EDGES))
        outer = np.array([box3d[:, 0].min(), box3d[:, 1].min(), box3d[:, 0].max(), box3d[:, 1].max()])
        assert (np.array(o.box[:2]) >= outer[:2] - 1.0).all() and (np.array(o.box[2:]) <= outer[2:] + 1.0).all()
        checked += 1
    assert checked == len(CARS)
    assert pinhole_miss > 2.5          # the lens moved the off-axis vehicles


def test_visibility_and_colour_follow_the_lens(frames):
    _, fr, truth = frames["barrel"]
    _, fr0, truth0 = frames["pinhole"]
    vis0 = {o.id: o.visibility for o in truth0.objects}
    for o in truth.objects:
        if vis0[o.id] == 1.0:
            assert o.visibility == pytest.approx(1.0, abs=0.03)
    # the colour image shows the vehicles where the id mask has them (their colour differs from the road's)
    grey = cv2.cvtColor(fr.image, cv2.COLOR_BGR2GRAY).astype(float)
    car = fr.id_mask == 2
    ring = (cv2.dilate(car.astype(np.uint8), np.ones((9, 9), np.uint8)) > 0) & ~car & (fr.id_mask < 0)
    assert abs(grey[car].mean() - grey[ring].mean()) > 5


def test_pinhole_scenario_unchanged():
    s = _scenario()
    assert "distortion" not in s.model_dump(mode="json")["camera"]
    assert lens_warp(s.camera.model()) is None


def test_bad_lenses_refused_in_one_line():
    with pytest.raises(ValueError) as e:
        _scenario([-0.5, 0.0, 0.0, 0.0, 0.0])
    assert "folds the image back" in str(e.value)
    wide = CameraModel.from_fov(320, 180, 100.0, 1.4, 0.05, distortion=(-0.2, 0.02, 0.0, 0.0, 0.0))
    with pytest.raises(LensError, match="milder lens") as e:      # invertible, but its corners look far out
        lens_warp(wide)
    assert "\n" not in str(e.value)


def _static(distortion):
    d = yaml.safe_load((Path(__file__).parents[1] / "scenarios" / "static_distances.yaml").read_text())
    d["duration_s"] = 1.0
    d["camera"] = {"width": 640, "height": 360, "hfov_deg": 70, **({"distortion": distortion} if distortion else {})}
    return parse_scenario(d)


def _distances(scenario, camera=None, n_frames=3):
    """Per truth name, the pipeline's last (d_x, d_y) and the box, with oracle detections."""
    from harness.run.frame_feed import rendered_frames
    from monorarp.pipeline.runner import Pipeline

    p = Pipeline.from_config({"detector": {"name": "oracle"}, "tracker": {"name": "sort"}},
                             camera or scenario.camera.model())
    out = {}
    for frame, truth in rendered_frames(scenario, n_frames):
        p.detector.set_truth(truth, frame.image)
        res = p.process(frame)
        for tr in res.tracks:
            st = res.states.get(tr.id)
            if st is not None:
                o = max(truth.objects, key=lambda o: iou(np.array(o.box), np.array(tr.box)))
                out[o.name] = (st.d_x, st.d_y, o.box)
    return out


def test_pipeline_distance_on_a_distorted_frame():
    """Oracle detections on the static scene (7.5-60 m, up to two lanes out): the distorted camera's distances
    are the pinhole camera's within 3 % (+5 cm), its lateral offsets within 4 % (+10 cm); read as a pinhole
    (no undistortion) the same frames are off by more than twice as much."""
    pin = _distances(_static(None))
    scen = _static(BARREL)
    lens = _distances(scen)
    naive = _distances(scen, camera=scen.camera.model().pinhole)
    inside = lambda b: b[0] > 4 and b[2] < 635 and b[3] < 355      # noqa: E731 - whole in the image
    names = [n for n in pin if n in lens and inside(pin[n][2]) and inside(lens[n][2])]
    assert len(names) >= 6
    for n in names:
        assert abs(lens[n][1] - pin[n][1]) <= 0.03 * pin[n][1] + 0.05, (n, pin[n], lens[n])
        assert abs(lens[n][0] - pin[n][0]) <= 0.04 * abs(pin[n][0]) + 0.1, (n, pin[n], lens[n])

    def worst(est):       # the largest relative error of d_x or d_y against the pinhole camera's
        return max(abs(est[n][i] - pin[n][i]) / max(abs(pin[n][i]), 1.0) for n in names for i in (0, 1))

    assert worst(naive) > 2 * worst(lens)
