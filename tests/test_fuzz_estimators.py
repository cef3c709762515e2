"""Property tests of the estimator maths: whatever boxes, states, images and timestamps come in,
no NaN or inf leaves a component, and nothing raises but a clear ``ValueError`` for input that
is not a number where one is required.

Components: the state estimator (``geometric``: Kalman CA/CV and the paper's differencing),
constant-velocity TTC (:func:`monorarp.risk.ttc.time_to_collision`, :func:`~monorarp.risk.ttc.closing_time`),
the paper's 1/TTC risk, the Monte Carlo IDM/MOBIL risk (numpy and numba backends), both
lane-marking ego-speed estimators on random images, and the forward-collision warning stage.

Inputs: boxes degenerate (zero size, inverted), huge, negative, beyond the image, at the horizon,
with NaN/inf coordinates; timestamps repeated, decreasing, with huge and tiny gaps, huge
absolute values; states with extreme and non-finite values; images of noise, flat colour or
random stripes.

Contract checked (per output): every float an estimator returns is finite; optional fields are
``None`` or finite; standard deviations are >= 0; TTCs lie in [0, horizon]; probabilities in
[0, 1]; ego speeds in [0, max_speed]. Non-finite *timestamps* are not valid frame times (a
:class:`~monorarp.core.types.Frame` from a video source or the simulation always has a finite
one); components given one raise ValueError rather than let NaN through.
"""

from __future__ import annotations

import collections
import math
import os
import warnings

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, note, settings
from hypothesis import strategies as st

from monorarp.core.camera import CameraModel
from monorarp.risk.estimators import TTCRiskEstimator
from monorarp.state.estimator import StateEstimator
from monorarp.risk.ttc import closing_time, time_to_collision
from monorarp.core.types import ObjectState, RiskEstimate, Track, WarningState
from monorarp.warning.fcw import ForwardCollisionWarning

EXAMPLES = int(os.environ.get("MONORARP_FUZZ_EXAMPLES", "60"))
FUZZ = settings(max_examples=EXAMPLES, deadline=None, database=None,
                derandomize=not os.environ.get("MONORARP_FUZZ_RANDOM"),
                suppress_health_check=list(HealthCheck))
COUNTS: collections.Counter = collections.Counter()

CAM = CameraModel.from_fov(640, 360, 70.0, 1.3, math.radians(2.0), 0.0, 0.5)
SMALL_CAM = CameraModel.from_fov(160, 90, 70.0, 1.3, math.radians(2.0), 0.0, 0.5)
NAN, INF = math.nan, math.inf


@pytest.fixture(scope="module", autouse=True)
def _write_counts():
    yield
    if os.environ.get("MONORARP_FUZZ_COUNTS"):
        import json
        from pathlib import Path

        path = Path(os.environ["MONORARP_FUZZ_COUNTS"])
        old = json.loads(path.read_text()) if path.exists() else {}
        path.write_text(json.dumps({**old, **dict(sorted(COUNTS.items()))}, indent=1))


def finite(x) -> bool:
    return x is None or (isinstance(x, (int, float, np.floating)) and math.isfinite(float(x)))


def assert_state_finite(s: ObjectState) -> None:
    vals = (s.d_x, s.d_y, s.v_x, s.v_y)
    opt = (s.d_x_std, s.d_y_std, s.v_x_std, s.v_y_std, s.a_y, s.a_y_std)
    assert all(v is not None and finite(v) for v in vals), f"non-finite state {s}"
    assert all(finite(v) for v in opt), f"non-finite uncertainty/acceleration {s}"
    assert all(v is None or v >= 0 for v in (s.d_x_std, s.d_y_std, s.v_x_std, s.v_y_std, s.a_y_std)), s


# --------------------------------------------------------------------------- strategies
ODD = [0.0, -0.0, -0.5, 0.5, 163.5, 163.6, 179.5, 180.0, 319.5, 359.5, 360.0, 639.5, 640.0, 1e-300, -1e-300,
       1e6, -1e6, 1e9, -1e9]
# Box coordinates up to 1e9 px (a million image widths); astronomical ones in
# test_state_estimator_astronomical_box_coordinates.
coord = st.one_of(st.floats(-100, 800), st.floats(-100, 800), st.floats(-1e9, 1e9), st.sampled_from(ODD))
coord_nan = st.one_of(coord, st.sampled_from([NAN, INF, -INF]))


@st.composite
def boxes(draw, allow_nan: bool = False) -> tuple[float, float, float, float]:
    c = coord_nan if allow_nan else coord
    kind = draw(st.sampled_from(["plausible", "plausible", "free", "degenerate", "inverted", "horizon"]))
    if kind == "plausible":
        x1, y1 = draw(st.floats(-50, 700)), draw(st.floats(100, 400))
        w, h = draw(st.floats(0, 400)), draw(st.floats(0, 300))
        box = (x1, y1, x1 + w, y1 + h)
    elif kind == "degenerate":
        x, y = draw(c), draw(c)
        box = (x, y, x, y) if draw(st.booleans()) else (x, y, x + draw(st.floats(0, 5)), y)
    elif kind == "inverted":
        x1, y1, x2, y2 = draw(c), draw(c), draw(c), draw(c)
        box = (max(x1, x2), max(y1, y2), min(x1, x2), min(y1, y2))
    elif kind == "horizon":   # bottom edge right at / around the horizon row: distance -> infinity
        hz = CAM.horizon_row
        x1 = draw(st.floats(0, 600))
        box = (x1, hz - 20, x1 + 40, hz + draw(st.sampled_from([-1.0, -1e-9, 0.0, 1e-12, 1e-9, 1e-6, 0.01, 0.5])))
    else:
        box = (draw(c), draw(c), draw(c), draw(c))
    if allow_nan and draw(st.booleans()):
        i = draw(st.integers(0, 3))
        box = box[:i] + (draw(st.sampled_from([NAN, INF, -INF])),) + box[i + 1:]
    return box


STEPS = [1 / 15, 1 / 30, 1 / 15, 0.0, -1 / 15, -10.0, 1e-12, 1e-6, 0.5, 2.0, 3600.0, 1e9]


@st.composite
def timestamps(draw, n: int, allow_nan: bool = False) -> list[float]:
    t = draw(st.one_of(st.just(0.0), st.floats(-1e6, 1e6), st.sampled_from([1e12, -1e12, 1e15])))
    out = []
    for _ in range(n):
        out.append(t)
        t = t + draw(st.one_of(st.sampled_from(STEPS), st.floats(-5, 5)))
    if allow_nan and n:
        out[draw(st.integers(0, n - 1))] = draw(st.sampled_from([NAN, INF, -INF]))
    return out


@st.composite
def track_frames(draw, allow_nan_boxes: bool = False, allow_nan_t: bool = False):
    n = draw(st.integers(1, 12))
    ts = draw(timestamps(n, allow_nan_t))
    frames = []
    for t in ts:
        ids = draw(st.lists(st.integers(0, 4), max_size=4, unique=True))
        frames.append(([Track(i, draw(boxes(allow_nan_boxes)), coasting=draw(st.booleans()) and draw(st.booleans()))
                        for i in ids], t))
    return frames


value = st.one_of(st.floats(-200, 200), st.floats(-1e6, 1e6), st.sampled_from([0.0, -0.0, 1e-300, 1e300, -1e300,
                                                                               1e12, -1e12, 5e-324]))
std_value = st.one_of(st.none(), st.floats(0, 100), st.sampled_from([0.0, 1e-300, 1e300]))


@st.composite
def object_states(draw, allow_nan: bool = False) -> dict[int, ObjectState]:
    v = st.one_of(value, st.sampled_from([NAN, INF, -INF])) if allow_nan else value
    sv = st.one_of(std_value, st.sampled_from([NAN, INF])) if allow_nan else std_value
    ids = draw(st.lists(st.integers(-3, 30), max_size=6, unique=True))
    out = {}
    for i in ids:
        plausible = draw(st.booleans())
        if plausible:   # near the ego, closing: exercises the TTC and in-path branches
            d = (draw(st.floats(-8, 8)), draw(st.floats(-10, 80)), draw(st.floats(-4, 4)), draw(st.floats(-40, 10)))
        else:
            d = (draw(v), draw(v), draw(v), draw(v))
        out[i] = ObjectState(i, *d, draw(sv), draw(sv), draw(sv), draw(sv), draw(st.one_of(st.none(), v)), draw(sv))
    return out


# --------------------------------------------------------------------------- state estimator
ESTIMATORS = [dict(velocity="kalman", motion="ca"), dict(velocity="kalman", motion="cv"),
              dict(velocity="difference")]


def _run_state(kw: dict, frames) -> None:
    est = StateEstimator(CAM, **kw)
    for tracks, t in frames:
        COUNTS["state estimator frames"] += 1
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            states = est.update(tracks, t)
        assert set(states) <= {tr.id for tr in tracks}
        for s in states.values():
            assert_state_finite(s)


@FUZZ
@given(frames=track_frames(), kw=st.sampled_from(ESTIMATORS))
def test_state_estimator_finite_boxes_any_timestamps(frames, kw):
    """Finite boxes of any size or shape, timestamps repeated, decreasing, with huge gaps."""
    _run_state(kw, frames)


@FUZZ
@given(frames=track_frames(allow_nan_boxes=True), kw=st.sampled_from(ESTIMATORS))
def test_state_estimator_nan_boxes(frames, kw):
    """NaN/inf box coordinates (a broken detector): the box gives no measurement, nothing NaN comes out."""
    _run_state(kw, frames)


def test_state_estimator_nan_timestamp():
    est = StateEstimator(CAM)
    est.update([Track(1, (300.0, 200.0, 340.0, 230.0))], 0.0)
    try:
        states = est.update([Track(1, (300.0, 200.0, 340.0, 231.0))], NAN)
    except ValueError:
        return
    for s in states.values():
        assert_state_finite(s)


# A box edge at ~1e300 px (finite) once gave d_x ~ -2.8e300 m and d_x_std = inf (Kalman) or v_x = inf
# (differencing); boxes beyond 10 image sizes are now no measurement (StateEstimator.plausible_boxes).
@pytest.mark.parametrize("kw, frames", [
    (dict(velocity="kalman"), [((320.0, 0.0, -1e300, 164.0), 0.0)]),          # d_x -2.8e300, d_x_std inf
    (dict(velocity="difference"), [((300.0, 150.0, 340.0, 200.0), 0.0),        # then d_x 7.8e306, v_x inf
                                   ((1.7976931348623157e308, 0.0, 636.0, 0.0), 0.001)])])
def test_state_estimator_astronomical_box_coordinates(kw, frames):
    est = StateEstimator(CAM, **kw)
    for box, t in frames:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            for s in est.update([Track(1, box)], t).values():
                assert_state_finite(s)


# --------------------------------------------------------------------------- TTC
@FUZZ
@given(st.lists(st.tuples(value, value, value, value, value, value), min_size=1, max_size=8),
       st.one_of(st.none(), st.lists(value, min_size=8, max_size=8)), st.sampled_from([0.5, 3.0, 10.0]))
def test_time_to_collision_in_horizon_or_nan(rows, accel, horizon):
    COUNTS["ttc arrays"] += 1
    a = np.array(rows, dtype=float)
    x_lo, x_hi = np.minimum(a[:, 0], a[:, 1]), np.maximum(a[:, 0], a[:, 1])
    y_lo, y_hi = np.minimum(a[:, 2], a[:, 3]), np.maximum(a[:, 2], a[:, 3])
    a_y = None if accel is None else np.array(accel[:len(rows)])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        ttc = time_to_collision(x_lo, x_hi, y_lo, y_hi, a[:, 4], a[:, 5], (-0.9, 0.9), (-2.75, 1.75), horizon, a_y=a_y)
    assert ttc.shape == (len(rows),)
    ok = np.isnan(ttc) | ((ttc >= 0) & (ttc <= horizon))
    assert ok.all(), ttc


@FUZZ
@given(st.lists(st.tuples(st.one_of(st.floats(0, 1e6), st.sampled_from([0.0, 1e-300, 1e300])), value, value),
                min_size=1, max_size=8))
def test_closing_time_nonnegative_or_inf(rows):
    COUNTS["closing_time arrays"] += 1
    gap, v, a = np.array(rows, dtype=float).T
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        t = closing_time(gap, v, a)
    assert not np.isnan(t).any(), t
    assert (t >= 0).all(), t


# --------------------------------------------------------------------------- risk (1/TTC)
def assert_risk(r: RiskEstimate, states: dict, upper: float | None, horizon: float) -> None:
    assert finite(r.risk) and r.risk >= 0 and (upper is None or r.risk <= upper + 1e-12), r.risk
    assert set(r.ttc) == set(states)
    for v in r.ttc.values():
        assert v is None or (finite(v) and 0 <= v <= horizon + 1e-9), r.ttc


def check_ttc_risk(states):
    """TTCRiskEstimator on `states` (RuntimeWarnings silenced): a well-formed, finite assessment."""
    est = TTCRiskEstimator(camera=CAM)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        r = est.assess(states, 0.0)
    assert_risk(r, states, 1 / est.min_ttc_s, est.horizon_s)


@FUZZ
@given(states=object_states())
def test_ttc_risk_finite(states):
    COUNTS["ttc risk scenes"] += 1
    check_ttc_risk(states)


@FUZZ
@given(states=object_states(allow_nan=True))
def test_ttc_risk_nan_states(states):
    """A NaN/inf state (from some other state estimator) gives no TTC, never a NaN risk."""
    COUNTS["ttc risk scenes"] += 1
    check_ttc_risk(states)


# --------------------------------------------------------------------------- Monte Carlo risk
@pytest.fixture(scope="module")
def mc_estimators():
    from monorarp.risk.monte_carlo.estimator import MonteCarloRisk, resolve_backend

    backends = ["numpy"] + (["numba"] if resolve_backend("auto") == "numba" else [])
    return {b: MonteCarloRisk(n_rollouts=16, backend=b, camera=CAM) for b in backends}


@FUZZ
@given(states=object_states(allow_nan=True), ego=st.one_of(st.none(), value, st.sampled_from([NAN, INF])),
       t=st.one_of(st.floats(-1e6, 1e6), st.sampled_from([0.0, 1e15])), backend=st.sampled_from(["numpy", "numba"]))
def test_monte_carlo_risk_probability(mc_estimators, states, ego, t, backend):
    assume(backend in mc_estimators)
    COUNTS["monte carlo scenes"] += 1
    est = mc_estimators[backend]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        r = est.assess(states, t, ego_speed=ego)
    assert_risk(r, states, 1.0, est.config.horizon_s)


# --------------------------------------------------------------------------- ego speed
@st.composite
def images(draw, cam: CameraModel) -> np.ndarray:
    h, w = cam.height, cam.width
    kind = draw(st.sampled_from(["noise", "flat", "stripes", "road"]))
    rng = np.random.default_rng(draw(st.integers(0, 2 ** 32 - 1)))
    if kind == "noise":
        return rng.integers(0, 256, (h, w, 3), dtype=np.uint8)
    if kind == "flat":
        return np.full((h, w, 3), draw(st.integers(0, 255)), np.uint8)
    img = np.full((h, w, 3), 60, np.uint8)
    if kind == "stripes":
        for _ in range(draw(st.integers(1, 12))):
            x = int(rng.integers(0, w))
            img[:, x:x + int(rng.integers(1, 6))] = 255
        return img
    # "road": white dashes on a few lines converging at the horizon, at random phase
    hz = int(round(cam.horizon_row))
    for lane in (-1, 1):
        for v in range(hz + 1, h):
            u = int(cam.cx + lane * (v - hz) * 1.5)
            if 0 <= u < w and (v + int(rng.integers(0, 30))) % 30 < 12:
                img[v, max(u - 1, 0):u + 2] = 255
    return img


@pytest.fixture(scope="module")
def ego_speed_estimators():
    from monorarp.ego_speed.ground_track import GroundTrackEgoSpeed
    from monorarp.ego_speed.lsd_period import LsdPeriodEgoSpeed

    return {"ground_track": GroundTrackEgoSpeed(SMALL_CAM), "lsd_period": LsdPeriodEgoSpeed(SMALL_CAM)}


@FUZZ
@given(data=st.data(), name=st.sampled_from(["ground_track", "lsd_period"]))
def test_ego_speed_on_random_images(ego_speed_estimators, data, name):
    est = ego_speed_estimators[name]
    est.reset()
    n = data.draw(st.integers(1, 8))
    for t in data.draw(timestamps(n)):
        COUNTS["ego speed frames"] += 1
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            v = est.update(data.draw(images(SMALL_CAM)), t)
        note(f"t={t} v={v}")
        assert v is None or (finite(v) and 0 <= v <= getattr(est, "max_speed_mps", 1e9)), v


@pytest.mark.parametrize("name", ["ground_track", "lsd_period"])
@pytest.mark.parametrize("image", [np.zeros((90, 161, 3), np.uint8), np.zeros((10, 10, 3), np.uint8),
                                   np.zeros((0, 0, 3), np.uint8), np.zeros((90,), np.uint8)])
def test_ego_speed_refuses_wrong_image_shapes(ego_speed_estimators, name, image):
    from monorarp.lanes.geometry import EgoSpeedError

    with pytest.raises(EgoSpeedError):
        ego_speed_estimators[name].update(image, 0.0)


# --------------------------------------------------------------------------- warning stage
@FUZZ
@given(frames=st.lists(st.tuples(object_states(allow_nan=True), st.sampled_from(STEPS)), min_size=1, max_size=12),
       t0=st.one_of(st.just(0.0), st.floats(-1e6, 1e6)), accel=st.sampled_from([None, 1.0]))
def test_warning_stage_outputs_finite(frames, t0, accel):
    """ForwardCollisionWarning.update with any states and timestamps (repeated, decreasing, huge gaps)."""
    fcw = ForwardCollisionWarning(camera=CAM, accel_sigmas=accel)
    t = t0
    for states, step in frames:
        COUNTS["warning frames"] += 1
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            w = fcw.update(states, None, t)
        assert isinstance(w, WarningState)
        assert finite(w.ttc) and (w.ttc is None or w.ttc >= 0), w
        assert finite(w.onset_t), w
        assert set(w.threat_ids) <= set(states)
        assert (w.track_id is None) == (not w.active)
        t += step


THREAT = {1: ObjectState(1, 0.0, 10.0, 0.0, -10.0, 0.1, 0.1, 0.1, 0.1)}   # closing at 10 m/s, TTC ~0.8 s


def test_warning_nan_timestamp_does_not_suppress_the_alert():
    fcw = ForwardCollisionWarning()
    try:
        fcw.update(THREAT, None, NAN)
    except ValueError:
        return
    assert any(fcw.update(THREAT, None, t).active for t in (0.1, 0.2, 0.3, 0.5))


def test_warning_time_going_backwards_does_not_suppress_the_alert():
    fcw = ForwardCollisionWarning()
    fcw.update(THREAT, None, 10.0)
    assert any(fcw.update(THREAT, None, t).active for t in (0.0, 0.1, 0.2, 0.5, 1.0))
