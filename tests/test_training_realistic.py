"""The detector trained on realistic renders only: its training scenes (``generate_data --look realistic
--fleet mixed``) and the shipped file."""

from __future__ import annotations

import contextlib
import copy
import json

import numpy as np

from harness.world.fleet import SHARES
from harness.world.scenario import parse_scenario
from training.generate_data import add_bays, dress, scenario_dict, streetify


def _drawn(seed: int, index: int, **kw) -> tuple[dict, dict]:
    sd = scenario_dict(np.random.default_rng([seed, index]), index, seed, (1242, 375))
    dressed = copy.deepcopy(sd)
    dress(dressed, seed, index, **kw)
    return sd, dressed


def test_dress_sets_look_and_fleet_from_their_own_streams_and_nothing_else():
    seeds = set()
    for index in range(20):
        sd, d = _drawn(10, index, look="realistic", look_family="train", fleet="mixed")
        scen = parse_scenario(d)
        assert scen.render.look == "realistic" and scen.render.look_family == "train"
        assert scen.traffic.fleet == "mixed"
        assert all(v.body in SHARES for v in scen.vehicles)
        seeds.add(scen.render.look_seed)
        strip = {k: v for k, v in d["render"].items() if not k.startswith("look")}
        assert strip == sd["render"] and d["camera"] == sd["camera"] and d["ego"] == sd["ego"]
        for a, b in zip(sd["vehicles"], d["vehicles"]):    # placement kept, body and footprint redrawn
            assert {k: a[k] for k in ("lane", "distance_m", "speed_mps")} == {k: b[k] for k in ("lane", "distance_m", "speed_mps")}
    assert len(seeds) == 20                                  # every scenario its own draw of the look
    assert _drawn(10, 3, look="realistic", look_family="train", fleet="mixed") == \
        _drawn(10, 3, look="realistic", look_family="train", fleet="mixed")


def test_dress_simple_and_no_fleet_is_the_plain_draw():
    sd, d = _drawn(10, 5, look="simple", look_family="train", fleet="none")
    assert d == sd


def test_streetify_makes_valid_slow_streets_and_keeps_the_camera():
    lanes = set()
    for index in range(30):
        sd = scenario_dict(np.random.default_rng([12, index]), index, 12, (1242, 375))
        st = copy.deepcopy(sd)
        streetify(np.random.default_rng([12, index, 0x57EE7]), st)
        scen = parse_scenario(st)                       # valid: every placed vehicle on a lane that exists
        assert scen.road.street is not None and 1 <= scen.road.lanes <= 2 and scen.road.shoulder_width_m >= 2.3
        assert 6 <= scen.ego.speed_mps <= 14 and max(scen.traffic.speed_range_mps) <= 17
        assert all(0 <= scen.ego.lane + v.lane < scen.road.lanes for v in scen.vehicles)
        assert st["camera"] == sd["camera"] and st["render"] == sd["render"]
        lanes.add(scen.road.lanes)
    assert lanes == {1, 2}


def test_add_bays_makes_valid_bay_streets_that_hold_a_5m_car_and_park_side_by_side():
    from harness.simulation.parking import parked_cars

    angles = []
    for index in range(20):
        st = scenario_dict(np.random.default_rng([14, index]), index, 14, (640, 360))
        streetify(np.random.default_rng([14, index, 0x57EE7]), st)
        add_bays(np.random.default_rng([14, index, 0xBA75]), st)
        scen = parse_scenario(st)
        a = np.radians(scen.road.street.bay_angle_deg)
        angles.append(scen.road.street.bay_angle_deg)
        assert scen.road.shoulder_width_m >= 5.0 * np.sin(a) + 1.9 * np.cos(a) + 0.1 - 0.01
        cars = parked_cars(scen.road, 1, 0.0, 500.0)
        assert len(cars) >= 10
        assert np.mean([abs(np.sin(c.heading)) > 0.6 for c in cars]) > 0.9     # across the strip, not along it
    assert min(angles) >= 45 and max(angles) == 90 and len(set(angles)) > 3


def test_street_bays_draw_from_their_own_stream(tmp_path, monkeypatch):
    """``--street-bays``: with P = 0 (the default) no street has bays; with P = 1 every street has, and each
    scenario differs from its P = 0 self only in its parking (strip depth, bays): nothing else is redrawn."""
    from harness.world.scenario import ScenarioError
    from training import generate_data

    drawn: dict[float, list[dict]] = {0.0: [], 1.0: []}

    def record(sd, bays):
        drawn[bays].append(copy.deepcopy(sd))
        raise ScenarioError("recorded")

    for bays in drawn:
        monkeypatch.setattr(generate_data, "parse_scenario", lambda sd, b=bays: record(sd, b))
        with contextlib.suppress(Exception):                   # every scenario "skipped": nothing to write
            generate_data.generate(tmp_path / str(bays), 8, 14, 1, 20, ((640, 360),), 0.3, 3.0, street=1.0,
                                   bays=bays)
    assert len(drawn[0.0]) == len(drawn[1.0]) == 8
    for plain, bay in zip(drawn[0.0], drawn[1.0]):
        assert "bay_angle_deg" not in plain["road"]["street"] and bay["road"]["street"]["bay_angle_deg"] >= 45
        for sd in (plain, bay):
            sd["road"].pop("shoulder_width_m")
            for k in ("bay_angle_deg", "parked_per_100m", "facing_traffic_share"):
                sd["road"]["street"].pop(k, None)
        assert plain == bay


# ------------------------------------------------------------------ the shipped model


def test_realistic_model_is_small_registered_and_finds_a_car_in_a_realistic_render():
    from monorarp.core.boxes import iou
    from monorarp.detection.centernet import REALISTIC_MODEL, RealisticCenterNetDetector
    from monorarp.pipeline.detectors import load_detector
    from rendered_frame import first_frame

    assert REALISTIC_MODEL.stat().st_size <= 10_000_000
    meta = REALISTIC_MODEL.with_suffix(".json").read_text()
    assert '"init": "from scratch"' in meta and "no real image" in meta
    scen, image, truth = first_frame({
        "name": "realistic_check", "seed": 5, "duration_s": 1.0, "fps": 15.0, "road": {"lanes": 3},
        "ego": {"lane": 1, "speed_mps": 25.0}, "traffic": {"vehicles_count": 1, "density": 0.2},
        "vehicles": [{"name": "lead", "lane": 0, "distance_m": 18.0, "speed_mps": 25.0, "behaviour": "constant_speed",
                      "body": "suv"}],
        "camera": {"width": 640, "height": 360, "hfov_deg": 70, "height_m": 1.4, "pitch_deg": 1.0},
        "render": {"look": "realistic", "look_family": "heldout", "look_seed": 11}})
    det = load_detector("centernet_realistic", camera=scen.camera.model())
    assert isinstance(det, RealisticCenterNetDetector) and det.path == REALISTIC_MODEL
    lead = min((o for o in truth.objects if abs(o.d_lat) < 1.0), key=lambda o: o.d_long)
    assert 16.0 < lead.d_long < 20.0
    boxes = np.array([d.box for d in det.detect(image)], float).reshape(-1, 4)
    assert len(boxes) and iou(boxes, np.array(lead.box, float)[None]).max() >= 0.7


def test_street_model_is_small_registered_and_finds_a_parked_car_in_a_street_render():
    from monorarp.core.boxes import iou
    from monorarp.detection.centernet import STREET_MODEL, StreetCenterNetDetector
    from monorarp.pipeline.detectors import load_detector
    from rendered_frame import first_frame

    assert STREET_MODEL.stat().st_size <= 10_000_000
    meta = STREET_MODEL.with_suffix(".json").read_text()
    assert "no real image" in meta and '"validation_street"' in meta
    scen, image, truth = first_frame({
        "name": "street_check", "seed": 3, "duration_s": 1.0, "fps": 15.0,
        "road": {"lanes": 2, "lane_width_m": 3.25, "shoulder_width_m": 2.4, "street": {"parked_per_100m": 6}},
        "ego": {"lane": 1, "speed_mps": 10.0}, "traffic": {"vehicles_count": 0},
        "vehicles": [{"name": "lead", "lane": 0, "distance_m": 14.0, "speed_mps": 10.0,
                      "behaviour": "constant_speed", "body": "hatchback"}],
        "camera": {"width": 640, "height": 360, "hfov_deg": 70, "height_m": 1.5, "pitch_deg": 1.0},
        "render": {"look": "realistic", "look_family": "heldout", "look_seed": 7}})
    det = load_detector("centernet_street", camera=scen.camera.model())
    assert isinstance(det, StreetCenterNetDetector) and det.path == STREET_MODEL
    boxes = np.array([d.box for d in det.detect(image)], float).reshape(-1, 4)
    near = [o for o in truth.objects if o.visibility > 0.8 and o.box[3] - o.box[1] > 30]
    assert len(near) >= 2 and {o.id >= 100_000 for o in near} == {True, False}   # the lead and a parked car
    for o in near:
        assert len(boxes) and iou(boxes, np.array(o.box, float)[None]).max() >= 0.6, o


def test_amodal_labels_hold_the_visible_boxes_and_change_no_pixel(tmp_path):
    """``generate_data --boxes amodal``: the same images and rows as the visible boxes; each box holds its
    visible box, and the parked cars hidden behind one another get larger ones."""
    from training.generate_data import generate

    kw = dict(n_scenarios=1, seed=12, frames_per_scenario=2, frame_stride=20, resolutions=((640, 360),),
              min_visibility=0.3, min_size=3.0, look="realistic", fleet="mixed", street=1.0)
    generate(tmp_path / "vis", **kw)
    generate(tmp_path / "amo", box_kind="amodal", **kw)
    assert np.array_equal(np.load(tmp_path / "vis" / "images.npy"), np.load(tmp_path / "amo" / "images.npy"))
    vis, amo = np.load(tmp_path / "vis" / "boxes.npy"), np.load(tmp_path / "amo" / "boxes.npy")
    assert vis.shape == amo.shape and np.array_equal(vis[:, 0], amo[:, 0])
    assert np.all(amo[:, 1:3] <= vis[:, 1:3] + 1e-9) and np.all(amo[:, 3:5] >= vis[:, 3:5] - 1e-9)
    grown = (amo[:, 3] - amo[:, 1]) * (amo[:, 4] - amo[:, 2]) > 1.2 * (vis[:, 3] - vis[:, 1]) * (vis[:, 4] - vis[:, 2])
    assert grown.sum() >= 3
    assert json.loads((tmp_path / "amo" / "meta.json").read_text())["boxes"] == "amodal"
    assert "boxes" not in json.loads((tmp_path / "vis" / "meta.json").read_text())
