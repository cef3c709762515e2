"""Scoring maths on hand-made cases, checked against hand computation and brute force."""

from __future__ import annotations

import dataclasses
import itertools
import json
import math

import numpy as np
import pytest

from harness.scoring import algo
from harness.scoring.evaluate import EvalConfig, evaluate, write_metrics
from harness.scoring.match import match_boxes, split_ignored
from harness.scoring.mot import MotScorer
from harness.scoring.records import read_csv, write_csv
from harness.world.truth import EgoTruth, FrameTruth, ObjectTruth
from monorarp.core.boxes import iou_matrix
from monorarp.core.camera import CameraModel
from monorarp.app.io import to_jsonable
from monorarp.core.types import Detection, FrameResult, ObjectState, RiskEstimate, Track


# ------------------------------------------------------------------ matching
def test_hungarian_beats_greedy_and_respects_threshold():
    gt = [(0, 0, 10, 10), (2, 0, 12, 10)]
    est = [(1, 0, 11, 10), (-1, 0, 9, 10)]
    iou = iou_matrix(gt, est)
    # Greedy would give est 0 to gt 0 (highest IoU) and est 1 to gt 1 (IoU < 0.5: unmatched).
    m = match_boxes(gt, est, 0.5)
    best = max((sum(iou[g, e] for g, e in zip(range(2), p) if iou[g, e] >= 0.5), p)
               for p in itertools.permutations(range(2)))
    assert {(g, e) for g, e, _ in m} == {(g, e) for g, e in zip(range(2), best[1]) if iou[g, e] >= 0.5}
    assert len(m) == 2
    assert match_boxes(gt, [(50, 50, 60, 60)]) == []
    # IoU exactly at the threshold matches; just below does not.
    assert len(match_boxes([(0, 0, 10, 10)], [(0, 0, 10, 5)], 0.5)) == 1
    assert len(match_boxes([(0, 0, 10, 10)], [(0, 0, 10, 4.9)], 0.5)) == 0


def test_split_ignored_drops_estimates_on_ignored_objects():
    gt = [(0, 0, 10, 10), (20, 0, 30, 10)]
    est = [(0, 0, 10, 10), (20, 0, 30, 10), (50, 0, 60, 10)]
    kept, ignored = split_ignored(gt, [True, False], est)
    assert [(g, e) for g, e, _ in kept] == [(0, 0)]
    assert ignored.tolist() == [False, True, False]


def test_split_ignored_cover_and_range_rules():
    gt = [(0, 0, 10, 10), (40, 0, 44, 10)]          # object 1 is only a sliver now (ignored)
    est = [(1, 0, 11, 10),                          # matches counted object 0
           (36, 0, 56, 10),                         # coasting on the whole of object 1: IoU 0.2, covers it all
           (100, 0, 110, 10),                       # far from everything
           (-2, 0, 9, 10)]                          # near counted object 0 (IoU >= 0.5) but lost the assignment
    _, plain = split_ignored(gt, [True, False], est)
    assert plain.tolist() == [False, False, False, False]
    kept, aside = split_ignored(gt, [True, False], est, ignore_cover=0.5,
                                est_out_of_range=[True, False, True, True])
    assert [(g, e) for g, e, _ in kept] == [(0, 0)]
    # est 1 covers the ignored sliver; est 2 is out of range; est 3 overlaps a counted object -> still a FP
    assert aside.tolist() == [False, True, True, False]


def test_range_filter_uses_the_camera_ground_distance():
    from harness.scoring.rules import out_of_range

    cam = CameraModel.from_fov(640, 360, 70.0, 1.3, pitch_rad=math.radians(2))
    rows = [cam.project_ego(np.array([0.0, d, -1.3]))[1] for d in (60.0, 79.0, 81.0, 300.0)]
    boxes = [(300, v - 10, 340, v) for v in rows] + [(300, 10, 340, cam.horizon_row - 1)]
    assert out_of_range(boxes, cam, 80.0).tolist() == [False, False, True, True, True]
    assert out_of_range(boxes, None, 80.0) is None


# --------------------------------------------------------------------- maths
def test_error_stats_by_hand():
    s = algo.error_stats([11.0, 18.0, 33.0, np.nan], [10.0, 20.0, 30.0, 40.0])
    assert s["count"] == 3
    assert s["abs_err_median_m"] == pytest.approx(2.0)
    assert s["abs_err_mean_m"] == pytest.approx(2.0)
    assert s["abs_err_p90_m"] == pytest.approx(2.8)       # linear interpolation between 2 and 3
    assert s["bias_m"] == pytest.approx(2 / 3)
    assert s["rel_err_median"] == pytest.approx(0.1)
    assert s["rel_err_p90"] == pytest.approx(0.1)
    empty = algo.error_stats([], [])
    assert empty["count"] == 0 and math.isnan(empty["rel_err_median"])


def test_range_bins():
    d = [0.0, 9.99, 10.0, 19.9, 20.0, 39.0, 40.0, 79.9, 80.0, -1.0]
    assert algo.bin_labels(d).tolist() == ["0-10", "0-10", "10-20", "10-20", "20-40", "20-40", "40-80", "40-80",
                                           None, None]
    est = np.array(d) * 1.02
    b = algo.binned_error_stats(est, d, d)
    assert [b[k]["count"] for k in algo.RANGE_BINS] == [2, 2, 2, 2]
    assert b["20-40"]["rel_err_median"] == pytest.approx(0.02)


def test_warning_classification_by_hand():
    est = [1.0, 1.5, None, 3.0, 1.9, np.nan]
    gt = [1.2, 2.5, 1.0, None, 1.99, 1.0]
    # warnings est: T T F F T F ; gt: T F T F T T  -> tp 2, fp 1, fn 2
    w = algo.warning_classification(est, gt, 2.0)
    assert (w["tp"], w["fp"], w["fn"]) == (2, 1, 2)
    assert w["precision"] == pytest.approx(2 / 3)
    assert w["recall"] == pytest.approx(2 / 4)
    assert algo.warnings_from_ttc([2.0])[0] == False  # noqa: E712 - strictly below the threshold
    none = algo.warning_classification([None, 5.0], [None, 3.0])
    assert math.isnan(none["precision"]) and math.isnan(none["recall"])
    assert to_jsonable(none)["precision"] is None


def test_precision_recall_counts():
    pr = algo.precision_recall(3, 4, 6)
    assert pr["precision"] == 0.75 and pr["recall"] == 0.5 and pr["fp"] == 1 and pr["fn"] == 3
    assert pr["f1"] == pytest.approx(2 * 0.75 * 0.5 / 1.25)
    with pytest.raises(ValueError):
        algo.precision_recall(5, 4, 6)


# ----------------------------------------------------------------------- MOT
def test_mot_one_id_switch_by_hand():
    s = MotScorer()
    b = [(0, 0, 10, 10)]
    s.update([1], b, [True], [7], b)
    s.update([1], b, [True], [8], b)     # identity switch 7 -> 8
    s.update([1], b, [True], [8], b)
    s.update([1], b, [True], [], [])     # miss
    m = s.compute()
    # MOTA = 1 - (FN + FP + IDSW) / GT = 1 - (1 + 0 + 1) / 4
    assert m["mota"] == pytest.approx(0.5)
    assert m["num_switches"] == 1
    # IDF1: best one-to-one id map GT 1 <-> track 8 gives IDTP 2; IDFP 1, IDFN 2 -> 2*2 / (2*2 + 1 + 2)
    assert m["idf1"] == pytest.approx(4 / 7)


def test_mot_ignored_objects_are_neither_misses_nor_false_positives():
    s = MotScorer()
    gt = [(0, 0, 10, 10), (20, 0, 30, 10)]
    s.update([1, 2], gt, [True, False], [5, 6], gt)           # track 6 sits on the ignored object
    s.update([1, 2], gt, [True, False], [5], gt[:1])          # ignored object missed
    s.update([1, 2], gt, [True, False], [5, 9], [gt[0], (50, 0, 60, 10)])  # a real false positive
    m = s.compute()
    assert m["num_objects"] == 3 and m["num_misses"] == 0 and m["num_false_positives"] == 1
    assert m["mota"] == pytest.approx(1 - 1 / 3)


# ---------------------------------------------------------------- evaluation
def _truth(frame, objects):
    return FrameTruth(frame=frame, t=frame / 10, ego=EgoTruth(speed=20.0), objects=tuple(objects))


def _obj(i, box, d_long, vis=1.0, ttc=None, v_long=-1.0):
    return ObjectTruth(id=i, box=tuple(box), visibility=vis, d_long=d_long, d_lat=0.5, v_long=v_long, v_lat=0.0,
                       ttc=ttc)


def _result(frame, tracks, states, ttc, dets):
    return FrameResult(index=frame, t=frame / 10, detections=[Detection(b) for b in dets], tracks=tracks,
                       states=states, risk=RiskEstimate(max([1 / v for v in ttc.values() if v] or [0.0]), ttc),
                       timings_ms={"detector": 2.0, "tracker": 0.5, "state": 0.1, "risk": 0.1, "total": 2.7 + frame})


def test_evaluate_small_run(tmp_path):
    A, B, C = (100, 100, 140, 130), (300, 100, 320, 112), (200, 90, 204, 93)
    truths = [
        _truth(0, [_obj(1, A, 15.0, ttc=1.5), _obj(2, B, 50.0), _obj(3, C, 90.0)]),   # 3 beyond 80 m: ignored
        _truth(1, [_obj(1, A, 14.0, ttc=1.4), _obj(2, B, 50.0, vis=0.1)]),            # 2 occluded: ignored
    ]
    results = [
        _result(0, [Track(10, A), Track(11, B), Track(12, C)],
                {10: ObjectState(10, 0.4, 15.3, 0, -1.5), 11: ObjectState(11, 0.7, 48.0, 0, -1.0)},
                {10: 1.6, 11: None}, [A, B, C]),
        _result(1, [Track(10, A), Track(11, B), Track(13, (500, 10, 520, 30))],
                {10: ObjectState(10, 0.5, 14.0, 0, -1.0, a_y=-2.5, a_y_std=0.75, age_s=0.1,
                                     expansion_rate=0.125, expansion_rate_std=0.03,
                                     registered_rate=0.11, registered_rate_std=0.02)}, {10: 3.0},
                [A, (500, 10, 520, 30)]),
    ]
    m, recs = evaluate(truths, results, EvalConfig(), wall_time_s=0.5, run_info={"scenario": "t"})
    assert m["frames"] == 2
    # distance pairs: (15.3 vs 15), (48 vs 50), (14 vs 14); ignored objects not scored
    assert m["distance"]["count"] == 3
    assert m["distance"]["rel_err_median"] == pytest.approx(0.02)
    assert m["distance"]["by_range"]["10-20"]["count"] == 2
    assert m["distance"]["by_range"]["40-80"]["rel_err_median"] == pytest.approx(0.04)
    assert m["distance"]["by_range"]["0-10"]["count"] == 0
    assert m["lateral"]["abs_err_median_m"] == pytest.approx(0.1)
    assert m["rel_velocity"]["abs_err_median_mps"] == pytest.approx(0.0)
    assert m["rel_velocity"]["abs_err_mean_mps"] == pytest.approx(0.5 / 3)
    w = m["ttc"]["warning"]        # gt warns on obj 1 in both frames; estimate only in frame 0
    assert (w["tp"], w["fp"], w["fn"]) == (1, 0, 1) and w["recall"] == 0.5 and w["precision"] == 1.0
    d = m["detection"]             # frame 0: A, B counted hit; C ignored. frame 1: A hit, one FP
    assert (d["tp"], d["fp"], d["fn"]) == (3, 1, 0)
    t = m["tracking"]              # 3 counted object-frames, all matched; one FP track (13)
    assert t["objects"] == 3 and t["misses"] == 0 and t["false_positives"] == 1 and t["id_switches"] == 0
    assert t["mota"] == pytest.approx(1 - 1 / 3)
    assert t["by_range"] is None   # without a camera an unmatched track has no range bin
    assert m["runtime_ms"]["total"] == pytest.approx(3.2) and m["fps"] == pytest.approx(4.0)
    assert len(recs) == 3 + 2 + 1   # every GT object, plus the unmatched track 13

    write_metrics(m, tmp_path / "metrics.json")
    loaded = json.loads((tmp_path / "metrics.json").read_text())
    assert loaded["distance"]["by_range"]["0-10"]["rel_err_median"] is None
    write_csv(recs, tmp_path / "o.csv")
    back = read_csv(tmp_path / "o.csv")
    assert [(r.gt_id, r.track_id, r.matched) for r in back] == [(r.gt_id, r.track_id, r.matched) for r in recs]
    assert back[0].d_y_est == pytest.approx(15.3) and back[3].d_y_est == pytest.approx(14.0)
    assert (back[3].a_y_est, back[3].a_y_std, back[3].age_s, back[3].expansion_rate,
            back[3].expansion_rate_std) == (-2.5, 0.75, 0.1, 0.125, 0.03)
    assert (back[3].registered_rate, back[3].registered_rate_std) == (0.11, 0.02)
    assert math.isnan(back[0].a_y_est) and math.isnan(back[0].age_s)                 # none estimated
    assert math.isnan(back[4].d_y_est) and back[4].counted is False     # occluded object, no state


def test_tracking_by_range_splits_the_run_into_bins_by_hand():
    cam = CameraModel.from_fov(640, 360, 70.0, 1.3, pitch_rad=math.radians(2))

    def box(d, x=300):                   # a box standing on the ground d m ahead
        v = cam.project_ego(np.array([0.0, d, -1.3]))[1]
        return (x, v - 10, x + 20, v)

    near, far = box(15.0, 100), box(41.0, 300)
    low = (far[0], far[1] + 2, far[2], far[3] + 2)     # IoU 0.67 with the far car, bottom edge at ~35 m
    truths = [_truth(k, [_obj(1, near, 15.0), _obj(2, far, 41.0)]) for k in range(4)]
    tracks = [
        [Track(10, near), Track(20, low)],               # a matched track counts in its object's bin
        [Track(10, near), Track(20, low), Track(30, box(30.0, 500))],    # a phantom claimed at 30 m
        [Track(11, near), Track(40, box(100.0, 500))],                   # id switch; far car missed; 100 m: set aside
        [Track(11, near)],                                               # far car missed
    ]
    results = [_result(k, trs, {}, {}, []) for k, trs in enumerate(tracks)]
    m, _ = evaluate(truths, results, EvalConfig(), camera=cam)
    t, bins = m["tracking"], m["tracking"]["by_range"]
    assert (t["objects"], t["misses"], t["false_positives"], t["id_switches"]) == (8, 2, 1, 1)
    # 10-20 m: object 1 in 4 frames, tracks 10 then 11 -> one switch; IDF1 2*2 / (2*2 + 2 + 2)
    assert (bins["10-20"]["objects"], bins["10-20"]["misses"], bins["10-20"]["id_switches"]) == (4, 0, 1)
    assert bins["10-20"]["mota"] == pytest.approx(0.75) and bins["10-20"]["idf1"] == pytest.approx(0.5)
    # 40-80 m: object 2 found twice, missed twice; IDF1 2*2 / (2*2 + 0 + 2)
    assert (bins["40-80"]["objects"], bins["40-80"]["misses"], bins["40-80"]["false_positives"]) == (4, 2, 0)
    assert bins["40-80"]["mota"] == pytest.approx(0.5) and bins["40-80"]["idf1"] == pytest.approx(2 / 3)
    # 20-40 m: no object, the phantom's one false positive; MOTA undefined
    assert (bins["20-40"]["objects"], bins["20-40"]["false_positives"]) == (0, 1)
    assert math.isnan(bins["20-40"]["mota"]) and bins["0-10"]["objects"] == 0
    for key in ("objects", "misses", "false_positives"):
        assert sum(b[key] for b in bins.values()) == t[key]


def test_evaluate_rejects_misaligned_frames():
    with pytest.raises(ValueError):
        evaluate([_truth(0, [])], [_result(1, [], {}, {}, [])])


def test_table_ii_lists_stage_times_and_fps():
    from harness.scoring.tables import table_ii

    m = {"runtime_ms": {"detector": 2.5, "tracker": 0.25, "state": 0.125, "risk": 0.0625, "total": 3.0},
         "fps": 250.0}
    rows = {line[:18].strip(): line[18:].split() for line in table_ii(m).splitlines()[3:]}
    assert rows["Object Detector"] == ["2.500", "120.7"]
    assert rows["Tracker"][0] == "0.250" and rows["Risk Estimator"][0] == "0.062"
    assert rows["Total (stages)"] == ["3.000"] and rows["Total (FPS)"] == ["250.00", "5.56"]
    assert "-" in table_ii({"runtime_ms": {}, "fps": float("nan")}, paper=False)


# ------------------------------------------------------------------------------ risk scoring
def _brute_auroc(scores, labels):
    """P(score of a positive > score of a negative) + 0.5 P(tie), by counting every pair."""
    pos = [s for s, y in zip(scores, labels) if y]
    neg = [s for s, y in zip(scores, labels) if not y]
    wins = sum(1.0 if p > n else 0.5 if p == n else 0.0 for p in pos for n in neg)
    return wins / (len(pos) * len(neg))


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_auroc_matches_pair_count_and_scipy_u(seed):
    from scipy.stats import mannwhitneyu

    rng = np.random.default_rng(seed)
    n = 60
    labels = rng.random(n) < 0.3
    scores = np.round(rng.normal(labels * 0.8, 1.0), 1)      # rounded: many ties
    scores[:10] = 0.0                                         # and a big block of them
    a = algo.auroc(scores, labels)
    assert a == pytest.approx(_brute_auroc(scores, labels), abs=1e-12)
    u = mannwhitneyu(scores[labels], scores[~labels], alternative="two-sided").statistic
    assert a * labels.sum() * (~labels).sum() == pytest.approx(u, abs=1e-9)


def test_auroc_edge_cases():
    assert algo.auroc([0.1, 0.9], [False, True]) == 1.0
    assert algo.auroc([0.9, 0.1], [False, True]) == 0.0
    assert algo.auroc([0.5, 0.5, 0.5], [False, True, True]) == 0.5
    assert math.isnan(algo.auroc([0.1, 0.2], [True, True]))
    assert math.isnan(algo.auroc([], []))


def test_brier_by_hand_and_ttc_mapping():
    # (0.9-1)^2 + (0.2-0)^2 + (0.5-1)^2 + 0 = 0.01 + 0.04 + 0.25 = 0.30 over 4
    assert algo.brier([0.9, 0.2, 0.5, 0.0], [1, 0, 1, 0]) == pytest.approx(0.075)
    assert math.isnan(algo.brier([], []))
    with pytest.raises(ValueError):
        algo.brier([1.5], [1])
    # 1/TTC -> probability: TTC <= 1 s -> 1, 2 s -> 0.5, 4 s -> 0.25, no collision course -> 0
    np.testing.assert_allclose(algo.inverse_ttc_probability([1 / 0.5, 1.0, 0.5, 0.25, 0.0]),
                               [1.0, 1.0, 0.5, 0.25, 0.0])


def _risk_truth(frame, fps=10.0, ego_crashed=False, objects=()):
    base = {"box": (0, 0, 1, 1), "visibility": 1.0, "d_long": 30.0, "d_lat": 0.0, "v_long": -1.0, "v_lat": 0.0}
    return FrameTruth(frame=frame, t=frame / fps, ego=EgoTruth(speed=20.0, crashed=ego_crashed),
                      objects=tuple(ObjectTruth(**{**base, **o}) for o in objects))


def test_risk_labels_from_a_crash_and_a_near_miss_with_exclusion_at_the_end():
    """10 fps, 0.3 s horizon (3 frames). Near miss (TTC 0.8 s) at frame 4; ego crash from frame 11 on."""
    from harness.scoring.risk import risk_labels

    far = {"id": 1, "ttc": 5.0, "crashed": False}
    near = {"id": 1, "ttc": 0.8, "crashed": False}
    truths = []
    for k in range(14):
        objs = [near] if k == 4 else [far] if k % 2 else []
        truths.append(_risk_truth(k, ego_crashed=k >= 11, objects=objs))
    cfg = EvalConfig(risk_horizon_s=0.3, near_miss_ttc_s=1.0)
    events, labels = risk_labels(truths, cfg)
    assert events.tolist() == [k == 4 or k >= 11 for k in range(14)]
    # frames 1..4 see the near miss within 3 frames, 8..13 the crash; 0, 5, 6, 7 see nothing
    expected = [0, 1, 1, 1, 1, 0, 0, 0, 1, 1, 1, 1, 1, 1]
    assert labels.tolist() == expected
    # Without the crash, the last 3 frames' windows run past the end: excluded, not negative.
    truths2 = [dataclasses.replace(t, ego=EgoTruth(speed=20.0, crashed=False)) for t in truths]
    _, labels2 = risk_labels(truths2, cfg)
    assert labels2[:10].tolist() == [0, 1, 1, 1, 1, 0, 0, 0, 0, 0]
    assert np.isnan(labels2[11:]).all() and labels2[10] == 0
    # A vehicle's own crash flag counts too; a TTC at or above the threshold does not.
    assert algo.horizon_labels([False, False, True], 0).tolist() == [0, 0, 1]
    _, l3 = risk_labels([_risk_truth(0, objects=[{"id": 2, "ttc": None, "crashed": True}]),
                         _risk_truth(1, objects=[{"id": 2, "ttc": 1.0, "crashed": False}])],
                        EvalConfig(risk_horizon_s=0.0))
    assert l3.tolist() == [1, 0]


def test_risk_and_lane_speed_metrics_in_evaluate():
    """Scores, baseline and lane speed from a hand-made 5-frame run."""
    from harness.scoring.per_frame import frame_rows

    truths = [_risk_truth(k, objects=[{"id": 1, "box": [0, 0, 1, 1], "visibility": 1.0, "d_long": 30.0,
                                       "d_lat": 0.0, "v_long": -1.0, "v_lat": 0.0,
                                       "ttc": 0.5 if k == 4 else None}]) for k in range(5)]
    risks = [0.0, 0.1, 0.7, 0.2, 0.9]                     # probabilities
    ego = [None, 19.0, 21.0, 20.5, None]
    results = [FrameResult(index=k, t=k / 10.0, detections=[], tracks=[], states={},
                           risk=RiskEstimate(risk=r, kind="probability"), ego_speed=e, timings_ms={"risk": 1.0})
               for k, (r, e) in enumerate(zip(risks, ego))]
    baseline = [RiskEstimate(risk=v) for v in (0.0, 0.0, 0.5, 2.0, 2.0)]    # 1/TTC, 1/s
    cfg = EvalConfig(risk_horizon_s=0.2)                 # 2 frames: labels 0,0,1,1,1
    m, _ = evaluate(truths, results, cfg, baseline_risk=baseline, ego_speed_method="fake")
    r = m["risk"]
    assert (r["positives"], r["negatives"], r["excluded_past_end"]) == (3, 2, 0)
    assert r["auroc"] == pytest.approx(_brute_auroc(risks, [0, 0, 1, 1, 1]))
    assert r["brier"] == pytest.approx(np.mean((np.array(risks) - [0, 0, 1, 1, 1]) ** 2))
    assert r["baseline_ttc"]["auroc"] == pytest.approx(1.0)
    assert r["baseline_ttc"]["brier"] == pytest.approx((0 + 0 + 0.25 + 0 + 0) / 5)   # p = min(1, 1/TTC x 1 s)
    ls = m["lane_speed"]
    assert ls["valid_fraction"] == pytest.approx(3 / 5) and ls["method"] == "fake"
    assert ls["abs_err_median_mps"] == pytest.approx(1.0)          # |19-20|, |21-20|, |20.5-20|
    assert ls["rel_err_median"] == pytest.approx(1.0 / 20.0)
    rows = frame_rows(truths, results, cfg, baseline)
    assert [row["risk_label"] for row in rows] == [0, 0, 1, 1, 1]
    assert math.isnan(rows[0]["ego_speed_est"]) and rows[1]["ego_speed_gt"] == 20.0
    # No ego-speed stage: the section is there, with nothing to score.
    m2, _ = evaluate(truths, results, cfg)
    assert m2["lane_speed"]["method"] is None and math.isnan(m2["lane_speed"]["valid_fraction"])
    assert "baseline_ttc" not in m2["risk"]
