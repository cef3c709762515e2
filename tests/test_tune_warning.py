"""scripts/tune_warning.py: a parameter set is scored with the scorecard's rules (trials, false alarms per hour)."""

import sys
from pathlib import Path
from types import SimpleNamespace

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "scripts"))

from tune_warning import grid_points, score_grid_point  # noqa: E402


def _trial(kind, test="T", required=None):
    return SimpleNamespace(kind=kind, test=test, key=f"{test}__k", trial=0, required_ttc_s=required)


def test_a_grid_point_is_scored_as_the_scorecard_scores():
    trials = [_trial("rear_end", "LVS", 2.1), _trial("rear_end", "LVS", 2.1), _trial("pass_by", "PassBy"),
              _trial("nominal", "Nominal"), _trial("nominal", "Nominal")]
    fa = {"false_alarm": True, "why": "far box"}
    metrics = [{"first_warning_ttc_s": 2.5, "episodes": 1}, {"first_warning_ttc_s": 1.9, "episodes": 1},
               {"first_warning_ttc_s": None, "episodes": 0},
               {"episode_list": [fa, {"false_alarm": False, "why": ""}], "exposure_s": 1800.0},
               {"episode_list": [fa], "exposure_s": 1800.0}]
    lines = score_grid_point(trials, metrics, why=True)
    assert lines[0] == "trials passed 2/3"               # 2.5 >= 2.1 passes, 1.9 fails; the pass-by never warned
    assert lines[1] == "false alarms 2 (2.0/h over 1.00 h)"
    assert lines[2] == "LVS:2.5 LVS:1.9 PassBy:-"
    assert lines[3:] == ["  Nominal__k seed 0: far box"] * 2
    assert score_grid_point(trials[:1], metrics[:1], why=False)[1] == "false alarms 0 (no nominal runs)"


def test_grid_points_are_the_product_of_the_axes():
    points = grid_points({"state": {"pixel_std": [0.5, 1.0]}, "warning": {"lateral_sigmas": [2, 3]}})
    assert len(points) == 4 and ({"pixel_std": 1.0}, {"lateral_sigmas": 2}) in points
