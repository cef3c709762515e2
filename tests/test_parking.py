"""Parked cars of a street: where they stand, how many, which way they face, and that they leave the
traffic and every scenario without a street as it was."""

from __future__ import annotations

import numpy as np
import pytest

from harness.simulation.parking import (PARKED_ID_BASE, PARKED_SHARES, WINDOW_AHEAD_M, WINDOW_BEHIND_M,
                                        ParkedCars, parked_cars)
from harness.simulation.simulator import simulate
from harness.world.ground_truth import frame_truth
from harness.world.scenario import Road, Scenario, Street


def _road(**street) -> Road:
    return Road(lanes=2, lane_width_m=3.25, shoulder_width_m=2.3, length_m=3000.0, street=Street(**street))


def _footprint(c) -> np.ndarray:
    """(4, 2) road-frame corners of a parked car's footprint, from its centre, heading and size."""
    ch, sh = np.cos(c.heading), np.sin(c.heading)
    hl, hw = c.length / 2, c.width / 2
    local = np.array([[hl, hw], [hl, -hw], [-hl, -hw], [-hl, hw]])
    return np.array([c.x, c.y]) + local @ np.array([[ch, sh], [-sh, ch]])


def test_cars_stand_on_their_strip_between_edge_line_and_kerb():
    road = _road()
    cars = parked_cars(road, 7, 0.0, road.length_m)
    edge_r, edge_l = 1.5 * 3.25, -0.5 * 3.25
    for c in cars:
        y = _footprint(c)[:, 1]
        if c.lane == road.lanes:
            assert edge_r < y.min() and y.max() < edge_r + 2.3, c
        else:
            assert c.lane == -1
            assert edge_l - 2.3 < y.min() and y.max() < edge_l, c


def test_cars_do_not_overlap_and_keep_their_density():
    road = _road(parked_per_100m=12.0)
    cars = parked_cars(road, 3, 0.0, road.length_m)
    for lane in (-1, road.lanes):
        side = sorted((c for c in cars if c.lane == lane), key=lambda c: c.x)
        assert all(b.x - b.length / 2 - (a.x + a.length / 2) >= 0.5 for a, b in zip(side, side[1:]))
        per_100m = 100.0 * len(side) / road.length_m
        assert per_100m == pytest.approx(12.0, rel=0.12)


def test_bodies_facing_and_ids():
    road = _road(facing_traffic_share=0.8)
    cars = parked_cars(road, 11, 0.0, road.length_m)
    assert {c.body for c in cars} <= set(PARKED_SHARES) and len({c.body for c in cars}) == len(PARKED_SHARES)
    assert len({c.id for c in cars}) == len(cars) and min(c.id for c in cars) == PARKED_ID_BASE
    right = [c for c in cars if c.lane == road.lanes]
    along = np.mean([np.cos(c.heading) > 0 for c in right])
    assert along == pytest.approx(0.8, abs=0.07)
    assert all(c.speed == c.vx == c.vy == 0.0 for c in cars)


def _bay_road(angle: float, shoulder_m: float, **street) -> Road:
    return Road(lanes=2, lane_width_m=3.25, shoulder_width_m=shoulder_m, length_m=3000.0,
                street=Street(bay_angle_deg=angle, **street))


@pytest.mark.parametrize("angle, shoulder_m", [(90, 5.4), (60, 5.3), (45, 4.8)])
def test_bays_stand_on_their_strip_at_their_angle_and_never_overlap(angle, shoulder_m):
    """Angled and perpendicular bays: every footprint between edge line and kerb, the long axis at the bay
    angle (within the yaw jitter), and no two cars intersecting (cv2.rotatedRectangleIntersection)."""
    import cv2

    road = _bay_road(angle, shoulder_m, parked_per_100m=14.0)
    cars = parked_cars(road, 3, 0.0, road.length_m)
    edge_r, edge_l = 1.5 * 3.25, -0.5 * 3.25
    for c in cars:
        y = _footprint(c)[:, 1]
        if c.lane == road.lanes:
            assert edge_r < y.min() and y.max() < edge_r + shoulder_m, c
        else:
            assert edge_l - shoulder_m < y.min() and y.max() < edge_l, c
        axis = np.degrees(c.heading) % 180.0                   # the long axis, either way round
        assert min(abs(axis - angle), 180 - abs(axis - angle)) <= 4.0 + 1e-6, c
    for lane in (-1, road.lanes):
        side = sorted((c for c in cars if c.lane == lane), key=lambda c: c.x)
        assert len(side) > 50
        for a, b in zip(side, side[1:]):
            rect = [((v.x, v.y), (v.length, v.width), float(np.degrees(v.heading))) for v in (a, b)]
            kind, pts = cv2.rotatedRectangleIntersection(*rect)
            assert kind == cv2.INTERSECT_NONE or pts is None or cv2.contourArea(pts) < 1e-6, (a, b)


def test_perpendicular_bays_keep_the_density_and_the_nose_in_share():
    road = _bay_road(90, 5.4, parked_per_100m=14.0, facing_traffic_share=0.7)
    cars = parked_cars(road, 5, 0.0, road.length_m)
    right = [c for c in cars if c.lane == road.lanes]
    assert 100.0 * len(right) / road.length_m == pytest.approx(14.0, rel=0.12)
    assert np.mean([np.sin(c.heading) > 0 for c in right]) == pytest.approx(0.7, abs=0.07)   # nose to the kerb (+y)
    left = [c for c in cars if c.lane == -1]
    assert np.mean([np.sin(c.heading) < 0 for c in left]) == pytest.approx(0.7, abs=0.07)    # left kerb: -y


def test_bay_angle_rules_and_dump():
    with pytest.raises(ValueError, match="bay_angle_deg: 20"):
        Street(bay_angle_deg=20)
    with pytest.raises(ValueError, match=r"shoulder_width_m: 2.3 m is too narrow .*\(at least 3.7 m"):
        _bay_road(90, 2.3)
    assert Street(bay_angle_deg=90).strip_needed_m() == pytest.approx(3.6 + 0.1)
    assert "bay_angle_deg" not in Street().model_dump() and Street(bay_angle_deg=60).model_dump()["bay_angle_deg"] == 60
    assert _bay_road(90, 2.3, parking="none").street.parking == "none"                    # no cars: any strip
    assert parked_cars(_road(), 7, 0.0, 3000.0) == parked_cars(_road(bay_angle_deg=0), 7, 0.0, 3000.0)


def test_parking_sides_and_none():
    assert {c.lane for c in parked_cars(_road(parking="right"), 1, 0.0, 3000.0)} == {2}
    assert parked_cars(_road(parking="none"), 1, 0.0, 3000.0) == ()
    assert parked_cars(Road(), 1, 0.0, 3000.0) == ()


def test_deterministic_and_windowed():
    road = _road()
    a, b = ParkedCars(road, 5), ParkedCars(road, 5)
    assert a.cars == b.cars and a.cars != ParkedCars(road, 6).cars
    near = a.near(1000.0)
    assert near and all(1000.0 - WINDOW_BEHIND_M <= c.x <= 1000.0 + WINDOW_AHEAD_M for c in near)
    assert len(near) == sum(1000.0 - WINDOW_BEHIND_M <= c.x <= 1000.0 + WINDOW_AHEAD_M for c in a.cars)


def _scenario(street, shoulder_m: float = 2.3) -> Scenario:
    return Scenario.model_validate({
        "name": "street", "seed": 4, "duration_s": 2.0, "fps": 5,
        "road": {"lanes": 2, "lane_width_m": 3.25, "shoulder_width_m": shoulder_m, "street": street},
        "traffic": {"vehicles_count": 5, "speed_range_mps": [8, 12]}, "ego": {"lane": 1, "speed_mps": 10.0}})


def test_parking_leaves_the_traffic_as_it_was():
    with_cars = list(simulate(_scenario({"parked_per_100m": 10}), 8))
    without = list(simulate(_scenario({"parking": "none"}), 8))
    for a, b in zip(with_cars, without):
        assert a.ego == b.ego
        assert tuple(v for v in a.vehicles if v.id < PARKED_ID_BASE) == b.vehicles
        assert any(v.id >= PARKED_ID_BASE for v in a.vehicles)
    assert "street" not in Scenario.model_validate({"name": "m"}).model_dump()["road"]


@pytest.mark.parametrize("street, shoulder_m", [({"parked_per_100m": 10}, 2.3),
                                                ({"parked_per_100m": 12, "bay_angle_deg": 90}, 5.4)])
def test_rendered_parked_cars_are_boxed_inside_their_projected_corners(street, shoulder_m):
    """A parked car in view (parallel or in perpendicular bays) is in the truth, beside the ego's lane, its
    pixel box inside the cv2.projectPoints box of its 3-D corners (the mesh lies in its 3-D box); the near
    ones are mostly visible."""
    import cv2

    from harness.render.renderer import Renderer

    sc = _scenario(street, shoulder_m)
    world = list(simulate(sc, 1))[0]
    cam = sc.camera.model()
    with Renderer(sc) as r:
        truth = frame_truth(world, cam, r.render(world))
    parked = {v.id: v for v in world.vehicles if v.id >= PARKED_ID_BASE}
    seen = [o for o in truth.objects if o.id in parked and o.d_long > 1.0]
    assert len(seen) >= 8 and {parked[o.id].lane for o in seen} == {-1, 2}
    assert max(o.visibility for o in seen) > 0.7
    k = np.array([[cam.fx, 0, cam.cx], [0, cam.fy, cam.cy], [0, 0, 1]], float)
    for o in seen:
        v = parked[o.id]
        assert o.lane_rel == v.lane - world.ego.lane != 0
        assert o.d_lat == pytest.approx(v.y - world.ego.y - cam.lateral_offset_m, abs=1e-6)
        px, _ = cv2.projectPoints(np.array(o.corners_cam, float), np.zeros(3), np.zeros(3), k, None)
        lo, hi = px.reshape(-1, 2).min(0), px.reshape(-1, 2).max(0)
        assert lo[0] - 1.5 <= o.box[0] and lo[1] - 1.5 <= o.box[1], o
        assert o.box[2] <= hi[0] + 1.5 and o.box[3] <= hi[1] + 1.5, o


def test_a_realistic_render_follows_parked_cars_in_and_out_of_the_frame():
    """Parked cars enter the frame window ahead and leave it behind while the renderer swaps their meshes
    (level of detail): every frame renders, each id mask holding only cars of that frame's state."""
    from harness.render.renderer import Renderer

    sc = _scenario({"parked_per_100m": 14})
    sc = sc.model_copy(update={"duration_s": 10.0,
                               "render": sc.render.model_copy(update={"look": "realistic", "look_seed": 2})})
    states = list(simulate(sc, 46))[::3]      # 9 s at 10 m/s: cars first seen beyond 65 m (far meshes) pass
    ids = [{v.id for v in w.vehicles if v.id >= PARKED_ID_BASE} for w in states]
    assert ids[0] - ids[-1] and ids[-1] - ids[0]           # some left behind, some new ahead
    with Renderer(sc) as r:
        for w in states:
            seen = set(np.unique(r.render(w).id_mask).tolist()) - {-1}
            assert seen <= {v.id for v in w.vehicles}
