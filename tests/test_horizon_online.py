"""The pipeline's answer to a pitching camera: the horizon stage (online vanishing point against the
true per-frame horizon row), equation 3 with the current horizon, distance intervals and their
scoring, the CLI switch and its bad input."""

from __future__ import annotations

import json
import math
from dataclasses import replace

import numpy as np
import pytest

from harness.scoring import algo
from harness.scoring.horizon import horizon_metrics
from harness.world.truth import CameraTruth, EgoTruth, FrameTruth
from monorarp.core.camera import CameraModel
from monorarp.app.cli import main
from monorarp.horizon.stages import CalibratedHorizon, OnlineHorizon, pitch_std_px, row_std_px
from monorarp.pipeline.config import PipelineConfig
from monorarp.pipeline.runner import Pipeline, run_sync, run_threaded
from monorarp.risk.estimators import ttc_std
from monorarp.state.estimator import StateEstimator
from monorarp.state.geometry import box_distance
from monorarp.core.types import Frame, FrameResult, HorizonReading, ObjectState, RiskEstimate, Track

NOMINAL = CameraModel.from_fov(640, 360, 70.0, 1.3, math.radians(2.0))


# ------------------------------------------------------------------ vanishing point uncertainty
def test_row_std_matches_monte_carlo_scatter():
    """Segments through a known point with Gaussian endpoint noise: the fit's stated row sigma
    agrees with the scatter of the fitted rows over many draws (within 35 %)."""
    from monorarp.horizon.vanishing import vanishing_point

    rng = np.random.default_rng(7)
    u0, v0 = 320.0, 160.0
    rows, stds = [], []
    for _ in range(300):
        segs = []
        for ang in (-60, -45, -35, 35, 48, 62):                    # lines leaning both ways
            t = math.radians(ang)
            for start in (60.0, 140.0):                            # two stripes per line
                p1 = np.array([u0, v0]) + start * np.array([math.cos(t), math.sin(abs(t))]) * [np.sign(ang), 1]
                p2 = p1 + 40.0 * np.array([math.cos(t), math.sin(abs(t))]) * [np.sign(ang), 1]
                segs.append(np.r_[p1, p2] + rng.normal(0, 0.4, 4))
        seg = np.array(segs)
        vp = vanishing_point(seg, rng=np.random.default_rng(0))
        rows.append(vp.v)
        stds.append(row_std_px(seg, vp.u, vp.v))
    scatter = np.std(rows)
    assert np.median(stds) == pytest.approx(scatter, rel=0.35)
    assert abs(np.mean(rows) - v0) < 3 * scatter / math.sqrt(len(rows)) + 0.01


def test_pitch_std_px_is_the_row_shift_of_that_pitch():
    s = pitch_std_px(NOMINAL, 0.5)
    up = replace(NOMINAL, pitch_rad=NOMINAL.pitch_rad + math.radians(0.5)).horizon_row
    down = replace(NOMINAL, pitch_rad=NOMINAL.pitch_rad - math.radians(0.5)).horizon_row
    assert s == pytest.approx((down - up) / 2, rel=1e-9)
    assert CalibratedHorizon(NOMINAL, 0.5).update(None, 0.0) == HorizonReading(NOMINAL.horizon_row, s, "calibrated")


# ------------------------------------------------------------------ online horizon on rendered frames
@pytest.fixture(scope="module")
def vibrating_frames():
    from harness.run.frame_feed import rendered_frames
    from harness.world.scenario import parse_scenario

    s = parse_scenario({"name": "v", "seed": 4, "duration_s": 2.0, "road": {"lanes": 3},
                        "traffic": {"vehicles_count": 4}, "ego": {"lane": 1, "speed_mps": 25.0},
                        "camera": {"width": 640, "height": 360, "hfov_deg": 70, "height_m": 1.3, "pitch_deg": 2.0},
                        "camera_motion": {"mount": {"pitch_deg": 0.3},
                                          "vibration": {"pitch_amplitude_deg": 0.5, "band_hz": [1.0, 3.0]}}})
    return s, list(rendered_frames(s, 20))


def test_online_horizon_follows_the_true_row(vibrating_frames):
    s, frames = vibrating_frames
    cam = s.camera.model()
    h = OnlineHorizon(cam)
    err, cal_err, std = [], [], []
    for frame, truth in frames:
        r = h.update(frame.image, frame.t)
        assert r.source == "vanishing_point"
        true = truth.camera.horizon_row
        err.append(r.row - true)
        cal_err.append(cam.horizon_row - true)
        std.append(r.std_px)
    err, cal_err = np.abs(err), np.abs(cal_err)
    assert np.median(err) < 0.4 and err.max() < 1.0                     # px
    assert np.median(cal_err) > 2.0                                     # 0.3 deg mount error + vibration
    assert np.mean(err <= algo.Z90 * np.array(std)) >= 0.9              # the stated sigma covers it


def test_online_horizon_holds_then_falls_back():
    h = OnlineHorizon(NOMINAL, hold_s=0.2)
    blank = np.full((360, 640, 3), 90, np.uint8)
    r0 = h.update(blank, 0.0)
    assert r0.source == "calibrated" and r0.row == NOMINAL.horizon_row
    h._last, h._last_t = HorizonReading(150.0, 0.3, "vanishing_point"), 1.0
    assert h.update(blank, 1.1) == HorizonReading(150.0, h.fallback_std_px, "held")
    assert h.update(blank, 1.3).source == "calibrated"


# ------------------------------------------------------------------ equation 3 with the current horizon
def _box_at(camera: CameraModel, d_rear: float, est: StateEstimator) -> np.ndarray:
    """A box whose bottom edge is where ``camera`` sees the contact line of a rear face at ``d_rear``."""
    y = d_rear + est.config.contact_offset_m
    v = camera.project_ego(np.array([0.0, y, -camera.height_m]))[1]
    return np.array([[300.0, v - 30.0, 340.0, v]])


def test_state_uses_the_reading_row_and_widens_its_interval():
    true = replace(NOMINAL, pitch_rad=NOMINAL.pitch_rad + math.radians(0.5))
    est = StateEstimator(NOMINAL, contact_offset_std_m=0.0, edge_std_px=0.0)
    box = _box_at(true, 30.0, est)
    plain = est.update([Track(1, tuple(box[0]))], 0.0)[1]
    est.reset()
    online = est.update([Track(1, tuple(box[0]))], 0.0, horizon=HorizonReading(true.horizon_row, 0.0, "held"))[1]
    assert online.d_y == pytest.approx(30.0, abs=1e-6)
    assert abs(plain.d_y - 30.0) > 1.0                                   # 0.5 deg = metres at 30 m
    est.reset()
    wide = est.update([Track(1, tuple(box[0]))], 0.0, horizon=HorizonReading(true.horizon_row, 2.0, "held"))[1]
    gain = est.horizon_gain(np.array([30.0]))[0]
    assert wide.d_y_std == pytest.approx(math.hypot(online.d_y_std, 2.0 * gain), rel=1e-9)
    assert est.camera is NOMINAL                                          # restored after the frame


def test_side_cut_box_states_a_wider_interval():
    est = StateEstimator(NOMINAL, edge_std_px=1.0, border_edge_std_px=3.0, contact_offset_std_m=0.0)
    d = np.array([20.0, 20.0])
    s = est.distance_std(d, np.zeros(2), 0.0, np.array([False, True]))
    g = est.horizon_gain(d)
    assert s == pytest.approx([g[0] * 1.0, g[1] * 3.0])


def test_horizon_gain_matches_the_numeric_derivative():
    est = StateEstimator(NOMINAL)
    for d in (8.0, 20.0, 40.0):
        box = _box_at(NOMINAL, d, est)
        shifted = [replace(NOMINAL, pitch_rad=math.atan((NOMINAL.cy - (NOMINAL.horizon_row + k)) / NOMINAL.fy))
                   for k in (-0.5, 0.5)]
        num = abs(box_distance(shifted[1], box)[0] - box_distance(shifted[0], box)[0])
        assert est.horizon_gain(np.array([d]))[0] == pytest.approx(num, rel=0.03)


def test_ttc_std_first_order():
    s = ObjectState(1, 0.0, 20.0, 0.0, -5.0, d_y_std=1.0, v_y_std=0.5)
    assert ttc_std({1: s}, {1: 4.0})[1] == pytest.approx(math.hypot(1.0 / 5.0, 4.0 * 0.5 / 5.0))
    assert ttc_std({1: s}, {1: None}) == {}


# ------------------------------------------------------------------ pipeline plumbing
class _Detector:
    def detect(self, image):
        return []


class _Horizon:
    def __init__(self):
        self.calls = 0

    def update(self, image, t):
        self.calls += 1
        return HorizonReading(170.0 + t, 0.5, "vanishing_point")


class _State:
    def __init__(self):
        self.seen = []

    def update(self, tracks, t, horizon=None):
        self.seen.append(horizon)
        return {}


class _Tracker:
    def update(self, image, detections, t):
        return []


class _Risk:
    def assess(self, states, t, ego_speed=None):
        return RiskEstimate(0.0)


@pytest.mark.parametrize("runner", [run_sync, run_threaded])
def test_pipeline_hands_the_reading_to_the_state_stage(runner):
    state = _State()
    p = Pipeline(_Detector(), _Tracker(), state, _Risk(), horizon=_Horizon())
    frames = [Frame(i, i / 10, np.zeros((4, 4, 3), np.uint8)) for i in range(3)]
    res = list(runner(p, frames))
    assert [r.horizon.row for r in res] == [170.0, 170.1, 170.2]
    assert [h.row for h in state.seen] == [170.0, 170.1, 170.2]
    assert "horizon" in res[0].timings_ms


def test_no_horizon_stage_changes_nothing():
    state = _State()
    frame = Frame(0, 0.0, np.zeros((4, 4, 3), np.uint8))
    res = list(run_sync(Pipeline(_Detector(), _Tracker(), state, _Risk()), [frame]))
    assert state.seen == [None] and res[0].horizon is None and "horizon" not in res[0].timings_ms
    assert PipelineConfig(detector={"name": "oracle"}).horizon is None


# ------------------------------------------------------------------ scoring
def test_interval_stats_counts_and_widths():
    est = np.array([10.0, 10.0, 10.0, np.nan, 10.0])
    std = np.array([1.0, 1.0, 1.0, 1.0, np.nan])
    gt = np.array([10.5, 11.7, 8.0, 10.0, 10.0])                  # inside, outside (1.7 > 1.645), outside
    out = algo.interval_stats(est, std, gt)
    assert out["interval_count"] == 3
    assert out["interval_coverage"] == pytest.approx(1 / 3)
    assert out["interval_width_median_m"] == pytest.approx(2 * algo.Z90)


def test_horizon_metrics_against_truth_rows():
    truths = [FrameTruth(frame=k, t=k / 10, ego=EgoTruth(speed=0.0),
                         camera=CameraTruth(0.0, 0.0, row, 0.0, row - NOMINAL.horizon_row))
              for k, row in enumerate((160.0, 170.0))]
    results = [FrameResult(0, 0.0, [], [], {}, RiskEstimate(0.0),
                           horizon=HorizonReading(161.0, 1.0, "vanishing_point")),
               FrameResult(1, 0.1, [], [], {}, RiskEstimate(0.0), horizon=HorizonReading(165.0, 1.0, "held"))]
    m = horizon_metrics(truths, results, NOMINAL)
    assert m["abs_err_median_px"] == pytest.approx(3.0) and m["coverage_90"] == pytest.approx(0.5)
    assert m["sources"] == {"vanishing_point": 1, "held": 1}
    assert m["calibrated_abs_err_median_px"] == pytest.approx(
        np.median([abs(NOMINAL.horizon_row - 160.0), abs(NOMINAL.horizon_row - 170.0)]))
    assert horizon_metrics(truths, [replace(r, horizon=None) for r in results], NOMINAL) is None


# ------------------------------------------------------------------ command line
def _scenario_file(tmp_path, amplitude, pitch_deg=2.0):
    p = tmp_path / "s.yaml"
    p.write_text(f"name: s\nseed: 2\nduration_s: 0.4\nroad: {{lanes: 3}}\ntraffic: {{vehicles_count: 3}}\n"
                 f"ego: {{lane: 1}}\ncamera: {{pitch_deg: {pitch_deg}}}\n"
                 f"camera_motion: {{vibration: {{pitch_amplitude_deg: {amplitude}}}}}\n")
    return p


def test_cli_online_horizon_run(tmp_path, capsys):
    out = tmp_path / "o"
    assert main(["run", str(_scenario_file(tmp_path, 0.5)), "--detector", "oracle", "--horizon", "online",
                 "--no-video", "--ego-speed", "none", "--out", str(out)]) == 0
    m = json.loads((out / "metrics.json").read_text())
    assert m["config"]["components"]["horizon"] == "online"
    assert m["horizon"]["count"] == 6 and m["horizon"]["abs_err_median_px"] < 0.5
    assert "interval_coverage" in m["distance"]
    truth = [json.loads(line) for line in (out / "ground_truth.jsonl").read_text().splitlines()]
    cam = json.loads((out / "camera.json").read_text())
    assert all("camera" in t for t in truth) and "roll_rad" not in cam      # camera.json = nominal calibration
    assert len({t["camera"]["horizon_row"] for t in truth}) == len(truth)


def test_cli_vibration_outside_the_image_exits_2(tmp_path, capsys):
    out = tmp_path / "o"
    bad = _scenario_file(tmp_path, 8.0, pitch_deg=15.0)
    assert main(["run", str(bad), "--detector", "oracle", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "camera_motion.vibration.pitch_amplitude_deg" in err
    assert "Traceback" not in err and not out.exists()


def test_cli_unknown_horizon_exits_2(tmp_path, capsys):
    assert main(["run", str(_scenario_file(tmp_path, 0.5)), "--horizon", "gyro"]) == 2
    err = capsys.readouterr().err
    assert len(err.splitlines()) == 1 and "--horizon: unknown horizon 'gyro'; available: calibrated, lane_width, online" in err
