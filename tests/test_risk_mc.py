"""Monte Carlo IDM/MOBIL risk: driver maths and rollouts against highway-env's own IDMVehicle, risk behaviour.

highway-env is imported here (tests only), never by ``monorarp``. Parameter
mapping: highway-env measures gaps centre to centre and its jam distance
``DISTANCE_WANTED`` (5 m + length) is centre to centre too; our IDM measures net
gaps, so a highway-env scene maps onto ours with vehicle length 0 and
``s0 = DISTANCE_WANTED``; ``COMFORT_ACC_MAX = a``, ``-COMFORT_ACC_MIN = b``,
``TIME_WANTED = T``, ``DELTA = delta``, ``target_speed = v0``.

Rollout tests run on both backends (``numpy`` and, when numba is importable,
``numba``); the two are also compared with each other on whole estimator scenes.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from highway_env.road.road import Road, RoadNetwork
from highway_env.vehicle.behavior import IDMVehicle

from monorarp.risk.monte_carlo.estimator import MonteCarloRisk
from monorarp.risk.monte_carlo.drivers import DriverDistribution, DriverParams, Truncated
from monorarp.risk.monte_carlo.idm import idm_acceleration
from monorarp.risk.monte_carlo.rollout import RolloutConfig, Scene, mobil_sides, simulate
from monorarp.risk.monte_carlo.rollout_numba import NUMBA_AVAILABLE, simulate_numba
from monorarp.core.types import ObjectState

LANE_W = 4.0  # highway-env's lane width

BACKENDS = ["numpy", pytest.param("numba", marks=pytest.mark.skipif(not NUMBA_AVAILABLE, reason="numba missing"))]
needs_numba = pytest.mark.skipif(not NUMBA_AVAILABLE, reason="numba not importable")


def _sim(backend: str):
    return simulate_numba if backend == "numba" else simulate


def _road(lanes: int, seed: int = 0) -> Road:
    net = RoadNetwork.straight_road_network(lanes=lanes, length=10000.0, speed_limit=1000.0)
    return Road(network=net, np_random=np.random.RandomState(seed))


def _hw_vehicle(road, x, lane, speed, v0, a=3.0, b=5.0, T=1.5, s0=10.0, p=0.0, th=0.2, bsafe=2.0):
    veh = IDMVehicle(road, np.array([x, lane * LANE_W], dtype=float), heading=0.0, speed=speed, target_speed=v0)
    veh.COMFORT_ACC_MAX, veh.COMFORT_ACC_MIN, veh.TIME_WANTED, veh.DISTANCE_WANTED = a, -b, T, s0
    veh.POLITENESS, veh.LANE_CHANGE_MIN_ACC_GAIN, veh.LANE_CHANGE_MAX_BRAKING_IMPOSED = p, th, bsafe
    veh.DELTA = 4.0
    road.vehicles.append(veh)
    return veh


# ----------------------------------------------------------------------------- (a) IDM acceleration
def test_idm_acceleration_equals_highway_env_idmvehicle():
    rng = np.random.default_rng(1)
    road = _road(1)
    ours, theirs = [], []
    for _ in range(300):
        a, b, T = rng.uniform(0.5, 3.0), rng.uniform(1.0, 6.0), rng.uniform(0.8, 2.5)
        s0, v, v0 = rng.uniform(6.0, 14.0), rng.uniform(0.0, 38.0), rng.uniform(5.0, 40.0)
        d, v_lead = rng.uniform(5.5, 120.0), rng.uniform(0.0, 38.0)
        road.vehicles.clear()
        ego = _hw_vehicle(road, 100.0, 0, v, v0, a, b, T, s0)
        front = _hw_vehicle(road, 100.0 + d, 0, v_lead, v_lead)
        theirs.append(ego.acceleration(ego_vehicle=ego, front_vehicle=front))
        ours.append(idm_acceleration(v, v0, d, v - v_lead, a, b, T, s0, floor_s_star=False))
        # free road
        theirs.append(ego.acceleration(ego_vehicle=ego, front_vehicle=None))
        ours.append(idm_acceleration(v, v0, np.inf, 0.0, a, b, T, s0, floor_s_star=False))
    np.testing.assert_allclose(ours, theirs, rtol=1e-12, atol=1e-9)
    # Treiber's floored s* differs only where the dynamic part v*T + v*dv/(2 sqrt(ab)) is negative
    assert np.ptp(theirs) > 10.0  # the sample spans free driving to hard braking


def test_idm_floor_only_matters_when_leader_pulls_away():
    v, v0, a, b, T, s0 = 20.0, 30.0, 1.5, 2.0, 1.5, 2.0
    closing = idm_acceleration(v, v0, 30.0, 3.0, a, b, T, s0)
    assert closing == idm_acceleration(v, v0, 30.0, 3.0, a, b, T, s0, floor_s_star=False)
    # leader much faster: s* dynamic part < 0; highway-env's unfloored s* would even brake
    floored = idm_acceleration(v, v0, 30.0, -30.0, a, b, T, s0)
    assert floored == pytest.approx(a * (1 - (v / v0) ** 4 - (s0 / 30.0) ** 2))


# ----------------------------------------------------------------------------- (b) car-following rollout
def _one_lane_case():
    xs = np.array([0.0, 35.0, 70.0, 120.0, 160.0])
    vs = np.array([28.0, 24.0, 26.0, 18.0, 22.0])
    v0s = np.array([31.0, 27.0, 30.0, 20.0, 24.0])
    return xs, vs, v0s


def _highway_one_lane(dt: float, steps: int):
    xs, vs, v0s = _one_lane_case()
    road = _road(1)
    vehs = [_hw_vehicle(road, 50.0 + x, 0, v, v0) for x, v, v0 in zip(xs, vs, v0s)]
    traj_x, traj_v = [[veh.position[0] - 50.0 for veh in vehs]], [[veh.speed for veh in vehs]]
    for _ in range(steps):
        road.act()
        road.step(dt)
        traj_x.append([veh.position[0] - 50.0 for veh in vehs])
        traj_v.append([veh.speed for veh in vehs])
    assert not any(veh.crashed for veh in vehs)
    return np.array(traj_x), np.array(traj_v)


def _ours_one_lane(dt: float, steps: int, integrator: str, backend: str = "numpy"):
    xs, vs, v0s = _one_lane_case()
    n = len(xs)
    scene = Scene(x=xs[None], y=np.zeros((1, n)), v=vs[None], target_lane=np.zeros((1, n), int),
                  length=np.zeros(n), width=np.full(n, 2.0), mobil=np.zeros(n, bool))
    params = DriverParams.uniform((1, n), v0=v0s[None], a=3.0, b=5.0, T=1.5, s0=10.0)
    cfg = RolloutConfig(dt=dt, horizon_s=steps * dt, lane_width_m=LANE_W, integrator=integrator,
                        floor_s_star=False, accel_limit_mps2=6.0, decel_limit_mps2=6.0)
    res = _sim(backend)(scene, params, cfg, record=True)
    return res.x[:, 0], res.v[:, 0]


@pytest.mark.parametrize("backend", BACKENDS)
def test_car_following_rollout_matches_highway_env_road_stepping(backend):
    dt, steps = 0.1, 60
    hx, hv = _highway_one_lane(dt, steps)
    assert np.abs(np.diff(hv, axis=0)).max() > 0.05   # the vehicles really interact
    # Same integrator as highway-env's Vehicle.step on a straight lane (x += v dt, then v += a dt):
    ex, ev = _ours_one_lane(dt, steps, "euler", backend)
    np.testing.assert_allclose(ex, hx, atol=1e-6)
    np.testing.assert_allclose(ev, hv, atol=1e-6)
    # Our default ballistic scheme differs by O(a dt^2 / 2) per step: |dx| <= sum |a| dt^2 / 2 <= 6 * 6 s * 0.1 / 2.
    bx, bv = _ours_one_lane(dt, steps, "ballistic", backend)
    assert np.abs(bx - hx).max() < 0.6
    assert np.abs(bv - hv).max() < 0.3


# ----------------------------------------------------------------------------- (c) MOBIL decisions
def _mobil_compare(cars, lanes: int, backend: str | None = None):
    """cars: list of dicts(x, lane, v, v0, a, b, T, s0, p, th, bsafe). Returns (ours (2, N), theirs (2, N)).

    ``backend=None``: ours from :func:`mobil_sides`; else ours is the direction (N,) in {-1, 0, +1} of the
    lane change each vehicle starts in the first step of a rollout on that backend.
    """
    road = _road(lanes)
    vehs = [_hw_vehicle(road, 50.0 + c["x"], c["lane"], c["v"], c["v0"], c["a"], c["b"], c["T"], c["s0"],
                        c["p"], c["th"], c["bsafe"]) for c in cars]
    theirs = np.zeros((2, len(cars)), bool)
    for i, veh in enumerate(vehs):
        for side, d in ((0, -1), (1, 1)):
            lane = cars[i]["lane"] + d
            if 0 <= lane < lanes:
                theirs[side, i] = veh.mobil(("0", "1", lane))
    n = len(cars)
    col = lambda k: np.array([[c[k] for c in cars]], dtype=float)  # noqa: E731
    scene = Scene(x=col("x"), y=col("lane") * LANE_W, v=col("v"), target_lane=col("lane").astype(int),
                  length=np.zeros(n), width=np.full(n, 2.0), mobil=np.ones(n, bool))
    params = DriverParams(v0=col("v0"), T=col("T"), s0=col("s0"), a=col("a"), b=col("b"), politeness=col("p"),
                          threshold=col("th"), b_safe=col("bsafe"))
    cfg = RolloutConfig(lane_width_m=LANE_W, lane_min=0, lane_max=lanes - 1, floor_s_star=False)
    if backend is None:
        return mobil_sides(scene, params, cfg)[:, 0], theirs
    res = _sim(backend)(scene, params, replace(cfg, horizon_s=2 * cfg.dt), record=True)
    # cars start on lane centres (no drift); lateral motion starts the step after the decision at t = 0
    direction = np.sign(res.y[2, 0] - res.y[1, 0]).astype(int)
    np.testing.assert_array_equal(res.lane_changes[0], np.abs(direction))
    return direction, theirs


def _car(x, lane, v, v0, **kw):
    base = dict(a=3.0, b=5.0, T=1.5, s0=10.0, p=0.0, th=0.2, bsafe=2.0)
    base.update(kw)
    return dict(x=x, lane=lane, v=v, v0=v0, **base)


def test_mobil_hand_built_situations_agree_with_highway_env():
    # slow leader ahead, adjacent lane free -> change right
    ours, theirs = _mobil_compare([_car(0.0, 0, 25.0, 30.0), _car(25.0, 0, 15.0, 15.0)], lanes=2)
    assert theirs[1, 0] and ours[1, 0]
    # same, but a fast car close behind in the target lane -> unsafe, no change
    cars = [_car(0.0, 0, 25.0, 30.0), _car(25.0, 0, 15.0, 15.0), _car(-8.0, 1, 30.0, 30.0)]
    ours, theirs = _mobil_compare(cars, lanes=2)
    assert not theirs[1, 0] and not ours[1, 0]
    # no reason to change: free road ahead
    ours, theirs = _mobil_compare([_car(0.0, 0, 25.0, 25.0)], lanes=2)
    assert not theirs[1, 0] and not ours[1, 0]
    # a polite driver does not cut in front of a follower it would make brake
    cars = [_car(0.0, 0, 20.0, 24.0, p=1.0), _car(30.0, 0, 17.0, 17.0), _car(-18.0, 1, 28.0, 30.0)]
    ours, theirs = _mobil_compare(cars, lanes=2)
    np.testing.assert_array_equal(ours, theirs)


def test_mobil_random_scenes_agree_with_highway_env():
    rng = np.random.default_rng(7)
    agree = total = changes = 0
    for _ in range(40):
        n, lanes = int(rng.integers(2, 7)), int(rng.integers(2, 4))
        xs = rng.permutation(np.arange(n) * 22.0 + rng.uniform(0, 8, n))   # distinct positions
        cars = [_car(float(xs[i]), int(rng.integers(0, lanes)), float(rng.uniform(8, 32)),
                     float(rng.uniform(15, 35)), a=rng.uniform(0.5, 3), b=rng.uniform(1, 5),
                     T=rng.uniform(0.8, 2.5), s0=rng.uniform(6, 12), p=rng.uniform(0, 1),
                     th=rng.uniform(0.05, 0.5), bsafe=rng.uniform(1.5, 5)) for i in range(n)]
        # avoid two cars in one lane overlapping (highway-env would count them as crashed)
        ours, theirs = _mobil_compare(cars, lanes)
        agree += int((ours == theirs).sum())
        total += ours.size
        changes += int(theirs.sum())
    assert changes > 10          # the sample contains plenty of positive decisions
    assert agree == total


def _random_mobil_scenes(n_scenes: int, seed: int):
    rng = np.random.default_rng(seed)
    for _ in range(n_scenes):
        n, lanes = int(rng.integers(2, 7)), int(rng.integers(2, 4))
        xs = rng.permutation(np.arange(n) * 22.0 + rng.uniform(0, 8, n))   # distinct positions
        yield [_car(float(xs[i]), int(rng.integers(0, lanes)), float(rng.uniform(8, 32)),
                    float(rng.uniform(15, 35)), a=rng.uniform(0.5, 3), b=rng.uniform(1, 5),
                    T=rng.uniform(0.8, 2.5), s0=rng.uniform(6, 12), p=rng.uniform(0, 1),
                    th=rng.uniform(0.05, 0.5), bsafe=rng.uniform(1.5, 5)) for i in range(n)], lanes


@pytest.mark.parametrize("backend", BACKENDS)
def test_rollout_lane_changes_follow_highway_env_mobil(backend):
    """The rollout's first MOBIL step starts a change exactly where highway-env's ``mobil`` approves a side;
    with one side approved it is that side (with both, ours takes the larger gain, highway-env the first)."""
    n_change = n_single = 0
    for cars, lanes in _random_mobil_scenes(40, 7):
        direction, theirs = _mobil_compare(cars, lanes, backend)
        np.testing.assert_array_equal(direction != 0, theirs.any(axis=0))
        single = theirs[0] ^ theirs[1]
        np.testing.assert_array_equal(direction[single], np.where(theirs[1], 1, -1)[single])
        n_change += int((direction != 0).sum())
        n_single += int(single.sum())
    assert n_change > 10 and n_single > 5


# ----------------------------------------------------------------------------- drivers
def test_truncated_sampling_respects_ranges_and_shape():
    rng = np.random.default_rng(0)
    blk = DriverDistribution().draw_block(rng, 20000)
    d = DriverDistribution()
    for row, name in enumerate(("T", "s0", "a", "b", "politeness", "threshold", "b_safe")):
        tr: Truncated = getattr(d, name)
        assert blk[row].min() >= tr.lo and blk[row].max() <= tr.hi
        # no pile-up at the bounds (inverse-CDF truncation, not clipping)
        assert np.mean(blk[row] == tr.lo) < 1e-3 and np.mean(blk[row] == tr.hi) < 1e-3
    # truncated-normal mean against scipy's closed form
    from scipy.stats import truncnorm
    tr = d.T
    ref = truncnorm.mean((tr.lo - tr.mean) / tr.std, (tr.hi - tr.mean) / tr.std, loc=tr.mean, scale=tr.std)
    assert blk[0].mean() == pytest.approx(ref, abs=0.01)


# ----------------------------------------------------------------------------- risk behaviour
def _state(tid, d_x, d_y, v_x=0.0, v_y=0.0):
    return ObjectState(tid, d_x, d_y, v_x, v_y)


def test_empty_and_far_scenes_have_no_risk():
    est = MonteCarloRisk(n_rollouts=200)
    assert est.assess({}, 0.0, ego_speed=25.0).risk == 0.0
    far = {1: _state(1, 0.0, 250.0), 2: _state(2, 3.7, 180.0, v_y=2.0), 3: _state(3, -3.7, 120.0, v_y=3.0)}
    r = est.assess(far, 0.0, ego_speed=25.0)
    assert r.risk <= 0.01
    assert all(v is None for v in r.ttc.values())


def test_stopped_vehicle_ahead_is_near_certain_conflict():
    est = MonteCarloRisk(n_rollouts=300)
    r = est.assess({7: _state(7, 0.0, 15.0, v_y=-25.0)}, 0.0, ego_speed=25.0)
    assert r.risk >= 0.95
    # its time to first conflict is the constant-velocity TTC: (15 m - half the ego's 4.5 m) / 25 m/s
    assert r.ttc[7] == pytest.approx((15.0 - 2.25) / 25.0, abs=0.06)
    paper = MonteCarloRisk(n_rollouts=300, score="inverse_ttc").assess({7: _state(7, 0.0, 15.0, v_y=-25.0)}, 0.0, 25.0)
    # most rollouts collide (IDM + 8 m/s^2 cannot stop in 12.75 m from 25 m/s): mean 1/t_collision is large
    assert paper.risk > 0.5


def test_risk_is_monotone_in_closing_speed():
    est = MonteCarloRisk(n_rollouts=300)
    risks = [est.assess({1: _state(1, 0.0, 40.0, v_y=-dv)}, 0.0, ego_speed=30.0).risk
             for dv in (0.0, 5.0, 10.0, 15.0, 20.0, 25.0, 30.0)]
    assert all(b >= a for a, b in zip(risks, risks[1:])), risks
    assert risks[0] < 0.05 and risks[-1] > 0.9


def test_deterministic_for_a_seed_and_seed_matters():
    scene = {1: _state(1, 0.0, 30.0, v_y=-20.0), 2: _state(2, 3.7, 10.0, v_x=-0.3, v_y=-2.0)}
    r1 = MonteCarloRisk(n_rollouts=200, seed=3).assess(scene, 1.0, ego_speed=25.0)
    r2 = MonteCarloRisk(n_rollouts=200, seed=3).assess(scene, 5.0, ego_speed=25.0)
    assert r1 == r2
    risks = {MonteCarloRisk(n_rollouts=200, seed=s).assess(scene, 1.0, ego_speed=25.0).risk for s in range(4)}
    assert 0.0 < min(risks) and max(risks) < 1.0 and len(risks) > 1


def test_ego_speed_sources_and_lane_geometry():
    est = MonteCarloRisk(n_rollouts=50, ego_speed_mps=20.0)
    st = {1: _state(1, 3.9, 30.0, v_y=-1.0)}
    est.assess(st, 0.0)
    assert est.ego_speed_source == "configured"
    est.set_ego_speed(31.0)
    scene, _ = est.build(st, est._ego_speed(None))
    assert est.ego_speed_source == "fed"
    # absolute speed = ego + relative; lane from lateral offset; centre = rear distance + half length
    assert np.median(scene.v[:, 1]) == pytest.approx(30.0, abs=0.2)
    assert np.median(scene.x[:, 1]) == pytest.approx(30.0 + 2.25, abs=0.2)
    assert (np.rint(scene.y[:, 1] / 3.7) == 1).mean() > 0.99
    est.assess(st, 0.0, ego_speed=10.0)
    assert est.ego_speed_source == "argument"
    est2 = MonteCarloRisk(n_rollouts=50)
    est2.assess(st, 0.0)
    assert est2.ego_speed_source == "fallback"


def test_registered_as_risk_monte_carlo():
    from importlib.metadata import entry_points

    from monorarp.pipeline.registry import get_factory

    assert get_factory("risk", "monte_carlo") is MonteCarloRisk
    assert "monte_carlo" not in {ep.name for ep in entry_points(group="monorarp.risk.estimators")}   # declared once


# ----------------------------------------------------------------------------- rollout internals
def _brute_neighbours(x, occ, i, n):
    """Leader / follower of vehicle i among the occupants ``occ`` of a lane, straight from the definition:
    nearest ahead / behind in (x, index) order (exact ties in x: the higher index is ahead); n = nobody."""
    ahead = [j for j in range(n) if occ[j] and j != i and (x[j], j) > (x[i], i)]
    behind = [j for j in range(n) if occ[j] and j != i and (x[j], j) < (x[i], i)]
    lead = min(ahead, key=lambda j: (x[j], j)) if ahead else n
    foll = max(behind, key=lambda j: (x[j], j)) if behind else n
    return lead, foll


def test_lane_neighbours_match_brute_force():
    from monorarp.risk.monte_carlo.rollout import PHANTOM_X, _Order

    rng = np.random.default_rng(11)
    s, lane_min, lane_max = 40, -1, 2
    for n in (1, 2, 7, 12):
        x = np.round(rng.uniform(-60, 60, (n, s)), 0)     # coarse: plenty of exact ties
        cur = rng.integers(lane_min, lane_max + 1, (n, s))
        tgt = np.clip(cur + rng.integers(-1, 2, (n, s)) * (rng.random((n, s)) < 0.4), lane_min, lane_max)
        xs = np.concatenate([x, np.full((1, s), PHANTOM_X)])
        order = _Order(xs, lane_min, lane_max)
        order.set_lanes(order.slot(cur), order.slot(tgt), tgt != cur)
        for d in (-1, 0, 1):
            lane = cur + d
            lead = order.leaders(order.slot(lane)) // s          # flat state index -> vehicle index
            foll = order.followers(order.slot(lane)) // s
            for si in range(s):
                for i in range(n):
                    occ = (cur[:, si] == lane[i, si]) | (tgt[:, si] == lane[i, si])
                    assert (lead[i, si], foll[i, si]) == _brute_neighbours(x[:, si], occ, i, n)


def test_rollout_idm_kernel_equals_reference_idm():
    from monorarp.risk.monte_carlo.rollout import _idm, _Zeros

    rng = np.random.default_rng(5)
    m = 4000
    v, v0, a, b = rng.uniform(0, 40, m), rng.uniform(5, 40, m), rng.uniform(0.5, 3, m), rng.uniform(1, 5, m)
    T, s0, dv = rng.uniform(0.8, 2.5, m), rng.uniform(1, 12, m), rng.uniform(-30, 30, m)
    gap = np.where(rng.random(m) < 0.1, np.inf, rng.uniform(-2, 150, m))   # overlaps and free road too
    for floor in (True, False):
        ref = idm_acceleration(v, v0, gap, dv, a, b, T, s0, floor_s_star=floor)
        ours = _idm(v, a, a * (1 - (v / v0) ** 4), T, 0.5 / np.sqrt(a * b), s0, dv, gap.copy(), floor, _Zeros(float))
        np.testing.assert_allclose(ours, ref, rtol=1e-9, atol=1e-9)


def test_rollouts_do_not_depend_on_chunking(monkeypatch):
    import monorarp.risk.monte_carlo.rollout as rollout

    est = MonteCarloRisk(n_rollouts=120, seed=2, dtype="float64", backend="numpy")   # chunking is numpy's
    scene = {i: _state(i, float(np.array([-3.7, 0.0, 3.7])[i % 3]), 8.0 + 9.0 * i, 0.1 * (i % 2), -4.0 + i)
             for i in range(1, 9)}
    whole = est.assess(scene, 0.0, ego_speed=25.0)
    res_whole = est.last_result
    monkeypatch.setattr(rollout, "_MAX_ELEMS", 500)       # forces several sample chunks
    chunked = est.assess(scene, 0.0, ego_speed=25.0)
    assert whole == chunked
    np.testing.assert_array_equal(res_whole.conflict_t, est.last_result.conflict_t)
    np.testing.assert_array_equal(res_whole.lane_changes, est.last_result.lane_changes)
    assert res_whole.lane_changes.sum() > 0                # lane changes really happen


def test_more_tracks_than_the_rollout_limit():
    from monorarp.risk.monte_carlo.rollout import MAX_VEHICLES

    n = MAX_VEHICLES + 9
    states = {i: _state(i, float([-3.7, 0.0, 3.7][i % 3]), 20.0 + 12.0 * i) for i in range(1, n + 1)}
    states[999] = _state(999, 0.0, 10.0, v_y=-25.0)       # the nearest one: stopped just ahead
    r = MonteCarloRisk(n_rollouts=32).assess(states, 0.0, ego_speed=25.0)
    assert set(r.ttc) == set(states)
    assert r.ttc[999] is not None and r.risk > 0.9
    assert r.ttc[n] is None                                  # the farthest were left out


# ----------------------------------------------------------------------------- backends
@pytest.mark.parametrize("backend", BACKENDS)
def test_contact_test_matches_closed_form_ttc(backend):
    """The per-step conflict test (with the numba pre-filter) against :func:`monorarp.risk.ttc.time_to_collision`.

    dt = 1.5 s > near_miss = 1 s: a conflict seen at t = 0 is recorded as its contact time (< 1 s), one
    seen only at the next step as >= 1.5 s, so the first step's verdict is read off ``conflict_t``.
    """
    from monorarp.risk.ttc import time_to_collision

    rng = np.random.default_rng(3)
    s, W, dt = 6000, 3.7, 1.5
    cfg = RolloutConfig(dt=dt, horizon_s=dt, lane_width_m=W, lane_min=-2, lane_max=2, lane_change_duration_s=W,
                        near_miss_ttc_s=1.0)
    lanes = rng.integers(-1, 2, (s, 2))
    lanes[:, 0] = 0
    y = lanes * W + rng.uniform(-0.5, 0.5, (s, 2))
    tgt = lanes + rng.integers(-1, 2, (s, 2)) * (rng.random((s, 2)) < 0.5)
    x = np.stack([np.zeros(s), rng.uniform(-25.0, 25.0, s)], axis=1)
    v = np.stack([np.full(s, 25.0), 25.0 + rng.uniform(-20.0, 20.0, s)], axis=1)
    v[::7, 1] = 25.0                                                  # no relative speed along the road
    length, width = np.array([4.5, 4.0]), np.array([1.8, 2.0])
    scene = Scene(x=x, y=y, v=v, target_lane=tgt, length=length, width=width, mobil=np.zeros(2, bool))
    res = _sim(backend)(scene, DriverParams.uniform((s, 2), v0=30.0), cfg)
    # lateral speeds at t = 0: towards the target lane centre at W / duration = 1 m/s, slower within the step
    vy = np.clip((tgt * W - y) / dt, -1.0, 1.0)
    ref = time_to_collision(y[:, 1] - 1.0, y[:, 1] + 1.0, x[:, 1] - 2.0, x[:, 1] + 2.0,
                            vy[:, 1] - vy[:, 0], v[:, 1] - v[:, 0], (y[:, 0] - 0.9, y[:, 0] + 0.9),
                            (-2.25, 2.25), horizon_s=1.0)
    hit = np.isfinite(ref)
    assert 0.1 < hit.mean() < 0.9
    np.testing.assert_allclose(res.conflict_t[hit, 1], ref[hit], rtol=0, atol=1e-9)
    assert (res.conflict_t[~hit, 1] >= dt).all()
    np.testing.assert_array_equal(res.collision_t[:, 1] == 0.0, ref == 0.0)
    assert np.isinf(res.conflict_t[:, 0]).all()                       # the ego's own column


def _parity_scenes():
    """(name, states, ego speed, lanes_left, lanes_right): free flow, cut-ins, a stopped car, dense traffic."""
    rng = np.random.default_rng(21)
    dense = {i: _state(i, float([-3.7, 0.0, 3.7][i % 3] + rng.normal(0, 0.3)), float(rng.uniform(6, 90)),
                       float(rng.normal(0, 0.3)), float(rng.normal(-2, 4))) for i in range(1, 21)}
    mixed = {i: _state(i, float([-3.7, 0.0, 3.7][i % 3] + rng.normal(0, 0.3)), float(rng.uniform(8, 100)),
                       float(rng.normal(0, 0.2)), float(rng.normal(0, 3))) for i in range(1, 11)}
    cut_in = {1: _state(1, 3.2, 9.0, v_x=-0.8, v_y=-3.0), 2: _state(2, 0.0, 45.0, v_y=-6.0),
              3: _state(3, -3.7, -12.0, v_y=4.0), 4: _state(4, -3.7, 25.0, v_x=0.5, v_y=-1.0)}
    stopped = {7: _state(7, 0.0, 30.0, v_y=-25.0), 8: _state(8, 3.7, 15.0, v_y=-2.0), 9: _state(9, -3.7, 5.0)}
    return [("mixed", mixed, 25.0, 1, 1), ("dense", dense, 28.0, 1, 1), ("cut_in", cut_in, 30.0, 1, 1),
            ("stopped", stopped, 25.0, 1, 1), ("two_lanes", cut_in, 20.0, 0, 1)]


@needs_numba
@pytest.mark.parametrize("score", ["probability", "inverse_ttc"])
def test_numba_and_numpy_backends_agree(score):
    """Same draws (made in numpy before either kernel), same futures up to floating-point rounding."""
    s_total = lanes = conflicts = 0
    for name, states, v_e, left, right in _parity_scenes():
        kw = dict(n_rollouts=400, seed=5, dtype="float64", score=score, lanes_left=left, lanes_right=right)
        a, b = MonteCarloRisk(backend="numpy", **kw), MonteCarloRisk(backend="numba", **kw)
        assert (a.backend, b.backend) == ("numpy", "numba")
        ra, rb = a.assess(states, 0.0, ego_speed=v_e), b.assess(states, 0.0, ego_speed=v_e)
        pa, pb = a.last_result, b.last_result
        fa, fb = np.isfinite(pa.conflict_t[:, 1:]).any(1), np.isfinite(pb.conflict_t[:, 1:]).any(1)
        assert (fa == fb).mean() >= 0.99, name
        if score == "probability":
            p = 0.5 * (ra.risk + rb.risk)
            assert abs(ra.risk - rb.risk) <= np.sqrt(p * (1 - p) / 400), name      # one binomial SE
        else:
            assert ra.risk == pytest.approx(rb.risk, rel=0.05, abs=1e-3), name
        for t_a, t_b in ((pa.conflict_t, pb.conflict_t), (pa.collision_t, pb.collision_t)):
            both = np.isfinite(t_a) & np.isfinite(t_b)
            np.testing.assert_allclose(t_a[both], t_b[both], rtol=0, atol=1e-6, err_msg=name)
            assert (np.isfinite(t_a) == np.isfinite(t_b)).mean() >= 0.99, name
        assert (pa.lane_changes == pb.lane_changes).mean() >= 0.99, name
        assert ra.ttc.keys() == rb.ttc.keys()
        s_total += 400
        lanes += int(pa.lane_changes.sum())
        conflicts += int(fa.sum())
    assert lanes > 1000 and 200 < conflicts < s_total - 200     # lane changes and conflicts both exercised


@needs_numba
def test_numba_records_the_same_trajectories():
    est = MonteCarloRisk(n_rollouts=60, seed=1, dtype="float64", backend="numpy", lanes_left=1, lanes_right=1)
    _, states, v_e, _, _ = _parity_scenes()[1]
    scene, params = est.build(states, v_e)
    lo, hi = est._lanes
    cfg = replace(est.rollout_config, lane_min=lo, lane_max=hi)
    a, b = simulate(scene, params, cfg, record=True), simulate_numba(scene, params, cfg, record=True)
    assert a.x.shape == b.x.shape == (cfg.n_steps + 1, 60, len(states) + 1)
    for f in ("x", "y", "v"):
        np.testing.assert_allclose(getattr(b, f), getattr(a, f), rtol=0, atol=1e-6)
    assert np.ptp(a.y) > 3.0                                           # vehicles do change lanes


def test_backend_option(monkeypatch):
    import monorarp.risk.monte_carlo.rollout_numba as rn
    from monorarp.core.errors import UserError
    from monorarp.risk.monte_carlo.estimator import MonteCarloConfigError

    assert MonteCarloRisk(n_rollouts=8, backend="numpy").backend == "numpy"
    assert MonteCarloRisk(n_rollouts=8).backend == ("numba" if NUMBA_AVAILABLE else "numpy")
    with pytest.raises(UserError, match="backend"):
        MonteCarloRisk(n_rollouts=8, backend="cuda")
    monkeypatch.setattr(rn, "NUMBA_AVAILABLE", False)                # a machine without numba
    assert MonteCarloRisk(n_rollouts=8).backend == "numpy"            # auto falls back
    with pytest.raises(MonteCarloConfigError, match="numba"):
        MonteCarloRisk(n_rollouts=8, backend="numba")


# ----------------------------------------------------------------------------- ego model
_NO_NOISE = dict(position_m=0.0, position_rel=0.0, lateral_m=0.0, speed_mps=0.0, speed_rel=0.0, ego_speed_mps=0.0)
# desired speeds pinned to the current speed (a stopped car stays (almost) stopped: it creeps < 0.3 m in 3 s)
_STILL_DRIVERS = DriverDistribution(v0_rel_std=0.0, v0_min_std_mps=1e-3, v0_floor_mps=1e-3)


@pytest.mark.parametrize("backend", BACKENDS)
def test_constant_speed_ego_hits_a_stopped_car_at_the_closed_form_ttc(backend):
    """A non-reacting ego (FCW test protocols) at v towards a stopped car d ahead collides in every rollout,
    at the constant-velocity TTC (d - ego front offset) / v; the default IDM ego brakes and avoids it."""
    d, v, dt = 60.0, 20.0, 0.2
    stopped = {1: _state(1, 0.0, d, v_y=-v)}
    ttc_cv = (d - 4.5 / 2.0) / v                                    # camera at the ego's centre: front offset 2.25 m
    kw = dict(n_rollouts=200, dt=dt, dtype="float64", backend=backend, noise=_NO_NOISE, drivers=_STILL_DRIVERS)
    est = MonteCarloRisk(ego_model="constant_speed", **kw)
    r = est.assess(stopped, 0.0, ego_speed=v)
    res = est.last_result
    assert r.risk == 1.0
    assert np.isfinite(res.collision_t[:, 1]).all()                 # every rollout collides ...
    assert ((res.collision_t[:, 1] >= ttc_cv) & (res.collision_t[:, 1] <= ttc_cv + dt)).all()  # ... at the grid step
    assert r.ttc[1] == pytest.approx(ttc_cv, abs=dt)
    assert np.abs(res.conflict_t[:, 1] - ttc_cv).max() < 0.05      # measured ~0.02 s (the stopped car creeps)
    # with the default noise and drivers too
    r_noisy = MonteCarloRisk(n_rollouts=200, dt=dt, backend=backend, ego_model="constant_speed").assess(
        stopped, 0.0, ego_speed=v)
    assert r_noisy.risk == 1.0 and r_noisy.ttc[1] == pytest.approx(ttc_cv, abs=dt)
    # the IDM ego has 57.75 m to stop from 20 m/s (needs ~25 m at 8 m/s^2): it brakes, no collision
    est_idm = MonteCarloRisk(ego_model="idm", **kw)
    r_idm = est_idm.assess(stopped, 0.0, ego_speed=v)
    assert np.isinf(est_idm.last_result.collision_t[:, 1]).mean() >= 0.9
    assert r_idm.risk <= 0.1 and r_idm.ttc[1] is None


@pytest.mark.parametrize("backend", BACKENDS)
def test_constant_speed_ego_holds_speed_and_lane_while_others_react(backend):
    states = {1: _state(1, 0.0, 25.0, v_y=-8.0), 2: _state(2, 3.7, 10.0, v_y=-3.0), 3: _state(3, 0.0, -15.0, v_y=2.0)}
    est = MonteCarloRisk(n_rollouts=50, seed=4, dtype="float64", backend=backend, lanes_left=1, lanes_right=1,
                         ego_model="constant_speed")
    assert est.config.ego_model == "constant_speed" and not est.ego_lane_changes
    scene, params = est.build(states, 22.0)
    np.testing.assert_array_equal(scene.v[:, 0], 22.0)              # no ego-speed noise
    lo, hi = est._lanes
    cfg = replace(est.rollout_config, lane_min=lo, lane_max=hi)
    res = _sim(backend)(scene, params, cfg, record=True)
    t = np.arange(cfg.n_steps + 1) * cfg.dt
    np.testing.assert_array_equal(res.v[:, :, 0], 22.0)
    np.testing.assert_allclose(res.x[:, :, 0], 22.0 * t[:, None] * np.ones((1, 50)), rtol=0, atol=1e-9)
    np.testing.assert_array_equal(res.y[:, :, 0], 0.0)
    assert (res.lane_changes[:, 0] == 0).all()
    assert np.ptp(res.v[:, :, 1:]) > 1.0                           # the others still drive IDM/MOBIL
    # the follower closing on the ego from behind (24 m/s) brakes for it in every rollout
    assert (res.v[:, :, 3].min(axis=0) < res.v[0, :, 3] - 1.0).all()


@needs_numba
def test_numba_and_numpy_backends_agree_with_constant_speed_ego():
    """Parity as :func:`test_numba_and_numpy_backends_agree`, with the ego holding its speed and lane."""
    s_total = lanes = conflicts = 0
    for name, states, v_e, left, right in _parity_scenes():
        kw = dict(n_rollouts=400, seed=5, dtype="float64", lanes_left=left, lanes_right=right,
                  ego_model="constant_speed")
        a, b = MonteCarloRisk(backend="numpy", **kw), MonteCarloRisk(backend="numba", **kw)
        ra, rb = a.assess(states, 0.0, ego_speed=v_e), b.assess(states, 0.0, ego_speed=v_e)
        pa, pb = a.last_result, b.last_result
        fa, fb = np.isfinite(pa.conflict_t[:, 1:]).any(1), np.isfinite(pb.conflict_t[:, 1:]).any(1)
        assert (fa == fb).mean() >= 0.99, name
        p = 0.5 * (ra.risk + rb.risk)
        assert abs(ra.risk - rb.risk) <= np.sqrt(p * (1 - p) / 400), name
        for t_a, t_b in ((pa.conflict_t, pb.conflict_t), (pa.collision_t, pb.collision_t)):
            both = np.isfinite(t_a) & np.isfinite(t_b)
            np.testing.assert_allclose(t_a[both], t_b[both], rtol=0, atol=1e-6, err_msg=name)
            assert (np.isfinite(t_a) == np.isfinite(t_b)).mean() >= 0.99, name
        assert (pa.lane_changes == pb.lane_changes).mean() >= 0.99, name
        assert (pa.lane_changes[:, 0] == 0).all() and (pb.lane_changes[:, 0] == 0).all(), name
        s_total += 400
        lanes += int(pa.lane_changes.sum())
        conflicts += int(fa.sum())
    assert lanes > 500 and 200 < conflicts < s_total - 50     # measured 1867 of 2000: the ego never brakes
    # whole trajectories, one scene
    est = MonteCarloRisk(n_rollouts=60, seed=1, dtype="float64", backend="numpy", lanes_left=1, lanes_right=1,
                         ego_model="constant_speed")
    _, states, v_e, _, _ = _parity_scenes()[1]
    scene, params = est.build(states, v_e)
    cfg = replace(est.rollout_config, lane_min=est._lanes[0], lane_max=est._lanes[1])
    ta, tb = simulate(scene, params, cfg, record=True), simulate_numba(scene, params, cfg, record=True)
    for f in ("x", "y", "v"):
        np.testing.assert_allclose(getattr(tb, f), getattr(ta, f), rtol=0, atol=1e-6)


def test_ego_model_option_is_validated():
    from monorarp.core.errors import UserError
    from monorarp.risk.monte_carlo.estimator import MonteCarloConfigError

    assert MonteCarloRisk(n_rollouts=8, backend="numpy").ego_model == "idm"
    with pytest.raises(MonteCarloConfigError, match="ego_model.*'constant_velocity'"):
        MonteCarloRisk(n_rollouts=8, backend="numpy", ego_model="constant_velocity")
    with pytest.raises(UserError, match="ego_model"):
        MonteCarloRisk(n_rollouts=8, backend="numpy", ego_model=None)
    with pytest.raises(ValueError, match="ego_model"):
        RolloutConfig(ego_model="cv")


# ------------------------------------------------------------------------------- settings
def test_settings_are_one_config_and_keyword_overrides_of_it():
    import inspect

    from monorarp.core.camera import CameraModel
    from monorarp.risk.monte_carlo.config import MonteCarloConfig, MonteCarloConfigError

    base = MonteCarloConfig(n_rollouts=40, seed=5, backend="numpy", dtype="float64")
    est = MonteCarloRisk(config=base, horizon_s=4.0)
    assert est.config == base.model_copy(update={"horizon_s": 4.0}) and est.rollout_config.horizon_s == 4.0
    states = {1: _state(1, 0.0, 20.0, v_y=-6.0), 2: _state(2, 3.7, 12.0, v_y=-2.0)}
    same = MonteCarloRisk(n_rollouts=40, seed=5, backend="numpy", dtype="float64", horizon_s=4.0)
    assert est.assess(states, 0.0, 25.0) == same.assess(states, 0.0, 25.0)
    cam = replace(CameraModel.from_fov(320, 180, 60.0, 1.3), forward_offset_m=1.5, lateral_offset_m=-0.2)
    est = MonteCarloRisk(camera=cam, n_rollouts=8, backend="numpy", camera_forward_offset_m=9.0)
    assert (est.config.camera_forward_offset_m, est.config.camera_lateral_offset_m) == (1.5, -0.2)  # the camera wins
    assert MonteCarloRisk(n_rollouts=8, backend="numpy", noise={"lateral_m": 0.0}).noise.lateral_m == 0.0
    with pytest.raises(MonteCarloConfigError, match="unknown monte_carlo risk setting 'n_rollout'"):
        MonteCarloRisk(n_rollout=8)
    with pytest.raises(MonteCarloConfigError, match="n_rollouts: .*greater than or equal to 1, got 0"):
        MonteCarloRisk(n_rollouts=0)
    with pytest.raises(MonteCarloConfigError, match="dt: .*greater than 0"):
        MonteCarloRisk(n_rollouts=8, backend="numpy", dt=0.0)
    with pytest.raises(MonteCarloConfigError, match="noise: unknown noise field"):
        MonteCarloRisk(n_rollouts=8, backend="numpy", noise={"position": 1.0})
    params = inspect.signature(MonteCarloRisk).parameters          # what the registry and help() read
    assert list(params)[:2] == ["camera", "config"] and set(MonteCarloConfig.model_fields) <= set(params)
