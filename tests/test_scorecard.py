"""Scorecard: protocol validation and expansion, warning-episode scoring, pooled risk metrics, CLI."""

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from sklearn.metrics import average_precision_score, roc_auc_score

from harness.scorecard import score
from harness.scorecard.protocols import ProtocolError, contact_time, expand_protocol, load_protocol
from harness.scoring import algo
from harness.scoring.warnings import warning_metrics
from harness.world.truth import FrameTruth
from monorarp.core.types import FrameResult, ObjectState, RiskEstimate, Track, WarningState

FCW = Path(__file__).resolve().parents[1] / "scenarios" / "fcw"


def test_shipped_protocols_expand_to_the_standard_grids():
    ncap = expand_protocol(load_protocol(FCW / "ncap.yaml"), FCW / "ncap.yaml")
    by = {t: sum(x.test == t for x in ncap) for t in ("CCRs", "CCRm", "CCRb")}
    assert by == {"CCRs": 8 * 3, "CCRm": 6 * 3, "CCRb": 2 * 2 * 3}
    nhtsa = expand_protocol(load_protocol(FCW / "nhtsa.yaml"), FCW / "nhtsa.yaml")
    assert len(nhtsa) == 21 and all(t.min_trials_passed == 5 and t.trials == 7 for t in nhtsa)
    lvs = [t for t in nhtsa if t.test == "LVS"]
    assert all(t.ego_speed_mps == pytest.approx(20.1) for t in lvs)
    assert len({t.scenario["vehicles"][0]["distance_m"] for t in lvs}) == 7      # start distance varies by trial
    # trials are deterministic
    again = expand_protocol(load_protocol(FCW / "nhtsa.yaml"), FCW / "nhtsa.yaml")
    assert [t.scenario for t in again] == [t.scenario for t in nhtsa]
    # the offset target sits half its width off the lane centre
    off = [t for t in ncap if t.test == "CCRs" and t.params["offset"] == 0.5][0]
    v = off.scenario["vehicles"][0]
    assert v["lateral_offset_m"] == pytest.approx(0.5 * v["width_m"])


def test_risk_family_has_at_least_200_runs_mixing_conflicts():
    fam = expand_protocol(load_protocol(FCW / "risk.yaml"), FCW / "risk.yaml")
    assert len(fam) >= 200
    assert 0.3 < sum(t.conflict for t in fam) / len(fam) < 0.7


def test_nominal_suite_warms_its_traffic_up():
    """Every nominal run of the suite starts after a 4 s warm-up (docs/scorecard.md); a protocol without
    ``warmup_s`` leaves the scenario's own traffic as it is."""
    runs = expand_protocol(load_protocol(FCW / "nominal.yaml"), FCW / "nominal.yaml")
    assert runs and all(t.scenario["traffic"]["warmup_s"] == 4.0 for t in runs)
    tuning = expand_protocol(load_protocol(FCW / "tuning.yaml"), FCW / "tuning.yaml")
    assert all("warmup_s" not in t.scenario.get("traffic", {}) for t in tuning if t.kind == "nominal")


def test_a_warmed_up_nominal_run_starts_later_and_the_scorecard_says_so(tmp_path):
    from harness.scorecard.report import console_table
    from harness.scorecard.run import ScorecardOptions, run_scorecard

    p = tmp_path / "warm.yaml"
    p.write_text(json.dumps({"suite": "warm", "tests": [
        {"test": "Nominal", "kind": "nominal", "scenarios": [str(FCW.parent / "highway_cruise.yaml")], "seeds": [5],
         "duration_s": 1.0, "warmup_s": 2.0}]}))
    card = run_scorecard(tmp_path / "out", ScorecardOptions(protocol_files=[p], detector="oracle", frames=4,
                                                            progress=False))
    assert card["false_alarms"]["runs"] == 1 and card["false_alarms"]["warmup_s"] == [2.0]
    assert "(1 runs, traffic warmed up 2 s)" in console_table(card)
    first = json.loads((tmp_path / "out" / "runs" / "warm__Nominal__highway_cruise__seed5" / "ground_truth.jsonl")
                       .read_text().splitlines()[0])
    assert first["frame"] == 0 and first["ego"]["x"] > 250 + 2.0 * 15   # the ego (25 m/s) drove 2 s before frame 0


def test_contact_time_closed_forms():
    assert contact_time(100.0, 20.0, 0.0, 0.0, 0.0) == pytest.approx(5.0, abs=0.011)
    assert contact_time(30.0, 20.0, 10.0, 0.0, 0.0) == pytest.approx(3.0, abs=0.011)
    # equal speeds, the lead brakes at 2 s with 5 m/s^2: the gap closes as 2.5 tau^2 = 30 -> 2 + sqrt(12) s
    assert contact_time(30.0, 20.0, 20.0, 5.0, 2.0) == pytest.approx(2 + 12 ** 0.5, abs=0.02)
    assert contact_time(30.0, 10.0, 20.0, 0.0, 0.0) is None


@pytest.mark.parametrize("test, field", [
    ({"test": "X", "kind": "rear_end", "target_motion": "braking", "ego_speed_kmh": [50], "target_speed_kmh": 50,
      "gap_m": [-5.0], "target_decel_mps2": [2.0], "required_ttc_s": 2.0}, "gap_m"),
    ({"test": "X", "kind": "rear_end", "target_motion": "moving", "ego_speed_kmh": [50], "target_speed_kmh": 0,
      "required_ttc_s": 2.0}, "target_speed_kmh"),
    ({"test": "X", "kind": "rear_end", "target_motion": "moving", "ego_speed_kmh": [20], "target_speed_kmh": 30,
      "required_ttc_s": 2.0}, "ego_speed_kmh"),
    ({"test": "X", "kind": "rear_end", "target_motion": "stationary", "ego_speed_kmh": [0], "required_ttc_s": 2.0},
     "ego_speed_kmh"),
    ({"test": "X", "kind": "rear_end", "target_motion": "stationary", "ego_speed_kmh": [50]}, "required_ttc_s"),
    ({"test": "X", "kind": "rear_end", "speed": 3}, "speed"),
    ({"test": "X", "kind": "rear_end", "target_motion": "stationary", "ego_speed_kmh": [50], "required_ttc_s": 2.0,
      "warmup_s": 4.0}, "warmup_s"),
    ({"test": "X", "kind": "nominal", "scenarios": ["s.yaml"], "seeds": [-1]}, "tests.0.seeds.0"),
    # a field the kind does not use would be ignored silently
    ({"test": "X", "kind": "pass_by", "ego_speed_kmh": [90], "target_speed_kmh": 108, "gap_m": [10.0],
      "required_ttc_s": 2}, "required_ttc_s: a pass_by test is no conflict"),
    ({"test": "X", "kind": "cut_in", "ego_speed_kmh": [90], "target_speed_kmh": 72, "gap_m": [12.0],
      "required_ttc_s": 1.0, "lateral_offset": [0.5]}, "lateral_offset: a cut_in test does not use it"),
    ({"test": "X", "kind": "cut_in", "ego_speed_kmh": [90], "target_speed_kmh": 72, "gap_m": [12.0],
      "required_ttc_s": 1.0, "target_motion": "braking"}, "target_motion: a cut_in test does not use it"),
    ({"test": "X", "kind": "rear_end", "target_motion": "stationary", "ego_speed_kmh": [50], "required_ttc_s": 2.0,
      "gap_m": [20.0]}, "gap_m: a rear_end test with a stationary target does not use it"),
    ({"test": "X", "kind": "rear_end", "target_motion": "braking", "ego_speed_kmh": [50], "target_speed_kmh": 50,
      "gap_m": [20.0], "target_decel_mps2": [2.0], "required_ttc_s": 2.0, "start_ttc_s": [4, 5]},
     "start_ttc_s: a rear_end test with a braking target does not use it"),
    ({"test": "X", "kind": "nominal", "scenarios": ["s.yaml"], "seeds": [1], "trials": 3},
     "trials: a nominal test does not use it"),
    ({"test": "X", "kind": "nominal", "scenarios": ["s.yaml"], "seeds": [True]}, "tests.0.seeds.0"),
    ({"test": "X", "kind": "nominal", "scenarios": ["s.yaml"], "seeds": ["7"]}, "tests.0.seeds.0"),
])
def test_impossible_protocols_name_the_field(tmp_path, test, field):
    p = tmp_path / "bad.yaml"
    p.write_text(json.dumps({"suite": "bad", "tests": [test]}))
    with pytest.raises(ProtocolError) as e:
        load_protocol(p)
    msg = str(e.value)
    assert "bad.yaml" in msg and field in msg and "\n" not in msg


def test_cli_bad_protocol_exits_2_and_writes_nothing(tmp_path):
    p = tmp_path / "bad.yaml"
    p.write_text("suite: bad\ntests:\n  - {test: X, kind: rear_end, target_motion: braking, ego_speed_kmh: [50],\n"
                 "     target_speed_kmh: 50, gap_m: [0], target_decel_mps2: [2], required_ttc_s: 2}\n")
    out = tmp_path / "out"
    r = subprocess.run([sys.executable, "-m", "monorarp", "scorecard", "--protocol", str(p), "--out", str(out)],
                       capture_output=True, text=True)
    assert r.returncode == 2
    assert len(r.stderr.strip().splitlines()) == 1 and "gap_m" in r.stderr and "Traceback" not in r.stderr
    assert not out.exists()
    r = subprocess.run([sys.executable, "-m", "monorarp", "scorecard", "--suite", "nhtsa", "--trials", "0",
                        "--out", str(out)], capture_output=True, text=True)
    assert r.returncode == 2 and "--trials" in r.stderr and not out.exists()


def test_average_precision_and_auroc_match_scikit_learn():
    rng = np.random.default_rng(3)
    for _ in range(20):
        y = rng.random(300) < 0.2
        s = np.round(rng.normal(y * 1.0, 1.0), 1)          # rounded: many ties
        assert score.average_precision(s, y) == pytest.approx(average_precision_score(y, s), abs=1e-12)
        assert algo.auroc(s, y) == pytest.approx(roc_auc_score(y, s), abs=1e-12)


def test_pooled_risk_labels_by_horizon():
    t = np.arange(40) / 10.0                                 # 10 fps, event (contact) from frame 30 on
    event = t >= 3.0
    perfect = np.where(t >= 2.0, t, 0.0)                      # rises 1 s before the event: perfect at h = 1 s
    runs = [{"t": t, "event": event, "inverse_ttc": perfect}]
    out = score.pooled_risk(runs, (1.0, 1.5))
    assert out["1s"]["inverse_ttc"]["auroc"] == 1.0 and out["1s"]["inverse_ttc"]["ap"] == pytest.approx(1.0)
    assert out["1s"]["inverse_ttc"]["positives"] == 20        # frames 20..39
    assert out["1.5s"]["inverse_ttc"]["positives"] == 25
    assert out["1.5s"]["inverse_ttc"]["auroc"] < 1.0          # frames 15..19 positive at 1.5 s but scored 0


def test_frame_arrays_score_the_truth_as_a_reference(tmp_path):
    """per_frame.csv -> the estimators' scores and the truth's own 1/TTC (0 where no collision course)."""
    from harness.scorecard.run import _frame_arrays
    cols = "t,risk,risk_kind,baseline_ttc_risk,fcw_ttc_risk,manoeuvre_ttc_risk,risk_event,true_min_ttc"
    rows = ["0.0,0.1,inverse_ttc,,0.0,0.3,0,", "0.1,0.5,inverse_ttc,,0.25,0.6,0,4.0", "0.2,2.0,inverse_ttc,,1.0,2.5,1,0.5"]
    (tmp_path / "per_frame.csv").write_text("\n".join([cols, *rows]) + "\n")
    out = _frame_arrays(tmp_path)
    np.testing.assert_allclose(out["truth_reference"], [0.0, 0.25, 2.0])
    np.testing.assert_allclose(out["inverse_ttc"], [0.1, 0.5, 2.0])
    np.testing.assert_allclose(out["manoeuvre_ttc"], [0.3, 0.6, 2.5])
    assert out["event"].tolist() == [False, False, True] and "monte_carlo" not in out


def _frame(k, ttc_gt=None, active=False, episode=None, crashed=False, d_lat=0.0):
    truth = FrameTruth.from_json({"frame": k, "t": k / 10, "ego": {"speed": 20.0, "crashed": crashed},
                                  "objects": [{"id": 5, "box": [100, 100, 140, 130], "visibility": 1.0, "ttc": ttc_gt,
                                               "d_lat": d_lat, "d_long": 20.0, "v_lat": 0.0, "v_long": -5.0,
                                               "lane_rel": 0}]})
    res = FrameResult(index=k, t=k / 10, detections=[], tracks=[Track(2, (100, 100, 140, 130))],
                      states={2: ObjectState(2, d_lat, 20.0, 0.0, -5.0)}, risk=RiskEstimate(0.0),
                      warning=WarningState(active=active, track_id=2 if active else None, ttc=1.5 if active else None,
                                           episode=episode))
    return truth, res


def test_warning_metrics_episodes_false_alarms_and_timing():
    frames = ([_frame(k) for k in range(5)] +                                        # no conflict
              [_frame(k, active=True, episode=0, d_lat=3.5) for k in range(5, 8)] +    # warning, no conflict: FA
              [_frame(k) for k in range(8, 10)] +
              [_frame(k, ttc_gt=3.5 - 0.1 * (k - 10), active=k >= 12, episode=1) for k in range(10, 30)] +
              [_frame(30, ttc_gt=0.0, active=True, episode=1, crashed=True)])
    truths, results = zip(*frames)
    m = warning_metrics(truths, results, threshold_s=2.7)
    assert m["episodes"] == 2 and m["false_alarms"] == 1
    fa, real = m["episode_list"]
    assert fa["false_alarm"] and "vehicle 5" in fa["why"] and not real["false_alarm"]
    assert m["first_warning_ttc_s"] is None and m["first_warning_false_alarm"] is True
    assert real["true_ttc_at_onset_s"] == pytest.approx(3.3)
    assert m["contact_t_s"] == pytest.approx(3.0) and m["lead_time_s"] == pytest.approx(3.0 - 0.5)
    assert m["exposure_s"] == pytest.approx(3.1) and m["exposure_km"] == pytest.approx(20 * 3.1 / 1000)
    # the first real warning alone
    m2 = warning_metrics(truths[10:], results[10:], threshold_s=2.7)
    assert m2["false_alarms"] == 0 and m2["first_warning_ttc_s"] == pytest.approx(3.3)
    assert score.trial_passed("rear_end", m2, 2.4) and not score.trial_passed("rear_end", m2, 3.5)
    assert not score.trial_passed("rear_end", m, 2.4) and not score.trial_passed("pass_by", m, None)


def test_early_warning_that_stays_on_into_the_conflict_is_timed_when_the_collision_course_begins():
    # on from frame 3 while the vehicle is on no collision course; the course begins at frame 6 (true TTC 2.6 s)
    frames = [_frame(k, ttc_gt=None if k < 6 else 2.6 - 0.1 * (k - 6), active=k >= 3, episode=0) for k in range(20)]
    truths, results = zip(*frames)
    m = warning_metrics(truths, results, threshold_s=3.0)
    assert m["episodes"] == 1 and m["false_alarms"] == 0
    assert m["episode_list"][0]["true_ttc_at_onset_s"] is None
    assert m["first_warning_ttc_s"] == pytest.approx(2.6) and m["first_warning_early"] is True
    assert score.trial_passed("cut_in", m, 2.4) and not score.trial_passed("cut_in", m, 2.7)
    # the same early alert switched off before the course began: no first-warning TTC, a false alarm
    frames = [_frame(k, ttc_gt=None if k < 6 else 2.6 - 0.1 * (k - 6), active=3 <= k < 5, episode=0)
              for k in range(20)]
    m = warning_metrics(*zip(*frames), threshold_s=3.0)
    assert m["first_warning_ttc_s"] is None and m["first_warning_early"] is False and m["false_alarms"] == 1


def _braking_frames(accel, n=8, active=range(0, 4), v_lat=0.0):
    """A lead 12 m ahead (gap) closing at 2 m/s and at ``accel`` m/s^2 more, 10 fps; the warning on in ``active``."""
    frames = []
    for k in range(n):
        t = k / 10
        v, gap = -2.0 + accel * t, 12.0 - 2.0 * t + accel * t * t / 2
        truth = FrameTruth.from_json({"frame": k, "t": t, "ego": {"speed": 20.0},
                                      "objects": [{"id": 5, "box": [100, 100, 140, 130], "visibility": 1.0,
                                                   "ttc": gap / -v, "d_lat": 0.0, "d_long": gap + 2.0,
                                                   "v_lat": v_lat, "v_long": v, "lane_rel": 0}]})
        on = k in active
        res = FrameResult(index=k, t=t, detections=[], tracks=[Track(2, (100, 100, 140, 130))],
                          states={2: ObjectState(2, 0.0, gap + 2.0, 0.0, v)}, risk=RiskEstimate(0.0),
                          warning=WarningState(active=on, track_id=2 if on else None, ttc=2.5 if on else None,
                                               episode=0 if on else None))
        frames.append((truth, res))
    return zip(*frames)


def test_a_false_alarm_for_a_truly_braking_lead_gets_its_braking_ttc():
    # gap 12 m closing at 2 m/s and braking at 3 m/s^2 relative: its constant-velocity TTC stays 3.9-6 s in the
    # episode (a false alarm at 3 s), but held, the braking meets the ego at the root of 12 = 2 t + 1.5 t^2
    truths, results = _braking_frames(-3.0)
    m = warning_metrics(truths, results, threshold_s=3.0)
    assert m["false_alarms"] == 1 and m["braking_false_alarms"] == 1
    (ep,) = m["episode_list"]
    contact = max(np.roots([1.5, 2.0, -12.0]).real)
    assert ep["true_braking_ttc_s"] == pytest.approx(contact - 0.3)       # lowest at the episode's last frame
    assert ep["true_accel_mps2"] == pytest.approx(-3.0) and "braking held (-3.0 m/s^2)" in ep["why"]
    # a steady lead: held, its braking TTC is its constant-velocity TTC, 12 / 2 - 0.3 = 5.7 s; no braking alarm
    m = warning_metrics(*_braking_frames(0.0), threshold_s=3.0)
    assert m["braking_false_alarms"] == 0 and m["episode_list"][0]["true_braking_ttc_s"] == pytest.approx(5.7)
    # moving sideways: its course is not the gap's alone, so none is given
    m = warning_metrics(*_braking_frames(-3.0, v_lat=1.0), threshold_s=3.0)
    assert m["episode_list"][0]["true_braking_ttc_s"] is None and m["braking_false_alarms"] == 0


def test_the_scorecard_says_how_many_false_alarms_were_for_a_braking_vehicle():
    from harness.scorecard.report import console_table
    from harness.scoring.warnings import braking_alarm as _braking

    fa_ep = {"false_alarm": True}
    assert _braking(fa_ep | {"true_braking_ttc_s": 2.2}, 3.0) and not _braking(fa_ep | {"true_braking_ttc_s": 3.2}, 3.0)
    assert not _braking(fa_ep | {"true_braking_ttc_s": None}, 3.0) and not _braking(fa_ep, 3.0)
    fa = {"episodes": 3, "hours": 2.0, "km": 129.0, "per_hour": 1.5, "runs": 360, "braking": 2,
          "list": [{"run": "r", "t_s": 2.0, "why": "w", "true_braking_ttc_s": 2.4}]}
    text = console_table({"tests": [], "false_alarms": fa, "risk": None, "summary": {}, "failed_runs": []})
    assert "= 1.5 per hour (2 of them for a vehicle truly braking" in text
    assert "(360 runs) =" in text        # no warm-up: nothing said
    fa["warmup_s"] = [0.0]
    assert "(360 runs) =" in console_table({"tests": [], "false_alarms": fa, "risk": None, "summary": {},
                                            "failed_runs": []})


@pytest.mark.parametrize("argv, needle", [
    # checked while parsing, in command-line order (--frames 0 after it: the request fails fast without the limit)
    (["--suite", "nhtsa", "--trials", "1001", "--frames", "0"], "--trials: must be 1..1000, got 1001"),
    (["--protocol", str(FCW)], f"--protocol {FCW}: is a directory"),
    (["--protocol", str(FCW / "ci.yaml"), "--protocol", str(FCW / ".." / "fcw" / "ci.yaml")], "ci.yaml: given twice"),
    (["--protocol", str(FCW / "ci.yaml"), "--weak-detections", "0.2", "--tracker", "sort"], "--weak-detections"),
])
def test_cli_bad_options_one_line_nothing_written(tmp_path, capsys, argv, needle):
    from monorarp.app.cli import main

    out = tmp_path / "out"
    rc = main(["scorecard", *argv, "--out", str(out)])
    assert rc == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and needle in err[0], err
    assert not out.exists()


def test_false_alarm_rate_interval_is_the_exact_poisson_one():
    """Garwood's interval against its closed forms: k = 0 upper -ln(0.025)/T; k = 1 lower -ln(0.975)/T
    (P(N >= 1) = 0.025) and upper solving P(N <= 1) = 0.025 ((1 + m) e^-m = 0.025, m = 5.5716)."""
    import math

    from harness.scorecard.score import exposure_needed, poisson_interval, rate_verdict

    lo, hi = poisson_interval(0, 0.5)
    assert lo == 0.0 and hi == pytest.approx(-math.log(0.025) / 0.5, rel=1e-9) and hi == pytest.approx(7.378, abs=1e-3)
    lo, hi = poisson_interval(1, 2.0)
    assert lo == pytest.approx(-math.log(0.975) / 2.0, rel=1e-9)
    m = hi * 2.0
    assert (1 + m) * math.exp(-m) == pytest.approx(0.025, rel=1e-9)
    assert poisson_interval(3, 0.0) == (0.0, None)
    assert exposure_needed(1.0) == pytest.approx(3.6889, abs=1e-4)
    # 36 s cannot show <= 1 per hour even with no false alarm; 4 h with none can, with 3 it cannot
    assert rate_verdict(0, 0.01) == "exposure too short to show ≤ 1 per hour"
    assert rate_verdict(0, 4.0) == "PASS" and rate_verdict(3, 4.0) == "FAIL"
    assert rate_verdict(0, 3.68) != "PASS" and rate_verdict(0, 3.69) == "PASS"


def test_console_scorecard_has_no_python_reprs_and_gives_units_and_margins():
    from harness.scorecard.report import console_table, param_text
    from harness.scorecard.run import rate_fields

    t = {"suite": "ci", "test": "LVD", "params": {"offset": 0.5, "gap_m": 30.0, "decel_mps2": 2.94},
         "ego_speed_mps": 20.1, "target_speed_mps": 20.1, "required_ttc_s": 2.4, "trials": 2, "trials_passed": 1,
         "min_trials_passed": 1, "ttc_at_first_warning_s": [2.95, None], "passed": True}
    fa = {"episodes": 0, "hours": 0.01, "km": 0.6, "per_hour": 0.0, "runs": 2, "braking": 0, "list": [],
          **rate_fields(0, 0.01, 0.6)}
    card = {"tests": [t], "false_alarms": fa, "risk": None, "failed_runs": [],
            "summary": {"tests_passed": {"ci": "5/5"}, "ncap_above_30kmh_ttc_ge_2s": 0.9,
                        "ncap_above_30kmh_runs": 10, "ncap_above_30kmh_ttc_ge_2s_ci95": [0.555, 0.997]}}
    text = console_table(card)
    assert "{" not in text and "}" not in text and "[" not in text
    assert "offset +50 %, gap 30 m, decel 2.94 m/s²" in text and "margin s" in text and "+0.55 –" in text
    assert "test points passed: ci 5/5" in text
    assert "95 % interval 0 – 369" in text and "exposure too short to show ≤ 1 per hour" in text
    assert param_text("offset", 0.0) == "offset 0 %" and param_text("speed_mps", 3) == "speed 3 m/s"
    assert fa["verdict"].startswith("exposure") and fa["per_hour_ci95"][1] == pytest.approx(368.9, abs=0.1)


def test_scorecard_progress_bar_is_named_after_the_command(monkeypatch):
    import harness.scorecard.run as run_mod

    seen = {}
    monkeypatch.setattr(run_mod, "execute", lambda *a, **k: seen.update(k) or [])
    monkeypatch.setattr(run_mod, "prepare_out_dir", lambda out, resume: out)
    monkeypatch.setattr(run_mod, "build_tasks", lambda opts: ([], []))
    class Stop(Exception):
        pass

    def stop(*a):
        raise Stop

    monkeypatch.setattr(run_mod, "scorecard", stop)

    class Ex:
        pass

    with pytest.raises(Stop):
        run_mod.run_scorecard("/nonexistent-out", run_mod.ScorecardOptions(), make=lambda *a, **k: Ex())
    assert seen == {"desc": "scorecard"}


def test_scorecard_look_option_sets_every_trials_render_look():
    """--look realistic reaches every run's scenario (each run's own seed draws its look: a family, not
    one look) and changes nothing else of it."""
    from harness.scorecard.run import ScorecardOptions, build_tasks

    _, plain = build_tasks(ScorecardOptions(suites=("nhtsa",), trials=2))
    _, real = build_tasks(ScorecardOptions(suites=("nhtsa",), trials=2, look={"look": "realistic"}))
    assert {t.scenario["render"]["look"] for t in plain} == {"simple"}
    assert {t.scenario["render"]["look"] for t in real} == {"realistic"}
    assert [t.id for t in real] == [t.id for t in plain]
    assert len({t.seed for t in real}) > 1
    strip = lambda t: {**t.scenario, "render": {k: v for k, v in t.scenario["render"].items() if k != "look"}}
    assert [strip(t) for t in real] == [strip(t) for t in plain]
