"""Body types of a real fleet (harness.world.fleet, harness.world.vehicles): the fleet's shares and dimensions,
each type's layout, meshes that fill their footprint box and height exactly, the scenario options
(traffic.fleet, a placed vehicle's body), the simulation's footprints, the truth's and KITTI export's types
and boxes against a rendered vehicle's mask, and the metallic paint of the realistic look."""

from __future__ import annotations

import typing
from collections import Counter

import cv2
import numpy as np
import pytest

from harness.export import geometry as geo
from harness.export.kitti import label_fields
from harness.render import materials
from harness.render.look import SkyLook, SunLook
from harness.render.materials import Material, shade_realistic
from harness.render.meshes import TRUCK_MAX_TRIANGLES, vehicle_faces, vehicle_faces_detailed
from harness.simulation.simulator import Simulation
from harness.world import fleet
from harness.world.scenario import PlacedVehicle, ScenarioError, Traffic, load_scenario, parse_scenario
from harness.world.truth import ObjectTruth
from harness.world.vehicles import BODY_TYPES, KITTI_TYPE, kitti_type, vehicle_height, vehicle_layout

RED = (170, 25, 30)


def _draws(body: str, n: int = 4) -> list[tuple[float, float]]:
    return [fleet.typical_dimensions(body, fleet.vehicle_rng(seed, 7)) for seed in range(n)]


# ------------------------------------------------------------------------------------------- fleet
def test_fleet_shares_follow_the_table():
    rng = np.random.default_rng(0)
    n = 20000
    counts = Counter(fleet.draw_body(rng)[0] for _ in range(n))
    for body in BODY_TYPES:
        p = fleet.SHARES[body]
        assert abs(counts[body] / n - p) < 4 * np.sqrt(p * (1 - p) / n) + 1e-3, body
    cars = sum(counts[b] for b in ("hatchback", "saloon", "estate", "suv")) / n
    hgv = (counts["box_truck"] + counts["artic"]) / n
    assert 0.70 < cars < 0.76 and 0.08 < hgv < 0.12 and counts["bus"] / n < 0.02


@pytest.mark.parametrize("body", BODY_TYPES)
def test_dimensions_stay_in_their_type_range_and_are_deterministic(body):
    (lm, _, llo, lhi), (wm, _, wlo, whi) = fleet.DIMENSIONS[body]
    extra = 0.0 if body in ("box_truck", "artic", "bus") else fleet.MIRRORS_M
    rng = np.random.default_rng(3)
    draws = np.array([fleet.typical_dimensions(body, rng) for _ in range(2000)])
    assert (draws[:, 0] >= llo - 1e-9).all() and (draws[:, 0] <= lhi + 1e-9).all()
    assert (draws[:, 1] >= wlo + extra - 0.006).all() and (draws[:, 1] <= whi + extra + 0.006).all()
    assert abs(np.median(draws[:, 0]) - lm) < 0.1 * lm and abs(np.median(draws[:, 1]) - wm - extra) < 0.05
    assert fleet.typical_dimensions(body, fleet.vehicle_rng(5, 9)) == fleet.typical_dimensions(
        body, fleet.vehicle_rng(5, 9))
    # within what a scenario's placed vehicle accepts
    assert draws[:, 0].min() >= 3.0 and draws[:, 0].max() <= 20.0 and 1.4 <= draws[:, 1].min() <= draws[:, 1].max() <= 3.0


def test_unknown_body_is_refused():
    with pytest.raises(ValueError, match="not one of"):
        vehicle_layout(4.5, 1.9, "limousine")
    with pytest.raises(ValueError, match="not one of"):
        fleet.typical_dimensions("tank", np.random.default_rng(0))


# ------------------------------------------------------------------------------------------ layouts
@pytest.mark.parametrize("length,width", [(3.8, 1.7), (4.5, 1.8), (5.0, 2.0), (6.0, 2.0), (7.5, 2.4), (16.0, 2.55)])
def test_no_body_keeps_the_footprint_rule(length, width):
    assert vehicle_layout(length, width) == vehicle_layout(length, width, None)
    lay = vehicle_layout(length, width)
    assert lay.body is None and lay.roof == (3.6 if length > 7 else 1.45 if length <= 5.5 else 2.1)
    assert vehicle_height(length, width) == lay.roof
    assert kitti_type(length, width) == geo.kitti_type(length, width) == ("Truck" if length > 7 else "Car")


def test_body_types_have_their_proportions():
    def lay(body):
        return vehicle_layout(*_draws(body, 1)[0], body)

    hatch, saloon, estate, suv, van, pickup = (lay(b) for b in ("hatchback", "saloon", "estate", "suv", "van",
                                                                  "pickup"))
    assert suv.roof > estate.roof > saloon.roof and suv.clearance > hatch.clearance and suv.belt > hatch.belt
    assert suv.wheel_radius > hatch.wheel_radius
    assert hatch.rear_overhang < saloon.rear_overhang                      # a hatchback's short rear
    assert 1.8 < van.roof < 2.8 and 1.75 < pickup.roof < 2.0 and pickup.belt > suv.belt
    assert 1.3 < pickup.length - pickup.cab_length < 2.0                    # an open bed behind the cab
    for car in (hatch, saloon, estate, suv):
        assert 0.6 <= car.rear_overhang <= 1.15 and 0.14 <= car.clearance <= 0.22
    for length in (7.2, 8.8, 10.5):
        box = vehicle_layout(length, 2.5, "box_truck")
        assert 3.3 <= box.roof <= 3.8 and len(box.axles) == (2 if length <= 9 else 3)
    artic = vehicle_layout(16.5, 2.55, "artic")
    assert artic.roof == 4.0 and len(artic.axles) == 5 and artic.axles[0] == artic.rear_axle_x
    bus = vehicle_layout(12.0, 2.55, "bus")
    assert 3.0 <= bus.roof <= 3.6 and 2.6 <= bus.rear_overhang <= 3.6 and len(bus.axles) == 2


def test_kitti_types_follow_kittis_convention():
    assert set(KITTI_TYPE) == set(BODY_TYPES)
    assert {b for b, t in KITTI_TYPE.items() if t == "Car"} == {"hatchback", "saloon", "estate", "suv", "pickup"}
    assert KITTI_TYPE["van"] == "Van" and {KITTI_TYPE[b] for b in ("box_truck", "artic", "bus")} == {"Truck"}
    assert geo.kitti_type(4.0, 1.9, "van") == "Van" and geo.kitti_type(12.0, 2.55, "bus") == "Truck"
    assert geo.kitti_type(5.5, 2.0, "pickup") == "Car"        # whatever its footprint says


def test_the_scenario_schema_lists_exactly_the_body_types():
    body = PlacedVehicle.model_fields["body"].annotation
    assert set(typing.get_args(typing.get_args(body)[0])) == set(BODY_TYPES)


# ------------------------------------------------------------------------------------------- meshes
@pytest.mark.parametrize("body", BODY_TYPES)
@pytest.mark.parametrize("seed,dirt", [(0, 0.0), (1, 0.6)])
def test_every_body_types_mesh_fills_its_box_exactly(body, seed, dirt):
    """Detailed (realistic look) and simple meshes: bounds = (length, width, vehicle_height), only the tyres on
    the ground, every axle's tyres touching it, every face tagged, within the triangle budget."""
    for length, width in _draws(body, 3):
        h = vehicle_height(length, width, body)
        want = np.array([[-length / 2, -width / 2, 0.0], [length / 2, width / 2, h]])
        t, n, a, m = vehicle_faces_detailed(length, width, RED, dirt, seed, body=body)
        v = t.reshape(-1, 3)
        np.testing.assert_allclose([v.min(0), v.max(0)], want, rtol=0, atol=1e-9)
        ts, _, _ = vehicle_faces(length, width, RED, body=body)
        vs = ts.reshape(-1, 3)
        np.testing.assert_allclose([vs.min(0), vs.max(0)], want, rtol=0, atol=1e-9)
        assert len(t) <= TRUCK_MAX_TRIANGLES and set(np.unique(m)) <= {int(x) for x in Material}
        assert not (m == Material.MATTE).any()
        cross = np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])
        assert np.linalg.norm(cross, axis=1).min() > 1e-10
        np.testing.assert_allclose(n, cross / np.linalg.norm(cross, axis=1, keepdims=True), atol=1e-12)
        tyre = t[m == Material.TYRE].reshape(-1, 3)
        assert t[m != Material.TYRE].reshape(-1, 3)[:, 2].min() > 0.0
        ground = tyre[tyre[:, 2] == 0.0]
        for ax in vehicle_layout(length, width, body).axles:
            for side in (-1, 1):
                assert ((np.abs(ground[:, 0] - ax) < 1e-9) & (np.sign(ground[:, 1]) == side)).any(), (body, ax)
        assert {Material.PAINT, Material.GLASS, Material.LIGHT, Material.PLATE, Material.SHADOW} <= set(
            Material(x) for x in np.unique(m))


def test_body_meshes_differ_from_the_footprint_rule_and_between_types():
    shapes = {b: vehicle_faces_detailed(4.6, 2.0, RED, 0.0, 1, body=b)[0] for b in ("saloon", "estate", "suv")}
    shapes[None] = vehicle_faces_detailed(4.6, 2.0, RED, 0.0, 1)[0]
    assert len({s.tobytes() for s in shapes.values()}) == 4


def test_pickup_has_an_open_bed_and_the_artic_a_gap_behind_its_cab():
    length, width = 5.4, 2.05
    lay = vehicle_layout(length, width, "pickup")
    t, n, _, m = vehicle_faces_detailed(length, width, RED, 0.0, 0, body="pickup")
    c = t.mean(axis=1)
    bed = (c[:, 0] < -length / 2 + (length - lay.cab_length) - 0.1) & (np.abs(c[:, 1]) < 0.5)
    assert c[bed, 2].max() < lay.belt + 0.01                       # nothing stands on the bed
    liner = bed & (m == Material.TRIM) & (n[:, 2] > 0.99)
    assert liner.any() and np.allclose(c[liner, 2].min(), lay.belt + 0.004)
    t, _, _, _ = vehicle_faces_detailed(16.5, 2.55, RED, 0.0, 0, body="artic")
    lo, hi = t.min(axis=1), t.max(axis=1)
    x_cab = 16.5 / 2 - vehicle_layout(16.5, 2.55, "artic").cab_length
    box_lo, box_hi = np.array([x_cab - 0.7, -0.3, 1.2]), np.array([x_cab - 0.05, 0.3, 4.0])
    through = ((lo < box_hi) & (hi > box_lo)).all(axis=1)
    assert not through.any()                                        # chassis only between trailer and cab
    rails_lo, rails_hi = np.array([x_cab - 0.7, -1.0, 0.5]), np.array([x_cab - 0.05, 1.0, 1.0])
    assert ((lo < rails_hi) & (hi > rails_lo)).all(axis=1).any()    # ... which is there


# ----------------------------------------------------------------------------------------- scenario
def _base(**over):
    d = {"name": "fleet", "seed": 11, "duration_s": 2.0, "road": {"lanes": 3},
         "traffic": {"vehicles_count": 12, "fleet": "mixed"}, "ego": {"lane": 1}}
    d.update(over)
    return d


def test_traffic_fleet_defaults_to_none_and_dumps_as_before():
    assert Traffic().fleet == "none" and "fleet" not in Traffic().model_dump()
    assert Traffic(fleet="mixed").model_dump()["fleet"] == "mixed"
    with pytest.raises(ScenarioError, match="fleet"):
        parse_scenario(_base(traffic={"fleet": "trucks"}))


def test_placed_body_is_validated_and_its_size_drawn_when_absent():
    p = PlacedVehicle(name="a", distance_m=10)
    assert (p.length_m, p.width_m, p.body) == (5.0, 2.0, None) and "body" not in p.model_dump()
    with pytest.raises(ScenarioError) as e:
        parse_scenario(_base(vehicles=[{"name": "a", "distance_m": 10, "body": "limousine"}]))
    assert "vehicles.0.body" in str(e.value) and "\n" not in str(e.value).strip()
    s = parse_scenario(_base(vehicles=[{"name": "a", "distance_m": 20, "body": "bus"},
                                       {"name": "b", "distance_m": 20, "lane": 1, "body": "van", "length_m": 6.5}]))
    assert s.vehicles[0].length_m is None and parse_scenario(s.model_dump(mode="json")) == s   # round trip
    w = Simulation(s).state()
    bus, van = w.vehicles[0], w.vehicles[1]
    assert bus.body == "bus" and (bus.length, bus.width) == fleet.typical_dimensions("bus", fleet.vehicle_rng(11, 1))
    assert van.body == "van" and van.length == 6.5 and van.width == fleet.typical_dimensions(
        "van", fleet.vehicle_rng(11, 2))[1]


def test_mixed_fleet_gives_highway_env_each_vehicles_footprint():
    s = parse_scenario(_base())
    sim = Simulation(s)
    w = sim.state()
    traffic = [v for v in w.vehicles if v.name is None]
    assert len(traffic) == 12 and all(v.body in BODY_TYPES for v in traffic)
    want = [fleet.draw_body(fleet.vehicle_rng(11, v.id)) for v in traffic]
    assert [(v.body, v.length, v.width) for v in traffic] == want
    hv = {v.vid: v for v in sim.road.vehicles}
    for v in traffic:                       # the dynamics and collisions use the same footprint
        assert (hv[v.id].LENGTH, hv[v.id].WIDTH) == (v.length, v.width)
        assert np.isclose(hv[v.id].diagonal, np.hypot(v.length, v.width))
    assert len({b for b, _, _ in want}) > 2
    again = Simulation(parse_scenario(_base())).state()
    assert again == w                       # deterministic
    plain = Simulation(parse_scenario(_base(traffic={"vehicles_count": 12}))).state()
    assert all(v.body is None and (v.length, v.width) == (5.0, 2.0) for v in plain.vehicles)


def test_truth_record_carries_the_body_only_when_set():
    o = ObjectTruth(id=3, box=(1.0, 2.0, 3.0, 4.0), visibility=1.0, d_long=5.0, d_lat=0.0, v_long=0.0, v_lat=0.0,
                    length=4.4, width=1.9)
    assert "body" not in o.to_json() and ObjectTruth.from_json(o.to_json()) == o
    b = ObjectTruth(**{**o.__dict__, "body": "suv"})
    d = b.to_json()
    assert d["body"] == "suv" and list(d).index("body") == list(d).index("width") + 1
    assert ObjectTruth.from_json(d) == b


# ------------------------------------------------------------------------------------ rendered truth
def _kitti_scene(look: str, bodies: tuple[str, ...]):
    placed = [{"name": f"v{i}", "body": b, "lane": (-1, 0, 1)[i % 3], "distance_m": 14.0, "speed_mps": 25.0,
               "behaviour": "constant_speed"} for i, b in enumerate(bodies)]
    return parse_scenario({"name": "bodies", "seed": 2, "duration_s": 1.0, "road": {"lanes": 3, "length_m": 800.0},
                           "traffic": {"vehicles_count": 0}, "ego": {"lane": 1, "speed_mps": 25.0},
                           "vehicles": placed, "camera": {"width": 640, "height": 360, "hfov_deg": 70,
                                                          "height_m": 1.5, "pitch_deg": 0.0},
                           "render": {"look": look}})


@pytest.mark.parametrize("look", ["realistic", "simple"])
@pytest.mark.parametrize("bodies", [BODY_TYPES[:3], BODY_TYPES[3:6], BODY_TYPES[6:]])
def test_kitti_box_of_each_rendered_body_matches_its_mask(look, bodies):
    """The exported KITTI label (type, h/w/l, location, rotation_y), rebuilt as KITTI's devkit does and projected
    by cv2.projectPoints, holds the vehicle's mask box (1 px) and fills most of it (IoU > 0.8; the simple look's
    box bodies share its left and right edges, 1 px)."""
    from harness.render.renderer import Renderer
    from harness.world.ground_truth import frame_truth

    s = _kitti_scene(look, bodies)
    cam = s.camera.model()
    world = Simulation(s).state()
    with Renderer(s) as r:
        frame = r.render(world)
    truth = frame_truth(world, cam, frame)
    by_id = {v.id: v for v in world.vehicles}
    seen = set()
    for o, f in zip(truth.objects, label_fields(truth.objects, cam)):
        v = by_id[o.id]
        assert o.body == v.body and f["type"] == KITTI_TYPE[v.body]
        np.testing.assert_allclose(f["dimensions"], [vehicle_height(v.length, v.width, v.body), v.width, v.length],
                                   atol=1e-5)
        corners = geo.kitti_box_corners(*f["dimensions"], f["location"], f["rotation_y"])[0]
        uv, _ = cv2.projectPoints(corners.reshape(-1, 1, 3), np.zeros(3), np.zeros(3), cam.K, None)
        uv = uv.reshape(-1, 2)
        (u0, v0), (u1, v1) = uv.min(0), uv.max(0)
        x1, y1, x2, y2 = o.box
        if o.visibility < 0.98 or u0 < 0 or u1 > cam.width - 1 or v0 < 0:
            continue                        # occluded or cut by the border: the mask box is only part of it
        seen.add(v.body)
        assert x1 >= u0 - 1 and y1 >= v0 - 1 and x2 <= u1 + 1 and y2 <= v1 + 1, v.body
        iou = (x2 - x1) * (y2 - y1) / ((u1 - u0) * (v1 - v0))            # the mask box lies inside
        if look == "simple":                # box bodies: the full width at the rear face's corners
            assert abs(x1 - u0) <= 1.0 and abs(x2 - u1) <= 1.0, v.body
        assert iou > 0.8 and abs(y1 - v0) <= 1.5, (v.body, iou)     # the roof at the box's height
    assert seen == set(bodies), seen


def test_sample_scenario_loads_with_a_mixed_fleet():
    s = load_scenario("scenarios/looks/fleet_mixed.yaml")
    assert s.traffic.fleet == "mixed" and s.render.look == "realistic"
    w = Simulation(s).state()
    assert len({v.body for v in w.vehicles}) >= 5 and all(v.body for v in w.vehicles)


# ------------------------------------------------------------------------------------ metallic paint
SUN = SunLook(elevation_deg=40.0, azimuth_deg=30.0, intensity=3.0, ambient=0.6, shadow_strength=0.8)
SKY = SkyLook(zenith_srgb=(70, 120, 200), horizon_srgb=(190, 205, 220), cloud_cover=0.2, cloud_seed=0)


def _pair(albedo, normal, gloss=1.0, sky=SKY):
    a, n = np.array([albedo] * 2, float), np.array([normal] * 2, float)
    return shade_realistic(a, n, np.array([Material.PAINT, Material.METALLIC]), np.array([0.3, 0.2, -1.0]), SUN, sky,
                           gloss)


def test_metallic_paint_has_a_darker_diffuse_and_a_stronger_reflection_in_its_own_hue():
    silver, black, red = (165, 168, 172), (22, 22, 25), (170, 25, 30)
    paint, metal = _pair(silver, (0.0, 1.0, 0.0))
    assert metal.mean() < paint.mean()                     # a bright paint's side: the darker diffuse part shows
    paint, metal = _pair(black, (0.0, 0.0, 1.0))
    assert metal.mean() > paint.mean() + 0.03              # a dark paint's roof: the stronger sky reflection shows
    grey = SkyLook(zenith_srgb=(180, 180, 180), horizon_srgb=(180, 180, 180), cloud_cover=1.0, cloud_seed=0)
    paint, metal = _pair(red, (0.0, 0.0, 1.0), sky=grey)   # under a grey sky the reflection is the paint's red
    assert metal[0] / metal[2] > 1.1 * paint[0] / paint[2]
    paint, metal = _pair(red, (0.0, 0.0, 1.0), gloss=0.0)  # no gloss: no reflection, the darker diffuse only
    assert (metal <= paint + 1e-12).all() and metal.mean() < paint.mean()


def test_a_share_of_the_fleet_is_metallic_and_only_its_paint_is_retagged():
    light = np.mean([materials.is_metallic(3, i) for i in range(4000)])
    heavy = np.mean([materials.is_metallic(3, i, "artic") for i in range(4000)])
    assert abs(light - materials.METALLIC_SHARE["light"]) < 0.03 and abs(heavy - materials.METALLIC_SHARE["heavy"]) < 0.03
    assert materials.is_metallic(3, 17) == materials.is_metallic(3, 17)
    m = vehicle_faces_detailed(4.6, 2.0, RED, 0.3, 1, body="suv")[3]
    out = materials.metallic_paint(m, True)
    assert ((out == Material.METALLIC) == (m == Material.PAINT)).all() and (out[m != Material.PAINT] == m[m != Material.PAINT]).all()
    assert materials.metallic_paint(m, False) is m
