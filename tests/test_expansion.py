"""The looming cue (monorarp.state.expansion): rate of change of the log box width against its closed form."""

import math

import numpy as np
import pytest

from monorarp.core.camera import CameraModel
from monorarp.state.expansion import ExpansionFilter
from monorarp.state.estimator import StateEstimator
from monorarp.core.types import Track

FPS = 15.0
F_PX = 457.0


def box_at(z: float, width_m: float = 1.8, bottom_shift: float = 0.0) -> tuple[float, float, float, float]:
    """A box of a vehicle ``width_m`` wide at depth ``z`` (m), centred at column 320: width f W / z."""
    w = F_PX * width_m / z
    h = F_PX * 1.5 / z
    return (320 - w / 2, 180 - h / 2, 320 + w / 2, 180 + h / 2 + bottom_shift)


def run(zs, ts, noise=0.0, seed=0, **kw):
    rng = np.random.default_rng(seed)
    f = ExpansionFilter(**kw)
    out = []
    for z, t in zip(zs, ts):
        b = np.array([box_at(z)]) + rng.normal(0.0, noise, 4) * [1, 0, 1, 0]
        out.append(f.update([1], b, np.array([True]), t))
    return out


def test_rate_converges_to_closing_speed_over_distance():
    # closing at 10 m/s from 40 m: d ln w / dt = v / z (the inverse of the constant-velocity TTC)
    ts = np.arange(30) / FPS
    zs = 40.0 - 10.0 * ts
    rate, std = run(zs, ts)[-1]
    # the rate grows (d/dt (v/z) = (v/z)^2) and a constant-rate filter lags it by a few per cent
    assert 0.9 * 10.0 / zs[-1] < rate[0] < 10.0 / zs[-1]
    assert 0 < std[0] < 0.15


def test_constant_speed_prediction_follows_a_steady_approach_without_lag():
    # closing at 20 m/s from 60 m to 12 m: the exact constant-closing-speed prediction has no lag,
    # the constant-rate one lags the rate's growth (rate^2) by more
    ts = np.arange(37) / FPS
    zs = 60.0 - 20.0 * ts
    truth = 20.0 / zs[-1]
    exact, _ = run(zs, ts, constant_speed=True, process_std=0.05)[-1]
    lagging, _ = run(zs, ts, process_std=0.05)[-1]
    assert exact[0] == pytest.approx(truth, rel=0.01)
    assert lagging[0] < 0.9 * truth


def test_distance_scales_the_process_noise():
    # accel_std / Z: at 80 m a 4 m/s^2 relative acceleration changes the rate by 0.05 /s^2, so a far
    # track's rate settles to a much smaller sigma than with a fixed 1 /s^2; with no distance, the fixed one
    ts = np.arange(45) / FPS
    def final_std(distance):
        f = ExpansionFilter(accel_std=4.0)
        for t in ts:
            _, std = f.update([1], np.array([box_at(80.0)]), np.array([True]), t,
                              distance=None if distance is None else np.array([distance]))
        return std[0]
    fixed = run(np.full(45, 80.0), ts)[-1][1][0]
    assert final_std(None) == pytest.approx(fixed)
    assert final_std(80.0) < 0.3 * fixed
    assert final_std(10.0) > final_std(80.0)


def test_noise_gives_a_rate_consistent_with_zero():
    ts = np.arange(45) / FPS
    rates = [run(np.full(45, 60.0), ts, noise=0.5, seed=s)[-1] for s in range(20)]
    z = np.array([r[0] / s[0] for r, s in rates])
    assert np.all(np.abs(z) < 3.5)          # |rate| / sigma: the stated uncertainty covers the noise
    assert np.std(z) < 2.0


def test_a_bottom_edge_step_is_no_expansion():
    # the box's bottom steps down by 2 px (equation 3 reads ~10 m closer at 60 m); its width does not change
    f = ExpansionFilter()
    for k in range(30):
        b = np.array([box_at(60.0, bottom_shift=2.0 if k >= 15 else 0.0)])
        rate, std = f.update([1], b, np.array([True]), k / FPS)
    assert abs(rate[0]) < 1e-9


def test_no_measurement_before_the_first_valid_box_and_restart():
    f = ExpansionFilter(init_rate_std=1.0)
    rate, std = f.update([1], np.array([box_at(30.0)]), np.array([False]), 0.0)
    assert math.isnan(rate[0]) and math.isnan(std[0])
    for k in range(10):
        f.update([1], np.array([box_at(30.0 - k)]), np.array([True]), k / FPS)
    rate, std = f.update([1], np.array([box_at(20.0)]), np.array([True]), 10 / FPS, restart=np.array([True]))
    assert rate[0] == 0.0 and std[0] == pytest.approx(1.0)


@pytest.mark.parametrize("kw", [{"pixel_std": 0}, {"process_std": -1}, {"forget_s": math.nan}, {"accel_std": 0}])
def test_bad_settings_are_refused(kw):
    with pytest.raises(ValueError):
        ExpansionFilter(**kw)


def test_state_estimator_outputs_the_rate_and_none_for_a_side_cut_box():
    cam = CameraModel.from_fov(640, 360, 70.0, 1.3, pitch_rad=0.0)
    est = StateEstimator(cam)
    for k in range(20):
        s = est.update([Track(1, box_at(40.0 - 0.5 * k)), Track(2, (600.0, 150.0, 639.5, 200.0))], k / FPS)
    assert s[1].expansion_rate == pytest.approx(7.5 / (40.0 - 0.5 * 19), rel=0.15)
    assert s[2].expansion_rate is None


def test_a_rate_only_predicted_until_it_is_no_better_than_the_prior_is_none():
    # a car closing at 5 m/s from 20 m, then seen only cut by the side border: the filter predicts its
    # rate at a constant closing speed, which grows without bound (to contact and beyond); the state
    # gives it while its sigma is within the prior (1 /s), then none
    cam = CameraModel.from_fov(640, 360, 70.0, 1.3, pitch_rad=0.0)
    est = StateEstimator(cam)
    outputs = []
    for k in range(60):
        box = box_at(20.0 - 5.0 * k / FPS) if k < 15 else (600.0, 150.0, 639.5, 200.0)
        s = est.update([Track(1, box)], k / FPS)
        outputs.append((s[1].expansion_rate, s[1].expansion_rate_std) if 1 in s else None)
    rate, std = outputs[14]
    assert rate == pytest.approx(5.0 / (20.0 - 5.0 * 14 / FPS), rel=0.25) and std < 0.2
    assert outputs[15][0] is not None                                   # predicted, still known
    internal_rate, internal_std = est._expansion.update([1], np.array([[600.0, 150.0, 639.5, 200.0]]),
                                                        np.array([False]), 60 / FPS)
    assert internal_rate[0] > 10.0 and internal_std[0] > 100.0          # what the filter alone gives at 4 s
    later = [o for o in outputs[15:] if o is not None]
    assert later and all(r is None or (sd <= 1.0 and r < 2.0) for r, sd in later)
    assert later[-1][0] is None
