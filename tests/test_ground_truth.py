"""Ground truth against independent geometry: cv2.projectPoints of the 3-D boxes and of the
tyre contact line, road-frame distances, closed-form relative velocity and TTC, and
visibility against separate renders (the vehicle alone; a larger image)."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from harness.world.ground_truth import frame_truth
from harness.world.vehicles import vehicle_layout
from harness.render.renderer import Renderer
from harness.world.scenario import parse_scenario
from harness.world.truth import FrameTruth
from harness.world.state import VehicleState, WorldState

FOCAL = 400.0
FWD, LAT, CAM_H = 0.5, 0.3, 1.3


def _scenario(width=640, height=360):
    return parse_scenario({"name": "gt", "seed": 3, "road": {"lanes": 3},
                           "camera": {"width": width, "height": height, "focal_px": FOCAL, "height_m": CAM_H,
                                      "pitch_deg": 2.0, "forward_offset_m": FWD, "lateral_offset_m": LAT}})


EGO = VehicleState(0, 100.0, 4.0, 0.0, 25.0, 25.0, 0.0, 1, 5.0, 2.0)


def _car(vid, d_rear, lane_offset_m=0.0, speed=25.0, vy=0.0, length=4.6, width=1.9, heading=0.0):
    """A car whose rear face is ``d_rear`` ahead of the camera (heading 0 ego)."""
    x = EGO.x + FWD + d_rear + length / 2
    return VehicleState(vid, x, EGO.y + LAT + lane_offset_m, heading, speed, speed, vy, 1, length, width)


@pytest.fixture(scope="module")
def renderer():
    with Renderer(_scenario()) as r:
        yield r


def _truth(renderer, vehicles, ego=EGO):
    world = WorldState(7, 7 / 15, ego, tuple(vehicles))
    frame = renderer.render(world)
    return frame, frame_truth(world, renderer.camera, frame)


def _project(cam, pts_cam):
    uv, _ = cv2.projectPoints(np.asarray(pts_cam, dtype=np.float64).reshape(-1, 1, 3), np.zeros(3), np.zeros(3),
                              cam.K, None)
    return uv.reshape(-1, 2)


def _road_to_cam(cam, ego, pts_road):
    """Independent road-frame -> OpenCV camera-frame transform (explicit trigonometry)."""
    p = np.asarray(pts_road, dtype=float)
    ch, sh = math.cos(ego.heading), math.sin(ego.heading)
    cam_x = ego.x + FWD * ch - LAT * sh
    cam_y = ego.y + FWD * sh + LAT * ch
    dx, dy = p[:, 0] - cam_x, p[:, 1] - cam_y
    ahead, right, up = dx * ch + dy * sh, -dx * sh + dy * ch, p[:, 2] - CAM_H
    th = cam.pitch_rad
    # Camera pitched down by th: optical axis tilted below the horizontal, image y points down.
    return np.stack([right, -up * math.cos(th) - ahead * math.sin(th), ahead * math.cos(th) - up * math.sin(th)], axis=1)


@pytest.mark.parametrize("lane_offset, d_rear", [(-LAT, 15.0), (-4.0 - LAT, 12.0), (4.0 - LAT, 20.0), (-LAT, 30.0)])
def test_box_matches_projected_geometry(renderer, lane_offset, d_rear):
    v = _car(5, d_rear, lane_offset)
    _, truth = _truth(renderer, [v])
    (obj,) = truth.objects
    cam = renderer.camera
    uv = _project(cam, obj.corners_cam)
    pu0, pv0 = uv.min(axis=0)
    pu1, pv1 = uv.max(axis=0)
    x1, y1, x2, y2 = obj.box
    # Inside the projected 3-D box (1 px), sharing its left and right edges.
    assert x1 >= pu0 - 1 and y1 >= pv0 - 1 and x2 <= pu1 + 1 and y2 <= pv1 + 1
    assert abs(x1 - pu0) <= 1.0 and abs(x2 - pu1) <= 1.0
    # Bottom edge = projection of the rear tyres' contact line on the ground.
    lay = vehicle_layout(v.length, v.width)
    axle_x = v.x - v.length / 2 + lay.rear_overhang
    ys = v.y + np.array([-lay.wheel_y, -lay.wheel_y + lay.wheel_width, lay.wheel_y - lay.wheel_width, lay.wheel_y])
    contact = np.stack([np.full(4, axle_x), ys, np.zeros(4)], axis=1)
    v_contact = _project(cam, _road_to_cam(cam, EGO, contact))[:, 1].max()
    assert abs(y2 - v_contact) <= 1.0
    # corners_cam itself against the independent transform (order: rear-left, rear-right, front-right, front-left).
    foot = np.array([[v.x - v.length / 2, v.y - v.width / 2], [v.x - v.length / 2, v.y + v.width / 2],
                     [v.x + v.length / 2, v.y + v.width / 2], [v.x + v.length / 2, v.y - v.width / 2]])
    h = lay.roof
    expect = np.concatenate([np.c_[foot, np.zeros(4)], np.c_[foot, np.full(4, h)]])
    np.testing.assert_allclose(obj.corners_cam, _road_to_cam(cam, EGO, expect), atol=1e-5)
    # Distances from the road-frame positions.
    assert obj.d_long == pytest.approx(d_rear, abs=1e-9)
    assert obj.d_lat == pytest.approx(v.y - (EGO.y + LAT), abs=1e-9)
    assert obj.visibility == 1.0


def test_distances_with_headings(renderer):
    ego = VehicleState(0, 500.0, 4.3, 0.04, 25.0, 25.0 * math.cos(0.04), 25.0 * math.sin(0.04), 1, 5.0, 2.0)
    v = VehicleState(9, 520.0, 3.0, -0.03, 20.0, 20.0 * math.cos(-0.03), 20.0 * math.sin(-0.03), 1, 4.5, 1.8)
    _, truth = _truth(renderer, [v], ego)
    (obj,) = truth.objects
    ch, sh = math.cos(ego.heading), math.sin(ego.heading)
    cam = np.array([ego.x + FWD * ch - LAT * sh, ego.y + FWD * sh + LAT * ch])
    fwd, right = np.array([ch, sh]), np.array([-sh, ch])
    c, s = math.cos(v.heading), math.sin(v.heading)
    corners = [np.array([v.x, v.y]) + a * v.length / 2 * np.array([c, s]) + b * v.width / 2 * np.array([-s, c])
               for a in (-1, 1) for b in (-1, 1)]
    assert obj.d_long == pytest.approx(min((p - cam) @ fwd for p in corners), abs=1e-9)
    assert obj.d_lat == pytest.approx((np.array([v.x, v.y]) - cam) @ right, abs=1e-9)
    dv = np.array([v.vx - ego.vx, v.vy - ego.vy])
    assert obj.v_long == pytest.approx(dv @ fwd, abs=1e-9)
    assert obj.v_lat == pytest.approx(dv @ right, abs=1e-9)


def test_relative_velocity_and_ttc_closed_form(renderer):
    lead = _car(1, 20.0, -LAT, speed=15.0)                      # same lane, 10 m/s slower
    drift = _car(2, 10.0, -4.0 - LAT, speed=20.0, vy=1.0)       # left lane, drifting right at 1 m/s
    away = _car(3, 40.0, 4.0 - LAT, speed=30.0)                 # right lane, faster
    _, truth = _truth(renderer, [lead, drift, away])
    objs = {o.id: o for o in truth.objects}
    assert objs[1].v_long == pytest.approx(-10.0) and objs[1].v_lat == pytest.approx(0.0)
    # Ego front is L/2 - FWD = 2.0 m ahead of the camera: gap 18 m at 10 m/s.
    assert objs[1].ttc == pytest.approx(1.8)
    assert objs[2].v_long == pytest.approx(-5.0) and objs[2].v_lat == pytest.approx(1.0)
    # Lateral: drift spans x in [-5.25, -3.35], ego [-1.3, 0.7] -> touch at t = 2.05 s;
    # longitudinal overlap (y in [10, 14.6] closing at 5 m/s on ego [-3, 2]) holds from 1.6 s to 3.52 s.
    assert objs[2].ttc == pytest.approx(2.05)
    assert objs[3].ttc is None
    assert objs[2].lane_rel == 0 and truth.ego.speed == 25.0


def test_visibility_occlusion_matches_solo_render(renderer):
    front = _car(1, 12.0, -LAT + 0.9)
    behind = _car(2, 25.0, -LAT - 0.6)
    frame, truth = _truth(renderer, [front, behind])
    objs = {o.id: o for o in truth.objects}
    assert objs[1].visibility == 1.0
    assert 0.05 < objs[2].visibility < 0.95
    solo, _ = _truth(renderer, [behind])
    n_solo = int((solo.id_mask == 2).sum())
    assert frame.full_pixels[2] == pytest.approx(n_solo, rel=0.01)
    assert objs[2].visibility == pytest.approx((frame.id_mask == 2).sum() / n_solo, rel=0.01)


def test_visibility_truncation_matches_larger_image(renderer):
    beside = _car(4, 3.0, -4.0 - LAT)            # left lane, close: cut by the left border
    frame, truth = _truth(renderer, [beside])
    (obj,) = truth.objects
    assert obj.box[0] == -0.5 and 0.05 < obj.visibility < 0.95
    # The same camera on a 3x larger sensor (principal point shifted by whole pixels) sees all of it.
    with Renderer(_scenario(3 * 640, 3 * 360)) as big:
        n_big = int((big.render(WorldState(7, 0.0, EGO, (beside,))).id_mask == 4).sum())
    assert frame.full_pixels[4] == pytest.approx(n_big, rel=0.01)


def test_a_queue_of_cars_hiding_each_other_counts_each_as_drawn_alone(renderer):
    """Four cars in a row, each hiding the next: one overlay sub-window pass counts them all (one bit each,
    no depth test); every unoccluded count is that car's pixels rendered with no other car."""
    queue = [_car(i + 1, 10.0 + 7.0 * i, -LAT + 0.5 * i) for i in range(4)]
    frame, truth = _truth(renderer, queue)
    for car in queue[1:]:
        solo, _ = _truth(renderer, [car])
        n_solo = int((solo.id_mask == car.id).sum())
        assert n_solo > 0 and frame.full_pixels[car.id] == pytest.approx(n_solo, rel=0.003)
        assert int((frame.id_mask == car.id).sum()) < frame.full_pixels[car.id]


def test_overlay_bit_counts_and_window_plan():
    from harness.render import visibility

    rng = np.random.default_rng(3)
    codes = rng.integers(0, 2 ** 24, (40, 50), dtype=np.uint32) & rng.integers(0, 2 ** 24, (40, 50), dtype=np.uint32)
    bits = np.unpackbits(codes[..., None].view(np.uint8)[..., :3], axis=-1, bitorder="little")     # (40, 50, 24)
    assert np.array_equal(visibility.bit_counts(codes, 24), bits.sum(axis=(0, 1)))
    assert np.array_equal(visibility.bit_counts(codes, 5), bits.sum(axis=(0, 1))[:5])
    # overlapping boxes share a window; a 25th vehicle starts another; a box beyond the canvas gets its own
    boxes = np.array([[100.0 + 2 * k, 100.0, 140.0 + 2 * k, 130.0] for k in range(25)] + [[-900.0, 0, 1500, 300]])
    plan = visibility.plan_full_renders(boxes, range(26), 640, 360, 640 * 360)
    assert [m for _, m in plan] == [list(range(24)), [24], [25]]
    assert plan[0][0].scale == 1 and plan[2][0].scale > 1


def test_subwindow_count_equals_visible_count_when_unhidden(renderer):
    vehicles = [_car(1, 20.0, -LAT), _car(2, 40.0, 4.0 - LAT), _car(3, 30.0, -4.0 - LAT, length=12.0, width=2.5)]
    world = WorldState(0, 0.0, EGO, tuple(vehicles))
    frame = renderer.render(world)
    forced = renderer.full_pixels_rendered(world, frame.id_mask)
    assert renderer.render(world).full_pixels == frame.full_pixels
    for vid in (1, 2, 3):
        n = int((frame.id_mask == vid).sum())
        assert n > 0 and forced[vid] == pytest.approx(n, rel=0.005)


def test_only_visible_vehicles_and_record_is_json(renderer):
    import json

    behind_ego = _car(8, -15.0, -LAT)
    hidden = _car(9, 40.0, -LAT)                  # straight behind the near lead
    lead = _car(1, 6.0, -LAT)
    _, truth = _truth(renderer, [behind_ego, hidden, lead])
    assert [o.id for o in truth.objects] == [1]
    record = json.loads(json.dumps(truth.to_json()))
    assert FrameTruth.from_json(record) == truth
    assert list(record["objects"][0]) == ["id", "name", "box", "visibility", "d_long", "d_lat", "v_long", "v_lat",
                                          "ttc", "lane_rel", "corners_cam", "length", "width", "crashed"]
