"""Simulation adapter (harness.simulation) against geometry, closed forms and highway-env's own models."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import yaml
from highway_env.road.road import Road, RoadNetwork
from highway_env.vehicle.behavior import IDMVehicle
from highway_env.vehicle.objects import Obstacle

from harness.world.scenario import ScenarioError, load_scenario, parse_scenario
from harness.simulation.simulator import Simulation, simulate
from monorarp.risk.ttc import ego_extent, time_to_collision

SCENARIOS = Path(__file__).resolve().parents[1] / "scenarios"


def scenario(**kw):
    return parse_scenario({"name": "t", **kw})


def by_name(state, name):
    return next(v for v in state.vehicles if v.name == name)


def camera_x(state, sc):
    """Road-frame x of the camera: ``forward_offset_m`` ahead of the ego's centre."""
    return state.ego.x + sc.camera.forward_offset_m


# ----------------------------------------------------------------- determinism, ids, time
BUSY = dict(seed=7, traffic={"vehicles_count": 25, "density": 2.0, "speed_range_mps": [15, 30]},
            road={"lanes": 4}, ego={"lane": 1, "behaviour": "idm", "speed_mps": 22},
            vehicles=[{"name": "lead", "distance_m": 30, "speed_mps": 22},
                      {"name": "cutter", "lane": 1, "distance_m": 10, "speed_mps": 20, "behaviour": "constant_speed"}],
            events=[{"type": "brake", "vehicle": "lead", "at_s": 1.0, "decel_mps2": 4, "until_speed_mps": 10},
                    {"type": "cut_in", "vehicle": "cutter", "at_s": 0.5, "gap_m": 12}])


def test_same_scenario_gives_identical_states():
    sc = scenario(**BUSY)
    a, b = list(simulate(sc, 40)), list(simulate(sc, 40))
    assert a == b                      # dataclass equality: every float bit-for-bit
    assert len(a) == 40 and len(a[0].vehicles) == 27


def test_different_seeds_give_different_traffic():
    s0, s1 = (next(simulate(scenario(**{**BUSY, "seed": seed}), 1)) for seed in (7, 8))
    assert [(v.x, v.lane) for v in s0.vehicles[2:]] != [(v.x, v.lane) for v in s1.vehicles[2:]]


def test_frames_and_times_by_step_count():
    sc = scenario(fps=30, duration_s=1.0, traffic={"vehicles_count": 3})
    states = list(simulate(sc))
    assert [s.frame for s in states] == list(range(30))
    assert [s.t for s in states] == [k / 30 for k in range(30)]
    sim = Simulation(sc)
    assert sim.fps == 30 and sim.dt == 1 / 30 and sim.state().frame == 0
    assert sim.step().frame == 1 and sim.state().t == 1 / 30


def test_ids_stable_and_unique():
    sc = scenario(**BUSY)
    states = list(simulate(sc, 60))
    ids0 = [v.id for v in states[0].vehicles]
    assert ids0 == list(range(1, 28)) and states[0].ego.id == 0
    assert [v.name for v in states[0].vehicles[:2]] == ["lead", "cutter"]
    for prev, cur in zip(states, states[1:]):
        assert [v.id for v in cur.vehicles] == ids0
        # the same id is the same vehicle: it moved by about speed * dt, no jump to another one
        for p, c in zip(prev.vehicles, cur.vehicles):
            assert math.hypot(c.x - p.x, c.y - p.y) <= max(p.speed, c.speed) / sc.fps + 1e-6 or c.crashed


# ----------------------------------------------------------------- placement
def test_placed_vehicle_rear_face_at_distance_from_camera():
    sc = scenario(road={"lanes": 3, "lane_width_m": 3.5}, ego={"lane": 1},
                  camera={"forward_offset_m": 1.2},
                  vehicles=[{"name": "truck", "lane": 1, "distance_m": 17.5, "length_m": 12, "width_m": 2.5},
                            {"name": "behind", "lane": -1, "distance_m": -30, "speed_mps": 20}])
    s0 = next(simulate(sc, 1))
    truck, behind = by_name(s0, "truck"), by_name(s0, "behind")
    assert truck.x - truck.length / 2 - camera_x(s0, sc) == pytest.approx(17.5, abs=1e-9)
    assert behind.x - behind.length / 2 - camera_x(s0, sc) == pytest.approx(-30, abs=1e-9)
    assert (truck.length, truck.width, truck.lane, truck.y) == (12, 2.5, 2, 2 * 3.5)
    assert (behind.lane, behind.y, behind.speed, behind.vx, behind.vy) == (0, 0.0, 20, 20, 0)
    assert (s0.ego.lane, s0.ego.y, s0.ego.heading) == (1, 3.5, 0.0)


def _rects_overlap(a, b):
    return abs(a.x - b.x) < (a.length + b.length) / 2 and abs(a.y - b.y) < (a.width + b.width) / 2


def test_traffic_never_overlaps_and_surrounds_ego():
    sc = scenario(seed=11, traffic={"vehicles_count": 40, "density": 3.0}, road={"lanes": 3},
                  vehicles=[{"name": f"p{k}", "lane": k % 3 - 1, "distance_m": 8 * k, "behaviour": "stationary"}
                            for k in range(1, 6)])
    s0 = next(simulate(sc, 1))
    everyone = [s0.ego, *s0.vehicles]
    assert len(s0.vehicles) == 45
    for i, a in enumerate(everyone):
        for b in everyone[i + 1:]:
            assert not _rects_overlap(a, b), (a, b)
    traffic = s0.vehicles[5:]
    ahead = [v for v in traffic if 0 < v.x - s0.ego.x < 100]
    assert len(ahead) >= 5 and any(v.x < s0.ego.x for v in traffic)
    lanes = sc.road.lanes
    assert all(v.y == v.lane * sc.road.lane_width_m and 0 <= v.lane < lanes for v in traffic)
    lo, hi = sc.traffic.speed_range_mps
    assert all(lo <= v.speed <= hi for v in traffic)


# ----------------------------------------------------------------- behaviours and events
def test_stationary_vehicle_stays_put():
    sc = scenario(ego={"speed_mps": 20}, traffic={"vehicles_count": 0},
                  vehicles=[{"name": "parked", "lane": 1, "distance_m": 5, "behaviour": "stationary"}])
    states = list(simulate(sc, 45))
    first = by_name(states[0], "parked")
    for s in states:
        p = by_name(s, "parked")
        assert (p.x, p.y, p.speed, p.vx, p.heading) == (first.x, first.y, 0.0, 0.0, 0.0)
    assert states[-1].ego.x - states[0].ego.x == pytest.approx(20 * 44 / 15)


@pytest.mark.parametrize("at_s", [1.0, 1.03])
def test_brake_event_decelerates_at_configured_rate(at_s):
    v0, a, until = 24.0, 6.0, 6.0
    sc = scenario(ego={"speed_mps": 10}, traffic={"vehicles_count": 0},
                  vehicles=[{"name": "lead", "distance_m": 60, "speed_mps": v0, "behaviour": "idm"}],
                  events=[{"type": "brake", "vehicle": "lead", "at_s": at_s, "decel_mps2": a, "until_speed_mps": until}])
    dt = 1 / sc.fps
    for s in simulate(sc, 75):
        v = by_name(s, "lead").speed
        expected = min(v0, max(until, v0 - a * (s.t - at_s)))
        assert abs(v - expected) <= a * dt + 1e-9, (s.t, v, expected)
        if s.t >= at_s + dt and expected > until + a * dt:
            assert v == pytest.approx(v0 - a * (s.t - at_s), abs=a * dt)
    assert v == until                  # lands on the target speed exactly and holds it


def test_cut_in_reaches_ego_lane_with_configured_gap():
    gap, at_s = 12.0, 2.0
    sc = scenario(road={"lanes": 3}, ego={"lane": 1, "speed_mps": 25}, traffic={"vehicles_count": 0},
                  vehicles=[{"name": "c", "lane": -1, "distance_m": 99, "speed_mps": 22, "behaviour": "constant_speed"}],
                  events=[{"type": "cut_in", "vehicle": "c", "at_s": at_s, "gap_m": gap}])
    states = list(simulate(sc, 60))    # 4 s: it is 3 m/s slower, contact would come at ~5.3 s
    c0 = by_name(states[0], "c")
    assert c0.x - c0.length / 2 - camera_x(states[0], sc) == pytest.approx(gap - (22 - 25) * at_s)
    k_at = round(at_s * sc.fps)
    at = states[k_at]
    c = by_name(at, "c")
    assert c.x - c.length / 2 - camera_x(at, sc) == pytest.approx(gap, abs=1e-6)
    for s in states[:k_at + 1]:     # holds lane and speed until at_s
        c = by_name(s, "c")
        assert (c.lane, c.y, c.speed) == (0, 0.0, 22.0)
    lane_of = [by_name(s, "c").lane for s in states]
    entered = next(k for k, lane in enumerate(lane_of) if lane == 1)
    assert k_at < entered <= k_at + 2 * sc.fps        # within 2 s of at_s
    c_end = by_name(states[-1], "c")
    assert c_end.lane == 1 and abs(c_end.y - 4.0) < 0.3 and abs(c_end.heading) < 0.02
    assert not any(v.crashed for s in states for v in [s.ego, *s.vehicles])


def test_speed_change_ramps_constant_speed_ego():
    sc = scenario(ego={"speed_mps": 20}, events=[{"type": "speed_change", "vehicle": "ego", "at_s": 1.0,
                                                 "target_speed_mps": 26}], traffic={"vehicles_count": 0})
    for s in simulate(sc, 90):
        expected = min(26.0, 20 + 2.0 * max(0.0, s.t - 1.0))
        assert s.ego.speed == pytest.approx(expected, abs=1e-9)


IDM_ATTRS = {"a_max": "COMFORT_ACC_MAX", "distance_wanted_m": "DISTANCE_WANTED",
             "time_wanted_s": "TIME_WANTED", "delta": "DELTA"}


def _highway_env_reference_stop(v0, gap0, n, dt, idm):
    """Plain highway-env: an IDMVehicle with the given parameters ``gap0`` m (centres) behind an Obstacle."""
    road = Road(RoadNetwork.straight_road_network(3, length=3000, speed_limit=33.0),
                np_random=np.random.default_rng(0))
    car = IDMVehicle(road, [1000.0, 8.0], 0.0, v0, enable_lane_change=False)
    for key, attr in IDM_ATTRS.items():
        if key in idm:
            setattr(car, attr, idm[key])
    if "b_comfort" in idm:
        car.COMFORT_ACC_MIN = -idm["b_comfort"]
    obstacle = Obstacle(road, [1000.0 + gap0, 8.0])
    obstacle.LENGTH, obstacle.WIDTH = 5.0, 2.0        # Obstacle's own size is 2 x 2 m
    obstacle.diagonal = math.hypot(5.0, 2.0)
    road.vehicles, road.objects = [car], [obstacle]
    xs, vs = [], []
    for _ in range(n):
        xs.append(car.position[0] - obstacle.position[0])
        vs.append(car.speed)
        road.act()
        road.step(dt)
    return np.array(xs), np.array(vs), car.crashed


def _idm_behind_wall(v0, dist, duration_s, idm):
    """An IDM car ``dist`` m (centre to centre) behind a stationary one, both in lane 2; the ego parked in lane 0."""
    sc = scenario(duration_s=duration_s, traffic={"vehicles_count": 0, "idm": idm}, ego={"lane": 0, "speed_mps": 0},
                  vehicles=[{"name": "wall", "lane": 2, "distance_m": 200, "behaviour": "stationary"},
                            {"name": "car", "lane": 2, "distance_m": 200 - dist, "speed_mps": v0}])
    states = list(simulate(sc))
    rel = np.array([by_name(s, "car").x - by_name(s, "wall").x for s in states])
    speeds = np.array([by_name(s, "car").speed for s in states])
    return sc, states, rel, speeds


@pytest.mark.parametrize("v0,dist,idm", [
    (20.0, 120.0, {}),                                  # room to brake comfortably
    (20.0, 40.0, {}),                                   # too close: IDM brakes at highway-env's ACC_MAX
    (15.0, 140.0, {"a_max": 2.0, "b_comfort": 4.0, "distance_wanted_m": 18.0, "time_wanted_s": 1.0, "delta": 3.0}),
])
def test_idm_stops_behind_stationary_obstacle_like_highway_env(v0, dist, idm):
    """Same trajectory as highway-env's IDMVehicle (same parameters) behind an Obstacle, up to the stop.

    highway-env's IDM then backs up to its standstill gap (distance_wanted_m, centre to centre)
    when it stopped short of it; ours never reverses and stays stopped, without contact.
    """
    sc, states, rel, speeds = _idm_behind_wall(v0, dist, 25.0, idm)
    ref, ref_v, ref_crashed = _highway_env_reference_stop(v0, dist, len(states), 1 / sc.fps, idm)
    assert not ref_crashed and not any(by_name(s, "car").crashed for s in states)
    k_stop = int(np.argmax(ref_v <= 0))            # the reference's first non-positive speed
    assert k_stop > 0
    assert np.max(np.abs(rel[:k_stop] - ref[:k_stop])) < 1e-6
    assert np.all(speeds[k_stop:] == 0) and np.all(speeds >= 0)
    assert np.all(rel[k_stop:] == rel[k_stop])
    d0 = sc.traffic.idm.distance_wanted_m
    assert by_name(states[-1], "car").length < -rel[-1] <= d0 + 1e-6
    assert ref[-1] == pytest.approx(-d0, abs=1.5)   # heading for its equilibrium gap: the parameters are in effect


def test_vectorised_road_matches_highway_env_road():
    """The vectorised neighbour search and collision pre-check give highway-env's exact results."""
    sc = scenario(seed=3, traffic={"vehicles_count": 30, "density": 2.0, "speed_range_mps": [15, 30]},
                  road={"lanes": 4}, ego={"behaviour": "idm"},
                  vehicles=[{"name": "parked", "lane": 1, "distance_m": 80, "behaviour": "stationary"},
                            {"name": "rammer", "lane": 2, "distance_m": -20, "speed_mps": 30, "behaviour": "constant_speed"},
                            {"name": "slow", "lane": 2, "distance_m": 10, "speed_mps": 15, "behaviour": "constant_speed"}])
    fast, plain = Simulation(sc), Simulation(sc)
    plain.road.__class__ = Road     # highway-env's own act / neighbour_vehicles / step
    for _ in range(150):
        for v in fast.road.vehicles[:8]:
            for lane in range(4):
                idx = ("0", "1", lane)
                assert fast.road.neighbour_vehicles(v, idx) == Road.neighbour_vehicles(fast.road, v, idx)
        assert fast.step() == plain.step()
    end = fast.state()
    assert by_name(end, "rammer").crashed and by_name(end, "slow").crashed   # vehicle-vehicle collisions exercised


# ----------------------------------------------------------------- warm-up
def test_warm_up_frame_zero_is_the_placement_run_that_long():
    """Frame 0 after a 2 s warm-up is frame 30 of the same world without one (15 frames/s), shown at t = 0."""
    base = {**{k: v for k, v in BUSY.items() if k != "events"}, "duration_s": 4.0}
    cold = list(simulate(scenario(**base)))
    warm = list(simulate(scenario(**{**base, "traffic": {**base["traffic"], "warmup_s": 2.0}})))
    assert warm[0].frame == 0 and warm[0].t == 0.0 and len(warm) == len(cold)
    assert warm[0].ego == cold[30].ego and warm[0].vehicles == cold[30].vehicles
    assert warm[10].vehicles == cold[40].vehicles
    assert warm[0].ego.x > cold[0].ego.x + 30          # the ego drove 2 s at about 22 m/s


def _hard_braking_in_path(sc, first_s: float, decel_mps2: float = 3.0) -> int:
    """Frames in the first ``first_s`` in which a vehicle in the ego's lane within 45 m ahead decelerates
    harder than ``decel_mps2`` (m/s^2), from the simulated speeds."""
    n, prev = 0, None
    for st in simulate(sc, int(round(first_s * sc.fps)) + 1):
        if prev is not None:
            before = {v.id: v for v in prev.vehicles}
            n += sum(1 for v in st.vehicles if v.id in before and v.lane == st.ego.lane and 0 < v.x - st.ego.x < 45
                     and (v.speed - before[v.id].speed) * sc.fps < -decel_mps2)
        prev = st
    return n


def test_warm_up_lets_the_placement_braking_wave_pass():
    """highway-env's random placement packs dense traffic closer than IDM's gap: leads brake hard in the
    first seconds. After the nominal suite's 4 s warm-up none does (seeds 1001-1004 of dense_traffic)."""
    data = yaml.safe_load((SCENARIOS / "dense_traffic.yaml").read_text())
    cold = [parse_scenario({**data, "seed": s}) for s in range(1001, 1005)]
    warm = [parse_scenario({**data, "seed": s, "traffic": {**data["traffic"], "warmup_s": 4.0}})
            for s in range(1001, 1005)]
    assert sum(_hard_braking_in_path(sc, 3.0) for sc in cold) >= 20
    assert sum(_hard_braking_in_path(sc, 3.0) for sc in warm) == 0


def test_warm_up_places_road_features_from_the_camera_at_frame_zero():
    sc = scenario(road={"profile": [{"start_m": 100, "grade": 0.03, "transition_m": 50}],
                        "curves": [{"start_m": 150, "radius_m": 800, "direction": "left", "length_m": 100}]},
                  traffic={"vehicles_count": 0, "warmup_s": 3.0}, ego={"speed_mps": 20})
    sim = Simulation(sc)
    camera = sim.state().ego.x + sc.camera.forward_offset_m
    assert sim.state().ego.x == pytest.approx(250 + 60)
    assert sim.profile.starts[0] == pytest.approx(camera + 100) and sim.plan.starts[0] == pytest.approx(camera + 150)


def test_no_warm_up_dumps_as_before_the_field_existed():
    """Cache keys and run.json of every scenario without a warm-up stay as they were."""
    assert "warmup_s" not in scenario().model_dump(mode="json")["traffic"]
    assert scenario(traffic={"warmup_s": 2.0}).model_dump(mode="json")["traffic"]["warmup_s"] == 2.0


# ----------------------------------------------------------------- bad input
@pytest.mark.parametrize("kw,needle", [
    (dict(road={"lanes": 1, "length_m": 400}, ego={"lane": 0}), "road.length_m"),
    (dict(vehicles=[{"name": "a", "distance_m": -3}]), "overlaps the ego"),
    (dict(vehicles=[{"name": "a", "distance_m": 10}, {"name": "b", "distance_m": 12}]), "overlaps 'a'"),
    (dict(vehicles=[{"name": "p", "distance_m": 20, "behaviour": "stationary"}],
          events=[{"type": "speed_change", "vehicle": "p", "at_s": 1, "target_speed_mps": 3}]), "stationary"),
    (dict(vehicles=[{"name": "c", "lane": 1, "distance_m": 20}],
          events=[{"type": "cut_in", "vehicle": "c", "at_s": 1, "gap_m": 10},
                  {"type": "cut_in", "vehicle": "c", "at_s": 3, "gap_m": 10}]), "more than one cut_in"),
    (dict(road={"lanes": 1, "length_m": 800}, ego={"lane": 0, "speed_mps": 20}, duration_s=10,
          traffic={"warmup_s": 10}), "road.length_m"),     # 250 + 20 m/s x 20 s + 200 > 800 (650 without it)
])
def test_unsimulatable_scenarios_raise_one_clear_error(kw, needle):
    with pytest.raises(ScenarioError, match=needle):
        Simulation(scenario(**kw))


# ----------------------------------------------------------------- shipped scenarios
def _scenario_files():
    """``scenarios/*.yaml`` that are scenarios (sweep specs have a ``variants`` or ``scenarios`` list)."""
    out = []
    for p in sorted(SCENARIOS.glob("*.yaml")):
        data = yaml.safe_load(p.read_text())
        if isinstance(data, dict) and not {"variants", "scenarios"} & data.keys():
            out.append(p)
    return out


def test_shipped_scenarios_present():
    names = {p.stem for p in _scenario_files()}
    assert {"static_distances", "highway_cruise", "dense_traffic", "lead_braking", "cut_in", "camera_1080p"} <= names


@pytest.mark.parametrize("path", _scenario_files(), ids=lambda p: p.stem)
def test_shipped_scenario_loads_and_runs_without_crashes(path):
    sc = load_scenario(path)
    states = list(simulate(sc))
    assert len(states) == sc.n_frames
    assert not any(v.crashed for s in states for v in [s.ego, *s.vehicles])


def test_static_distances_ground_truth():
    sc = load_scenario(SCENARIOS / "static_distances.yaml")
    s0 = next(simulate(sc, 1))
    assert s0.ego.speed == 0 and sc.traffic.vehicles_count == 0
    for spec in sc.vehicles:
        v = by_name(s0, spec.name)
        assert v.x - v.length / 2 - camera_x(s0, sc) == pytest.approx(spec.distance_m)
        assert v.lane - s0.ego.lane == spec.lane
    near = {(p.lane, p.distance_m) for p in sc.vehicles if p.distance_m <= 15}
    assert {lane for lane, _ in near} >= {-1, 0, 1} and max(p.distance_m for p in sc.vehicles) >= 60


def _ttc_to(state, v, sc):
    """monorarp's constant-velocity TTC of vehicle v, from exact states (ego frame, camera origin)."""
    cam = sc.camera
    cx, cy = state.ego.x + cam.forward_offset_m, state.ego.y + cam.lateral_offset_m
    ex, ey = ego_extent(state.ego.length, state.ego.width, cam.forward_offset_m, cam.lateral_offset_m)
    return float(time_to_collision(v.y - v.width / 2 - cy, v.y + v.width / 2 - cy,
                                   v.x - v.length / 2 - cx, v.x + v.length / 2 - cx,
                                   v.vy - state.ego.vy, v.vx - state.ego.vx, ex, ey)[()])


def test_lead_braking_ttc_falls_below_two_seconds():
    sc = load_scenario(SCENARIOS / "lead_braking.yaml")
    states = list(simulate(sc))
    ttc = np.array([_ttc_to(s, by_name(s, "lead"), sc) for s in states])
    before = np.array([s.t < 3.0 for s in states])
    assert np.all(np.isnan(ttc[before]))                 # same speeds: no collision course
    assert np.nanmin(ttc) < 2.0
    # closed form, lead braking at a = 7 from tau = t - 3 s: TTC = gap / closing speed, closing = a tau
    g0 = 40.0 - 2.0    # camera-to-rear minus the ego's front, 2 m ahead of the camera
    dt = 1 / sc.fps
    for s, t in zip(states, ttc):
        tau = s.t - 3.0
        # explicit Euler (highway-env moves with the speed before the update): gap shrinks by a tau (tau - dt) / 2
        expected = (g0 - 3.5 * tau * (tau - dt)) / (7.0 * tau) if tau > 0 else math.inf
        if expected < 9.5:
            assert t == pytest.approx(expected, abs=1e-6)


def test_cut_in_scenario_enters_ego_lane():
    sc = load_scenario(SCENARIOS / "cut_in.yaml")
    states = list(simulate(sc))
    ego_lane = sc.ego.lane
    at = next(s for s in states if s.t == 3.0)
    c = by_name(at, "cutter")
    assert c.x - c.length / 2 - camera_x(at, sc) == pytest.approx(14.0, abs=1e-6)
    assert by_name(states[-1], "cutter").lane == ego_lane
