"""State estimator: equations 3 and 4 against cv2.projectPoints, contact-line bias, velocity filters."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from monorarp.core.camera import CameraModel
from monorarp.pipeline.registry import create
from monorarp.state.estimator import StateEstimator
from monorarp.state.geometry import eq3_distance, eq4_lateral, lateral_from_terms, lateral_terms, measure_boxes
from monorarp.core.types import Track

FPS = 30.0


def project_cv2(cam: CameraModel, points_ego: np.ndarray) -> np.ndarray:
    """Project ego-frame points with OpenCV, rotation built independently of CameraModel.

    Ego (x right, y ahead, z up) -> level OpenCV camera (x, -z, y) -> pitched down about x.
    """
    level = np.array([[1.0, 0, 0], [0, 0, -1.0], [0, 1.0, 0]])
    R_pitch, _ = cv2.Rodrigues(np.array([[cam.pitch_rad], [0.0], [0.0]]))
    # Pitching the camera down turns the world up in its view: a point ahead at camera height gets
    # y_cam = -sin(theta) * distance < 0 -- the rotation by +theta about the camera's x axis.
    R = R_pitch @ level
    rvec, _ = cv2.Rodrigues(R)
    uv, _ = cv2.projectPoints(np.asarray(points_ego, dtype=np.float64).reshape(-1, 1, 3), rvec,
                              np.zeros(3), cam.K, None)
    return uv.reshape(-1, 2)


def vehicle_points(cam: CameraModel, d_x, d_y, W, L, H, overhang, clearance):
    """Ego-frame points of a box-shaped vehicle: body corners (clearance..H) and the tyre contact lines."""
    h = cam.height_m
    pts = []
    for x in (d_x - W / 2, d_x + W / 2):
        for y in (d_y, d_y + L):
            pts += [(x, y, -h + clearance), (x, y, -h + H)]
        pts += [(x, d_y + overhang, -h), (x, d_y + L - overhang, -h)]
    return np.array(pts)


def vehicle_box(cam: CameraModel, d_x: float, d_y: float, W=1.8, L=4.5, H=1.5, overhang=0.95, clearance=0.17):
    """Tight image box of a box-shaped vehicle (rear face at d_y, centre d_x), via cv2.projectPoints.

    Lowest points: rear bumper's lower edge (clearance above ground at the rear face) and the rear
    tyres' contact line (overhang ahead of the rear face).
    """
    uv = project_cv2(cam, vehicle_points(cam, d_x, d_y, W, L, H, overhang, clearance))
    return (uv[:, 0].min(), uv[:, 1].min(), uv[:, 0].max(), uv[:, 1].max())


@pytest.fixture
def level_cam():
    return CameraModel.from_fov(640, 360, 60.0, 1.3)


@pytest.fixture
def pitched_cam():
    return CameraModel.from_fov(640, 360, 60.0, 1.3, pitch_rad=math.radians(3.0))


def test_cv2_reference_agrees_with_camera_model(pitched_cam):
    pts = np.array([[1.0, 10.0, -1.3], [-3.0, 25.0, 0.4], [0.5, 7.0, -0.2]])
    np.testing.assert_allclose(project_cv2(pitched_cam, pts), pitched_cam.project_ego(pts), atol=1e-9)
    far_ahead = project_cv2(pitched_cam, np.array([[0.0, 1e7, 0.0]]))[0]
    assert far_ahead[1] < pitched_cam.cy                       # pitched down: horizon above the centre
    assert far_ahead[1] == pytest.approx(pitched_cam.horizon_row, abs=1e-4)


@pytest.mark.parametrize("Y", [3.0, 7.5, 15.0, 40.0, 80.0])
def test_eq3_level_camera_equals_paper_formula(level_cam, Y):
    v_b = project_cv2(level_cam, np.array([[0.7, Y, -level_cam.height_m]]))[0, 1]
    paper = eq3_distance(v_b, level_cam.horizon_row, level_cam.height_m, level_cam.fy)
    box = np.array([[300.0, v_b - 40, 340.0, v_b]])
    exact = measure_boxes(level_cam, box, contact_offset_m=0.0, ground_clearance_m=0.0, border_tol_px=None)[0, 1]
    assert paper == pytest.approx(Y, rel=1e-12)
    assert exact == pytest.approx(paper, rel=1e-12)


@pytest.mark.parametrize("Y", [4.0, 12.0, 30.0, 60.0])
def test_eq3_pitched_camera_is_exact_where_paper_formula_is_not(pitched_cam, Y):
    v_b = project_cv2(pitched_cam, np.array([[-1.0, Y, -pitched_cam.height_m]]))[0, 1]
    exact = measure_boxes(pitched_cam, np.array([[300.0, v_b - 40, 340.0, v_b]]),
                          contact_offset_m=0.0, ground_clearance_m=0.0)[0, 1]
    paper = eq3_distance(v_b, pitched_cam.horizon_row, pitched_cam.height_m, pitched_cam.fy)
    assert exact == pytest.approx(Y, rel=1e-9)
    assert abs(paper - Y) / Y > 1e-4          # the small-angle formula is measurably off at 3 deg


def test_eq3_above_horizon_is_nan(level_cam):
    assert np.isnan(eq3_distance(level_cam.horizon_row - 1.0, level_cam.horizon_row, 1.3, level_cam.fy))


@pytest.mark.parametrize("X", [3.7, -3.7, 8.0, -1.2, 1.2])
@pytest.mark.parametrize("Y", [6.0, 20.0, 50.0])
def test_eq4_far_edge_level_camera(level_cam, X, Y):
    """Rear face only (no side): far edge from cv2, d_x from equation 4 and from the estimator."""
    W, h = 1.8, level_cam.height_m
    corners = np.array([[X - W / 2, Y, -h], [X + W / 2, Y, -h], [X - W / 2, Y, -h + 1.4], [X + W / 2, Y, -h + 1.4]])
    uv = project_cv2(level_cam, corners)
    box = np.array([[uv[:, 0].min(), uv[:, 1].min(), uv[:, 0].max(), uv[:, 1].max()]])
    far = box[0, 2] if X > 0 else box[0, 0]
    if abs(X) > W / 2:  # not straddling: the paper's equation 4 applies
        assert eq4_lateral(Y, far - level_cam.cx, level_cam.fx, W) == pytest.approx(X, abs=1e-9)
    d_x, d_y = measure_boxes(level_cam, box, W, 0.0, 0.0, border_tol_px=None)[0]
    assert d_y == pytest.approx(Y, rel=1e-9)
    assert d_x == pytest.approx(X, abs=1e-9)


@pytest.mark.parametrize("cam_name", ["level_cam", "pitched_cam"])
@pytest.mark.parametrize("X", [0.0, 0.6, 3.5, -3.5, -7.0])
@pytest.mark.parametrize("Y", [3.0, 5.0, 8.0, 20.0, 45.0, 80.0])
def test_full_vehicle_rear_face_recovered_with_contact_correction(request, cam_name, X, Y):
    """A 3-D box vehicle seen with its side, tyres and bumper: the default estimator recovers (X, Y)."""
    cam = request.getfixturevalue(cam_name)
    box = np.array([vehicle_box(cam, X, Y)])
    d_x, d_y = measure_boxes(cam, box, 1.8, contact_offset_m=0.95, ground_clearance_m=0.17,
                             border_tol_px=None)[0]  # unclipped boxes: pure geometry
    assert d_y == pytest.approx(Y, rel=1e-9)
    assert d_x == pytest.approx(X, abs=1e-6)
    # The paper's formula (no correction) measures the tyre contact line or the bumper instead.
    d_y_paper = measure_boxes(cam, box, 1.8, 0.0, 0.0, border_tol_px=None)[0, 1]
    assert d_y_paper - Y > 0.05


def make_track_seq(cam, seq, noise, seed):
    rng = np.random.default_rng(seed)
    return [Track(1, tuple(np.array(vehicle_box(cam, dx, dy)) + rng.normal(0, noise, 4))) for _, dx, dy, _, _ in seq]


def errors(est, cam, seq, noise, seed=0, skip=15):
    est.reset()
    out = []
    for (t, dx, dy, vx, vy), tr in zip(seq, make_track_seq(cam, seq, noise, seed)):
        s = est.update([tr], t)[1]
        out.append((abs(s.d_y - dy) / dy, abs(s.v_y - vy), abs(s.d_x - dx)))
    return np.median(np.array(out)[skip:], axis=0)


def approach(d0=40.0, v=-5.0, dur=5.0, dx=0.0):
    t = np.arange(int(dur * FPS)) / FPS
    return [(ti, dx, d0 + v * ti, 0.0, v) for ti in t]


def braking(d0=30.0, a=-4.0, dur=3.0):
    t = np.arange(int(dur * FPS)) / FPS
    return [(ti, 0.0, d0 + 0.5 * a * ti ** 2, 0.0, a * ti) for ti in t]


@pytest.mark.parametrize("seq", [approach(), approach(dx=3.5), braking()], ids=["ahead", "adjacent", "braking"])
def test_kalman_beats_difference_on_noisy_boxes(level_cam, seq):
    kal = StateEstimator(level_cam, velocity="kalman")
    dif = StateEstimator(level_cam, velocity="difference")
    e_k = np.mean([errors(kal, level_cam, seq, 0.5, s) for s in range(3)], axis=0)
    e_d = np.mean([errors(dif, level_cam, seq, 0.5, s) for s in range(3)], axis=0)
    assert e_k[1] < e_d[1] / 5          # velocity
    assert e_k[0] < e_d[0]              # distance
    assert e_k[1] < 0.6                 # m/s
    assert e_k[0] < 0.01                # 1 %


def test_constant_acceleration_model_does_not_lag_braking(level_cam):
    cv = errors(StateEstimator(level_cam, motion="cv", process_std=2.0), level_cam, braking(), 0.0)
    ca = errors(StateEstimator(level_cam, motion="ca"), level_cam, braking(), 0.0)
    assert ca[1] < 0.2 and ca[0] < 0.002
    assert cv[1] > 1.0                   # the constant-velocity filter lags a 4 m/s^2 deceleration


def test_difference_uses_frame_timestamps(level_cam):
    """Irregular frame times (dropped frames): differencing is exact on exact boxes; v = 0 at init."""
    est = StateEstimator(level_cam, velocity="difference")
    times = [0.0, 1 / 30, 2 / 30, 5 / 30, 6 / 30, 11 / 30]
    v_true = -6.0
    for k, t in enumerate(times):
        d = 30.0 + v_true * t
        s = est.update([Track(4, vehicle_box(level_cam, 2.0, d))], t)[4]
        assert s.d_y == pytest.approx(d, rel=1e-9)
        assert s.v_y == pytest.approx(0.0 if k == 0 else v_true, abs=1e-6)
        assert s.v_x == pytest.approx(0.0, abs=1e-6)


def test_kalman_starts_at_rest_and_converges(level_cam):
    est = StateEstimator(level_cam)
    seq = approach(d0=25.0, v=-8.0, dur=2.0)
    states = [est.update([tr], t)[1] for (t, *_), tr in zip(seq, make_track_seq(level_cam, seq, 0.0, 0))]
    assert states[0].v_y == 0.0
    assert states[-1].v_y == pytest.approx(-8.0, abs=0.05)


def test_stale_coasting_tracks_are_dropped(level_cam):
    est = StateEstimator(level_cam, max_coast_used=2)
    box = vehicle_box(level_cam, 0.0, 20.0)
    assert 1 in est.update([Track(1, box)], 0.0)
    seen = [1 in est.update([Track(1, box, coasting=True)], k / FPS) for k in range(1, 6)]
    assert seen == [True, True, False, False, False]
    assert 1 in est.update([Track(1, box)], 6 / FPS)          # detected again: used again


def test_registered_and_box_above_horizon_skipped(level_cam):
    est = create("state", "geometric", camera=level_cam, velocity="difference")
    assert isinstance(est, StateEstimator)
    sky = (300.0, 10.0, 340.0, level_cam.horizon_row - 5.0)
    assert est.update([Track(1, sky), Track(2, vehicle_box(level_cam, 0, 10))], 0.0).keys() == {2}
    with pytest.raises(ValueError):
        StateEstimator(level_cam, velocity="magic")


# --------------------------------------------------------------------- boxes cut by the image border
def visible_box(cam: CameraModel, d_x: float, d_y: float, W=1.8, L=4.5, H=1.5, overhang=0.95, clearance=0.17):
    """Tight box of the part of a box-shaped vehicle inside the image (cv2 only).

    The vehicle is the convex hull of its body corners (clearance..H) and tyre contact lines;
    its projection (``cv2.projectPoints``) is clipped to the image rectangle
    (-0.5..w-0.5, -0.5..h-0.5) with ``cv2.intersectConvexConvex``.
    """
    uv = project_cv2(cam, vehicle_points(cam, d_x, d_y, W, L, H, overhang, clearance)).astype(np.float32)
    hull = cv2.convexHull(uv)
    w, hh = cam.width - 0.5, cam.height - 0.5
    rect = np.array([[-0.5, -0.5], [w, -0.5], [w, hh], [-0.5, hh]], dtype=np.float32)
    area, inter = cv2.intersectConvexConvex(hull, rect)
    assert area > 0, "vehicle not in view"
    p = inter.reshape(-1, 2).astype(float)
    return (p[:, 0].min(), p[:, 1].min(), p[:, 0].max(), p[:, 1].max())


@pytest.mark.parametrize("cam_name", ["level_cam", "pitched_cam"])
@pytest.mark.parametrize("X", [3.7, -3.7, 5.0])
@pytest.mark.parametrize("Y", [3.0, 4.5, 6.0])
def test_far_edge_cut_by_border_uses_the_near_edge(request, cam_name, X, Y):
    """A vehicle in an adjacent lane leaving the view: the near edge (inner front corner) gives d_x."""
    cam = request.getfixturevalue(cam_name)
    box = np.array([visible_box(cam, X, Y)])
    x1, _, x2, _ = box[0]
    assert (x2 >= cam.width - 0.5 - 1e-3) if X > 0 else (x1 <= -0.5 + 1e-3)   # the far edge is the border
    # Equation 4 on the near edge is exact at the true distance.
    assert lateral_from_terms(lateral_terms(cam, box), np.array([Y]))[0] == pytest.approx(X, abs=1e-4)
    # On the far edge (the border) it pulls the vehicle towards the centre line.
    d_x_border = measure_boxes(cam, box, border_tol_px=None)[0, 0]
    assert abs(d_x_border) < abs(X) - 0.3
    d_x, d_y = measure_boxes(cam, box)[0]
    u_c = project_cv2(cam, np.array([[X - np.sign(X) * 0.9, Y + 0.95, -cam.height_m]]))[0, 0]
    if -0.5 < u_c < cam.width - 0.5:
        # The border also cuts the underside between the rear corner and the tyres, so the bottom
        # edge is not exactly the contact line: a few % in d_y, which carries into d_x.
        assert d_y == pytest.approx(Y, rel=0.03)
        assert d_x == pytest.approx(X, abs=0.03 * abs(X))
    else:   # no part of the contact line in view: the box gives no distance
        assert np.isnan(d_y)


def test_near_edge_error_from_a_wrong_assumed_length_is_small(level_cam):
    """A 5 m x 2 m vehicle (highway-env's) measured with the defaults (4.5 m x 1.8 m assumed)."""
    for Y in (4.5, 6.0, 8.0):
        box = np.array([visible_box(level_cam, 4.0, Y, W=2.0, L=5.0)])
        assert level_cam.width - 0.5 - box[0, 2] < 1e-3
        d_x = measure_boxes(level_cam, box)[0, 0]
        assert abs(d_x - 4.0) < 0.35


def test_straddling_box_with_one_side_cut_uses_the_other_rear_corner():
    """Camera laterally within the vehicle's width, very close: only the rear face; one side cut."""
    cam = CameraModel.from_fov(640, 360, 90.0, 1.0)
    X, Y = -0.8, 1.5
    box = visible_box(cam, X, Y, clearance=0.3)
    assert box[0] <= -0.5 + 1e-3 and box[2] < cam.width - 2 and box[0] < cam.cx < box[2]
    assert box[3] < cam.height - 5
    d_x, d_y = measure_boxes(cam, np.array([box]), ground_clearance_m=0.3)[0]
    assert d_y == pytest.approx(Y, rel=1e-5)
    assert d_x == pytest.approx(X, abs=1e-4)
    assert abs(measure_boxes(cam, np.array([box]), ground_clearance_m=0.3, border_tol_px=None)[0, 0] - X) > 0.05


def test_both_sides_cut_gives_no_lateral_and_bottom_cut_gives_no_distance(level_cam):
    wide = np.array([[-0.5, 100.0, level_cam.width - 0.5, 300.0]])
    d_x, d_y = measure_boxes(level_cam, wide)[0]
    assert np.isnan(d_x) and np.isfinite(d_y)
    # A lead vehicle 1.5 m ahead: the contact line is below the image, the box's bottom is the border.
    box = np.array([visible_box(level_cam, 0.0, 1.5)])
    assert box[0, 3] == pytest.approx(level_cam.height - 0.5)
    d_x, d_y = measure_boxes(level_cam, box)[0]
    assert np.isnan(d_y) and np.isnan(d_x)
    d_y_border = measure_boxes(level_cam, box, border_tol_px=None)[0, 1]
    assert d_y_border > 1.5 + 0.5                     # what equation 3 would have said: too far


@pytest.mark.parametrize("velocity", ["kalman", "difference"])
def test_bottom_cut_track_keeps_its_filtered_distance(level_cam, velocity):
    """A known track whose box bottom reaches the border: distance predicted/held, never the border's."""
    est = StateEstimator(level_cam, velocity=velocity)
    v = -3.0
    out = []
    for k in range(40):
        t = k / FPS
        box = visible_box(level_cam, 0.0, 4.0 + v * t)
        out.append((t, 4.0 + v * t, box[3] >= level_cam.height - 1.5, est.update([Track(1, box)], t).get(1)))
    cut = [o for o in out if o[2]]
    assert cut and not out[0][2]
    last_whole = [o for o in out if not o[2]][-1][3].d_y
    for t, d_true, _, s in cut:
        assert s is not None
        assert s.d_y <= last_whole + 1e-6                 # never the (farther) distance of the border row
        if velocity == "kalman":
            assert s.d_y == pytest.approx(max(d_true, 0.0), abs=0.3)  # predicted on, never behind the camera
    # A new track whose first box is cut is not output.
    est.reset()
    assert est.update([Track(2, visible_box(level_cam, 0.0, 1.5))], 0.0) == {}


def test_vehicle_leaving_the_view_gives_no_lateral_velocity_or_false_warning(pitched_cam):
    """Adjacent-lane vehicle (5 m x 2 m) at a constant 4 m offset, the ego overtaking it at 3 m/s."""
    from monorarp.risk.estimators import TTCRiskEstimator

    def run(border_tol_px):
        est = StateEstimator(pitched_cam, border_tol_px=border_tol_px)
        risk = TTCRiskEstimator()
        v_x, d_x, warn = [], [], []
        for k in range(60):
            t = k / FPS
            Y = 9.0 - 3.0 * t
            box = visible_box(pitched_cam, 4.0, Y, W=2.0, L=5.0)
            if box[2] - box[0] < 3:
                break
            s = est.update([Track(1, box)], t).get(1)
            if s is not None and k > 5:
                v_x.append(s.v_x)
                d_x.append(s.d_x)
                ttc = risk.assess({1: s}, t).ttc.get(1)
                warn.append(ttc is not None and ttc < 2.0)
        return np.array(v_x), np.array(d_x), np.array(warn)

    v_x, d_x, warn = run(1.0)
    assert np.abs(v_x).max() < 0.6 and np.abs(d_x - 4.0).max() < 0.4 and not warn.any()
    v_x_old, _, _ = run(None)                          # the far edge taken at the border
    assert v_x_old.min() < -1.5


def test_vehicle_stuck_below_the_bottom_border_is_not_extrapolated_through_the_ego():
    """A lead closing at 20 m/s whose box then stays cut by the bottom border (e.g. after a crash):
    its distance must stay within [0, near_limit], not run off to minus tens of metres."""
    cam = CameraModel.from_fov(640, 360, 70.0, 1.3, math.radians(2.0))
    est = StateEstimator(cam)
    fps = 15.0
    half_w = 1.0
    states = []
    for k in range(60):
        t = k / fps
        d = max(20.0 - 20.0 * t, 1.0)      # rear face distance (m); reaches 1 m at t = 0.95 s and stays
        rear_ground = np.array([[-half_w, d + 0.95, -1.3], [half_w, d + 0.95, -1.3]])   # tyre contact line
        uv = cam.project_ego(rear_ground)
        top = cam.project_ego(np.array([[0.0, d, 0.2]]))[0, 1]
        box = (uv[0, 0], top, uv[1, 0], min(uv[0, 1], cam.height - 0.5))
        states.append(est.update([Track(id=1, box=box)], t)[1])
    late = [s.d_y for s in states[30:]]
    assert all(0.0 <= y <= est.near_limit_m + 1e-9 for y in late)
    assert states[-1].v_y == 0.0 or states[-1].d_y > 0.0


def test_a_jump_to_another_vehicle_restarts_the_filter(level_cam):
    """A box that jumps from a car at ~20 m to one at ~40 m is a new sighting, not 300 m/s of motion."""
    cam = level_cam
    near = vehicle_box(cam, 0.0, 20.0)
    far = vehicle_box(cam, 0.0, 40.0)
    frames = [near] * 10 + [far] * 3
    for sigmas, restarted in ((5.0, True), (math.inf, False)):
        est = StateEstimator(cam, reinit_sigmas=sigmas)
        for k, box in enumerate(frames[:11]):
            out = est.update([Track(id=1, box=box)], k / 15)
        st = out[1]
        if restarted:
            assert st.v_y == pytest.approx(0.0) and st.d_y == pytest.approx(est.measure(np.array([far]))[0, 1])
            assert st.v_y_std == pytest.approx(10.0, rel=0.05)      # the wide prior: unknown velocity
        else:
            assert st.v_y > 3.0 and st.d_y < 30.0      # absorbed: a spurious opening speed, a lagging distance
    assert StateEstimator(cam).update([Track(id=1, box=near)], 0.0)[1].a_y == pytest.approx(0.0)
    assert StateEstimator(cam, motion="cv").update([Track(id=1, box=near)], 0.0)[1].a_y is None


def gauss_markov(rng, n, dt, tau, std):
    """First-order Gauss-Markov series (stationary std ``std``, time constant ``tau`` s)."""
    phi = math.exp(-dt / tau)
    out = np.empty(n)
    out[0] = rng.normal(0, std)
    for k in range(1, n):
        out[k] = phi * out[k - 1] + rng.normal(0, std * math.sqrt(1 - phi * phi))
    return out


def velocity_nees(est, cam, seq, seed, bias_px=0.6, white_px=0.2, tau=0.5, skip=15):
    """|v_y - truth| / sigma over a sequence whose box edges carry slowly varying (correlated) errors."""
    rng = np.random.default_rng(seed)
    n = len(seq)
    err = np.stack([gauss_markov(rng, n, 1 / FPS, tau, bias_px) for _ in range(4)], axis=1)
    err += rng.normal(0, white_px, (n, 4))
    est.reset()
    out = []
    for k, (t, dx, dy, vx, vy) in enumerate(seq):
        s = est.update([Track(1, tuple(np.array(vehicle_box(cam, dx, dy)) + err[k]))], t)[1]
        out.append(abs(s.v_y - vy) / s.v_y_std)
    return out[skip:]


def test_bias_state_makes_the_velocity_sigma_honest_under_correlated_edge_errors(level_cam):
    """White-noise filter: overconfident (|err|/sigma p90 far above a Gaussian's 1.64); with the
    Gauss-Markov bias state of the same statistics it is near 1.64."""
    seq = approach(d0=35.0, v=-5.0, dur=4.0, dx=1.0)
    white = StateEstimator(level_cam, pixel_std=0.2)
    biased = StateEstimator(level_cam, pixel_std=0.2, bias_pixel_std=0.6, bias_tau_s=0.5)
    p90_w = np.percentile(np.concatenate([velocity_nees(white, level_cam, seq, s) for s in range(12)]), 90)
    p90_b = np.percentile(np.concatenate([velocity_nees(biased, level_cam, seq, s) for s in range(12)]), 90)
    assert p90_w > 2.5
    assert 1.2 < p90_b < 2.1


def test_kf_update_with_a_measurement_row_matches_the_matrix_formula():
    from monorarp.core.kalman import kf_update
    rng = np.random.default_rng(3)
    A = rng.normal(size=(4, 4))
    P = A @ A.T + np.eye(4)
    x, h, z, r = rng.normal(size=4), np.array([1.0, 0.0, 0.0, 0.7]), 1.3, 0.25
    H = h[None]
    K = P @ H.T @ np.linalg.inv(H @ P @ H.T + r)
    x_ref, P_ref = x + (K @ (np.array([z]) - H @ x)), (np.eye(4) - K @ H) @ P
    xu, Pu = kf_update(x, P, np.array(z), np.array(r), h)
    np.testing.assert_allclose(xu, x_ref, atol=1e-12)
    np.testing.assert_allclose(Pu, P_ref, atol=1e-12)
    x0, P0 = kf_update(x, P, np.array(z), np.array(r))            # default row: the position
    x1, P1 = kf_update(x, P, np.array(z), np.array(r), np.eye(4)[0])
    np.testing.assert_allclose(x0, x1), np.testing.assert_allclose(P0, P1)


def test_huber_update_limits_a_single_outlier(level_cam):
    """One box 1.5 px low (below the 5-sigma restart): the robust update moves the velocity less."""
    seq = approach(d0=30.0, v=-5.0, dur=2.0)
    jumps = {}
    for robust in (None, 2.0):
        est = StateEstimator(level_cam, robust_sigmas=robust, pixel_std_per_height=0.0)
        for k, (t, dx, dy, *_ ) in enumerate(seq):
            box = np.array(vehicle_box(level_cam, dx, dy)) + (np.array([0, 0, 0, 1.5]) if k == 45 else 0.0)
            s = est.update([Track(1, tuple(box))], t)[1]
            if k == 45:
                jumps[robust] = abs(s.v_y + 5.0)
    assert jumps[2.0] < jumps[None] / 2


def test_age_counts_from_the_filter_start_and_restarts_on_a_jump(level_cam):
    est = StateEstimator(level_cam)
    ages = [est.update([Track(1, vehicle_box(level_cam, 0.0, 30.0 - k * 0.1))], k / FPS)[1].age_s for k in range(10)]
    np.testing.assert_allclose(ages, np.arange(10) / FPS)
    s = est.update([Track(1, vehicle_box(level_cam, 3.5, 12.0))], 10 / FPS)[1]     # jumped to another vehicle
    assert s.age_s == 0.0


@pytest.mark.parametrize("kw", [{"robust_sigmas": 0.0}, {"bias_tau_s": 0.0}])
def test_bad_noise_parameters_are_refused(level_cam, kw):
    with pytest.raises(ValueError):
        StateEstimator(level_cam, **kw)


def test_a_short_box_cannot_move_the_near_edge_reading_inwards():
    """A next-lane car entering from the right: the detector's box stops 12 px short of the border
    (its far edge is no edge), then reaches it. Learnt from the short box without a limit, the
    near-edge reading is shifted by ~-2.4 m for good (a false in-path car); with a 16 px margin it
    is not learnt; an inward shift is clipped to 0.3 m; and by default the short box, too narrow
    for a vehicle at its distance, is taken as cut by the border, so nothing wrong is learnt."""
    cam = CameraModel.from_fov(640, 360, 70.0, 1.3, pitch_rad=math.radians(2.0))
    short, cut = (500.0, 200.0, 627.0, 276.0), (441.1, 200.0, 639.5, 245.7)

    def lateral(**kw):
        est = StateEstimator(cam, **kw)
        for k in range(3):
            est.update([Track(1, short)], k / FPS)
        s = est.update([Track(1, cut)], 3 / FPS)[1]
        return s.d_x

    fresh = StateEstimator(cam).update([Track(1, cut)], 0.0)[1].d_x        # the near-edge reading alone
    assert fresh == pytest.approx(3.77, abs=0.05)
    assert lateral(max_inward_offset_m=None, min_vehicle_width_m=0.0) < fresh - 1.0
    assert lateral(offset_learn_margin_px=16, min_vehicle_width_m=0.0) == pytest.approx(fresh, abs=0.3)
    assert lateral(min_vehicle_width_m=0.0) == pytest.approx(fresh - 0.3, abs=1e-6)
    # by default the short box (127 px: under 1.4 m at its ~9 m) is taken as reaching the border
    assert lateral(max_inward_offset_m=None) == pytest.approx(fresh, abs=0.05)


def test_a_distance_not_measured_for_long_is_no_longer_output(level_cam):
    est = StateEstimator(level_cam, max_unmeasured_s=0.5)
    for k in range(10):
        assert 1 in est.update([Track(1, vehicle_box(level_cam, 0.0, 20.0 - 0.5 * k))], k / FPS)
    above = (300.0, 100.0, 340.0, 150.0)          # above the horizon: no distance, no new track
    kept = [1 in est.update([Track(1, above)], (10 + k) / FPS) for k in range(20)]
    assert FPS == 30 and kept == [True] * 15 + [False] * 5     # predicted for 0.5 s, then dropped


def test_a_narrow_box_near_the_side_border_is_taken_as_cut(level_cam):
    est = StateEstimator(level_cam)
    whole = vehicle_box(level_cam, 3.7, 12.0)
    # a car mostly out of view on the right: 60 px wide at 12 m (1.4 m there is 65 px), 20 px short of the border
    short = (560.0, whole[1], 620.0, whole[3])
    out = est.border_cut_boxes(np.array([whole, short, (100.0, 150.0, 200.0, 200.0)]))
    np.testing.assert_array_equal(out[0], whole)
    assert out[1][2] == 639.5 and out[1][0] == short[0]
    np.testing.assert_array_equal(out[2], (100.0, 150.0, 200.0, 200.0))
    assert StateEstimator(level_cam, min_vehicle_width_m=0.0).border_cut_boxes(np.array([short]))[0][2] == 620.0


def settled_v_x_std(camera, box, **kw) -> float:
    """Lateral-velocity one-sigma (m/s) of a track held at ``box`` for 10 frames."""
    est = StateEstimator(camera, **kw)
    for k in range(10):
        out = est.update([Track(1, box)], k / FPS)
    return out[1].v_x_std


def test_a_far_edge_in_the_side_band_gets_the_side_cut_lateral_uncertainty(level_cam):
    """A next-lane car whose far edge lies within side_band_frac of the border (not cut) reports at
    least side_cut_lateral_std_mps of lateral-velocity uncertainty; one further in does not."""
    near = vehicle_box(level_cam, 3.7, 10.0)
    shift = 639.5 - 10.0 - near[2]          # 10 px from the border: inside 0.03 * 640 = 19 px, outside 4 px
    in_band = (near[0] + shift, near[1], near[2] + shift, near[3])
    away = vehicle_box(level_cam, 3.7, 20.0)
    assert 639.5 - away[2] > 0.03 * 640
    assert settled_v_x_std(level_cam, in_band) >= 2.0
    assert settled_v_x_std(level_cam, in_band, side_band_frac=0.0) < 1.0
    assert settled_v_x_std(level_cam, away) < 1.0
    left = (639.0 - in_band[2], in_band[1], 639.0 - in_band[0], in_band[3])   # mirrored: the left border
    assert settled_v_x_std(level_cam, left) >= 2.0
    for bad in (-0.1, 0.5, float("nan")):
        with pytest.raises(ValueError, match="side_band_frac"):
            StateEstimator(level_cam, side_band_frac=bad)


def test_a_box_too_narrow_for_a_vehicle_gets_the_side_cut_lateral_uncertainty(level_cam):
    """A box narrower than min_vehicle_width_m at its distance, away from the borders, holds a part of a
    vehicle (its far edge is not the vehicle's): at least side_cut_lateral_std_mps of lateral-velocity
    uncertainty; a whole car's box at the same place does not get it."""
    whole = vehicle_box(level_cam, 3.7, 9.0)
    cx = (whole[0] + whole[2]) / 2
    w_min = level_cam.fx * 1.4 / (9.0 - 0.0)          # 1.4 m at about the box's distance, px
    part = (cx - 0.3 * w_min, whole[1], cx + 0.3 * w_min, whole[3])    # about 0.85 m wide
    assert settled_v_x_std(level_cam, whole) < 1.0
    assert settled_v_x_std(level_cam, part) >= 2.0
    assert settled_v_x_std(level_cam, part, min_vehicle_width_m=0.0) < 1.0


def test_a_box_mostly_behind_a_nearer_one_gets_the_side_cut_lateral_uncertainty(level_cam):
    """A far car two lanes over whose box lies mostly behind a nearer car's (its bottom edge and sides then
    belong to what is left in view) reports at least side_cut_lateral_std_mps of lateral-velocity
    uncertainty; alone, or with hidden_share None, it does not; the nearer car never does."""
    near, far = vehicle_box(level_cam, -3.7, 20.0), vehicle_box(level_cam, -7.4, 38.0)
    w = far[2] - far[0]
    behind = (near[0] - 0.3 * w, far[1], near[0] + 0.7 * w, far[3])     # 70 % of it over the nearer box

    def stds(tracks, **kw):
        est = StateEstimator(level_cam, **kw)
        for k in range(10):
            out = est.update(tracks, k / FPS)
        return {i: s.v_x_std for i, s in out.items()}

    both = stds([Track(1, near), Track(2, behind)])
    assert both[2] >= 2.0 and both[1] < 1.0
    assert stds([Track(2, behind)])[2] < 1.5
    assert stds([Track(1, near), Track(2, behind)], hidden_share=None)[2] < 1.5
    for bad in (1.0, -0.1, float("nan")):
        with pytest.raises(ValueError, match="hidden_share"):
            StateEstimator(level_cam, hidden_share=bad)


def test_border_tolerance_scales_with_the_frame_width():
    cam = CameraModel.from_fov(1920, 1080, 70.0, 1.6, pitch_rad=math.radians(4.0))
    assert StateEstimator(cam).border_tol_px == pytest.approx(12.0)
    assert StateEstimator(cam, border_tol_px=4.0).border_tol_px == 4.0
    assert StateEstimator(cam, border_tol_px=None).border_tol_px is None


def test_a_far_side_behind_a_nearer_parked_car_is_read_from_the_near_edge(level_cam):
    """Two cars parked in a row on the right, 1.5 m apart (cv2.projectPoints boxes): the nearer one hides the
    farther one's outer (far) side, so the farther box ends where the nearer begins. Its far-edge reading
    pulls it over 0.9 m towards the ego's path; taken as a cut side (hidden_sides) the near edge reads its
    lateral position exactly (its length is the assumed 4.5 m), and the estimator does the same."""
    from monorarp.state.geometry import hidden_sides

    X, Y_far, Y_near = 2.8, 15.0, 9.0
    near = vehicle_box(level_cam, X, Y_near)
    whole = vehicle_box(level_cam, X, Y_far)
    far = (whole[0], whole[1], near[0], whole[3])                   # its right part lies behind the nearer car
    assert whole[0] < near[0] < whole[2] and near[3] > whole[3]
    boxes = np.array([far, near])
    hidden = hidden_sides(boxes)
    np.testing.assert_array_equal(hidden, [[False, True], [False, False]])
    y = np.array([Y_far, Y_near])
    assert lateral_from_terms(lateral_terms(level_cam, boxes, hidden=hidden), y) == pytest.approx([X, X], abs=1e-3)
    assert lateral_from_terms(lateral_terms(level_cam, boxes), y)[0] < X - 0.9
    # nothing is hidden by a box that is not nearer, nor by one holding the whole box
    np.testing.assert_array_equal(hidden_sides(boxes[::-1])[::-1], hidden)
    assert not hidden_sides(np.array([far, (far[0] - 5, far[1] - 5, far[2] + 5, far[3] + 5)])).any()
    assert not hidden_sides(np.array([far, (near[0], far[1], near[2], far[3])])).any()   # same bottom row

    def d_x(**kw):
        est = StateEstimator(level_cam, **kw)
        for k in range(10):
            out = est.update([Track(1, far), Track(2, near)], k / FPS)
        return out[1].d_x

    assert d_x() == pytest.approx(X, abs=0.1)
    assert d_x(hidden_side_px=None) < X - 0.7


def test_a_filter_restarted_on_a_box_that_gives_no_distance_outputs_none_until_one_does(level_cam):
    """A track on a next-lane car at 12 m whose box jumps to another vehicle, close beside the ego with its
    bottom below the frame: the filter restarts there and knows no distance (it started at 0 m and read
    the car as in the ego's path at contact); it is output again once a box gives a distance."""
    est = StateEstimator(level_cam)
    for k in range(10):
        assert 1 in est.update([Track(1, vehicle_box(level_cam, 3.5, 12.0))], k / FPS)
    cut = visible_box(level_cam, -1.0, 1.0)
    assert cut[3] >= level_cam.height - 1.5
    assert est.update([Track(1, cut)], 10 / FPS) == {}
    assert est.update([Track(1, cut)], 11 / FPS) == {}
    back = est.update([Track(1, vehicle_box(level_cam, -1.0, 6.0))], 12 / FPS)
    assert back[1].d_y == pytest.approx(6.0, abs=0.3)
