"""Lane-width ranging (monorarp.horizon.ground_profile, the ``lane_width`` horizon stage) against closed forms.

Synthetic frames: a level camera over a straight road with solid lines at known lateral offsets,
level up to ``D`` ahead and then climbing or descending at grade ``g`` (a kink). Each image row's road
distance is the closed-form intersection of its ray with that road, independent of the code under test.
"""

from __future__ import annotations

import numpy as np
import pytest

from monorarp.core.camera import CameraModel
from monorarp.core.ground_profile import GroundProfile
from monorarp.horizon.ground_profile import ridge_peak
from monorarp.state.ground_contact import contact_ground, width_distance
from monorarp.horizon.stages import LaneWidthRanging
from monorarp.state.estimator import StateEstimator
from monorarp.core.types import Track

CAM = CameraModel(width=640, height=360, fx=457.0, fy=457.0, cx=319.5, cy=179.5, height_m=1.3)
LINES = (-6.0, -2.0, 2.0, 6.0)        # lateral offsets of the painted lines (m)
D = 40.0                               # where the grade starts (m ahead)


def road_distance(v: np.ndarray, grade: float, h: float = CAM.height_m) -> np.ndarray:
    """Closed form: distance (m) of the road seen at rows ``v`` by the level camera; NaN where none."""
    tan_a = (np.asarray(v, dtype=float) - CAM.cy) / CAM.fy
    with np.errstate(divide="ignore", invalid="ignore"):
        flat = np.where(tan_a > 0, h / tan_a, np.inf)
        beyond = (h + grade * D) / (tan_a + grade)              # h - y tan a = g (y - D)
    y = np.where(flat <= D, flat, np.where((tan_a + grade > 0) & (beyond > D), beyond, np.nan))
    return y


def synthetic_frame(grade: float, width_m: float = 0.15) -> np.ndarray:
    """BGR frame: asphalt (70) with white (230) lines, each pixel's paint by its column coverage."""
    img = np.full((CAM.height, CAM.width), 110.0)               # grass / sky above the road
    cols = np.arange(CAM.width, dtype=float)
    for v in range(CAM.height):
        y = road_distance(np.array([v]), grade)[0]
        if not np.isfinite(y):
            continue
        img[v] = 70.0
        for x in LINES:
            lo = CAM.cx + CAM.fx * (x - width_m / 2) / y
            hi = CAM.cx + CAM.fx * (x + width_m / 2) / y
            cover = np.clip(np.minimum(cols + 0.5, hi) - np.maximum(cols - 0.5, lo), 0.0, 1.0)
            img[v] += cover * (230.0 - 70.0)
    g = np.clip(np.round(img), 0, 255).astype(np.uint8)
    return np.repeat(g[:, :, None], 3, axis=2)


def test_ridge_peak_finds_a_sub_pixel_line():
    cols = np.arange(60, dtype=float)
    for centre in (20.0, 20.3, 20.5, 31.75):
        lo, hi = centre - 0.45, centre + 0.45                   # a 0.9 px line
        row = 70.0 + 160.0 * np.clip(np.minimum(cols + 0.5, hi) - np.maximum(cols - 0.5, lo), 0, 1)
        assert ridge_peak(row, centre + 1.0, 2.5, 2.0, 12.0) == pytest.approx(centre, abs=0.12)
    step = np.where(cols < 30, 70.0, 200.0)                     # an edge is no line
    assert ridge_peak(step, 30.0, 3.0, 2.0, 12.0) is None


@pytest.mark.parametrize("grade, tol", [(0.04, 0.03), (-0.02, 0.08)])
def test_profile_reads_the_closed_form_road_distance_on_a_grade(grade, tol):
    """Beyond a descent's crest the road squeezes into a few rows (10-15 m each), where the local fit
    of ``s(v)`` spans the kink: a looser bound there, and the stated one-sigma must cover it."""
    reading = LaneWidthRanging(CAM).update(synthetic_frame(grade), 0.0)
    p = reading.profile
    assert reading.row == pytest.approx(CAM.horizon_row)
    beyond = p.rows[road_distance(p.rows, grade) > D + 5]
    assert beyond.size >= 3                                     # the lines were followed past the change
    d, sd, _ = p.at(beyond)
    truth = road_distance(beyond, grade)
    flat = CAM.ground_point_from_pixel(np.full_like(beyond, CAM.cx), beyond)[:, 1]
    flat = np.where(np.isfinite(flat), flat, np.inf)            # above the flat horizon: no flat reading
    mid = truth < 120.0                                         # the lines >= 15 px apart
    assert mid.sum() >= 3 and np.max(np.abs(d - truth)[mid] / truth[mid]) < tol
    assert np.all(np.abs(d - truth) < np.abs(flat - truth) / 2)   # the flat ground is far off there
    assert np.mean(np.abs(d - truth) <= 1.645 * sd) >= 0.9


def test_state_estimator_uses_the_profile_beyond_a_climb_and_flat_ground_before_it():
    grade, offset = 0.04, 0.95
    reading = LaneWidthRanging(CAM).update(synthetic_frame(grade), 0.0)
    rows = np.arange(CAM.height)
    y_true = road_distance(rows, grade)
    v_far = float(rows[np.nanargmin(np.abs(y_true - 70.0))])    # a car's contact line 70 m ahead, on the climb
    v_near = float(rows[np.nanargmin(np.abs(y_true - 20.0))])   # and one on the level part
    tracks = [Track(1, (CAM.cx - 10, v_far - 8, CAM.cx + 10, v_far)), Track(2, (CAM.cx - 30, v_near - 25,
                                                                               CAM.cx + 30, v_near))]
    with_profile = StateEstimator(CAM).update(tracks, 0.0, horizon=reading)
    plain = StateEstimator(CAM).update(tracks, 0.0)
    far_truth = road_distance(np.array([v_far]), grade)[0] - offset
    assert with_profile[1].d_y == pytest.approx(far_truth, rel=0.03)
    assert abs(plain[1].d_y - far_truth) > 0.3 * far_truth      # equation 3 on flat ground: far too far
    assert abs(with_profile[1].d_y - far_truth) <= 1.645 * with_profile[1].d_y_std
    # before the change the profile agrees with the flat ground: the plain answer, bit for bit
    assert with_profile[2].d_y == plain[2].d_y and with_profile[2].d_y_std == plain[2].d_y_std


def test_flat_road_gives_the_flat_ground_answer():
    reading = LaneWidthRanging(CAM).update(synthetic_frame(0.0), 0.0)
    p = reading.profile
    far = p.rows[road_distance(p.rows, 0.0) > 30]
    d, _, _ = p.at(far)
    truth = road_distance(far, 0.0)
    assert np.max(np.abs(d - truth) / truth) < 0.03
    y, add = contact_ground(CAM, p, p.rows, 0.9)
    flat = CAM.ground_point_from_pixel(np.full_like(p.rows, CAM.cx), p.rows)[:, 1]
    assert np.array_equal(y, flat) and np.all(add == 0.0)


def test_contact_ground_outside_the_profile():
    p = GroundProfile(np.array([190.0, 200.0, 210.0]), np.array([40.0, 30.0, 20.0]), np.array([0.5, 0.3, 0.2]),
                      fallback_grade_std=0.02)
    rows = np.array([195.0, 185.0, 250.0])                     # inside, beyond the far end, nearer than it
    flat = CAM.ground_point_from_pixel(np.full_like(rows, CAM.cx), rows)[:, 1]
    y, add = contact_ground(CAM, p, rows, 0.9)
    assert y[0] == pytest.approx(35.0) and add[0] == pytest.approx(0.4)   # against the flat ground's ~38 m
    assert y[1] == flat[1] and add[1] == pytest.approx(flat[1] ** 2 / CAM.height_m * 0.02)
    assert y[2] == flat[2] and add[2] == 0.0
    y0, add0 = contact_ground(CAM, None, rows, 0.9)
    assert np.array_equal(y0, flat) and np.all(add0 == 0.0)


def test_a_box_where_the_road_vanishes_beyond_a_crest_is_stated_wide():
    """A 4 % descent 40 m ahead hides the road beyond (the camera's 1.3 m is below the line over the
    crest): a car 65 m ahead shows only its top, its box bottom on the crest. The lines are lost there,
    the profile says so, and the interval reaches the car."""
    reading = LaneWidthRanging(CAM).update(synthetic_frame(-0.04), 0.0)
    assert reading.profile.open_end
    crest = float(reading.profile.rows[0])                     # the farthest road row seen
    track = Track(1, (CAM.cx - 7, crest - 6, CAM.cx + 7, crest + 0.5))
    state = StateEstimator(CAM).update([track], 0.0, horizon=reading)[1]
    plain = StateEstimator(CAM).update([track], 0.0)[1]
    assert plain.d_y < 40.0                                    # equation 3 reads the crest
    assert abs(65.0 - plain.d_y) > 1.645 * plain.d_y_std       # and its interval misses the car
    # the box's 14 px of width (a 2 m car at 65 m) read with the assumed 1.8 m: 457 x 1.8 / 14 = 58.8 m
    assert state.d_y == pytest.approx(CAM.fx * 1.8 / 14.0, rel=0.01)
    assert abs(65.0 - state.d_y) <= 1.645 * state.d_y_std
    # without the boxes the same reading only widens the crest's distance
    y, add = contact_ground(CAM, reading.profile, np.array([crest + 0.5]), 0.9)
    assert y[0] < 41.0 and 65.0 - y[0] <= 1.645 * add[0]


@pytest.mark.parametrize("x_centre", [0.3, 4.0, -4.0, 8.0])
def test_width_distance_of_a_box_drawn_by_cv2_style_projection(x_centre):
    """A 1.8 x 4.5 m box-shaped vehicle 60 m ahead: its image box from the projected corners (at the
    height of the camera, where a level camera sees every corner's extreme column) gives 60 m back."""
    W, L, d = 1.8, 4.5, 60.0
    xs, ys = (x_centre - W / 2, x_centre + W / 2), (d, d + L)
    pts = np.array([[x, y, 0.0] for x in xs for y in ys])
    u = CAM.project_ego(pts)[:, 0]
    box = np.array([[u.min(), 170.0, u.max(), 180.0]])
    assert width_distance(CAM, box, W, L)[0] == pytest.approx(d, rel=1e-9)


def test_width_bears_out_or_overrides_a_reading_where_the_road_is_unseen():
    """Beyond the profile's far end: a box as wide as a 1.8 m car at the flat reading keeps it with
    only the two readings' difference added (no grade); one half as wide stands twice as far."""
    p = GroundProfile(np.array([200.0, 210.0, 220.0]), np.array([30.0, 22.0, 15.0]), np.array([0.5, 0.3, 0.2]))
    row = 195.0                                                # the flat ground's 38 m
    flat = CAM.ground_point_from_pixel(np.array([CAM.cx]), np.array([row]))[0, 1]
    w_px = CAM.fx * 1.8 / (flat - 0.95)                        # the rear face at the contact line's distance
    same = np.array([[CAM.cx - w_px / 2, row - 20, CAM.cx + w_px / 2, row]])
    half = np.array([[CAM.cx - w_px / 4, row - 10, CAM.cx + w_px / 4, row]])
    y, add = contact_ground(CAM, p, np.array([row, row]), 0.9, boxes=np.vstack([same, half]))
    assert y[0] == flat and add[0] == pytest.approx(0.0, abs=1e-9)
    assert y[1] == pytest.approx(2 * (flat - 0.95) + 0.95)
    assert add[1] == pytest.approx(y[1] * np.hypot(0.15 / 1.8, 1.0 / (w_px / 2)))
