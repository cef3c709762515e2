"""Risk estimator (equation 5) on analytic TTC cases and against a brute-force forward simulation."""

from __future__ import annotations

import numpy as np
import pytest

from monorarp.core.camera import CameraModel
from monorarp.pipeline.registry import create
from monorarp.risk.estimators import ManoeuvreTTCRisk, TTCRiskEstimator, significant_velocity
from monorarp.core.types import ObjectState, RiskEstimate


def simulate_ttc(s: ObjectState, W=1.8, L=4.5, ego_w=1.8, ego_l=4.5, fwd=0.0, lat=0.0, horizon=10.0, dt=1e-4):
    """Step both rectangles forward (the paper's procedure) until they overlap; None if never."""
    t = np.arange(0.0, horizon + dt, dt)
    x_lo, x_hi = s.d_x - W / 2 + s.v_x * t, s.d_x + W / 2 + s.v_x * t
    y_lo, y_hi = s.d_y + s.v_y * t, s.d_y + L + s.v_y * t
    ex, ey = (-lat - ego_w / 2, -lat + ego_w / 2), (-fwd - ego_l / 2, -fwd + ego_l / 2)
    hit = (x_lo < ex[1]) & (x_hi > ex[0]) & (y_lo < ey[1]) & (y_hi > ey[0])
    return float(t[np.argmax(hit)]) if hit.any() else None


def test_closing_straight_ahead_is_gap_over_speed():
    r = TTCRiskEstimator()
    est = r.assess({3: ObjectState(3, 0.0, 20.0, 0.0, -5.0)}, 0.0)
    gap = 20.0 - 4.5 / 2                      # rear face to the ego's front (camera at the ego centre)
    assert est.ttc[3] == pytest.approx(gap / 5.0)
    assert est.risk == pytest.approx(5.0 / gap)


def test_significant_velocity_ttc_is_the_closed_form_of_what_its_sigmas_leave():
    gap = 20.0 - 4.5 / 2
    r = TTCRiskEstimator(velocity_sigmas=2.0)
    old = dict(d_y_std=0.5, v_y_std=3.0, age_s=2.0)   # distance floor sqrt(2) 0.5 / 2 = 0.35 m/s < 3 m/s
    assert r.ttc({1: ObjectState(1, 0.0, 20.0, 0.0, -5.0, **old)})[1] is None            # 5 m/s within 2 sigmas
    assert r.ttc({1: ObjectState(1, 0.0, 20.0, 0.0, -10.0, **old)})[1] == pytest.approx(gap / 4.0)   # 10 - 6
    assert TTCRiskEstimator().ttc({1: ObjectState(1, 0.0, 20.0, 0.0, -5.0, **old)})[1] == pytest.approx(gap / 5.0)
    # the distance's sigma over the age floors the velocity's: a young track's 10 m/s is no motion
    young = ObjectState(1, 0.0, 20.0, 0.0, -10.0, d_y_std=1.0, v_y_std=1.0, age_s=0.1)   # floor 14.1 m/s
    assert significant_velocity(young, 2.0)[1] == 0.0 and r.ttc({1: young})[1] is None
    aged = ObjectState(1, 0.0, 20.0, 0.0, -10.0, d_y_std=1.0, v_y_std=1.0, age_s=2.0)    # floor 0.71 m/s
    assert r.ttc({1: aged})[1] == pytest.approx(gap / 8.0)
    # lateral: sign kept, shrunk by its own sigma; no sigma: as is; age 0: none on an axis with a distance sigma
    assert significant_velocity(ObjectState(1, 0.0, 20.0, -3.0, -10.0, v_x_std=1.0), 2.0) == (-1.0, -10.0)
    assert significant_velocity(ObjectState(1, 0.0, 20.0, 2.0, -10.0, d_y_std=1.0, v_y_std=1.0, age_s=0.0),
                                2.0) == (2.0, 0.0)


@pytest.mark.parametrize("k", [-1.0, float("nan"), float("inf")])
def test_velocity_sigmas_must_be_a_non_negative_number(k):
    with pytest.raises(ValueError, match="velocity_sigmas"):
        TTCRiskEstimator(velocity_sigmas=k)


def test_camera_offset_moves_the_ego_front():
    cam = CameraModel.from_fov(640, 360, 60, 1.3, forward_offset_m=1.5)
    est = TTCRiskEstimator(camera=cam).assess({1: ObjectState(1, 0.0, 20.0, 0.0, -5.0)})
    assert est.ttc[1] == pytest.approx((20.0 - (4.5 / 2 - 1.5)) / 5.0)


def test_diverging_gives_zero_risk():
    est = TTCRiskEstimator().assess({1: ObjectState(1, 0.0, 10.0, 0.0, 3.0)}, 0.0)
    assert est.ttc == {1: None} and est.risk == 0.0


def test_adjacent_lane_no_collision():
    est = TTCRiskEstimator().assess({1: ObjectState(1, 3.7, 15.0, 0.0, -8.0)}, 0.0)
    assert est.ttc[1] is None and est.risk == 0.0


def test_beyond_horizon_is_no_collision():
    est = TTCRiskEstimator().assess({1: ObjectState(1, 0.0, 80.0, 0.0, -5.0)}, 0.0)   # 15.55 s away
    assert est.risk == 0.0


def test_lateral_drift_in():
    s = ObjectState(1, 3.7, 10.0, -1.0, -5.0)
    est = TTCRiskEstimator().assess({1: s})
    # x windows: enters when 3.7 - 0.9 - t = 0.9 -> 1.9 s; y window [1.55, 3.35] s -> TTC 1.9 s
    assert est.ttc[1] == pytest.approx(1.9)
    assert est.ttc[1] == pytest.approx(simulate_ttc(s), abs=2e-4)


@pytest.mark.parametrize("seed", range(5))
def test_random_states_match_forward_simulation(seed):
    rng = np.random.default_rng(seed)
    states = {i: ObjectState(i, rng.uniform(-8, 8), rng.uniform(3, 60), rng.uniform(-2, 2), rng.uniform(-15, 5))
              for i in range(20)}
    est = TTCRiskEstimator().assess(states)
    for i, s in states.items():
        ref = simulate_ttc(s)
        if ref is None:
            assert est.ttc[i] is None
        else:
            assert est.ttc[i] == pytest.approx(ref, abs=2e-4)
    finite = [v for v in est.ttc.values() if v is not None]
    assert est.risk == pytest.approx(max((1 / max(v, 0.1) for v in finite), default=0.0))


def test_max_over_objects_and_floor():
    r = create("risk", "ttc", min_ttc_s=0.1)
    states = {1: ObjectState(1, 0.0, 30.0, 0.0, -5.0), 2: ObjectState(2, 0.0, 1.0, 0.0, -1.0)}  # 2 overlaps now
    est = r.assess(states, 0.0)
    assert est.ttc[2] == 0.0 and est.risk == pytest.approx(10.0)
    assert r.assess({}, 0.0).risk == 0.0


def simulate_manoeuvre_ttc(s: ObjectState, brake: float, lateral: float, W=1.8, L=4.5, horizon=10.0, dt=1e-4):
    """Forward simulation of the two hypotheses, the sooner contact: the other brakes at ``brake`` in its
    lane (once its rear has reached the ego's front it stays in contact, a stopped wreck), or it moves
    towards the ego's centre line at ``lateral`` at constant closing speed."""
    t = np.arange(0.0, horizon + dt, dt)
    ex, ey = (-0.9, 0.9), (-2.25, 2.25)
    y = s.d_y + s.v_y * t - brake * t * t / 2
    y_touch = np.maximum.accumulate(y < ey[1]) if s.d_y >= ey[1] else (y < ey[1]) & (y + L > ey[0])
    hit_brake = (s.d_x - W / 2 < ex[1]) & (s.d_x + W / 2 > ex[0]) & y_touch
    x = s.d_x - np.sign(s.d_x) * lateral * t
    y = s.d_y + s.v_y * t
    hit_turn = (x - W / 2 < ex[1]) & (x + W / 2 > ex[0]) & (y < ey[1]) & (y + L > ey[0])
    times = [float(t[np.argmax(h)]) for h in (hit_brake, hit_turn) if h.any()]
    return min(times) if times else None


def test_manoeuvre_ttc_of_a_lead_at_the_ego_speed_is_the_braking_distance_time():
    gap = 15.0 - 4.5 / 2
    est = ManoeuvreTTCRisk(brake_mps2=4.0).assess({1: ObjectState(1, 0.0, 15.0, 0.0, 0.0)})
    assert est.ttc[1] == pytest.approx(np.sqrt(2 * gap / 4.0))       # gap = b t^2 / 2
    assert TTCRiskEstimator().assess({1: ObjectState(1, 0.0, 15.0, 0.0, 0.0)}).risk == 0.0


def test_manoeuvre_ttc_of_a_next_lane_car_is_its_drift_time():
    # lane +1 (3.5 m), 5 m ahead and closing at 1 m/s: at 0.5 m/s it reaches the ego's side (0.9 m)
    # after (3.5 - 0.9 - 0.9) / 0.5 = 3.4 s, its rear level with the ego's front from 2.75 s to 11.75 s;
    # braking in its lane it never meets the ego
    s = ObjectState(1, 3.5, 5.0, 0.0, -1.0)
    est = ManoeuvreTTCRisk(brake_mps2=4.0, lateral_mps=0.5).assess({1: s})
    assert est.ttc[1] == pytest.approx(3.4)
    assert ManoeuvreTTCRisk(lateral_mps=0.0).assess({1: s}).ttc[1] is None
    # a lead braking and turning is not both at once: each manoeuvre alone, the sooner counts
    lead = ObjectState(2, 0.5, 15.0, 0.0, 0.0)
    assert ManoeuvreTTCRisk(brake_mps2=4.0, lateral_mps=1.0).assess({2: lead}).ttc[2] == pytest.approx(
        np.sqrt(2 * (15.0 - 2.25) / 4.0))


def test_manoeuvre_ttc_without_a_manoeuvre_is_the_constant_velocity_ttc():
    rng = np.random.default_rng(7)
    states = {i: ObjectState(i, rng.uniform(-1, 1), rng.uniform(3, 60), 0.0, rng.uniform(-15, 5)) for i in range(30)}
    assert ManoeuvreTTCRisk(brake_mps2=0.0, lateral_mps=0.0).assess(states).ttc == TTCRiskEstimator().assess(states).ttc


@pytest.mark.parametrize("seed", range(4))
def test_manoeuvre_ttc_matches_forward_simulation(seed):
    rng = np.random.default_rng(seed)
    brake, lateral = rng.uniform(1, 8), rng.uniform(0.2, 1.5)
    states = {i: ObjectState(i, rng.uniform(-8, 8), rng.uniform(3, 60), rng.uniform(-2, 2), rng.uniform(-15, 5))
              for i in range(20)}
    est = ManoeuvreTTCRisk(brake_mps2=brake, lateral_mps=lateral).assess(states)
    for i, s in states.items():
        ref = simulate_manoeuvre_ttc(s, brake, lateral)
        if ref is None:
            assert est.ttc[i] is None
        else:
            assert est.ttc[i] == pytest.approx(ref, abs=5e-4)


def test_manoeuvre_risk_holds_its_peak_for_hold_s():
    # a lead 15 m ahead at the ego speed scores 1 / sqrt(2 gap / b); it drops out for 3 frames at 10 fps,
    # then a car far away: the peak stays for 0.6 s (frames 0.1-0.7 s), then the far car's own score
    lead = {1: ObjectState(1, 0.0, 15.0, 0.0, 0.0)}
    far = {2: ObjectState(2, 0.0, 60.0, 0.0, 0.0)}
    peak = 1 / np.sqrt(2 * (15.0 - 2.25) / 4.0)
    low = 1 / np.sqrt(2 * (60.0 - 2.25) / 4.0)
    stage = ManoeuvreTTCRisk(hold_s=0.6)
    seq = [lead, {}, {}, {}, far, far, far, far, far]
    risks = [stage.assess(s, 0.1 * k).risk for k, s in enumerate(seq)]
    np.testing.assert_allclose(risks, [peak] * 7 + [low] * 2)
    assert stage.assess(far, 0.9).ttc == {2: pytest.approx(1 / low)}    # per-object TTC: the frame's own
    stage.reset()
    assert stage.assess({}, 1.0).risk == 0.0
    # a time earlier than the last starts afresh; no time or hold 0: no hold
    stage.assess(lead, 5.0)
    assert stage.assess({}, 0.0).risk == 0.0
    stage.assess(lead, 1.0)
    assert stage.assess({}, None).risk == 0.0
    off = ManoeuvreTTCRisk(hold_s=0.0)
    off.assess(lead, 0.0)
    assert off.assess({}, 0.1).risk == 0.0


def test_manoeuvre_risk_mixes_the_looming_closing_speed_with_the_filters():
    # the filter reads 4 m/s of closing, the box grows at 0.3 /s at 20 m: 6 m/s; half and half: 5 m/s
    s = ObjectState(1, 0.0, 20.0, 0.0, -4.0, expansion_rate=0.3)
    cv = TTCRiskEstimator()
    for w, v_y in ((0.0, -4.0), (0.5, -5.0), (1.0, -6.0)):
        stage = ManoeuvreTTCRisk(brake_mps2=0.0, lateral_mps=0.0, looming_weight=w)
        assert stage.closing_velocity(s) == pytest.approx(v_y)
        assert stage.assess({1: s}).ttc[1] == pytest.approx(cv.assess({1: ObjectState(1, 0.0, 20.0, 0.0, v_y)}).ttc[1])
    no_rate = ObjectState(1, 0.0, 20.0, 0.0, -4.0)                  # no looming reading: the filter's alone
    assert ManoeuvreTTCRisk(looming_weight=1.0).closing_velocity(no_rate) == -4.0


def test_manoeuvre_risk_uses_the_looming_rate_only_where_its_sigma_is_within_the_bound():
    # a rate the filter only predicts (its sigma grown past 0.5 /s) reads as 30 m/s of closing at 20 m
    def state(rate_std):
        return ObjectState(1, 0.0, 20.0, 0.0, -4.0, expansion_rate=1.5, expansion_rate_std=rate_std)
    stage = ManoeuvreTTCRisk()                                                  # weight 0.5, bound 0.5 /s
    assert stage.closing_velocity(state(0.6)) == -4.0                           # the filter's alone
    assert stage.closing_velocity(state(float("nan"))) == -4.0
    assert stage.closing_velocity(state(0.5)) == pytest.approx(0.5 * -4.0 - 0.5 * 1.5 * 20.0)
    assert stage.closing_velocity(state(None)) == pytest.approx(-17.0)         # no sigma: trusted
    assert ManoeuvreTTCRisk(looming_max_std=None).closing_velocity(state(5.0)) == pytest.approx(-17.0)
    assert stage.assess({1: state(0.6)}).ttc[1] > stage.assess({1: state(0.4)}).ttc[1]


def test_manoeuvre_risk_mixes_in_the_registered_patchs_closing_speed():
    # filter 4 m/s, box growth 0.3 /s at 20 m (6 m/s): 5 m/s; the patch 0.4 /s (8 m/s), weight 0.5: 6.5 m/s
    def state(reg_std, expansion=0.3):
        return ObjectState(1, 0.0, 20.0, 0.0, -4.0, expansion_rate=expansion, registered_rate=0.4,
                           registered_rate_std=reg_std)
    stage = ManoeuvreTTCRisk(brake_mps2=0.0, lateral_mps=0.0)                 # weight 0.5, bound 0.05 /s
    assert stage.closing_velocity(state(0.01)) == pytest.approx(-6.5)
    assert stage.closing_velocity(state(0.01, expansion=None)) == pytest.approx(-6.0)   # filter and patch
    assert stage.closing_velocity(state(0.06)) == pytest.approx(-5.0)          # over the bound: the box mix alone
    assert stage.closing_velocity(state(float("nan"))) == pytest.approx(-5.0)
    assert stage.closing_velocity(state(None)) == pytest.approx(-6.5)          # no sigma: trusted
    assert ManoeuvreTTCRisk(registered_max_std=None).closing_velocity(state(1.0)) == pytest.approx(-6.5)
    assert ManoeuvreTTCRisk(registered_weight=0.0).closing_velocity(state(0.01)) == pytest.approx(-5.0)
    assert ManoeuvreTTCRisk(registered_weight=1.0).closing_velocity(state(0.01)) == pytest.approx(-8.0)
    cv = TTCRiskEstimator().assess({1: ObjectState(1, 0.0, 20.0, 0.0, -6.5)}).ttc[1]
    assert stage.assess({1: state(0.01)}).ttc[1] == pytest.approx(cv)


@pytest.mark.parametrize("kw", [{"brake_mps2": -1.0}, {"lateral_mps": float("nan")}, {"hold_s": -0.1},
                                {"looming_weight": 1.5}, {"looming_weight": float("nan")},
                                {"looming_max_std": 0.0}, {"looming_max_std": float("nan")},
                                {"registered_weight": -0.1}, {"registered_weight": float("nan")},
                                {"registered_max_std": 0.0}, {"registered_max_std": float("nan")}])
def test_manoeuvre_ttc_rejects_bad_settings(kw):
    with pytest.raises(ValueError, match=next(iter(kw))):
        create("risk", "manoeuvre_ttc", **kw)


def test_a_run_with_the_manoeuvre_risk_is_also_scored_with_the_papers_1_over_ttc():
    from types import SimpleNamespace

    from harness.run.scoring import baseline_ttc_risk, manoeuvre_ttc_risk
    from monorarp.core.types import FrameResult

    cam = CameraModel.from_fov(640, 360, 60, 1.3)
    states = {1: ObjectState(1, 0.0, 20.0, 0.0, -5.0), 2: ObjectState(2, 3.5, 8.0, 0.0, -1.0)}
    results = [FrameResult(index=0, t=0.0, detections=[], tracks=[], states=states, risk=RiskEstimate(0.0))]
    own = baseline_ttc_risk(results, cam, SimpleNamespace(risk=TTCRiskEstimator(camera=cam)))
    assert own is None                                   # the run's risk is the paper's already
    other = baseline_ttc_risk(results, cam, SimpleNamespace(risk=ManoeuvreTTCRisk(camera=cam)))
    assert other[0].risk == pytest.approx(TTCRiskEstimator(camera=cam).assess(states).risk)
    assert manoeuvre_ttc_risk(results, cam)[0] == pytest.approx(ManoeuvreTTCRisk(camera=cam).assess(states).risk)
    assert manoeuvre_ttc_risk(results, cam)[0] > other[0].risk > 0   # the hypothesis only brings contact nearer
