"""The tuning sets share no test point with the suites they are held out from: every conflict trial's
(speeds, gap, deceleration) and every nominal seed of a tuning file is absent from its held-out files."""

from pathlib import Path

import pytest

from harness.scorecard.protocols import expand_protocol, load_protocol

FCW = Path(__file__).resolve().parents[1] / "scenarios" / "fcw"


def _points(name: str) -> tuple[set, set]:
    """(conflict and pass-by points as (speeds, gap, deceleration), nominal (scenario, seed)) of a protocol file."""
    trials = expand_protocol(load_protocol(FCW / name), FCW / name)
    points = {(t.ego_speed_mps, t.target_speed_mps, t.params.get("gap_m"), t.params.get("decel_mps2"))
              for t in trials if t.kind != "nominal"}
    seeds = {(t.params["scenario"], t.trial) for t in trials if t.kind == "nominal"}
    return points, seeds


@pytest.mark.parametrize("tuning, held_out", [
    ("risk_tuning.yaml", ["risk.yaml"]),
    ("tuning.yaml", ["nhtsa.yaml", "ncap.yaml", "cut_in.yaml", "nominal.yaml", "ci.yaml"]),
])
def test_a_tuning_set_shares_no_point_with_what_it_is_held_out_from(tuning, held_out):
    points, seeds = _points(tuning)
    assert points and seeds
    for name in held_out:
        other_points, other_seeds = _points(name)
        assert not points & other_points, (name, sorted(points & other_points)[:3])
        assert not seeds & other_seeds, (name, sorted(seeds & other_seeds)[:3])


def test_the_1080p_check_set_shares_no_seed_with_any_other_protocol():
    _, seeds = _points("nominal_1080p_check.yaml")
    assert len(seeds) == 60
    benchmark = {(t.params["scenario"], t.trial) for t in expand_protocol(
        load_protocol(FCW / "nominal.yaml"), FCW / "nominal.yaml", trials=90)}   # the 2-hour benchmark
    assert not seeds & benchmark
    for name in ("tuning.yaml", "risk_tuning.yaml", "risk.yaml", "ci.yaml"):
        assert not seeds & _points(name)[1], name
