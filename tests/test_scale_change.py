"""Patch registration (monorarp.state.scale_change) against images warped by a known scale with cv2.warpAffine."""

import math

import cv2
import numpy as np
import pytest

from monorarp.core.camera import CameraModel
from monorarp.state.scale_change import (LoomingRegistration, RateWindow, gradient_stack, lateral_displacement, region,
                                   register_scale)
from monorarp.state.estimator import StateEstimator
from monorarp.state.geometry import fragments
from monorarp.core.types import Track

CENTRE = (320.0, 200.0)


def texture(seed: int = 0, shape=(360, 640)) -> np.ndarray:
    """A smooth random grey texture (0-255, float32)."""
    rng = np.random.default_rng(seed)
    noise = rng.normal(0.0, 1.0, shape).astype(np.float32)
    img = cv2.GaussianBlur(noise, (0, 0), 2.5)
    return (127.0 + 60.0 * img / img.std()).astype(np.float32)


def scaled(img: np.ndarray, s: float, shift=(0.0, 0.0), centre=CENTRE) -> np.ndarray:
    """``img`` scaled by ``s`` about ``centre`` and shifted: a point p moves to c + s (p - c) + shift."""
    cx, cy = centre
    m = np.array([[s, 0.0, (1 - s) * cx + shift[0]], [0.0, s, (1 - s) * cy + shift[1]]], dtype=np.float64)
    return cv2.warpAffine(img, m, (img.shape[1], img.shape[0]), flags=cv2.INTER_CUBIC, borderMode=cv2.BORDER_REFLECT)


def box_scaled(box, s, shift=(0.0, 0.0), centre=CENTRE):
    cx, cy = centre
    x1, y1, x2, y2 = box
    return (cx + s * (x1 - cx) + shift[0], cy + s * (y1 - cy) + shift[1],
            cx + s * (x2 - cx) + shift[0], cy + s * (y2 - cy) + shift[1])


BOX = (270.0, 160.0, 370.0, 240.0)


@pytest.mark.parametrize("s, shift", [(1.0, (0.0, 0.0)), (1.02, (0.0, 0.0)), (1.05, (1.5, -0.7)), (0.97, (-2.0, 1.0))])
def test_the_fitted_scale_is_the_warp_s(s, shift):
    prev = texture()
    cur = scaled(prev, s, shift)
    # the boxes given as the fit's start are off by a pixel, as a tracker's are
    start = np.array(box_scaled(BOX, s, shift)) + [1.0, -0.5, -1.0, 0.8]
    r = register_scale(prev, gradient_stack(cur), BOX, tuple(start))
    assert r.ok
    assert r.scale == pytest.approx(s, abs=1.5e-3)


def test_a_patch_too_small_or_a_failed_fit_is_no_scale():
    prev = texture()
    assert not register_scale(prev, gradient_stack(prev), (300.0, 190.0, 305.0, 195.0), (300.0, 190.0, 305.0, 195.0)).ok
    other = texture(seed=1)           # another scene altogether: the fit runs away or is refused
    r = register_scale(prev, gradient_stack(other), BOX, BOX, max_change=0.01)
    assert not r.ok or abs(r.scale - 1.0) <= 0.01


def test_the_registration_needs_two_frames_a_valid_box_and_no_nearer_box_over_it():
    reg = LoomingRegistration(pixel_std=0.2)
    prev = texture()
    near = (250.0, 150.0, 300.0, 260.0)                     # lower bottom edge: nearer, overlaps box 1
    s0, sd0, *_ = reg.update(prev, [1, 2], np.array([BOX, near]), np.array([True, True]))
    assert np.isnan(s0).all() and np.isnan(sd0).all()      # nothing before
    cur = scaled(prev, 1.03)
    s1, sd1, *_ = reg.update(cur, [1, 2], np.array([box_scaled(BOX, 1.03), box_scaled(near, 1.03)]), np.array([True, True]))
    assert np.isnan(s1[0])                                   # box 1 lies behind box 2
    assert s1[1] == pytest.approx(1.03, abs=2e-3)
    assert sd1[1] == pytest.approx(s1[1] * 0.2 / 50.0)      # pixel_std over the previous box's width
    reg.reset()
    reg.update(prev, [1], np.array([BOX]), np.array([True]))
    s2, *_ = reg.update(cur, [1], np.array([box_scaled(BOX, 1.03)]), np.array([False]))
    assert np.isnan(s2[0])                                   # a coasting or cut box is no measurement
    with pytest.raises(ValueError):
        LoomingRegistration(pixel_std=0.0)


def test_the_rate_window_averages_the_last_frames_rates():
    w = RateWindow(window_s=0.2, min_samples=2)
    dt = 1.0 / 15.0
    sd = np.array([0.003])
    r, s = w.update([7], np.array([np.nan]), sd, 0.0)
    assert np.isnan(r[0])                                    # first call: no interval yet
    r, s = w.update([7], np.array([1.02]), sd, dt)
    assert np.isnan(r[0])                                    # one sample: fewer than min_samples
    r, s = w.update([7], np.array([1.03]), sd, 2 * dt)
    assert r[0] == pytest.approx((0.02 + 0.03) / 2 / dt)
    assert s[0] == pytest.approx(math.sqrt(2) * 0.003 / dt / 2)
    w.update([7], np.array([1.04]), sd, 3 * dt)
    r, s = w.update([7], np.array([1.05]), sd, 4 * dt)     # the window holds 3 frames at 15 fps
    assert r[0] == pytest.approx((0.03 + 0.04 + 0.05) / 3 / dt)
    r, _ = w.update([7], np.array([np.nan]), sd, 5 * dt)
    assert np.isnan(r[0])                                    # not registered this frame: none
    w.reset()
    r, _ = w.update([7], np.array([1.02]), sd, 6 * dt)
    assert np.isnan(r[0])
    for bad in ({"window_s": 0.0}, {"min_samples": 0}):
        with pytest.raises(ValueError):
            RateWindow(**bad)


def test_a_box_inside_a_wider_one_on_the_same_ground_row_is_a_fragment():
    # the 2-hour benchmark's case (dense_traffic seed 1022): a wide vehicle's box at 8 m and a
    # 59 px part of it read as a car
    wide, part = (49.0, 155.0, 218.0, 227.0), (162.0, 162.0, 221.0, 227.0)
    assert fragments(np.array([part, wide])).tolist() == [True, False]
    assert fragments(np.array([(162.0, 162.0, 221.0, 215.0), wide])).tolist() == [False, False]   # stands further away
    assert fragments(np.array([(300.0, 155.0, 469.0, 227.0), wide])).tolist() == [False, False]   # side by side
    assert fragments(np.array([(60.0, 150.0, 200.0, 227.0), wide])).tolist() == [False, False]    # as wide (< 1.5x)
    assert fragments(np.zeros((0, 4))).tolist() == []


def test_the_state_stage_outputs_the_registered_rate_of_an_approaching_vehicle():
    camera = CameraModel.from_fov(640, 360, 60.0, 1.3)
    est = StateEstimator(camera)
    base = texture()
    dt, s = 1.0 / 15.0, 1.02
    out = []
    for k in range(4):
        img = scaled(base, s ** k)
        box = box_scaled(BOX, s ** k)
        out.append(est.update([Track(id=3, box=box)], k * dt, image=np.dstack([img] * 3).clip(0, 255).astype(np.uint8)))
    assert out[1][3].registered_rate is None                 # one registration: not yet
    assert out[3][3].registered_rate == pytest.approx((s - 1) / dt, rel=0.1)
    assert out[3][3].registered_rate_std == pytest.approx(s * 0.2 / (100 * s ** 2) / dt / math.sqrt(3), rel=0.05)
    assert StateEstimator(camera).update([Track(id=3, box=BOX)], 0.0)[3].registered_rate is None   # no image
    off = StateEstimator(camera, registration=False)
    for k in range(4):
        st = off.update([Track(id=3, box=box_scaled(BOX, s ** k))], k * dt, image=np.zeros((360, 640, 3), np.uint8))
    assert st[3].registered_rate is None


def test_the_state_stage_gives_a_fragment_no_state():
    camera = CameraModel.from_fov(640, 360, 60.0, 1.3)
    tracks = [Track(id=1, box=(49.0, 155.0, 218.0, 227.0)), Track(id=2, box=(162.0, 162.0, 221.0, 227.0))]
    assert set(StateEstimator(camera).update(tracks, 0.0)) == {1}
    assert set(StateEstimator(camera, fragment_cover=None).update(tracks, 0.0)) == {1, 2}
    with pytest.raises(ValueError, match="fragment_cover"):
        StateEstimator(camera, fragment_cover=1.5)


def test_a_stack_of_the_patches_region_gives_the_full_frames_scale():
    prev = texture()
    cur = scaled(prev, 1.04, (0.5, -0.3))
    box_cur = box_scaled(BOX, 1.04, (0.5, -0.3))
    full = register_scale(prev, gradient_stack(cur), BOX, box_cur)
    x0, y0, x1, y1 = region(np.array([BOX, box_cur]), cur.shape)
    assert 200 < x0 < 220 and 100 < y0 < 120 and 420 < x1 < 440 and 280 < y1 < 300   # boxes grown by half their size
    part = register_scale(prev, gradient_stack(cur[y0:y1, x0:x1]), BOX, box_cur, origin=(x0, y0))
    assert part.ok and part.scale == pytest.approx(full.scale, abs=1e-6)


def test_a_wide_frame_is_registered_reduced_with_the_same_scale():
    prev = cv2.resize(texture(), (1920, 1080), interpolation=cv2.INTER_CUBIC)
    big = tuple(3 * v for v in BOX)
    cur = scaled(prev, 1.03, centre=(960.0, 600.0))
    cur_box = box_scaled(big, 1.03, centre=(960.0, 600.0))
    out = {}
    for max_width in (640, None):
        reg = LoomingRegistration(max_width=max_width)
        reg.update(prev, [1], np.array([big]), np.array([True]))
        out[max_width] = reg.update(cur, [1], np.array([cur_box]), np.array([True]))
    assert out[640][0][0] == pytest.approx(1.03, abs=2e-3) and out[None][0][0] == pytest.approx(1.03, abs=2e-3)
    assert out[640][1][0] == pytest.approx(3 * out[None][1][0], rel=1e-2)   # 0.2 px of the reduced width
    with pytest.raises(ValueError, match="max_width"):
        LoomingRegistration(max_width=4)


def test_a_box_cut_by_the_image_bottom_is_not_registered():
    # a vehicle at contact: its box runs off the bottom of the frame, and its patch with it
    camera = CameraModel.from_fov(640, 360, 60.0, 1.3)
    est = StateEstimator(camera)
    seen = []
    inner = est.registration.update
    est.registration.update = lambda image, ids, boxes, valid: (seen.append(list(valid)), inner(image, ids, boxes, valid))[1]
    img = np.zeros((360, 640, 3), np.uint8)
    est.update([Track(id=5, box=(270.0, 250.0, 370.0, 340.0))], 0.0, image=img)
    est.update([Track(id=5, box=(265.0, 260.0, 375.0, 360.0))], 1 / 15, image=img)
    assert seen == [[True], [False]]


def test_the_3x3_solve_matches_numpy():
    from monorarp.state.scale_change import _solve3
    rng = np.random.default_rng(3)
    for _ in range(200):
        a = rng.normal(size=(3, 3))
        a = a @ a.T + 0.05 * np.eye(3)
        b = rng.normal(size=3)
        assert np.allclose(_solve3(a, b), np.linalg.solve(a, b), rtol=1e-9, atol=1e-12)
    assert _solve3(np.zeros((3, 3)), np.ones(3)) is None


def test_the_lateral_displacement_inverts_the_projection():
    # a point at (X, Z) moves to (X', Z'); cv2.projectPoints gives its columns; s = Z / Z'
    k = np.array([[500.0, 0.0, 320.0], [0.0, 500.0, 180.0], [0.0, 0.0, 1.0]])
    for (x0, z0), (x1, z1) in (((1.5, 20.0), (1.2, 18.0)), ((-3.7, 9.0), (-3.0, 8.5)), ((0.0, 40.0), (0.4, 41.0))):
        (u0, u1), _ = cv2.projectPoints(np.array([[x0, 0.5, z0], [x1, 0.5, z1]]), np.zeros(3), np.zeros(3), k, None)
        u0, u1 = u0[0, 0], u1[0, 0]
        assert lateral_displacement(u0, u1 - u0, z0 / z1, z0, 500.0, 320.0) == pytest.approx(x1 - x0, abs=1e-9)


def test_the_state_stage_outputs_the_registered_lateral_velocity_of_a_vehicle_moving_sideways():
    camera = CameraModel.from_fov(640, 360, 60.0, 1.3)
    est = StateEstimator(camera)
    base = texture(4)
    dt, step = 1.0 / 15.0, 3.0                      # 3 px a frame to the right, no scale change
    for k in range(4):
        img = scaled(base, 1.0, shift=(step * k, 0.0))
        st = est.update([Track(id=3, box=box_scaled(BOX, 1.0, shift=(step * k, 0.0)))], k * dt,
                        image=np.dstack([img] * 3).clip(0, 255).astype(np.uint8))
    o = st[3]
    assert o.registered_v_x == pytest.approx(o.d_y / camera.fx * step / dt, rel=0.05)
    assert o.registered_v_x_std == pytest.approx(o.d_y / camera.fx * 0.2 / dt / math.sqrt(3), rel=0.05)
    assert abs(o.registered_rate) < 0.02


def camera_frames(seed: int, s: float, shift, blur_px: float = 0.5, k: int = 4):
    """Two 640 x 360 frames of a sharp texture as a camera takes them: drawn at ``k`` times the resolution,
    scaled by ``s`` about CENTRE and shifted there, then averaged over each pixel (INTER_AREA)."""
    rng = np.random.default_rng(seed)
    hi = cv2.resize(rng.normal(0.0, 1.0, (360, 640)).astype(np.float32), (640 * k, 360 * k),
                    interpolation=cv2.INTER_NEAREST)
    hi = 127.0 + 60.0 * cv2.GaussianBlur(hi, (0, 0), blur_px * k)
    cx, cy = ((c + 0.5) * k - 0.5 for c in CENTRE)

    def shoot(sc, sh):
        m = np.array([[sc, 0.0, (1 - sc) * cx + sh[0] * k], [0.0, sc, (1 - sc) * cy + sh[1] * k]])
        return cv2.resize(cv2.warpAffine(hi, m, (640 * k, 360 * k), flags=cv2.INTER_LINEAR,
                                         borderMode=cv2.BORDER_REFLECT), (640, 360), interpolation=cv2.INTER_AREA)
    return shoot(1.0, (0.0, 0.0)), shoot(s, shift)


def test_bicubic_sampling_reads_a_small_scale_of_sharp_edges_better_than_bilinear():
    # bilinear sampling blurs by an amount that varies with each point's sub-pixel phase, which a small scale
    # changes across the patch: on a texture sharp at the pixel scale its fitted scale change scatters
    # several times as widely (and is pulled towards 1)
    box = (290.0, 170.0, 350.0, 215.0)
    errors = {"linear": [], "cubic": []}
    for seed in range(16):
        rng = np.random.default_rng(100 + seed)
        s, shift = 1.0 + rng.uniform(0.01, 0.02), tuple(rng.uniform(-1.0, 1.0, 2))
        prev, cur = camera_frames(seed, s, shift)
        for interp, errs in errors.items():
            r = register_scale(prev, gradient_stack(cur), box, box_scaled(box, s, shift), interpolation=interp)
            assert r.ok
            errs.append((r.scale - s) / (s - 1.0))
    rms = {k: float(np.sqrt(np.mean(np.square(v)))) for k, v in errors.items()}
    assert rms["cubic"] < 0.1                       # the scale change to within 10 %
    assert rms["cubic"] < 0.3 * rms["linear"]


@pytest.mark.parametrize("kw", [{"interpolation": "nearest"}, {"top": 1.0}, {"top": -0.1}])
def test_bad_registration_settings_are_refused(kw):
    with pytest.raises(ValueError):
        LoomingRegistration(**kw)
    with pytest.raises(ValueError):
        StateEstimator(CameraModel.from_fov(640, 360, 60.0, 1.3), **{f"registration_{k}": v for k, v in kw.items()})


@pytest.mark.parametrize("shape", [(360, 640), (2, 2)])
def test_boxes_off_the_image_are_not_registered_and_do_not_fail(shape):
    """Boxes wholly outside the frame (a coasting track that left it, or a frame smaller than the boxes' camera)
    leave no region to register: no scale, and no error from the gradient filter on an empty region."""
    reg = LoomingRegistration()
    img = texture(shape=shape)
    off = np.array([(700.0, 160.0, 760.0, 220.0), (660.0, 200.0, 700.0, 240.0)])     # right of a 640-px frame
    reg.update(img, [1, 2], off, np.array([True, True]))
    s, sd, centre, shift = reg.update(img, [1, 2], off + 1.0, np.array([True, True]))
    assert np.isnan(s).all() and np.isnan(sd).all() and np.isnan(centre).all() and np.isnan(shift).all()
