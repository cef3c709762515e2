"""`monorarp check`: baseline comparison, exit codes, --update, and the committed CI baseline."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from harness.check.baseline import DEFAULT_RULES, judge, load_baseline
from harness.sweep.expand import load_and_expand
from monorarp.app.cli import main

ROOT = Path(__file__).resolve().parent.parent


def sweep_dir(tmp: Path, runs: dict[str, dict], failed: dict[str, str] | None = None) -> Path:
    d = tmp / "sweep"
    d.mkdir(exist_ok=True)
    rows = [{"id": rid, "status": "ok", "error": None, "metrics": m} for rid, m in runs.items()]
    rows += [{"id": rid, "status": "failed", "error": e, "metrics": {}} for rid, e in (failed or {}).items()]
    (d / "summary.json").write_text(json.dumps({"version": 1, "runs": rows}))
    return d


def baseline(tmp: Path, runs: dict, **extra) -> Path:
    p = tmp / "baseline.json"
    p.write_text(json.dumps({"version": 1, "runs": runs, **extra}))
    return p


METRICS = {"distance.rel_err_median": 0.020, "tracking.mota": 0.95, "frames": 60, "ttc.warning.precision": None,
           "runtime_ms.total": 3.0, "fps": 300.0}
BASE = {"r1": {"distance.rel_err_median": {"value": 0.020, "tolerance": 0.005, "direction": "lower_is_better"},
               "tracking.mota": {"value": 0.95, "tolerance": 0.02, "direction": "higher_is_better"},
               "frames": {"value": 60, "tolerance": 0, "direction": "two_sided"},
               "ttc.warning.precision": {"value": None, "tolerance": 0.05, "direction": "higher_is_better"}}}


def check(*args) -> int:
    return main(["check", *map(str, args)])


def test_identical_metrics_pass(tmp_path, capsys):
    assert check(sweep_dir(tmp_path, {"r1": METRICS}), "--baseline", baseline(tmp_path, BASE)) == 0
    out = capsys.readouterr().out
    assert "check: OK" in out and "distance.rel_err_median" in out


@pytest.mark.parametrize("metric, value, code", [
    ("distance.rel_err_median", 0.0249, 0),    # worse, within tolerance 0.005
    ("distance.rel_err_median", 0.0251, 1),    # worse beyond tolerance
    ("distance.rel_err_median", 0.0100, 0),    # better: "improved", passes
    ("tracking.mota", 0.931, 0),
    ("tracking.mota", 0.929, 1),               # higher_is_better: a drop beyond 0.02 fails
    ("tracking.mota", 1.0, 0),
    ("frames", 59, 1),                         # two_sided, tolerance 0
    ("frames", 61, 1),
    ("ttc.warning.precision", 0.5, 1),         # was null (undefined), now a number: changed
])
def test_tolerances_and_directions(tmp_path, capsys, metric, value, code):
    now = {**METRICS, metric: value}
    assert check(sweep_dir(tmp_path, {"r1": now}), "--baseline", baseline(tmp_path, BASE)) == code
    out = capsys.readouterr().out
    if code:
        assert "REGRESSION" in out and metric in out.split("REGRESSION")[1]


def test_judge_against_hand_cases():
    assert judge(1.0, 1.2, 0.1, "lower_is_better") == "REGRESSED"
    assert judge(1.0, 0.8, 0.1, "lower_is_better") == "improved"
    assert judge(1.0, 0.8, 0.1, "higher_is_better") == "REGRESSED"
    assert judge(1.0, 1.05, 0.1, "two_sided") == "ok"
    assert judge(None, None, 0.1, "two_sided") == "ok"
    assert judge(1.0, None, 0.1, "lower_is_better") == "changed"


def test_relative_tolerance_and_default_rules(tmp_path):
    base = {"r1": {"distance.rel_err_median": {"value": 0.2, "tolerance": 0.001, "rel_tolerance": 0.1,
                                               "direction": "lower_is_better"},
                   "tracking.idf1": {"value": 0.9}}}          # tolerance/direction from DEFAULT_RULES (0.02, higher)
    assert check(sweep_dir(tmp_path, {"r1": {"distance.rel_err_median": 0.219, "tracking.idf1": 0.881}}),
                 "--baseline", baseline(tmp_path, base)) == 0
    assert check(sweep_dir(tmp_path, {"r1": {"distance.rel_err_median": 0.221, "tracking.idf1": 0.9}}),
                 "--baseline", baseline(tmp_path, base)) == 1
    assert check(sweep_dir(tmp_path, {"r1": {"distance.rel_err_median": 0.2, "tracking.idf1": 0.879}}),
                 "--baseline", baseline(tmp_path, base)) == 1


def test_missing_and_failed_runs_are_listed(tmp_path, capsys):
    base = {**BASE, "r2": BASE["r1"], "r3": BASE["r1"]}
    res = sweep_dir(tmp_path, {"r1": METRICS, "r4": METRICS}, failed={"r3": "RuntimeError: boom"})
    assert check(res, "--baseline", baseline(tmp_path, base)) == 1
    out = capsys.readouterr().out
    assert "r2" in out and "missing-run" in out
    assert "run-failed" in out and "boom" in out
    assert "not in the baseline" in out and "r4" in out
    # a metric the results lack
    now = {k: v for k, v in METRICS.items() if k != "tracking.mota"}
    assert check(sweep_dir(tmp_path, {"r1": now}), "--baseline", baseline(tmp_path, BASE)) == 1
    assert "missing-metric" in capsys.readouterr().out


@pytest.mark.parametrize("content", [
    "{not json",
    json.dumps({"version": 2, "runs": {}}),
    json.dumps({"version": 1}),
    json.dumps({"version": 1, "runs": {"r1": {"tracking.mota": {"value": 0.9, "tolerance": -1, "direction": "higher_is_better"}}}}),
    json.dumps({"version": 1, "runs": {"r1": {"tracking.mota": {"value": 0.9, "tolerance": 0.1, "direction": "up"}}}}),
    json.dumps({"version": 1, "runs": {"r1": {"tracking.mota": {"tolerance": 0.1}}}}),
    json.dumps({"version": 1, "runs": {"r1": {"some.metric": {"value": 1.0}}}}),   # no tolerance, no rule matches
    json.dumps({"version": 1, "runs": {"r1": {"tracking.mota": {"value": "high"}}}}),
    json.dumps([1, 2]),
])
def test_malformed_baseline_exits_2(tmp_path, capsys, content):
    p = tmp_path / "baseline.json"
    p.write_text(content)
    assert check(sweep_dir(tmp_path, {"r1": METRICS}), "--baseline", p) == 2
    err = capsys.readouterr().err
    assert str(p) in err and len(err.strip().splitlines()) == 1


def test_bad_results_exit_2(tmp_path, capsys):
    b = baseline(tmp_path, BASE)
    assert check(tmp_path / "nope", "--baseline", b) == 2
    (tmp_path / "empty").mkdir()
    assert check(tmp_path / "empty", "--baseline", b) == 2
    assert check(sweep_dir(tmp_path, {"r1": METRICS}), "--baseline", tmp_path / "missing.json") == 2
    assert "no such baseline" in capsys.readouterr().err


def test_baseline_path_that_is_a_directory_or_under_a_file(tmp_path, capsys):
    results = sweep_dir(tmp_path, {"r1": METRICS})
    (tmp_path / "adir").mkdir()
    (tmp_path / "afile").write_text("x")
    for update in ([], ["--update"]):
        assert check(results, "--baseline", tmp_path / "adir", *update) == 2
        assert "not a file (a baseline is one JSON file)" in capsys.readouterr().err
    assert check(results, "--baseline", tmp_path / "afile" / "b.json", "--update") == 2
    assert f"{tmp_path / 'afile'} is not a directory" in capsys.readouterr().err
    assert (tmp_path / "afile").read_text() == "x" and not any((tmp_path / "adir").iterdir())


def test_single_run_directory(tmp_path):
    run = tmp_path / "r1"
    run.mkdir()
    (run / "metrics.json").write_text(json.dumps({"distance": {"rel_err_median": 0.02}, "tracking": {"mota": 0.95},
                                                  "frames": 60, "ttc": {"warning": {"precision": None}},
                                                  "config": {"scenario": "x"}}))
    assert check(run, "--baseline", baseline(tmp_path, BASE)) == 0
    (run / "run.json").write_text(json.dumps({"id": "other"}))    # run.json's id wins over the dir name
    assert check(run, "--baseline", baseline(tmp_path, BASE)) == 1


def test_update_keeps_tolerances_and_is_atomic(tmp_path, capsys):
    custom = {"r1": {"tracking.mota": {"value": 0.5, "tolerance": 0.123, "direction": "higher_is_better"},
                     "custom.metric": {"value": 1.0, "tolerance": 0.5, "direction": "two_sided"}}}
    b = baseline(tmp_path, custom)
    now = {**METRICS, "custom.metric": 2.0, "tracking.idf1": 0.9, "distance.by_range.0-10.rel_err_median": 0.03}
    res = sweep_dir(tmp_path, {"r1": now, "r2": METRICS})
    assert check(res, "--baseline", b, "--update") == 0
    new = json.loads(b.read_text())
    r1 = new["runs"]["r1"]
    assert r1["tracking.mota"] == {"value": 0.95, "tolerance": 0.123, "direction": "higher_is_better"}
    assert r1["custom.metric"]["value"] == 2.0 and r1["custom.metric"]["tolerance"] == 0.5
    assert r1["tracking.idf1"]["direction"] == "higher_is_better"
    assert "distance.by_range.0-10.rel_err_median" in r1
    assert not any(k.startswith("runtime_ms") or k == "fps" for k in r1)     # wall-clock metrics never baselined
    assert set(new["runs"]) == {"r1", "r2"}
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []
    assert check(res, "--baseline", b) == 0                                   # the new baseline holds
    # a sweep with a failed run does not overwrite the baseline
    before = b.read_text()
    assert check(sweep_dir(tmp_path, {"r1": now}, failed={"r2": "x"}), "--baseline", b, "--update") == 1
    assert b.read_text() == before


def test_committed_baseline_matches_the_ci_sweep():
    base = load_baseline(ROOT / "results" / "baseline.json")
    ids = {t.id for t in load_and_expand(ROOT / "scenarios" / "ci.yaml").tasks}
    assert set(base["runs"]) == ids
    for rid, metrics in base["runs"].items():
        assert "distance.rel_err_median" in metrics and "tracking.mota" in metrics, rid
        assert not any(k.startswith("runtime_ms") or k == "fps" for k in metrics)
    assert any(m["ttc.warning.recall"]["value"] is not None for m in base["runs"].values())   # a risky scenario
    assert {r.metric for r in DEFAULT_RULES} >= {"tracking.mota", "tracking.idf1", "distance.rel_err_median"}


def test_default_baseline_is_said_to_be_relative_to_the_current_directory(capsys):
    with pytest.raises(SystemExit):
        main(["check", "--help"])
    assert "results/baseline.json, relative to the current directory" in " ".join(capsys.readouterr().out.split())
