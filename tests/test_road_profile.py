"""Road vertical profile: closed forms, the scenario field's validation, rendering on a grade checked
against cv2.projectPoints, exact truth (d_long, s_long) on a known grade, and a level profile
rendering byte-identical frames."""

from __future__ import annotations

import math
from pathlib import Path

import cv2
import numpy as np
import pytest

from harness.world.ground_truth import frame_truth
from harness.world.geometry import vehicle_corners_ego
from harness.render.meshes import vehicle_trimesh
from harness.world.vehicles import vehicle_height
from harness.render.renderer import Renderer
from harness.world.road_profile import RoadProfile
from harness.world.scenario import ScenarioError, parse_scenario
from synthetic import assert_scenario_rejected
from harness.world.road import EGO_START_X_M, road_profile
from harness.world.state import VehicleState, WorldState
from monorarp.app.cli import main
from silhouette import assert_silhouette


def test_profile_closed_forms():
    p = RoadProfile(starts=(100.0,), lengths=(40.0,), grades=(0.04,))
    x = np.array([0.0, 100.0, 110.0, 140.0, 200.0])
    assert np.allclose(p.slope(x), [0.0, 0.0, 0.01, 0.04, 0.04])
    # parabola over the transition, then a straight line of grade 0.04 that continues it
    assert np.allclose(p.z(x), [0.0, 0.0, 0.04 * 10 ** 2 / 80, 0.04 * 40 / 2, 0.04 * 40 / 2 + 0.04 * 60])
    fine = np.linspace(0, 300, 300001)
    assert np.allclose(np.gradient(p.z(fine), fine), p.slope(fine), atol=1e-6)   # slope is dz/dx
    # a crest back to level and a kink (transition 0)
    q = RoadProfile(starts=(0.0, 100.0, 200.0), lengths=(0.0, 50.0, 0.0), grades=(0.06, -0.02, 0.0))
    assert np.allclose(q.slope([-1.0, 50.0, 125.0, 199.0, 201.0]), [0.0, 0.06, 0.02, -0.02, 0.0])
    assert q.z(300.0) == pytest.approx(0.06 * 100 + (0.06 * 50 - 0.08 * 50 / 2) - 0.02 * 50)


def test_arc_length_closed_form():
    g = 0.05
    p = RoadProfile(starts=(10.0,), lengths=(0.0,), grades=(g,))
    assert p.arc_length(0.0, 60.0) == pytest.approx(10.0 + 50.0 * math.sqrt(1 + g * g))
    assert p.arc_length(60.0, 0.0) == pytest.approx(-(10.0 + 50.0 * math.sqrt(1 + g * g)))
    c = RoadProfile(starts=(20.0, 120.0), lengths=(60.0, 30.0), grades=(0.12, -0.08))
    x = np.linspace(-5.0, 250.0, 400001)
    numeric = np.trapezoid(np.sqrt(1 + c.slope(x) ** 2), x)
    assert c.arc_length(-5.0, 250.0) == pytest.approx(numeric, abs=1e-6)
    assert np.allclose(c.arc_length(np.array([0.0, 30.0]), np.array([30.0, 0.0])), [30.0, -30.0], atol=0.02)


def _scenario(profile, **extra):
    return parse_scenario({"name": "hill", "seed": 3, "duration_s": 0.4, "road": {"lanes": 3, "profile": profile},
                           "traffic": {"vehicles_count": 4}, "ego": {"lane": 1},
                           "vehicles": [{"name": "lead", "lane": 0, "distance_m": 70.0, "speed_mps": 24.0}],
                           **extra}, "s.yaml")


@pytest.mark.parametrize("segment, field", [
    ({"start_m": 50, "grade": 0.16}, "road.profile.0.grade"),
    ({"start_m": 50, "grade": -0.2, "transition_m": 40}, "road.profile.0.grade"),
    ({"start_m": 50, "grade": 0.04, "transition_m": -1}, "road.profile.0.transition_m"),
])
def test_impossible_profile_rejected(segment, field):
    assert_scenario_rejected(_scenario, [segment], field=field)


def test_overlapping_changes_rejected_and_level_road_dumps_as_before():
    with pytest.raises(ScenarioError, match="profile.1.start_m"):
        _scenario([{"start_m": 50, "grade": 0.04, "transition_m": 40}, {"start_m": 60, "grade": 0.0}])
    assert "profile" not in _scenario([]).model_dump(mode="json")["road"]
    assert _scenario([{"start_m": 5, "grade": 0.1}]).model_dump(mode="json")["road"]["profile"][0]["grade"] == 0.1


def test_cli_grade_too_steep_exits_2(tmp_path, capsys):
    bad = tmp_path / "s.yaml"
    bad.write_text("name: s\nduration_s: 0.2\nroad: {profile: [{start_m: 50, grade: 0.2, transition_m: 40}]}\n")
    out = tmp_path / "o"
    assert main(["run", str(bad), "--detector", "oracle", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "road.profile.0.grade" in err
    assert "Traceback" not in err and not out.exists()


# ------------------------------------------------------------------ 3-D placement and truth
LANE_W = 4.0
EGO = VehicleState(0, EGO_START_X_M, LANE_W, 0.0, 25.0, 25.0, 0.0, 1, 5.0, 2.0)


def _car(vid, x, lane=1, heading=0.0, length=4.6):
    return VehicleState(vid, x, lane * LANE_W, heading, 20.0, 20.0, 0.0, lane, length, 1.9)


def test_truth_on_a_known_grade_is_the_closed_form():
    """Ego level, a kink to grade g at 30 m; the car beyond it is pitched by atan(g)."""
    g, kink = 0.08, 30.0
    s = _scenario([{"start_m": kink, "grade": g}])
    camera = s.camera.model()
    prof = road_profile(s.road.profile, camera.forward_offset_m)
    car = _car(1, EGO.x + camera.forward_offset_m + 60.0)
    world = WorldState(0, 0.0, EGO, (car,), profile=prof)
    mask = np.full((camera.height, camera.width), -1)
    mask[200, 320] = 1
    truth = frame_truth(world, camera, mask, {1: 1.0}).objects[0]
    theta = math.atan(g)
    x_cam = EGO.x + camera.forward_offset_m
    x_rear = car.x - car.length / 2 * math.cos(theta)
    assert truth.d_long == pytest.approx(x_rear - x_cam, abs=1e-9)
    assert truth.s_long == pytest.approx(kink + (x_rear - x_cam - kink) * math.sqrt(1 + g * g), abs=1e-9)
    assert truth.s_long - truth.d_long == pytest.approx(0.0885, abs=1e-3)     # 27.7 m of 8 % slope
    # the rear-face ground corners at height z(x_rear) - h_c in the ego frame, roof corners pitched back
    corners = np.asarray(truth.corners_cam)
    ego_pts = camera.cam_to_ego(corners)
    assert ego_pts[0, 2] == pytest.approx(g * (x_rear - x_cam - kink) - camera.height_m, abs=1e-5)  # 6 decimals
    h = vehicle_height(car.length, car.width)
    assert ego_pts[4, 1] - ego_pts[0, 1] == pytest.approx(-h * math.sin(theta), abs=1e-5)
    # the level ego frame's v_long is the along-x closing speed; the car's climb (1.6 m/s) is vertical
    assert truth.v_long == pytest.approx(-5.0, abs=1e-9)


def test_on_a_constant_grade_the_ego_frame_sees_a_level_road():
    """Ego and car both on the same 6 % grade: the ego frame rides the slope, so d_long is the slope
    distance and the box corners are the level road's at that distance."""
    g = 0.06
    s = _scenario([{"start_m": -500.0, "grade": g}])
    camera = s.camera.model()
    prof = road_profile(s.road.profile, camera.forward_offset_m)
    dx = 40.0
    car = _car(1, EGO.x + camera.forward_offset_m + dx)
    heights = np.array([vehicle_height(car.length, car.width)])
    on_grade = vehicle_corners_ego([car], EGO, camera, heights, prof)[0]
    level_car = _car(1, EGO.x + (car.x - EGO.x) * math.sqrt(1 + g * g))
    level = vehicle_corners_ego([level_car], EGO, camera, heights, None)[0]
    assert np.allclose(on_grade, level, atol=1e-9)
    # and the 3-D path on a level stretch equals the level road's own
    far = RoadProfile(starts=(EGO.x + 5000.0,), lengths=(0.0,), grades=(0.1,))
    assert np.allclose(vehicle_corners_ego([car], EGO, camera, heights, far),
                       vehicle_corners_ego([car], EGO, camera, heights, None), atol=1e-9)


@pytest.mark.parametrize("ego_x_offset", [0.0, 120.0])   # ego level below the sag / on the 5 % grade itself
def test_rendered_vehicle_on_a_grade_where_cv2_projects_it(ego_x_offset):
    """A car beyond a 5 % sag: its id-pass silhouette's extremes against its mesh placed by an
    independent construction (centre at z(x), pitched by cv2.Rodrigues about the lateral axis) and
    projected by cv2.projectPoints from the camera riding on the ego's pitched body."""
    g, start, trans = 0.05, 30.0, 20.0
    s = _scenario([{"start_m": start, "grade": g, "transition_m": trans}])
    camera = s.camera.model()
    x0 = EGO_START_X_M + camera.forward_offset_m

    def z_closed(x):   # level, parabola, then the straight grade
        u = x - (x0 + start)
        return 0.0 if u <= 0 else (g * u * u / (2 * trans) if u <= trans else g * (u - trans / 2))

    def slope_closed(x):
        return float(np.clip((x - x0 - start) / trans, 0, 1)) * g

    ego = VehicleState(0, EGO.x + ego_x_offset, LANE_W, 0.0, 25.0, 25.0, 0.0, 1, 5.0, 2.0)
    car = _car(1, ego.x + 55.0)
    with Renderer(s) as r:
        world = WorldState(0, 0.0, ego, (car,), profile=road_profile(s.road.profile, camera.forward_offset_m))
        f = r.render(world)
        truth = frame_truth(world, r.camera, f)
    # the ego's body and camera: pitched by atan(slope) up, camera h_c along the body's up axis
    a_e = math.atan(slope_closed(ego.x))
    r_ego, _ = cv2.Rodrigues(np.array([0.0, -a_e, 0.0]))          # about W's Y (left): +a_e noses up
    base_e = np.array([ego.x, -ego.y, z_closed(ego.x)])
    cam_w = base_e + r_ego @ np.array([camera.forward_offset_m, 0.0, camera.height_m])
    a_c = math.atan(slope_closed(car.x))
    r_car, _ = cv2.Rodrigues(np.array([0.0, -a_c, 0.0]))
    tm = vehicle_trimesh(car.length, car.width, (0, 0, 0))
    pw = tm.vertices @ r_car.T + np.array([car.x, -car.y, z_closed(car.x)])
    # the truth's box is the silhouette's, its corners the same 3-D placement
    obj = truth.objects[0]
    p_ego = assert_silhouette(camera, pw, cam_w, r_ego, f, obj)
    rear_ground = p_ego[np.argmin(p_ego[:, 1])]
    assert obj.d_long == pytest.approx(np.asarray(camera.cam_to_ego(np.asarray(obj.corners_cam)))[:4, 1].min())
    assert obj.d_long == pytest.approx(rear_ground[1], abs=0.05)
    # the road surface: the rendered road/sky boundary of the climbing road lies above the level horizon
    if ego_x_offset == 0.0:
        assert np.mean(f.image[int(camera.horizon_row) - 3, :, 2]) < 200        # road, not sky, just above it


def test_level_profile_renders_byte_identical_frames():
    from harness.run.frame_feed import rendered_frames

    plain = list(rendered_frames(_scenario([]), n_frames=3))
    level = list(rendered_frames(_scenario([{"start_m": 40.0, "grade": 0.0, "transition_m": 30.0}]), n_frames=3))
    for (fa, ta), (fb, tb) in zip(plain, level):
        assert np.array_equal(fa.image, fb.image) and ta.to_json() == tb.to_json()
    hill = list(rendered_frames(_scenario([{"start_m": 40.0, "grade": 0.04, "transition_m": 30.0}]), n_frames=1))
    assert not np.array_equal(hill[0][0].image, plain[0][0].image)
    assert all(o.s_long is not None for o in hill[0][1].objects)


# ------------------------------------------------------------------ the state estimator's grade term
def test_grade_gain_is_the_tilted_plane_derivative_and_widens_d_y_std():
    from monorarp.core.camera import CameraModel
    from monorarp.state.estimator import StateEstimator

    cam = CameraModel.from_fov(640, 360, 70.0, 1.3, math.radians(2.0))
    est = StateEstimator(cam, grade_std=0.02)
    d_y = np.array([10.0, 40.0, 80.0])
    Y0 = d_y + est.config.contact_offset_m
    tan_a = cam.height_m / Y0                                          # the flat reading's ray
    dg = 1e-6
    numeric = (cam.height_m / (tan_a - dg) - cam.height_m / (tan_a + dg)) / (2 * dg)   # |dY/dg| on z = g y
    assert np.allclose(est.grade_gain(d_y), numeric, rtol=1e-4)
    filt = np.array([0.1, 0.5, 1.0])
    plain = StateEstimator(cam).distance_std(d_y, filt, 0.0)
    wide = est.distance_std(d_y, filt, 0.0)
    assert np.allclose(wide ** 2 - plain ** 2, (numeric * 0.02) ** 2, rtol=1e-4)
    assert np.array_equal(StateEstimator(cam, grade_std=0.0).distance_std(d_y, filt, 0.0), plain)
    with pytest.raises(ValueError, match="grade_std"):
        StateEstimator(cam, grade_std=-0.01)


def test_shipped_hill_scenario_and_grade_sweep():
    from harness.world.scenario import load_scenario
    from harness.sweep.expand import load_and_expand

    root = Path(__file__).resolve().parents[1] / "scenarios" / "conditions"
    hill = load_scenario(root / "hill.yaml")
    seg = hill.road.profile[0]
    assert (seg.start_m, seg.grade) == (50.0, 0.04)
    assert all(v.distance_m >= seg.start_m + seg.transition_m for v in hill.vehicles if v.name != "right_near")
    exp = load_and_expand(root / "grade.yaml")
    grades = {t.scenario["road"]["profile"][0]["grade"] for t in exp.tasks}
    assert grades == {-0.04, -0.02, 0.0, 0.02, 0.04} and len(exp.tasks) == 90
    assert {t.pipeline["state"]["kwargs"].get("grade_std", 0.0) for t in exp.tasks} == {0.0, 0.01, 0.025}
