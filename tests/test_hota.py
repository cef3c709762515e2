"""HOTA (``harness/scoring/hota.py``) against TrackEval's own numbers.

``tests/data/hota_trackeval.json`` holds inputs and TrackEval 1.3.0's outputs, made by
``scripts/hota_reference.py`` (TrackEval run in a separate environment: it pulls
``opencv-python``, which would replace the project's contrib OpenCV): two MOT sequences
exported by ``monorarp export --format mot`` with three trackers each (SORT and ByteTrack on
the exported detections, a perturbed truth), scored by TrackEval's MOTChallenge evaluator
from the files, and synthetic per-frame cases scored by its ``HOTA`` class directly,
edge cases included (empty frames, no tracks, no truth, ties, thresholds on the edge).
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from harness.scoring.hota import ALPHAS, HotaAccumulator, HotaResult, combine, hota
from monorarp.core.boxes import iou_matrix

FIXTURE = Path(__file__).parent / "data" / "hota_trackeval.json"
TOL = 1e-6
KEYS = {"HOTA": "hota", "DetA": "deta", "AssA": "assa", "LocA": "loca", "DetRe": "detre", "DetPr": "detpr",
        "AssRe": "assre", "AssPr": "asspr", "OWTA": "owta", "HOTA(0)": "hota0", "LocA(0)": "loca0"}


@pytest.fixture(scope="module")
def ref():
    return json.loads(FIXTURE.read_text())


def _xyxy(rows: np.ndarray) -> np.ndarray:
    """MOT (left, top, width, height) -> (x0, y0, x1, y1), as TrackEval converts them."""
    b = rows[:, 2:6].copy()
    b[:, 2] = b[:, 0] + b[:, 2]
    b[:, 3] = b[:, 1] + b[:, 3]
    return b


def _sequence_hota(gt_rows, tr_rows, n_frames: int) -> HotaResult:
    gt = np.array(gt_rows, dtype=float).reshape(-1, 7)
    gt = gt[gt[:, 6] != 0]                                      # conf 0: not part of the truth
    tr = np.array(tr_rows, dtype=float).reshape(-1, 6)
    acc = HotaAccumulator()
    for f in range(1, n_frames + 1):
        g, t = gt[gt[:, 0] == f], tr[tr[:, 0] == f]
        acc.update(g[:, 1].astype(int), t[:, 1].astype(int), iou_matrix(_xyxy(g), _xyxy(t)))
    return acc.compute()


def _assert_matches(mine: HotaResult, theirs: dict) -> None:
    s = mine.summary()
    for k, ours in KEYS.items():
        assert math.isclose(s[ours], theirs[k], abs_tol=TOL), (k, s[ours], theirs[k])
    np.testing.assert_array_equal(mine.tp, theirs["HOTA_TP"])
    np.testing.assert_array_equal(mine.fn, theirs["HOTA_FN"])
    np.testing.assert_array_equal(mine.fp, theirs["HOTA_FP"])
    np.testing.assert_allclose(mine.hota, theirs["HOTA_alpha"], atol=TOL, rtol=0)


def test_alphas_are_trackevals():
    assert len(ALPHAS) == 19 and ALPHAS[0] == pytest.approx(0.05) and ALPHAS[-1] == pytest.approx(0.95)


def test_exported_mot_sequences_match_trackeval(ref):
    mot = ref["mot"]
    for tracker, per_seq in mot["hota"].items():
        results = []
        for seq, data in mot["sequences"].items():
            mine = _sequence_hota(data["gt"], data["trackers"][tracker], mot["frames"][seq])
            _assert_matches(mine, per_seq[seq])
            results.append(mine)
        _assert_matches(combine(results), per_seq["COMBINED_SEQ"])


def test_synthetic_cases_match_trackeval(ref):
    assert len(ref["synthetic"]) >= 10
    for case in ref["synthetic"]:
        frames = case["frames"]
        mine = hota([f["gt"] for f in frames], [f["tr"] for f in frames],
                    [np.array(f["sim"], dtype=float).reshape(len(f["gt"]), len(f["tr"])) for f in frames])
        try:
            _assert_matches(mine, case["trackeval"])
        except AssertionError as e:
            raise AssertionError(f"case {case['name']}: {e}") from None


def test_closed_form_cases():
    """Hand-computed values from the paper's definitions."""
    # Perfect tracking at IoU 1: every score 1.
    r = hota([[1, 2]] * 4, [[5, 6]] * 4, [np.eye(2)] * 4).summary()
    assert r["hota"] == pytest.approx(1.0) and r["deta"] == pytest.approx(1.0) and r["assa"] == pytest.approx(1.0)
    # One object, one track, IoU 0.5 in every frame: matched for alpha <= 0.5 (10 of 19 thresholds),
    # where DetA = AssA = 1; LocA = 0.5 there, and 1e-10 / 1e-10 = 1 where nothing matched (TrackEval).
    r = hota([[1]] * 3, [[1]] * 3, [np.array([[0.5]])] * 3)
    assert r.summary()["deta"] == pytest.approx(10 / 19)
    assert r.summary()["hota"] == pytest.approx(10 / 19)
    # Identity switch half-way (4 + 4 frames, IoU 1): DetA = 1; each TP's A(c) = 4 / (8 + 4 - 4) = 0.5.
    frames_g = [[1]] * 8
    frames_t = [[7]] * 4 + [[8]] * 4
    r = hota(frames_g, frames_t, [np.ones((1, 1))] * 8).summary()
    assert r["deta"] == pytest.approx(1.0) and r["assa"] == pytest.approx(0.5)
    assert r["hota"] == pytest.approx(math.sqrt(0.5))
    # No tracks at all: every object a miss, HOTA 0, LocA 1 (TrackEval's convention).
    r = hota([[1], [1, 2]], [[], []], [np.zeros((1, 0)), np.zeros((2, 0))])
    assert r.fn.tolist() == [3.0] * 19 and r.summary()["hota"] == 0.0 and r.summary()["loca"] == 1.0


def test_round_trip_through_dict():
    r = hota([[1, 2], [1]], [[3], [3, 4]], [np.array([[0.7], [0.2]]), np.array([[0.9, 0.1]])])
    back = HotaResult.from_dict(json.loads(json.dumps(r.to_dict())))
    assert back.summary() == pytest.approx(r.summary())


def test_duplicate_ids_in_a_frame_are_refused():
    with pytest.raises(ValueError, match="twice"):
        hota([[1, 1]], [[2]], [np.ones((2, 1))])


# ------------------------------------------------------------------ in the harness's scoring
def test_mot_scorer_hota_by_hand():
    """The id-switch case of test_scoring: 4 frames, tracks 7, 8, 8, then a miss (IoU 1)."""
    from harness.scoring.mot import MotScorer

    s = MotScorer()
    b = [(0, 0, 10, 10)]
    for tracks in ([7], [8], [8], []):
        s.update([1], b, [True], tracks, b[:len(tracks)])
    r = s.hota_result().summary()
    # TP 3, FN 1: DetA 3/4. A(c): pair (1, 7) 1 / (4 + 1 - 1); pair (1, 8) 2 / (4 + 2 - 2), weighted by TPs.
    assa = (1 * 0.25 + 2 * 0.5) / 3
    assert r["deta"] == pytest.approx(0.75) and r["assa"] == pytest.approx(assa)
    assert r["hota"] == pytest.approx(math.sqrt(0.75 * assa))


def test_mot_scorer_hota_skips_ignored_objects_and_the_tracks_on_them():
    from harness.scoring.mot import MotScorer

    s = MotScorer()
    gt = [(0, 0, 10, 10), (20, 0, 30, 10)]
    s.update([1, 2], gt, [True, False], [5, 6], gt)           # track 6 sits on the ignored object
    s.update([1, 2], gt, [True, False], [5], gt[:1])
    r = s.hota_result()
    assert r.tp.tolist() == [2.0] * 19 and r.fp.tolist() == [0.0] * 19 and r.fn.tolist() == [0.0] * 19


def test_evaluate_reports_hota_and_bench_pools_it_like_trackeval(ref):
    from harness.bench.trackers import pooled_tracking
    from harness.scoring.evaluate import EvalConfig, evaluate
    from monorarp.core.types import FrameResult, RiskEstimate, Track

    box = [100.0, 100.0, 140.0, 130.0]
    from harness.world.truth import FrameTruth

    truths = [FrameTruth.from_json({"frame": k, "t": k / 10, "ego": {"speed": 20.0},
                                    "objects": [{"id": 1, "box": box, "visibility": 1.0, "d_long": 15.0, "d_lat": 0.0,
                                                 "v_long": 0.0, "v_lat": 0.0, "ttc": None}]}) for k in range(3)]
    results = [FrameResult(index=k, t=k / 10, detections=[], tracks=[Track(4, tuple(box))], states={},
                           risk=RiskEstimate(0.0, {})) for k in range(3)]
    t = evaluate(truths, results, EvalConfig())[0]["tracking"]
    assert t["hota"] == pytest.approx(1.0) and t["deta"] == pytest.approx(1.0) and t["assa"] == pytest.approx(1.0)
    assert len(t["hota_by_alpha"]["tp"]) == 19

    # Pooling per-sequence sections (as `monorarp bench trackers` does) = TrackEval's COMBINED_SEQ.
    mot = ref["mot"]
    for tracker, per_seq in mot["hota"].items():
        sections = [{"objects": 1, "false_positives": 0, "misses": 0, "id_switches": 0, "idr": 1.0,
                     "hota_by_alpha": _sequence_hota(d["gt"], d["trackers"][tracker], mot["frames"][s]).to_dict()}
                    for s, d in mot["sequences"].items()]
        pooled = pooled_tracking(sections)
        for k in ("HOTA", "DetA", "AssA"):
            assert pooled[k.lower()] == pytest.approx(per_seq["COMBINED_SEQ"][k], abs=TOL)
