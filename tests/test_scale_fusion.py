"""The registered scale fused into the range filter (StateConfig.fusion_sigmas): the measurement model
against constant-acceleration kinematics, the gate, and the velocity of a textured vehicle approaching
with a noisy box bottom edge against the truth."""

import numpy as np
import pytest

from monorarp.core.camera import CameraModel
from monorarp.state.estimator import StateEstimator
from monorarp.state.filters import fuse_scale
from monorarp.core.types import Track
from tests.test_scale_change import scaled, texture

DT = 1.0 / 15.0


GATE = 3.0        # fusion_sigmas


def one_track(d, v, a, P=None):
    """State arrays of one track: x (1, 2, 3) with the longitudinal axis (d, v, a), P (1, 2, 3, 3)."""
    x = np.zeros((1, 2, 3))
    x[0, 1] = d, v, a
    P = np.eye(3)[None, None].repeat(2, axis=1) if P is None else P
    return x, P


def test_the_exact_scale_of_the_true_state_changes_nothing():
    d, v, a = 20.0, -5.0, -3.0
    d_prev = d - v * DT + a * DT * DT / 2          # constant acceleration, integrated one frame back
    x, P = one_track(d, v, a)
    xu, Pu = fuse_scale(x, P, np.array([d_prev / d]), np.array([1e-3]), np.array([DT]), np.array([True]), GATE)
    np.testing.assert_allclose(xu, x, atol=1e-12)
    assert Pu[0, 1, 1, 1] < P[0, 1, 1, 1]          # but the velocity is known better


def test_a_wrong_velocity_moves_by_the_kalman_gain():
    d, v_true, v_wrong = 20.0, -5.0, -3.0
    s, s_std = (d - v_true * DT) / d, 2e-3
    x, P = one_track(d, v_wrong, 0.0)
    xu, _ = fuse_scale(x, P, np.array([s]), np.array([s_std]), np.array([DT]), np.array([True]), GATE)
    h = np.array([s - 1.0, DT, -DT * DT / 2])
    gain = P[0, 1] @ h / (h @ P[0, 1] @ h + (d * s_std) ** 2)
    np.testing.assert_allclose(xu[0, 1], x[0, 1] + gain * (0.0 - h @ x[0, 1]))
    assert abs(xu[0, 1, 1] - v_true) < abs(v_wrong - v_true)
    np.testing.assert_array_equal(xu[0, 0], x[0, 0])          # the lateral axis is untouched


def test_a_scale_beyond_the_gate_or_unusable_is_not_fused():
    x, P = one_track(20.0, 0.0, 0.0, np.eye(3)[None, None].repeat(2, axis=1) * 0.01)
    far_off = np.array([1.2])                         # 20 % growth in a frame: 60 m/s at 20 m
    for scale, usable in ((far_off, True), (np.array([1.01]), False), (np.array([np.nan]), True)):
        xu, Pu = fuse_scale(x, P, scale, np.array([1e-3]), np.array([DT]), np.array([usable]), GATE)
        np.testing.assert_array_equal(xu, x)
        np.testing.assert_array_equal(Pu, P)


@pytest.mark.parametrize("kw", [{"fusion_sigmas": 0.0}, {"fusion_sigmas": float("nan")}, {"fusion_pixel_std": -1.0},
                                {"longitudinal_process_std": 0.0}])
def test_bad_fusion_settings_are_refused(kw):
    with pytest.raises(ValueError, match=next(iter(kw))):
        StateEstimator(CameraModel.from_fov(640, 360, 60.0, 1.3), **kw)


def approach_errors(fusion_sigmas, seed=0, frames=30, d0=25.0, v=-6.0, bottom_std_px=1.0):
    """Closing-speed errors (m/s) of frames 10 on for a textured vehicle approaching at ``v`` (m/s), its box
    bottom edge noisy; the texture is scaled by the true distance ratio (the rear face's image)."""
    camera = CameraModel.from_fov(640, 360, 60.0, 1.3)
    est = StateEstimator(camera, fusion_sigmas=fusion_sigmas)
    rng = np.random.default_rng(seed)
    base = texture(seed)
    errors = []
    for k in range(frames):
        d = d0 + v * k * DT
        s = d0 / d
        row = camera.cy + camera.height_m * camera.fy / (d + est.config.contact_offset_m) + rng.normal(0.0, bottom_std_px)
        half = camera.fx * 1.8 / d / 2
        top = camera.cy - s * 40.0
        img = scaled(base, s, centre=(320.0, camera.cy))
        box = (320.0 - half, top, 320.0 + half, row)
        st = est.update([Track(id=1, box=box)], k * DT, image=np.dstack([img] * 3).clip(0, 255).astype(np.uint8))
        if k >= 10:
            errors.append(st[1].v_y - v)
    return np.array(errors)


def test_the_fused_closing_speed_is_nearer_the_truth_than_the_ranges_alone():
    for seed in range(3):
        fused, ranged = approach_errors(3.0, seed), approach_errors(None, seed)
        assert np.sqrt(np.mean(fused ** 2)) < 0.6 * np.sqrt(np.mean(ranged ** 2))
        assert np.sqrt(np.mean(fused ** 2)) < 0.5      # m/s


def test_the_longitudinal_process_noise_leaves_the_lateral_axis_alone():
    camera = CameraModel.from_fov(640, 360, 60.0, 1.3)
    a, b = StateEstimator(camera), StateEstimator(camera, longitudinal_process_std=20.0)
    rng = np.random.default_rng(1)
    for k in range(12):
        box = (300.0 + 2 * k + rng.normal(), 170.0, 360.0 + 2 * k + rng.normal(), 215.0 + 0.5 * k + rng.normal())
        sa, sb = a.update([Track(id=1, box=box)], k * DT)[1], b.update([Track(id=1, box=box)], k * DT)[1]
    assert (sa.d_x, sa.v_x, sa.v_x_std) == (sb.d_x, sb.v_x, sb.v_x_std)
    assert sa.v_y_std < sb.v_y_std
