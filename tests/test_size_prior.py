"""The state estimator's size prior (monorarp/state/size_prior.py): the height distance against its closed form,
the fusion against the inverse-variance formula, the per-frame ground fit on a pitched ground, off by default,
a kind without a prior on the ground plane, and the real-frame defaults of the commands."""

from __future__ import annotations

import numpy as np
import pytest

from harness.kitti_eval.options import KittiEvalOptions
from monorarp.app.options import REAL_FRAMES, default_pipeline_config
from monorarp.core.camera import CameraModel
from monorarp.core.types import Track
from monorarp.state.config import REAL_FRAMES_STATE, StateConfig, StateConfigError
from monorarp.state.estimator import StateEstimator
from monorarp.state.size_prior import SIZE_PRIORS, fuse, ground_fit, height_distance, width_distance

CAM = CameraModel(width=1242, height=375, fx=721.5, fy=721.5, cx=609.6, cy=172.9, height_m=1.65)


def _car_box(cam: CameraModel, d: float, x: float = 0.0, height: float = 1.5, width: float = 1.75,
             ground: float | None = None, pitch: float = 0.0) -> tuple[float, float, float, float]:
    """The rear face of a car ``d`` m ahead, ``x`` m right, on a ground ``ground`` m below the camera and
    tilted by ``pitch`` (rad) against it: (x1, y1, x2, y2) px, pinhole, rear face only."""
    g = cam.height_m if ground is None else ground
    bottom = cam.cy + cam.fy * (g / d + pitch)
    top = bottom - cam.fy * height / d
    return (cam.cx + cam.fx * (x - width / 2) / d, top, cam.cx + cam.fx * (x + width / 2) / d, bottom)


def test_height_distance_is_the_closed_form() -> None:
    boxes = np.array([[600.0, 100.0, 660.0, 150.0], [10.0, 50.0, 30.0, 62.5]])
    d, std = height_distance(CAM, boxes, np.array([1.5, 3.2]), np.array([0.08, 0.6]), 1.0, 0.4)
    h = np.array([50.0, 12.5])
    z = CAM.fy * np.array([1.5, 3.2]) / h
    np.testing.assert_allclose(d, z - 0.4)
    np.testing.assert_allclose(std, z * np.hypot(np.array([0.08 / 1.5, 0.6 / 3.2]), np.sqrt(2) / h))


def test_width_distance_of_a_rear_face_and_a_side_view() -> None:
    d = 20.0
    straddling = np.array([_car_box(CAM, d)])
    z, _ = width_distance(CAM, straddling, np.array([1.75]), np.array([0.08]), np.array([4.3]), np.array([0.4]), 1.0)
    assert z[0] == pytest.approx(d)
    # right of the centre column: the near edge is the front-left corner, L further
    x, w, length = 4.0, 1.75, 4.3
    box = np.array([[CAM.cx + CAM.fx * (x - w / 2) / (d + length), 150.0, CAM.cx + CAM.fx * (x + w / 2) / d, 200.0]])
    z, _ = width_distance(CAM, box, np.array([w]), np.array([0.08]), np.array([length]), np.array([0.4]), 1.0)
    assert z[0] == pytest.approx(d)


def test_fusion_is_inverse_variance() -> None:
    a, sa = np.array([10.0, 20.0, np.nan]), np.array([1.0, 2.0, 1.0])
    b, sb = np.array([12.0, np.nan, 30.0]), np.array([2.0, 1.0, 3.0])
    m, s = fuse([a, b], [sa, sb])
    w1, w2 = 1 / 1.0 ** 2, 1 / 2.0 ** 2
    assert m[0] == pytest.approx((10 * w1 + 12 * w2) / (w1 + w2))
    assert s[0] == pytest.approx((w1 + w2) ** -0.5)
    assert (m[1], s[1]) == (20.0, 2.0)          # a NaN reading takes no part
    assert (m[2], s[2]) == (30.0, 3.0)
    m, s = fuse([np.array([np.nan])], [np.array([1.0])])
    assert np.isnan(m[0]) and np.isnan(s[0])


def test_ground_fit_without_other_vehicles_is_the_prior() -> None:
    theta, cov = ground_fit(np.array([0.1]), np.array([0.05]), np.array([0.01]), 1.65, 0.1, 0.01)
    np.testing.assert_allclose(theta[0], [1.65, 0.0])
    np.testing.assert_allclose(np.diag(cov[0]), [0.01, 1e-4])


def test_off_by_default_and_bit_for_bit() -> None:
    assert StateConfig().size_prior is False
    tracks = [Track(id=0, box=_car_box(CAM, 15.0)), Track(id=1, box=_car_box(CAM, 30.0, x=3.5))]
    plain = StateEstimator(CAM).update(tracks, 0.0)
    again = StateEstimator(CAM, size_prior=False).update(tracks, 0.0)
    assert plain == again
    assert plain[0].d_y == pytest.approx(StateEstimator(CAM).measure(np.array([tracks[0].box]))[0, 1])


def test_a_pitched_ground_reads_nearer_the_truth_with_the_prior() -> None:
    """Cars 10-40 m ahead on a ground 1.85 m below the camera, tilted 0.01 rad: the flat ground reads them
    too near by 10 % and more; the size prior's fusion is within 3 %."""
    ds = np.array([10.0, 18.0, 27.0, 40.0])
    tracks = [Track(id=k, box=_car_box(CAM, d, x=(-3.5, 0.0, 3.5, 0.0)[k], ground=1.85, pitch=0.01), label="car")
              for k, d in enumerate(ds)]
    flat = StateEstimator(CAM, contact_offset_m=0.0).update(tracks, 0.0)
    fused = StateEstimator(CAM, size_prior=True, contact_offset_m=0.0).update(tracks, 0.0)
    flat_err = np.array([flat[k].d_y / d - 1 for k, d in enumerate(ds)])
    fused_err = np.array([fused[k].d_y / d - 1 for k, d in enumerate(ds)])
    assert (flat_err < -0.10).all()
    assert np.abs(fused_err).max() < 0.03
    # the flat ground's one-sigma knows nothing of the tilt; the fusion's covers the truth
    assert all(abs(flat[k].d_y - d) > 2 * flat[k].d_y_std for k, d in enumerate(ds))
    assert all(abs(fused[k].d_y - d) < 2 * fused[k].d_y_std for k, d in enumerate(ds))


def test_a_kind_without_a_prior_keeps_the_ground_plane() -> None:
    assert "motorcycle" not in SIZE_PRIORS
    box = _car_box(CAM, 20.0, ground=1.85)
    ground = StateEstimator(CAM).update([Track(id=0, box=box, label="motorcycle")], 0.0)
    prior = StateEstimator(CAM, size_prior=True).update([Track(id=0, box=box, label="motorcycle")], 0.0)
    assert prior[0].d_y == ground[0].d_y and prior[0].d_y_std == ground[0].d_y_std
    car = StateEstimator(CAM, size_prior=True).update([Track(id=0, box=box, label="car")], 0.0)
    assert car[0].d_y != ground[0].d_y
    # beside cars on a tilted ground (whose fit moves their ground readings), still the flat ground plane's
    boxes = np.array([box, _car_box(CAM, 12.0, x=-3.5, ground=1.85, pitch=0.01),
                      _car_box(CAM, 35.0, x=3.5, ground=1.85, pitch=0.01)])
    est = StateEstimator(CAM, size_prior=True)
    d_y = est.measure(boxes)[:, 1]
    fused, std, parts = est.size_fused(["bicycle", "car", "car"], boxes, d_y, 0.0)
    assert fused[0] == d_y[0] and np.isnan(std[0])
    assert parts["ground"][0] != d_y[0] and np.isfinite(std[1:]).all()


def test_bad_priors_are_refused() -> None:
    with pytest.raises(StateConfigError, match="size_priors"):
        StateEstimator(CAM, size_priors={"car": (1.5, 0.08)})


def test_real_frame_defaults() -> None:
    assert "size_prior" not in default_pipeline_config().state.kwargs          # run, sweep, scorecard, bench
    real = default_pipeline_config(REAL_FRAMES).state.kwargs                   # video
    assert {k: real[k] for k in REAL_FRAMES_STATE} == REAL_FRAMES_STATE
    assert KittiEvalOptions().state_settings(rendered=False) == REAL_FRAMES_STATE
    assert KittiEvalOptions().state_settings(rendered=True) == {}
    assert KittiEvalOptions(state_kwargs={"size_prior": False}).state_settings(rendered=False) == {"size_prior": False}


def test_a_box_cut_by_a_side_border_takes_no_height() -> None:
    box = np.array([[-0.5, 150.0, 60.0, 210.0]])          # cut by the left border
    est = StateEstimator(CAM, size_prior=True)
    d_y = est.measure(box)[:, 1]
    _, _, parts = est.size_fused(["car"], box, d_y, 0.0)
    assert np.isnan(parts["height"][0])
    whole = np.array([[40.0, 150.0, 100.0, 210.0]])
    _, _, parts = est.size_fused(["car"], whole, est.measure(whole)[:, 1], 0.0)
    assert np.isfinite(parts["height"][0])
