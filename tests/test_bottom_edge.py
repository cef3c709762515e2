"""Sub-pixel bottom-edge refinement (monorarp.detection.bottom_edge).

Reference images are drawn independently of the refinement's model: a vehicle (body + two
dark tyres) on a grey road is drawn with cv2 at 16x the resolution and reduced with
``cv2.resize(INTER_AREA)`` (an exact 16x16 box filter, i.e. what an ideal anti-aliased
renderer gives), so the true continuous bottom edge is known to 1/16 px.
"""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from monorarp.detection.bottom_edge import refine_bottom
from monorarp.detection.centernet import CenterNetDetector

SS = 16  # supersampling factor


def scene(bottom: float, x1: float = 100.0, x2: float = 160.0, height: float = 40.0, w: int = 320,
          h: int = 240, body=(40, 40, 160), road=(95, 100, 100), noise: float = 0.0, seed: int = 0) -> np.ndarray:
    """BGR uint8 image of a vehicle whose tyres end at continuous row ``bottom`` (pixel centres at integers)."""
    big = np.empty((h * SS, w * SS, 3), np.uint8)
    big[:] = road

    def Y(v: float) -> int:            # continuous coordinate -> row boundary index at SS resolution
        return int(round((v + 0.5) * SS))

    def X(v: float) -> int:
        return int(round((v + 0.5) * SS))

    tyre_top = bottom - 0.18 * height
    body_bottom = bottom - 0.08 * height
    big[Y(bottom - height):Y(body_bottom), X(x1):X(x2)] = body
    tw = 0.12 * (x2 - x1)
    for a in (x1 + 0.05 * (x2 - x1), x2 - 0.05 * (x2 - x1) - tw):
        big[Y(tyre_top):Y(bottom), X(a):X(a + tw)] = (25, 25, 25)
    img = cv2.resize(big, (w, h), interpolation=cv2.INTER_AREA).astype(np.float32)
    if noise:
        img += np.random.default_rng(seed).normal(0, noise, img.shape).astype(np.float32)
    return np.clip(np.round(img), 0, 255).astype(np.uint8)


@pytest.mark.parametrize("bottom", [150.0, 150.3, 150.5, 150.81, 171.44])
@pytest.mark.parametrize("offset", [-1.6, 0.0, 1.3])
def test_recovers_sub_pixel_edge(bottom, offset):
    img = scene(bottom)
    box = np.array([[100.0, bottom - 40 + offset, 160.0, bottom + offset]])
    out, moved = refine_bottom(img, box)
    assert moved[0]
    assert abs(out[0, 3] - bottom) <= 0.07, out[0, 3]
    assert np.array_equal(out[0, :3], box[0, :3])      # only the bottom edge moves


def test_noisy_image_stays_within_a_fifth_of_a_pixel():
    errs = []
    for k, bottom in enumerate(np.linspace(150.0, 151.0, 11)):
        img = scene(bottom, noise=4.0, seed=k)
        out, moved = refine_bottom(img, np.array([[100.0, bottom - 39, 160.0, bottom + 1.0]]))
        assert moved[0]
        errs.append(out[0, 3] - bottom)
    assert np.max(np.abs(errs)) <= 0.2, errs


def test_small_far_vehicle():
    bottom = 120.37
    img = scene(bottom, x1=150.0, x2=166.0, height=13.0)
    out, moved = refine_bottom(img, np.array([[150.0, bottom - 13.0, 166.0, bottom - 0.8]]))
    assert moved[0] and abs(out[0, 3] - bottom) <= 0.1, out[0, 3]


def test_no_edge_or_edge_out_of_reach_keeps_the_detector_edge():
    flat = np.full((240, 320, 3), 100, np.uint8)
    box = np.array([[100.0, 110.0, 160.0, 150.0]])
    out, moved = refine_bottom(flat, box)
    assert not moved[0] and np.array_equal(out, box)
    img = scene(150.0)
    far = np.array([[100.0, 120.0, 160.0, 160.0]])          # 10 px below the true edge: out of reach
    out, moved = refine_bottom(img, far)
    assert not moved[0] and np.array_equal(out, far)


def test_box_at_the_image_border_and_degenerate_boxes_are_left_alone():
    img = scene(250.0)                                          # the vehicle runs off the image's bottom
    boxes = np.array([[100.0, 199.5, 160.0, 239.5],          # cut by the border: no road below it
                      [100.0, 149.0, 160.0, 150.0],          # 1 px tall
                      [np.nan, 110.0, 160.0, 150.0]])
    out, moved = refine_bottom(img, boxes)
    assert not moved.any()
    np.testing.assert_array_equal(out, boxes)


def test_box_of_a_vehicle_cut_by_the_bottom_border_ends_at_the_border():
    img = scene(250.0)                                          # tyres 10 px below the last row (239)
    boxes = np.array([[100.0, 199.0, 160.0, 238.7],          # the net stops short of the border
                      [100.0, 199.0, 160.0, 236.0]])         # 3.5 px short: out of the 2.4 px search
    out, moved = refine_bottom(img, boxes)
    assert moved.tolist() == [True, False]
    assert out[0, 3] == 239.5 and np.array_equal(out[1], boxes[1])
    bottom = 237.6                                             # road under the tyres, 1.4 px above the border
    img = scene(bottom)
    out, moved = refine_bottom(img, np.array([[100.0, bottom - 40.0, 160.0, bottom - 0.6]]))
    assert moved[0] and abs(out[0, 3] - bottom) <= 0.07          # the edge is found, not the border


def test_vehicle_near_the_image_border_is_refined():
    img = scene(237.2, x1=-20.0, x2=40.0)                       # 2 px above the last row, cut on the left
    out, moved = refine_bottom(img, np.array([[-0.5, 197.0, 40.0, 236.0]]))
    assert moved[0] and abs(out[0, 3] - 237.2) <= 0.07


def test_empty_input():
    out, moved = refine_bottom(np.zeros((10, 10, 3), np.uint8), np.zeros((0, 4)))
    assert out.shape == (0, 4) and moved.shape == (0,)


def test_detector_option_is_validated_and_applied():
    """On a rendered frame: ``refine_bottom=True`` = the plain detector's boxes through :func:`refine_bottom`."""
    from harness.render.renderer import Renderer
    from harness.world.scenario import parse_scenario
    from harness.simulation.simulator import simulate
    from tests.test_detection import SCENE

    with pytest.raises(ValueError, match="refine_bottom"):
        CenterNetDetector(refine_bottom="yes")
    scen = parse_scenario(SCENE)
    with Renderer(scen) as r:
        img = r.render(next(iter(simulate(scen, 1)))).image
    cam = scen.camera.model()
    b0, s0 = CenterNetDetector(camera=cam, refine_bottom=False).detect_arrays(img)
    b1, s1 = CenterNetDetector(camera=cam, refine_bottom=True).detect_arrays(img)
    want, moved = refine_bottom(img, b0)
    assert len(b0) >= 3 and moved.sum() >= 2
    np.testing.assert_array_equal(s0, s1)
    np.testing.assert_array_equal(b1, want)


@settings(max_examples=200, deadline=None, derandomize=True, database=None)
@given(seed=st.integers(0, 2**31 - 1),
       boxes=st.lists(st.tuples(*[st.one_of(st.floats(-50, 200), st.sampled_from([np.nan, np.inf, -np.inf]))] * 4),
                      min_size=0, max_size=6))
def test_any_boxes_on_any_image_only_move_the_bottom_within_reach(seed, boxes):
    rng = np.random.default_rng(seed)
    img = rng.integers(0, 256, (int(rng.integers(1, 120)), int(rng.integers(1, 160)), 3), dtype=np.uint8)
    if rng.random() < 0.5:   # blocky content: real edges
        img = cv2.resize(img[::8, ::8], (img.shape[1], img.shape[0]), interpolation=cv2.INTER_NEAREST)
    b = np.array(boxes, float).reshape(-1, 4)
    out, moved = refine_bottom(img, b)
    assert out.shape == b.shape and moved.shape == (len(b),)
    np.testing.assert_array_equal(out[:, :3], b[:, :3])
    np.testing.assert_array_equal(out[~moved], b[~moved])
    assert np.all(np.abs(out[moved, 3] - b[moved, 3]) <= 5.0)     # BottomEdgeParams.search_max_px
    np.testing.assert_array_equal(refine_bottom(img, b)[0], out)    # deterministic
