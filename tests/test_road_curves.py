"""Road horizontal curves: the plan against closed forms (circle, clothoid by Fresnel integrals), the
scenario field's validation, a rendered car on a curve where cv2.projectPoints puts it, exact truth
(d_long, d_lat, v_long, s_long, s_lat) on a known circle, and a straight plan rendering
byte-identical frames."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest
import scipy.special

from harness.world.ground_truth import frame_truth
from harness.render.meshes import vehicle_trimesh
from harness.render.renderer import Renderer
from harness.world.road_plan import RoadPlan, path_length
from harness.world.road_profile import RoadProfile
from harness.world.scenario import ScenarioError, parse_scenario
from synthetic import assert_scenario_rejected
from harness.world.road import EGO_START_X_M, road_plan
from harness.world.state import VehicleState, WorldState
from monorarp.app.cli import main
from silhouette import assert_silhouette, rot_ego_to_cv


# ------------------------------------------------------------------ the plan's maths
@pytest.mark.parametrize("sign", [1.0, -1.0])   # right, left
def test_circle_is_the_closed_form(sign):
    R, x0 = 300.0, 100.0
    p = RoadPlan((x0,), (0.0,), (400.0,), (sign / R,))
    x = np.array([-50.0, 100.0, 130.0, 250.0, 499.0, 500.0, 620.0])
    u = np.clip(x - x0, 0.0, 400.0)
    ref = np.stack([x0 + R * np.sin(u / R), sign * R * (1 - np.cos(u / R))], -1)   # y right: + for a right turn
    ref[x < x0] = np.stack([x[x < x0], 0 * x[x < x0]], -1)
    beyond = x > 500.0
    ref[beyond] = ref[x == 500.0] + (x[beyond] - 500.0)[:, None] * [math.cos(400 / R), sign * math.sin(400 / R)]
    assert np.abs(p.centre(x) - ref).max() < 1e-9
    assert np.allclose(p.theta(x), sign * u / R)
    assert np.allclose(p.curvature(np.array([99.0, 101.0, 499.0, 501.0])), [0, sign / R, sign / R, 0])
    # a lane at offset y runs on the circle of radius R - sign y about the same centre
    y = 4.0
    centre = np.array([x0, sign * R])
    q = p.to_plane(np.array([200.0, 400.0]), np.array([y, y]))
    assert np.allclose(np.linalg.norm(q - centre, axis=-1), R - sign * y, atol=1e-9)


def test_clothoid_is_the_fresnel_integral():
    R, T = 250.0, 120.0
    p = RoadPlan((0.0,), (T,), (0.0,), (1.0 / R,))
    a = math.sqrt(math.pi * R * T)            # theta = u^2 / (2 R T) = (pi / 2) (u / a)^2
    u = np.array([5.0, 40.0, 90.0, 120.0])
    s, c = scipy.special.fresnel(u / a)
    assert np.abs(p.centre(u) - np.stack([a * c, a * s], -1)).max() < 1e-9
    assert np.allclose(p.theta(u), u ** 2 / (2 * R * T)) and np.allclose(p.curvature(u[:-1]), u[:-1] / (R * T))
    # the exit clothoid mirrors the entry: a symmetric curve ends with theta = (T + L) / R
    q = RoadPlan((10.0,), (T,), (200.0,), (-1.0 / R,))
    assert q.theta(10.0 + 2 * T + 200.0 + 5.0) == pytest.approx(-(T + 200.0) / R)
    fine = np.linspace(0.0, 600.0, 600001)
    assert np.allclose(np.gradient(q.theta(fine), fine), q.curvature(fine), atol=1e-5)


def test_from_plane_inverts_to_plane_and_path_length():
    p = RoadPlan((20.0, 400.0), (60.0, 0.0), (150.0, 200.0), (-1 / 300.0, 1 / 500.0))
    x = np.array([0.0, 50.0, 150.0, 300.0, 450.0, 900.0])
    y = np.array([-3.0, 8.0, 0.0, 12.0, -4.0, 2.0])
    xb, yb = p.from_plane(p.to_plane(x, y))
    assert np.allclose(xb, x, atol=1e-9) and np.allclose(yb, y, atol=1e-9)
    # the length of the lane at offset y, against the mapped polyline's length
    fine = np.linspace(10.0, 700.0, 200001)
    for lane_y in (-6.0, 0.0, 8.0):
        poly = p.to_plane(fine, np.full_like(fine, lane_y))
        numeric = np.linalg.norm(np.diff(poly, axis=0), axis=-1).sum()
        assert path_length(p, None, 10.0, 700.0, lane_y) == pytest.approx(numeric, abs=1e-4)
        prof = RoadProfile(starts=(100.0,), lengths=(50.0,), grades=(0.05,))
        with_z = np.linalg.norm(np.diff(np.c_[poly, prof.z(fine)], axis=0), axis=-1).sum()
        assert path_length(p, prof, 10.0, 700.0, lane_y) == pytest.approx(with_z, abs=1e-4)


# ------------------------------------------------------------------ the scenario field
def _scenario(curves, **extra):
    return parse_scenario({"name": "curve", "seed": 3, "duration_s": 0.4, "road": {"lanes": 3, "curves": curves},
                           "traffic": {"vehicles_count": 4}, "ego": {"lane": 1},
                           "vehicles": [{"name": "lead", "lane": 0, "distance_m": 50.0, "speed_mps": 24.0}],
                           **extra}, "s.yaml")


@pytest.mark.parametrize("curve, field", [
    ({"start_m": 50, "radius_m": 40, "direction": "left", "length_m": 10}, "road.curves.0.radius_m"),
    ({"start_m": 50, "radius_m": 500, "direction": "left", "length_m": -1}, "road.curves.0.length_m"),
    ({"start_m": 50, "radius_m": 500, "direction": "right", "transition_m": -5}, "road.curves.0.transition_m"),
    ({"start_m": 50, "radius_m": 500, "direction": "up", "length_m": 10}, "road.curves.0.direction"),
    ({"start_m": 50, "radius_m": 300, "direction": "left", "length_m": 500}, "curves.0"),   # 95 deg
])
def test_impossible_curves_rejected(curve, field):
    assert_scenario_rejected(_scenario, [curve], field=field)


def test_overlapping_curves_rejected_and_straight_road_dumps_as_before():
    with pytest.raises(ScenarioError, match="curves.1.start_m"):
        _scenario([{"start_m": 50, "radius_m": 500, "direction": "left", "length_m": 100, "transition_m": 20},
                   {"start_m": 180, "radius_m": 500, "direction": "right", "length_m": 10}])
    assert "curves" not in _scenario([]).model_dump(mode="json")["road"]
    dumped = _scenario([{"start_m": 5, "radius_m": 600, "direction": "right", "length_m": 50}]).model_dump(mode="json")
    assert dumped["road"]["curves"][0]["radius_m"] == 600


@pytest.mark.parametrize("curves, field", [
    ("[{start_m: 50, radius_m: 20, direction: left}]", "road.curves.0.radius_m"),
    ("[{start_m: 0, radius_m: 900, direction: left, length_m: 90}, {start_m: 80, radius_m: 900, direction: right}]",
     "curves.1.start_m"),
])
def test_cli_bad_curves_exit_2_with_one_line(tmp_path, capsys, curves, field):
    (tmp_path / "s.yaml").write_text(f"name: s\nduration_s: 0.2\nroad: {{curves: {curves}}}\n")
    code = main(["run", str(tmp_path / "s.yaml"), "--detector", "oracle", "--out", str(tmp_path / "o")])
    lines = capsys.readouterr().err.strip().splitlines()
    assert (code, len(lines)) == (2, 1) and field in lines[0] and "Traceback" not in lines[0]
    assert not (tmp_path / "o").exists()


# ------------------------------------------------------------------ 3-D placement and truth
LANE_W = 4.0


def _vehicle(vid, x, vx, lane=1, length=4.6, width=1.9):
    return VehicleState(vid, x, lane * LANE_W, 0.0, vx, vx, 0.0, lane, length, width)


def _on_circle(R, u, rho, sign):
    """Horizontal road-frame point (x, y right) at reference arc ``u`` on the circle of radius ``rho``
    about a left (sign -1) or right (+1) turn's centre (0, sign R) that starts at the origin."""
    return np.array([rho * math.sin(u / R), sign * (R - rho * math.cos(u / R))])


@pytest.mark.parametrize("sign", [-1.0, 1.0])
def test_truth_on_a_known_circle_is_the_closed_form(sign):
    """Ego and car in lane 1 of a circle of radius R (the ego already on it): everything by hand."""
    R, gap = 400.0, 60.0
    s = _scenario([{"start_m": -400, "radius_m": R, "direction": "left" if sign < 0 else "right", "length_m": 600}])
    camera = s.camera.model()
    plan = road_plan(s.road.curves, camera.forward_offset_m)
    x_start = EGO_START_X_M + camera.forward_offset_m - 400.0
    ego = _vehicle(0, EGO_START_X_M, 25.0, length=5.0, width=2.0)
    car = _vehicle(1, ego.x + camera.forward_offset_m + gap + 2.3, 20.0)     # rear face gap along road x
    world = WorldState(0, 0.0, ego, (car,), plan=plan)
    mask = np.full((camera.height, camera.width), -1)
    mask[200, 320] = 1
    record = frame_truth(world, camera, mask, {1: 1.0})
    obj = record.objects[0]

    rho = R - sign * LANE_W                            # the lane's radius
    assert record.ego.speed == pytest.approx(ego.vx * rho / R, abs=1e-9)   # the ego's speed on its lane
    phi_e, phi_c = (ego.x - x_start) / R, (car.x - x_start) / R
    fwd_e = np.array([math.cos(sign * phi_e), math.sin(sign * phi_e)])
    right_e = np.array([-fwd_e[1], fwd_e[0]])
    cam = _on_circle(R, ego.x - x_start, rho, sign) + camera.forward_offset_m * fwd_e
    fwd_c = np.array([math.cos(sign * phi_c), math.sin(sign * phi_c)])
    right_c = np.array([-fwd_c[1], fwd_c[0]])
    centre = _on_circle(R, car.x - x_start, rho, sign)
    corners = [centre + a * car.length / 2 * fwd_c + b * car.width / 2 * right_c for a in (-1, 1) for b in (-1, 1)]
    ego_xy = np.array([[(c - cam) @ right_e, (c - cam) @ fwd_e] for c in corners])
    assert obj.d_long == pytest.approx(ego_xy[:, 1].min(), abs=1e-8)
    assert obj.d_lat == pytest.approx(((centre - cam) @ right_e), abs=1e-8)
    assert obj.d_lat * sign > 4.0                      # the curve carries the lead out of the straight-ahead lane
    stretch = rho / R                                  # the lane moves (1 - kappa y) per unit road x
    v_rel = stretch * (car.vx * fwd_c - ego.vx * fwd_e)
    assert obj.v_long == pytest.approx(v_rel @ fwd_e, abs=1e-8)
    assert obj.v_lat == pytest.approx(v_rel @ right_e, abs=1e-8)
    # along the road: from the camera's foot point to the rear face's middle, on the camera's line
    foot_rho, foot_u = math.hypot(rho, camera.forward_offset_m), math.atan2(camera.forward_offset_m, rho) * R
    rear_rho, rear_u = math.hypot(rho, car.length / 2), -math.atan2(car.length / 2, rho) * R
    assert obj.s_long == pytest.approx((car.x + rear_u - ego.x - foot_u) * foot_rho / R, abs=1e-6)
    assert obj.s_lat == pytest.approx(-sign * (rear_rho - foot_rho), abs=1e-6)
    assert obj.s_long == pytest.approx(gap * rho / R, abs=0.05) and obj.d_long < obj.s_long - 0.1


def test_truth_ttc_on_a_curve_follows_the_lanes():
    """A slower lead 30 m ahead in the ego's lane of a 300 m left arc: it closes at 10 m/s along the
    lane, so TTC = (30 - 2) / 10 s (2 m: the ego's front ahead of the camera), as on the straight
    road, although extrapolated straight ahead in the ego frame it would drift clear to the left."""
    s = _scenario([{"start_m": -100, "radius_m": 300.0, "direction": "left", "length_m": 300}])
    camera = s.camera.model()
    ego = _vehicle(0, EGO_START_X_M, 25.0, length=5.0, width=2.0)
    lead = _vehicle(1, ego.x + camera.forward_offset_m + 30.0 + 2.3, 15.0)
    mask = np.full((camera.height, camera.width), -1)
    mask[200, 320] = 1
    curved = frame_truth(WorldState(0, 0.0, ego, (lead,), plan=road_plan(s.road.curves, 0.5)), camera, mask,
                         {1: 1.0}).objects[0]
    assert curved.ttc == pytest.approx(2.8, abs=1e-9)
    assert curved.d_lat < -1.2 and curved.v_lat < -1.2     # drifting left in the ego frame
    straight = frame_truth(WorldState(0, 0.0, ego, (lead,)), camera, mask, {1: 1.0}).objects[0]
    assert straight.ttc == curved.ttc


@pytest.mark.parametrize("ego_offset, car_u, lane", [(-30.0, 40.0, 0), (60.0, 100.0, 2)])   # ego before / on it
def test_rendered_vehicle_on_a_curve_where_cv2_projects_it(ego_offset, car_u, lane):
    """A car on a 150 m-radius left arc: its id-pass silhouette's extremes against its mesh placed by
    an independent construction (centre on the closed-form circle, yawed by cv2.Rodrigues) and
    projected by cv2.projectPoints from the camera on the ego's yawed body."""
    R = 150.0
    s = _scenario([{"start_m": 0.0, "radius_m": R, "direction": "left", "length_m": 200.0}])
    camera = s.camera.model()
    x_start = EGO_START_X_M + camera.forward_offset_m

    def pose(x, y):   # W position (Y left) and yaw (+ left) of road point (x, y) and its heading
        u = x - x_start
        if u <= 0:
            return np.array([x, -y, 0.0]), 0.0
        p = _on_circle(R, u, R + y, -1.0)
        return np.array([x_start + p[0], -p[1], 0.0]), u / R

    ego = VehicleState(0, EGO_START_X_M + ego_offset, LANE_W, 0.0, 25.0, 25.0, 0.0, 1, 5.0, 2.0)
    car = _vehicle(1, x_start + car_u, 20.0, lane=lane)
    with Renderer(s) as r:
        world = WorldState(0, 0.0, ego, (car,), plan=road_plan(s.road.curves, camera.forward_offset_m))
        f = r.render(world)
        truth = frame_truth(world, r.camera, f)
    base_e, yaw_e = pose(ego.x, ego.y)
    r_ego, _ = cv2.Rodrigues(np.array([0.0, 0.0, yaw_e]))
    cam_w = base_e + r_ego @ np.array([camera.forward_offset_m, 0.0, camera.height_m])
    base_c, yaw_c = pose(car.x, car.y)
    r_car, _ = cv2.Rodrigues(np.array([0.0, 0.0, yaw_c]))
    tm = vehicle_trimesh(car.length, car.width, (0, 0, 0))
    obj = truth.objects[0]
    p_ego = assert_silhouette(camera, tm.vertices @ r_car.T + base_c, cam_w, r_ego, f, obj)
    assert obj.d_long == pytest.approx(p_ego[:, 1].min(), abs=0.05)
    if ego_offset > 0:
        return
    # the road bends: on every image row, the left shoulder's outer edge is drawn where
    # cv2.projectPoints puts the arc's edge (up to 80 m ahead: 50 m into the arc, 8 m left of the
    # straight road's)
    edge = -LANE_W / 2 - s.road.shoulder_width_m
    pts = np.array([pose(x_start + u, edge)[0] for u in np.linspace(-20.0, 50.0, 1401)])
    b = (pts - cam_w) @ r_ego
    rvec, _ = cv2.Rodrigues(rot_ego_to_cv(camera.pitch_rad))
    uv = cv2.projectPoints(np.stack([-b[:, 1], b[:, 0], b[:, 2]], 1).reshape(-1, 1, 3), rvec, np.zeros(3),
                           camera.K, None)[0].reshape(-1, 2)
    rows = np.arange(math.ceil(uv[:, 1].min()), math.floor(uv[:, 1].max()) + 1)
    checked = 0
    for v in rows:
        u_px = np.interp(v, uv[::-1, 1], uv[::-1, 0])
        if not 1 <= u_px <= camera.width - 2:
            continue
        row = f.image[v].astype(int)
        first_road = np.argmax(row[:, 1] - row[:, 2] < 15)      # BGR: first non-grass pixel from the left
        assert abs(first_road - u_px) <= 1.5, (v, u_px, first_road)
        checked += 1
    assert checked > 20


def test_straight_plan_renders_byte_identical_frames():
    from harness.run.frame_feed import rendered_frames

    plain = list(rendered_frames(_scenario([]), n_frames=2))
    empty = list(rendered_frames(_scenario([{"start_m": 40.0, "radius_m": 500, "direction": "left"}]), n_frames=2))
    for (fa, ta), (fb, tb) in zip(plain, empty):
        assert np.array_equal(fa.image, fb.image) and ta.to_json() == tb.to_json()
    curve = _scenario([{"start_m": -50.0, "radius_m": 300, "direction": "left", "length_m": 300}])
    bent = list(rendered_frames(curve, n_frames=1))
    assert not np.array_equal(bent[0][0].image, plain[0][0].image)
    assert all(o.s_long is not None and o.s_lat is not None for o in bent[0][1].objects)
    line = bent[0][1].to_json()["objects"][0]
    assert list(line)[:8] == ["id", "name", "box", "visibility", "d_long", "s_long", "d_lat", "s_lat"]


def test_shipped_curve_scenario_and_curves_sweep():
    from pathlib import Path

    from harness.world.scenario import load_scenario
    from harness.sweep.axes import _log_scale
    from harness.sweep.expand import load_and_expand

    root = Path(__file__).resolve().parents[1] / "scenarios" / "conditions"
    curve = load_scenario(root / "curve.yaml").road.curves[0]
    assert (curve.start_m, curve.radius_m, curve.direction) == (50.0, 500.0, "left")
    exp = load_and_expand(root / "curves.yaml")
    radii = [t.scenario["road"]["curves"][0]["radius_m"] for t in exp.tasks]
    assert set(radii) == {100000.0, 1000.0, 500.0, 300.0} and len(exp.tasks) == 32
    assert not any(t.error for t in exp.tasks)                  # 300 m still turns less than 90 deg
    assert {t.pipeline["ego_speed"]["name"] for t in exp.tasks} == {"ground_track", "lsd_period"}
    assert _log_scale(sorted(set(radii))) and not _log_scale([-0.04, 0.0, 0.04]) and not _log_scale([1.0, 50.0])
