"""The dense-traffic detector: its training scenes (``generate_data --dense``) and the shipped file."""

from __future__ import annotations

import copy

import numpy as np
import pytest

from harness.world.scenario import parse_scenario
from monorarp.pipeline.detectors import load_detector
from monorarp.detection.centernet import DENSE_MODEL, DenseCenterNetDetector
from rendered_frame import first_frame
from training.generate_data import densify, scenario_dict


def _drawn(seed: int, index: int) -> tuple[dict, dict]:
    """One training scenario as drawn, and the same densified."""
    sd = scenario_dict(np.random.default_rng([seed, index]), index, seed, (640, 360))
    dense = copy.deepcopy(sd)
    densify(np.random.default_rng([seed, index, 0xDE5]), dense)
    return sd, dense


def test_densify_adds_adjacent_lane_pairs_that_hide_one_another():
    for index in range(40):
        sd, dense = _drawn(20, index)
        parse_scenario(dense)                                # a valid scenario
        lanes = dense["road"]["lanes"]
        assert lanes >= 3 and 25 <= dense["traffic"]["vehicles_count"] <= 50
        assert 2.0 <= dense["traffic"]["density"] <= 3.5
        new = dense["vehicles"][len(sd["vehicles"]):]
        assert dense["vehicles"][:len(sd["vehicles"])] == sd["vehicles"]   # the drawn ones are kept
        assert new, "no pair placed"
        for v in new:
            assert -dense["ego"]["lane"] <= v["lane"] < lanes - dense["ego"]["lane"]
            assert 20.0 <= v["distance_m"] <= 82.0
        pairs = {}
        for v in new:
            pairs.setdefault(v["name"].split("_")[0], []).append(v)
        for near, far in (p for p in pairs.values() if len(p) == 2):
            assert abs(near["lane"] - far["lane"]) == 1            # adjacent lanes
            assert 2.0 <= far["distance_m"] - near["distance_m"] <= 12.0


def test_densify_is_seeded_and_leaves_the_plain_draw_unchanged():
    sd_a, dense_a = _drawn(20, 3)
    sd_b, dense_b = _drawn(20, 3)
    assert dense_a == dense_b and sd_a == sd_b
    assert sd_a != dense_a


# ------------------------------------------------------------------ the shipped alternative model


@pytest.mark.parametrize("near_m, gap_m", [(15, 10), (20, 14), (25, 14), (25, 18)])
def test_dense_model_finds_a_car_partly_hidden_behind_the_next_lanes_car(near_m, gap_m):
    """A car two lanes left, 25-43 m ahead, 45-75 % hidden by a car in the lane between.
    Measured 2026-11-28: the dense model scores these 0.49-0.62 (threshold 0.422); the shipped model
    0.23-0.51 (threshold 0.431), so it misses the (20, 14) and (25, 18) ones."""
    from monorarp.core.boxes import iou

    assert DENSE_MODEL.stat().st_size <= 10_000_000
    scen, image, truth = first_frame({
        "name": "occluded", "seed": 3, "duration_s": 1.0, "fps": 15.0, "road": {"lanes": 4},
        "ego": {"lane": 2, "speed_mps": 25.0}, "traffic": {"vehicles_count": 1, "density": 0.2},
        "vehicles": [{"name": "near", "lane": -1, "distance_m": near_m, "speed_mps": 25.0,
                      "behaviour": "constant_speed"},
                     {"name": "far", "lane": -2, "distance_m": near_m + gap_m, "speed_mps": 25.0,
                      "behaviour": "constant_speed"}],
        "camera": {"width": 640, "height": 360, "hfov_deg": 70, "height_m": 1.4, "pitch_deg": 1.0}})
    det = load_detector("centernet_dense", camera=scen.camera.model())
    assert isinstance(det, DenseCenterNetDetector) and det.path == DENSE_MODEL
    far = [o for o in truth.objects if abs(o.d_lat + 8.0) < 1.0]
    assert len(far) == 1 and 0.25 <= far[0].visibility <= 0.6          # mostly hidden
    boxes = np.array([d.box for d in det.detect(image)], float).reshape(-1, 4)
    assert len(boxes) and np.max(iou(boxes, np.array(far[0].box, float)[None])) >= 0.5
