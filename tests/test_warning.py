"""The forward-collision warning stage (monorarp.warning.fcw): in-path test, TTC, episodes."""

import math

import pytest

from monorarp.core.types import ObjectState
from monorarp.warning.fcw import ForwardCollisionWarning, significant_lateral_velocity


def fcw(**kw):
    kw.setdefault("camera_forward_offset_m", 0.5)
    return ForwardCollisionWarning(**kw)


def test_stopped_lead_ttc_is_the_closed_form():
    # Rear face 30 m ahead of the camera, closing at 20 m/s; the ego's front is 4.5/2 - 0.5 = 1.75 m ahead.
    w = fcw(ttc_threshold_s=3.0)
    threats = w.threats({7: ObjectState(7, 0.3, 30.0, 0.0, -20.0, v_x_std=0.1)})
    assert threats[7] == pytest.approx((30.0 - 1.75) / 20.0)
    assert fcw(ttc_threshold_s=1.0).threats({7: ObjectState(7, 0.3, 30.0, 0.0, -20.0)}) == {}


def test_lateral_velocity_counts_only_beyond_its_uncertainty():
    assert significant_lateral_velocity([-3.0, 3.0, 0.5], [1.0, 0.2, 1.0], 2.0).tolist() == pytest.approx([-1.0, 2.6, 0.0])
    # Next lane (3.7 m right), 8 m ahead, drifting left at 3 m/s and slower by 4 m/s.
    drifting = ObjectState(1, 3.7, 8.0, -3.0, -4.0, v_x_std=2.0)       # poorly observed: not in path
    sure = ObjectState(1, 3.7, 8.0, -3.0, -4.0, v_x_std=0.1)           # a real cut-in: in path
    assert fcw().threats({1: drifting}) == {}
    ttc = fcw().threats({1: sure})[1]
    assert 0 < ttc < 2.7
    # No uncertainty given: lateral_velocity_std_mps stands in for it.
    assert fcw(lateral_velocity_std_mps=2.0).threats({1: ObjectState(1, 3.7, 8.0, -3.0, -4.0)}) == {}


def test_episode_needs_min_on_then_holds():
    w = fcw(min_on_s=0.1, hold_s=0.5)
    threat = {3: ObjectState(3, 0.0, 10.0, 0.0, -10.0, v_x_std=0.1)}
    dt = 1 / 15
    seq = [threat, {}, threat, threat, threat, {}, {}, {}, threat, {}] + [{}] * 10 + [threat] * 3
    out = [w.update(s, None, k * dt) for k, s in enumerate(seq)]
    active = [o.active for o in out]
    # a one-frame blip raises nothing; the alert comes on when the threat has lasted 0.1 s (3rd frame of it)
    assert active[:4] == [False, False, False, False] and active[4]
    # a gap shorter than hold_s keeps the same episode; then it ends, and a new one starts later
    assert all(active[4:12]) and out[8].episode == 0
    assert not active[16]
    assert out[-1].active and out[-1].episode == 1 and out[-1].track_id == 3
    assert out[4].onset_t == pytest.approx(4 * dt)


def test_warned_object_is_the_lowest_ttc():
    w = fcw(min_on_s=0.0)
    s = {1: ObjectState(1, 0.0, 40.0, 0.0, -20.0, v_x_std=0.1), 2: ObjectState(2, 0.2, 20.0, 0.0, -15.0, v_x_std=0.1)}
    out = w.update(s, None, 0.0)
    assert out.active and out.track_id == 2 and out.threat_ids == (2, 1)
    assert out.ttc == pytest.approx((20.0 - 1.75) / 15.0)


@pytest.mark.parametrize("kw", [{"ttc_threshold_s": 0}, {"ttc_threshold_s": math.nan}, {"hold_s": -1},
                                {"lateral_sigmas": -0.5}, {"min_lateral_age_s": -1.0}, {"young_far_age_s": -0.1},
                                {"young_far_distance_m": float("nan")},
                                {"max_raw_lateral_speed_mps": 0.0}, {"max_raw_lateral_speed_mps": math.inf}])
def test_bad_settings_are_refused(kw):
    with pytest.raises(ValueError):
        fcw(**kw)


def test_registered_and_in_the_default_pipeline():
    from monorarp.pipeline import registry
    from monorarp.pipeline.config import PipelineConfig

    assert "fcw" in registry.available("warning")
    assert PipelineConfig(detector={"name": "centernet"}).warning.name == "fcw"


def _simulated_closing_time(gap: float, v: float, a: float, dt: float = 1e-4, horizon: float = 20.0) -> float:
    """Independent reference: integrate the gap forward in small steps."""
    t = 0.0
    while t < horizon:
        if gap <= 0:
            return t
        gap += v * dt + 0.5 * a * dt * dt
        v += a * dt
        t += dt
    return math.inf


@pytest.mark.parametrize("gap,v,a", [(20.0, -10.0, 0.0), (15.0, 0.0, -5.0), (30.0, -5.0, -2.94),
                                     (20.0, -10.0, 3.0), (20.0, -4.0, 3.0), (10.0, 2.0, -1.0), (10.0, 2.0, 0.0)])
def test_closing_time_matches_integrated_kinematics(gap, v, a):
    from monorarp.risk.ttc import closing_time

    got = float(closing_time(gap, v, a))
    want = _simulated_closing_time(gap, v, a)
    if math.isinf(want):
        assert math.isinf(got)
    else:
        assert got == pytest.approx(want, abs=2e-3)


def test_acceleration_brings_a_braking_lead_sooner_only_when_significant():
    # Lead 15 m ahead (rear face; camera at the ego's front), same speed, braking relative 5 m/s^2.
    braking = ObjectState(1, 0.0, 15.0, 0.0, 0.0, v_x_std=0.1, v_y_std=0.1, a_y=-5.0, a_y_std=0.5)
    ttc = fcw(accel_sigmas=2.0).threats({1: braking})[1]
    from monorarp.risk.ttc import closing_time
    assert ttc == pytest.approx(float(closing_time(15.0 - 1.75, 0.0, -5.0 + 2 * 0.5)))   # a shrunk by 2 sigma
    assert fcw(accel_sigmas=None).threats({1: braking}) == {}                              # constant velocity: never
    noisy = ObjectState(1, 0.0, 15.0, 0.0, 0.0, v_x_std=0.1, v_y_std=0.1, a_y=-5.0, a_y_std=3.0)
    assert fcw(accel_sigmas=2.0).threats({1: noisy}) == {}                                 # within its noise


def test_implausible_motion_raises_no_threat():
    # Two lanes over, read as cutting across at 8 m/s: an artefact, not a vehicle (not clipped into a threat).
    jumpy = ObjectState(1, 7.5, 10.0, -8.0, -10.0, v_x_std=0.1, v_y_std=0.1)
    assert fcw().threats({1: jumpy}) == {}
    assert fcw(max_lateral_speed_mps=20.0, max_raw_lateral_speed_mps=None).threats({1: jumpy})  # allowed: in path
    # A far track closing at 60 m/s (216 km/h): a mis-scaled box, not a car.
    far = ObjectState(2, 0.0, 100.0, 0.0, -60.0, v_x_std=0.1, v_y_std=0.1)
    assert fcw().threats({2: far}) == {}
    assert fcw(max_closing_speed_mps=80.0).threats({2: far})


def test_raw_lateral_speed_limit_applies_before_the_sigma_shrinkage():
    # Two lanes over, read at 8 m/s across with a wide sigma (a box cut by the side border):
    # shrunk by 3 sigma it is a plausible 2 m/s and reaches the corridor; the raw limit refuses it.
    cut = ObjectState(1, 7.5, 10.0, -8.0, -10.0, v_x_std=2.0, v_y_std=0.1)
    assert fcw(lateral_sigmas=3.0, max_raw_lateral_speed_mps=None).threats({1: cut})
    assert fcw(lateral_sigmas=3.0).threats({1: cut}) == {}              # the default limit: 6 m/s
    # A real cut-in at 2.5 m/s is under the limit: still a threat.
    cut_in = ObjectState(2, 3.7, 8.0, -2.5, -4.0, v_x_std=0.1, v_y_std=0.1)
    assert fcw().threats({2: cut_in})


def test_lateral_velocity_of_a_young_filter_is_not_trusted_when_asked():
    # next lane, 8 m ahead, a sure lateral velocity towards the ego: a threat at any age by default
    young = ObjectState(1, 3.7, 8.0, -3.0, -4.0, v_x_std=0.1, age_s=0.3)
    old = ObjectState(1, 3.7, 8.0, -3.0, -4.0, v_x_std=0.1, age_s=1.2)
    assert 1 in fcw().threats({1: young})
    assert fcw(min_lateral_age_s=1.0).threats({1: young}) == {}
    assert 1 in fcw(min_lateral_age_s=1.0).threats({1: old})
    # an in-lane lead needs no lateral velocity: young or not, it threatens
    lead = ObjectState(2, 0.2, 15.0, 0.0, -8.0, v_x_std=0.1, age_s=0.1)
    assert 2 in fcw(min_lateral_age_s=1.0).threats({2: lead})


def test_looming_veto_needs_the_box_to_grow():
    # 50 m ahead read closing at 20 m/s (TTC ~2.4 s): a threat only if the box's width grows accordingly
    far = dict(v_x_std=0.1, v_y_std=0.5)
    w = fcw(looming_share=0.6)
    assert w.threats({1: ObjectState(1, 0.0, 50.0, 0.0, -20.0, **far, expansion_rate=0.0, expansion_rate_std=0.05)}) == {}
    assert 1 in w.threats({1: ObjectState(1, 0.0, 50.0, 0.0, -20.0, **far, expansion_rate=0.4, expansion_rate_std=0.05)})
    # with looming_share 0.6 the rate must reach that share of the claimed closing speed over distance, here
    # 0.6 x 19.75 / 50 = 0.237 /s (v_y shrunk by 0.5 sigma), within 1 sigma
    assert 1 in w.threats({1: ObjectState(1, 0.0, 50.0, 0.0, -20.0, **far, expansion_rate=0.26, expansion_rate_std=0.05)})
    assert w.threats({1: ObjectState(1, 0.0, 50.0, 0.0, -20.0, **far, expansion_rate=0.15, expansion_rate_std=0.05)}) == {}
    # without any share, a rate within 1 sigma of the floor 1 / (2.5 x 3 s) = 0.133 /s is consistent
    assert 1 in fcw(looming_far_share=0.0).threats(
        {1: ObjectState(1, 0.0, 50.0, 0.0, -20.0, **far, expansion_rate=0.09, expansion_rate_std=0.05)})
    assert fcw().threats({1: ObjectState(1, 0.0, 50.0, 0.0, -20.0, **far, expansion_rate=0.09, expansion_rate_std=0.05)}) == {}
    assert w.threats({1: ObjectState(1, 0.0, 50.0, 0.0, -20.0, **far, expansion_rate=0.09, expansion_rate_std=0.05)}) == {}
    # looming_share is asked only of a vehicle keeping its lane: one moving sideways for sure (10 m ahead,
    # 2.5 m/s towards the ego lane) is asked looming_side_share instead (off here: only the floor)
    cut_in = dict(d_x=3.7, d_y=10.0, v_x=-2.5, v_y=-5.0, v_x_std=0.1, v_y_std=0.1, expansion_rate=0.1,
                  expansion_rate_std=0.05)
    w_lane = fcw(looming_share=0.6, looming_side_share=0.0)
    assert 1 in w_lane.threats({1: ObjectState(1, **cut_in)})
    assert w_lane.threats({1: ObjectState(1, **{**cut_in, "d_x": 0.0, "v_x": 0.0})}) == {}
    # none measured: no veto
    assert 1 in w.threats({1: ObjectState(1, 0.0, 50.0, 0.0, -20.0, **far)})
    assert fcw(looming_sigmas=None).threats(
        {1: ObjectState(1, 0.0, 50.0, 0.0, -20.0, **far, expansion_rate=0.0, expansion_rate_std=0.05)})


def test_far_vehicles_must_loom_and_a_car_turning_in_is_exempt():
    # by default, from 35 m on every vehicle must widen at 0.6 of its claimed closing speed over distance
    near = ObjectState(1, 0.0, 25.0, 0.0, -10.0, v_x_std=0.1, v_y_std=0.5, expansion_rate=0.12, expansion_rate_std=0.05)
    assert 1 in fcw().threats({1: near})                          # 25 m: only the floor (0.133 /s, within 1 sigma)
    assert fcw(looming_far_distance_m=20.0).threats({1: near}) == {}   # 0.6 x 9.75 / 25 = 0.23 /s needed
    # a next-lane car 60 m ahead read drifting in (a range error moves its lateral reading too): its
    # lateral motion no longer exempts it from the share, as it does nearer
    drift = ObjectState(1, -3.0, 60.0, 1.0, -25.0, v_x_std=0.1, v_y_std=0.5, expansion_rate=0.12, expansion_rate_std=0.03)
    assert 1 in fcw(looming_far_share=0.0, looming_side_share=0.0).threats({1: drift})
    assert fcw().threats({1: drift}) == {}
    # a car 10 m ahead across the lane line (0 m from the corridor) moving in: its width shrinks with its
    # yaw, so no looming veto; the same motion 1.9 m out in the next lane is vetoed by the floor
    turning = ObjectState(1, 1.6, 10.0, -1.5, -5.0, v_x_std=0.1, v_y_std=0.1, expansion_rate=-0.3, expansion_rate_std=0.05)
    assert 1 in fcw().threats({1: turning})
    assert fcw(looming_exempt_gap_m=None).threats({1: turning}) == {}
    assert fcw().threats({1: ObjectState(1, 3.7, 10.0, -1.5, -5.0, v_x_std=0.1, v_y_std=0.1, expansion_rate=-0.3,
                                         expansion_rate_std=0.05)}) == {}
    for bad in ({"looming_far_share": 1.5}, {"looming_far_distance_m": -1.0}, {"looming_exempt_gap_m": -0.1}):
        with pytest.raises(ValueError, match=next(iter(bad))):
            fcw(**bad)


def test_a_next_lane_car_read_drifting_in_must_loom():
    # 10 m ahead in the next lane (1.7 m beyond the corridor) read moving in at 2.5 m/s and closing at
    # 7 m/s: its box must widen at 0.6 x 7 / 10 = 0.42 /s; at 0.30 +- 0.05 it is not that car
    def drifting(rate):
        return {1: ObjectState(1, 3.5, 10.0, -2.5, -7.0, v_x_std=0.1, v_y_std=0.1, expansion_rate=rate,
                               expansion_rate_std=0.05)}
    assert fcw().threats(drifting(0.30)) == {}
    assert 1 in fcw(looming_side_share=0.0).threats(drifting(0.30))   # only the floor (0.133 /s)
    assert 1 in fcw().threats(drifting(0.45))                          # it widens as claimed
    # across the lane line (within looming_exempt_gap_m) it is turning in: exempt, as before
    crossing = {1: ObjectState(1, 1.6, 10.0, -2.5, -7.0, v_x_std=0.1, v_y_std=0.1, expansion_rate=0.30,
                               expansion_rate_std=0.05)}
    assert 1 in fcw().threats(crossing)
    for bad in (-0.1, 1.5, float("nan")):
        with pytest.raises(ValueError, match="looming_side_share"):
            fcw(looming_side_share=bad)


def test_closing_speed_is_capped_at_the_ego_speed():
    # 80 m ahead read closing at 40 m/s (TTC 1.96 s); the ego drives 24 m/s, so at most 25 m/s: TTC 3.1 s
    s = {1: ObjectState(1, 0.0, 80.0, 0.0, -40.0, v_x_std=0.1, v_y_std=0.01)}
    w = fcw()
    assert 1 in w.threats(s)
    assert w.threats(s, ego_speed=24.0) == {}
    assert w.threats(s, ego_speed=30.0) != {}          # 80 - 1.75 m at 31 m/s: 2.5 s
    assert 1 in fcw(ego_speed_margin_mps=None).threats(s, ego_speed=24.0)
    out = w.update(s, None, 0.0, ego_speed=24.0)
    assert not out.active and out.threat_ids == ()


def test_a_young_far_track_is_no_threat_yet_a_young_near_one_is():
    # a lead 30 m ahead read closing at 12 m/s (TTC 2.5 s): its filter 0.2 s old is no threat yet;
    # 0.3 s old, or 15 m ahead at the same TTC, it is
    def lead(d_y, v_y, age):
        return ObjectState(1, 0.0, d_y, 0.0, v_y, v_x_std=0.1, v_y_std=0.1, age_s=age)
    assert fcw().threats({1: lead(30.0, -12.0, 0.2)}) == {}
    assert 1 in fcw().threats({1: lead(30.0, -12.0, 0.3)})
    assert 1 in fcw().threats({1: lead(15.0, -6.0, 0.0)})
    assert 1 in fcw(young_far_age_s=0.0).threats({1: lead(30.0, -12.0, 0.0)})
    assert 1 in fcw(young_far_distance_m=40.0).threats({1: lead(30.0, -12.0, 0.0)})
    assert 1 in fcw().threats({1: ObjectState(1, 0.0, 30.0, 0.0, -12.0, v_x_std=0.1, v_y_std=0.1)})  # no age: no gate


def test_a_lead_whose_registered_patch_does_not_grow_as_claimed_is_no_threat():
    # 12 m ahead read closing at 4 m/s (TTC 2.6 s): its patch must grow at 0.6 x 4 / 12 = 0.2 /s
    def lead(rate, std=0.02, d_x=0.0, v_x=0.0):
        return {1: ObjectState(1, d_x, 12.0, v_x, -4.0, v_x_std=0.1, v_y_std=0.1, registered_rate=rate,
                               registered_rate_std=std)}
    assert fcw().threats(lead(0.15)) == {}                   # 0.15 + 0.02 < 0.2
    assert 1 in fcw().threats(lead(0.19))                    # within one sigma
    assert 1 in fcw().threats(lead(0.33))                    # the true 4 / 12
    assert 1 in fcw().threats(lead(None, None))              # no registration: no veto
    assert 1 in fcw(registered_share=None).threats(lead(0.0))
    assert 1 in fcw(registered_sigmas=10.0).threats(lead(0.0))
    # a car read moving sideways (beyond 2 of its lateral sigmas) turns, and its patch with it: exempt
    assert 1 in fcw().threats(lead(0.0, d_x=1.6, v_x=-1.5))                # 1.5 m/s > 2 x 0.1
    assert 1 in fcw().threats(lead(0.0, d_x=0.3, v_x=-0.25))               # in the lane, 0.25 > 0.2
    assert fcw(registered_lateral_sigmas=3.0).threats(lead(0.0, d_x=0.3, v_x=-0.25)) == {}
    for bad in ({"registered_share": 1.5}, {"registered_share": float("nan")}, {"registered_sigmas": -1.0},
                {"registered_lateral_sigmas": float("inf")}):
        with pytest.raises(ValueError, match=next(iter(bad))):
            fcw(**bad)


def test_a_threat_its_registered_patch_confirms_comes_on_at_once():
    # 12 m ahead read closing at 4 m/s (v_y_std 0.1: 3.95 m/s after the 0.5-sigma discount): the TTC assumes a
    # rate of 3.95 / 12 = 0.329 /s; a patch growing at 0.40 +- 0.02 /s confirms it, one at 0.33 +- 0.02 does not
    def lead(rate, v_x=0.0):
        return {1: ObjectState(1, 0.0, 12.0, v_x, -4.0, v_x_std=0.1, v_y_std=0.1, registered_rate=rate,
                               registered_rate_std=0.02)}
    dt = 1 / 15

    def onset(states, **kw):
        w = fcw(min_on_s=0.1, **kw)
        return next(k for k in range(5) if w.update(states, None, k * dt).active)
    assert fcw().assess_threats(lead(0.40))[1] == {1}
    assert fcw().assess_threats(lead(0.33))[1] == frozenset()
    assert fcw(confirm_share=0.9).assess_threats(lead(0.33))[1] == {1}    # 0.31 >= 0.9 x 0.329
    assert fcw().assess_threats(lead(0.40, v_x=-1.5))[1] == frozenset()   # turning: its patch proves nothing
    assert onset(lead(0.40), confirmed_min_on_s=0.0) == 0                 # both cues agree: the first frame
    assert onset(lead(0.33), confirmed_min_on_s=0.0) == 2                 # the filter alone: min_on_s, 2 frames
    assert onset(lead(0.40), confirmed_min_on_s=None) == 2                # the rule off
    assert onset(lead(0.40), confirmed_min_on_s=0.05) == 1
    for bad in ({"confirmed_min_on_s": -0.1}, {"confirm_share": 0.0}):
        with pytest.raises(ValueError, match=next(iter(bad))):
            fcw(**bad)



def test_a_sideways_motion_the_registered_patch_does_not_show_is_none():
    # next lane (3.7 m right), 8 m ahead, read drifting in at 3 m/s (sure: sigma 0.1), closing at 4 m/s
    def car(lat, lat_std=0.1):
        return {1: ObjectState(1, 3.7, 8.0, -3.0, -4.0, v_x_std=0.1, v_y_std=0.1, registered_v_x=lat,
                               registered_v_x_std=lat_std)}
    assert 1 in fcw().threats(car(0.0))                                    # the rule off (default)
    on = fcw(registered_lateral_share=0.5)
    assert on.threats(car(0.0)) == {}                                      # the patch stays put: no cut-in
    assert on.threats(car(-1.0)) == {}                                     # 1.0 + 0.1 < 0.5 x (3 - 3 x 0.1)
    assert on.threats(car(+2.0)) == {}                                     # moving away
    assert 1 in on.threats(car(-2.0))                                      # the patch moves in too: a cut-in
    assert 1 in on.threats(car(-1.0, lat_std=0.5))                         # within its sigma
    assert 1 in on.threats(car(None, None))                                # no patch: the filter's reading
    with pytest.raises(ValueError, match="registered_lateral_share"):
        fcw(registered_lateral_share=1.5)
