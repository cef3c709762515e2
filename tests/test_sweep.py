"""`monorarp sweep`: spec validation, expansion ids, failure isolation, resume, summary, report, determinism.

Most tests replace :func:`harness.run.runner.run_scenario` by a fast fake (the serial
executor runs in this process); the report and determinism tests make real,
tiny runs (320x180, a few frames).
"""

from __future__ import annotations

import csv
import json
import math
import re
from pathlib import Path

import pytest
import yaml

import harness.run.runner
from harness.world.scenario import parse_scenario
from harness.sweep.expand import format_value, load_and_expand, run_id
from harness.sweep.spec import check_override_path
from harness.check.metrics import deterministic_metrics
from monorarp.app.cli import main

SCENARIO = {
    "name": "tiny", "seed": 0, "duration_s": 1.0, "fps": 15, "road": {"lanes": 3},
    "traffic": {"vehicles_count": 0}, "ego": {"lane": 1, "speed_mps": 25},
    "vehicles": [  # the lead closes at 8 m/s from 13 m: true TTC below 2 s from the start (a risky case)
        {"name": "lead", "lane": 0, "distance_m": 13, "speed_mps": 17, "behaviour": "constant_speed"},
        {"name": "left", "lane": -1, "distance_m": 22, "speed_mps": 26, "behaviour": "constant_speed"}],
    "camera": {"width": 320, "height": 180},
}
ORACLE = {"detector": "oracle", "tracker": "particle"}


def write_case(tmp: Path, spec: dict, scenario: dict = SCENARIO) -> Path:
    (tmp / "tiny.yaml").write_text(yaml.safe_dump(scenario))
    path = tmp / "spec.yaml"
    path.write_text(yaml.safe_dump(spec, sort_keys=False))
    return path


def spec_dict(**kw) -> dict:
    base = {"name": "t", "scenarios": ["tiny.yaml"], "seeds": [1, 2], "frames": 4,
            "grid": {"camera.pitch_deg": [1.0, 2.5]}, "variants": [{"name": "a", **ORACLE}]}
    base.update(kw)
    return base


class FakeRun:
    """Stands in for run_scenario: records calls, writes metrics that depend only on the inputs."""

    def __init__(self, fail_when=None):
        self.calls: list[tuple] = []
        self.fail_when = fail_when

    def __call__(self, scenario, pipeline_config, n_frames=None, out_dir=None, **kw):
        key = (scenario.seed, scenario.camera.pitch_deg, pipeline_config["tracker"]["name"])
        self.calls.append(key)
        if self.fail_when and self.fail_when(*key):
            raise RuntimeError(f"boom for seed {scenario.seed}")
        metrics = {"frames": n_frames, "distance": {"rel_err_median": 0.01 * scenario.seed + scenario.camera.pitch_deg / 100},
                   "runtime_ms": {"total": 1.0}, "fps": 100.0, "config": {"x": 1}}
        out = Path(out_dir)
        (out / "metrics.json").write_text(json.dumps(metrics))
        return metrics


def run_cli(*args: str) -> int:
    return main(["sweep", *map(str, args), "--no-progress"])


# ------------------------------------------------------------------ validation
@pytest.mark.parametrize("change, needle", [
    ({"colour": "red"}, "colour"),
    ({"grid": {"camera.pich_deg": [1]}}, "pich_deg"),
    ({"overrides": {"traffic.idm.nope": 1}}, "nope"),
    ({"variants": [{"name": "a", "detector": "oracle", "tracker": "no_such_tracker"}]}, "no_such_tracker"),
    ({"variants": [{"name": "a", "detector": "oracle", "risk": "nope_risk"}]}, "nope_risk"),
    ({"variants": [{"name": "a", "detector": "missing_model.onnx"}]}, "missing_model.onnx"),
    ({"variants": [{"name": "a", "detector": "oracle", "tracker_kwargs": {"bogus_kw": 1}}]}, "bogus_kw"),
    ({"scenarios": ["tiny.yaml", "no_such_scenario.yaml"]}, "no_such_scenario.yaml"),
    ({"seeds": [1, 1]}, "seeds"),
    ({"seeds": [-1]}, "seeds.0: Input should be greater than or equal to 0"),
    ({"seeds": [True]}, "seeds.0: Input should be a valid integer"),
    ({"seeds": ["7"]}, "seeds.0: Input should be a valid integer"),
    ({"frames": 0}, "frames"),
    ({"grid": {"vehicles.nobody.speed_mps": [10]}}, "nobody"),
])
def test_bad_spec_exits_2_before_any_run(tmp_path, monkeypatch, capsys, change, needle):
    fake = FakeRun()
    monkeypatch.setattr(harness.run.runner, "run_scenario", fake)
    spec = write_case(tmp_path, spec_dict(**change))
    out = tmp_path / "out"
    assert run_cli(spec, "--out", out) == 2
    err = capsys.readouterr().err
    assert needle in err and str(spec) in err
    assert len(err.strip().splitlines()) == 1          # one line, no traceback
    assert fake.calls == [] and not out.exists()


def test_duplicate_key_in_spec_exits_2_before_any_run(tmp_path, monkeypatch, capsys):
    fake = FakeRun()
    monkeypatch.setattr(harness.run.runner, "run_scenario", fake)
    spec = write_case(tmp_path, spec_dict())
    spec.write_text(spec.read_text() + "frames: 6\n")   # spec_dict() already has frames: 4
    line = len(spec.read_text().splitlines())
    out = tmp_path / "out"
    assert run_cli(spec, "--out", out) == 2
    err = capsys.readouterr().err
    assert f"{spec}: invalid YAML at line {line}: duplicate key 'frames'" in err
    assert len(err.strip().splitlines()) == 1 and fake.calls == [] and not out.exists()


def test_override_paths_follow_the_schema():
    for ok in ("camera.pitch_deg", "traffic.vehicles_count", "road.markings.period_m", "vehicles.0.speed_mps",
               "vehicles.lead.distance_m", "events.0.at_s", "events.0.decel_mps2", "traffic.speed_range_mps.1"):
        check_override_path(ok)
    for bad in ("camera.pitch", "cameras.pitch_deg", "camera.pitch_deg.x", "traffic.speed_range_mps.2", "", "a..b"):
        with pytest.raises(ValueError):
            check_override_path(bad)


def test_out_dir_with_other_content_is_refused(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(harness.run.runner, "run_scenario", FakeRun())
    spec = write_case(tmp_path, spec_dict())
    (tmp_path / "out").mkdir()
    (tmp_path / "out" / "mine.txt").write_text("x")
    assert run_cli(spec, "--out", tmp_path / "out") == 2
    assert "--resume" in capsys.readouterr().err


# ------------------------------------------------------------------- expansion
def test_ids_are_readable_stable_and_ordered(tmp_path):
    spec = write_case(tmp_path, spec_dict(variants=[{"name": "a", **ORACLE}, {"name": "k", "detector": "oracle",
                                                                            "tracker": "kcf"}]))
    ids = [t.id for t in load_and_expand(spec).tasks]
    assert ids == ["tiny__seed1__camera.pitch_deg=1__a", "tiny__seed1__camera.pitch_deg=1__k",
                   "tiny__seed1__camera.pitch_deg=2.5__a", "tiny__seed1__camera.pitch_deg=2.5__k",
                   "tiny__seed2__camera.pitch_deg=1__a", "tiny__seed2__camera.pitch_deg=1__k",
                   "tiny__seed2__camera.pitch_deg=2.5__a", "tiny__seed2__camera.pitch_deg=2.5__k"]
    # growing the spec keeps every existing id
    spec2 = write_case(tmp_path, spec_dict(seeds=[3, 1, 2], variants=[{"name": "a", **ORACLE}, {"name": "k", "detector": "oracle",
                                                                                                "tracker": "kcf"}]))
    assert set(ids) < {t.id for t in load_and_expand(spec2).tasks}
    assert format_value(12.19) == "12.19" and format_value(4.0) == "4" and format_value([20, 25.5]) == "20-25.5"
    assert run_id("a b", 1, {"x.y": "p/q"}, "v") == "a_b__seed1__x.y=p_q__v"


def test_overrides_reach_the_validated_scenario(tmp_path):
    spec = write_case(tmp_path, spec_dict(grid={"vehicles.lead.speed_mps": [12.0, 15.0], "camera.height_m": [1.1]},
                                          overrides={"traffic.vehicles_count": 2}, seeds=[7]))
    tasks = load_and_expand(spec).tasks
    for t, speed in zip(tasks, (12.0, 15.0)):
        s = parse_scenario(t.scenario)
        assert s.seed == 7 and s.vehicles[0].name == "lead" and s.vehicles[0].speed_mps == speed
        assert s.camera.height_m == 1.1 and s.traffic.vehicles_count == 2
        assert t.pipeline["detector"]["kwargs"]["seed"] == 7      # seeded components get the run's seed
    base = yaml.safe_load((tmp_path / "tiny.yaml").read_text())
    assert base["vehicles"][0]["speed_mps"] == 17                 # the file itself is untouched


def test_shipped_sweep_specs_are_valid():
    root = Path(__file__).resolve().parent.parent / "scenarios"
    ls = load_and_expand(root / "lane_speed_sweep.yaml").tasks
    assert len(ls) == 5 * 3 * 2
    assert ls[0].id == "lane_speed__seed0__ego.speed_mps=15__road.markings.period_m=9__lsd_period"
    assert parse_scenario(ls[0].scenario).road.markings.period_m == 9.0
    ci = load_and_expand(root / "ci.yaml").tasks
    assert {t.variant for t in ci} == {"particle", "kcf"} and len({t.seed for t in ci}) == 2
    brake = next(t for t in ci if t.scenario_key == "lead_braking")
    assert parse_scenario(brake.scenario).events[0].at_s == 1.0


# ------------------------------------------------------- failures, resume, CSV
def test_failing_runs_are_recorded_and_others_finish(tmp_path, monkeypatch, capsys):
    fake = FakeRun(fail_when=lambda seed, pitch, tracker: seed == 2 and pitch == 1.0)
    monkeypatch.setattr(harness.run.runner, "run_scenario", fake)
    # ego.lane 5 does not exist on the 3-lane road: caught when that combination is validated
    spec = write_case(tmp_path, spec_dict(grid={"camera.pitch_deg": [1.0, 2.5], "ego.lane": [1, 5]}))
    out = tmp_path / "out"
    assert run_cli(spec, "--out", out) == 1
    rows = list(csv.DictReader((out / "summary.csv").open()))
    assert len(rows) == 8 and len(fake.calls) == 4                 # the 4 invalid combinations never ran
    status = {r["id"]: r for r in rows}
    boom = status["tiny__seed2__camera.pitch_deg=1__ego.lane=1__a"]
    assert boom["status"] == "failed" and "boom for seed 2" in boom["error"]
    bad = status["tiny__seed1__camera.pitch_deg=2.5__ego.lane=5__a"]
    assert bad["status"] == "failed" and "ego.lane" in bad["error"]
    ok = [r for r in rows if r["status"] == "ok"]
    assert len(ok) == 3
    for r in ok:   # the CSV carries metrics.json's numbers and the run's parameters
        m = json.loads((out / "runs" / r["id"] / "metrics.json").read_text())
        assert float(r["distance.rel_err_median"]) == m["distance"]["rel_err_median"]
        assert float(r["grid.camera.pitch_deg"]) in (1.0, 2.5) and r["grid.ego.lane"] == "1"
        assert "config.x" not in r
        run = json.loads((out / "runs" / r["id"] / "run.json").read_text())
        assert run["status"] == "ok" and run["params"]["seed"] == int(r["seed"])
    err = json.loads((out / "runs" / boom["id"] / "error.json").read_text())
    assert "RuntimeError" in err["error"] and "Traceback" in err["traceback"]
    assert not (out / "runs" / boom["id"] / "metrics.json").exists()
    summary = json.loads((out / "summary.json").read_text())
    assert summary["counts"] == {"runs": 8, "ok": 3, "failed": 5, "missing": 0}
    assert "FAILED tiny__seed2__camera.pitch_deg=1__ego.lane=1__a" in capsys.readouterr().out
    assert not [p for p in out.rglob(".*")]                         # no temporary leftovers


def test_resume_skips_finished_runs(tmp_path, monkeypatch):
    first = FakeRun(fail_when=lambda seed, pitch, tracker: seed == 1 and pitch == 2.5)
    monkeypatch.setattr(harness.run.runner, "run_scenario", first)
    spec = write_case(tmp_path, spec_dict())
    out = tmp_path / "out"
    assert run_cli(spec, "--out", out) == 1 and len(first.calls) == 4
    second = FakeRun()
    monkeypatch.setattr(harness.run.runner, "run_scenario", second)
    assert run_cli(spec, "--out", out, "--resume") == 0
    assert second.calls == [(1, 2.5, "particle")]                  # only the failed run again
    assert run_cli(spec, "--out", out, "--resume") == 0 and len(second.calls) == 1
    # a changed variant (same name, other parameters) is not "finished": it runs again
    spec = write_case(tmp_path, spec_dict(variants=[{"name": "a", "detector": "oracle", "tracker": "particle",
                                                     "velocity": "difference"}]))
    assert run_cli(spec, "--out", out, "--resume") == 0 and len(second.calls) == 5


def test_resume_refuses_runs_the_spec_does_not_have(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(harness.run.runner, "run_scenario", FakeRun())
    out = tmp_path / "out"
    assert run_cli(write_case(tmp_path, spec_dict()), "--out", out) == 0
    before = sorted(p.name for p in (out / "runs").iterdir())
    assert len(before) == 4
    assert run_cli(write_case(tmp_path, spec_dict(seeds=[1])), "--out", out, "--resume") == 2
    err = capsys.readouterr().err
    assert "2 run(s) not in this spec (tiny__seed2__" in err and len(err.strip().splitlines()) == 1
    assert sorted(p.name for p in (out / "runs").iterdir()) == before      # nothing deleted


def test_spec_metric_in_no_run_is_reported(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(harness.run.runner, "run_scenario", FakeRun())
    spec = write_case(tmp_path, spec_dict(metrics=["distance.rel_err_median", "no.such.metric"]))
    assert run_cli(spec, "--out", tmp_path / "out") == 0
    err = capsys.readouterr().err
    assert "misspelled?" in err and err.strip().endswith(": no.such.metric")


# -------------------------------------------------- real runs: report, workers
@pytest.fixture(scope="module")
def real_sweeps(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("real")
    spec = write_case(tmp, spec_dict(seeds=[1], frames=6, grid={"camera.pitch_deg": [2.0]},
                                     variants=[{"name": "pf", **ORACLE},
                                               {"name": "kcf", "detector": "oracle", "tracker": "kcf"}]))
    assert run_cli(spec, "--out", tmp / "w1", "--workers", "1") == 0
    assert run_cli(spec, "--out", tmp / "w2", "--workers", "2") == 0
    return tmp


def test_report_is_self_contained(real_sweeps):
    html = (real_sweeps / "w1" / "report.html").read_text()
    pngs = re.findall(r'<img alt="plot" src="data:image/png;base64,([A-Za-z0-9+/=]+)"', html)
    assert len(pngs) >= 3       # distance vs range, TTC of the risky case, runtime breakdown
    # no external resource; the images' base64 is left out (it spells "http" by chance, the runtime plot varies)
    text = re.sub(r"base64,[A-Za-z0-9+/=]+", "base64,", html)
    assert "http" not in text.lower() and "<script" not in text and "<link" not in text
    for section in ("Distance error against range", "TTC over time against truth", "Tracker comparison",
                    "Runtime breakdown", "tiny__seed1__camera.pitch_deg=2__kcf"):
        assert section in html
    assert "No case has a true TTC" not in html


def test_one_and_two_workers_give_identical_metrics(real_sweeps):
    def metrics(d):
        return {r["id"]: deterministic_metrics(r["metrics"]) for r in json.loads((d / "summary.json").read_text())["runs"]}

    a, b = metrics(real_sweeps / "w1"), metrics(real_sweeps / "w2")
    assert len(a) == 2 and a == b
    assert all(r["frames"] == 6 and not math.isnan(r["distance.rel_err_median"]) for r in a.values())
    # the excluded metrics are the wall-clock ones only
    full = json.loads((real_sweeps / "w1" / "summary.json").read_text())["runs"][0]["metrics"]
    assert sorted(set(full) - set(deterministic_metrics(full))) == sorted(
        k for k in full if k.startswith("runtime_ms.") or k in ("fps", "wall_time_s"))


def test_report_copes_with_runs_without_objects(tmp_path):
    """A scenario with no vehicles gives a header-only per_object.csv; the report still renders."""
    from harness.scoring.records import COLUMNS
    from harness.sweep.report import render_report

    (tmp_path / "r1").mkdir()
    (tmp_path / "r1" / "per_object.csv").write_text(",".join(COLUMNS) + "\n")
    rows = [{"id": "r1", "scenario": "s", "seed": 0, "grid": {}, "variant": "v", "tracker": "particle",
             "detector": "oracle", "status": "ok", "error": None, "metrics": {"frames": 3, "runtime_ms.total": 1.0}}]
    html = render_report(rows, tmp_path, name="n", spec_path="spec.yaml", grid_keys=[])
    assert "No scored object-frames" in html and "No case has a true TTC" in html


def test_sweep_with_baseline_puts_the_verdict_at_the_top_of_the_report(tmp_path, monkeypatch, capsys):
    """--baseline: OK when the runs match it; a shifted value is REGRESSED, named in the report's top box
    and highlighted in the runs table, and the sweep exits 1; a bad baseline exits 2 before any run."""
    monkeypatch.setattr(harness.run.runner, "run_scenario", FakeRun())
    spec = write_case(tmp_path, spec_dict())
    out = tmp_path / "out"
    assert run_cli(spec, "--out", out) == 0
    base = tmp_path / "base.json"
    assert main(["check", str(out), "--baseline", str(base), "--update"]) == 0
    assert run_cli(spec, "--out", tmp_path / "ok", "--baseline", base) == 0
    page = (tmp_path / "ok" / "report.html").read_text()
    assert "Regression check: OK" in page and page.index("Regression check") < page.index("<h2>Runs</h2>")
    data = json.loads(base.read_text())
    rid = sorted(data["runs"])[0]
    data["runs"][rid]["distance.rel_err_median"]["value"] = -1.0      # now is worse by far more than the slack
    base.write_text(json.dumps(data))
    capsys.readouterr()
    assert run_cli(spec, "--out", tmp_path / "bad", "--baseline", base) == 1
    assert f"{rid}  distance.rel_err_median: REGRESSED" in capsys.readouterr().out
    page = (tmp_path / "bad" / "report.html").read_text()
    top = page[:page.index("<h2>Runs</h2>")]
    assert "REGRESSION: 1 of" in top and rid in top and "distance error, median %" in top
    assert 'class="hl" title="REGRESSED against the baseline' in page
    base.write_text("{")
    assert run_cli(spec, "--out", tmp_path / "never", "--baseline", base) == 2 and not (tmp_path / "never").exists()


def test_report_names_metrics_with_units_highlights_zero_recall_and_dashes_stages_not_run(tmp_path):
    from harness.sweep.labels import display_value, metric_label
    from harness.sweep.report import render_report

    assert metric_label("distance.by_span.5-40.rel_err_median") == "distance error 5–40 m, median %"
    assert metric_label("rel_velocity.abs_err_median_mps") == "closing-speed error, median m/s"
    assert display_value("distance.rel_err_median", 0.05) == pytest.approx(5.0)
    assert display_value("tracking.mota", 0.5) == 0.5
    rows = []
    for v, recall in (("particle", 0.9), ("kcf", 0.0)):
        (tmp_path / v).mkdir()
        (tmp_path / v / "run.json").write_text(json.dumps({"params": {"pipeline": {
            "detector": {"name": "oracle"}, "tracker": {"name": v}, "state": {}, "risk": {}, "ego_speed": None,
            "warning": {}}}}))
        rows.append({"id": v, "scenario": "s", "seed": 0, "grid": {}, "variant": v, "tracker": v, "detector": "oracle",
                     "status": "ok", "error": None,
                     "metrics": {"distance.rel_err_median": 0.0123, "ttc.warning.recall": recall,
                                 "runtime_ms.detector": 2.0, "runtime_ms.ego_speed": 0.0, "runtime_ms.total": 5.0}})
    page = render_report(rows, tmp_path, name="n", spec_path="spec.yaml", grid_keys=[],
                         headline=["distance.rel_err_median", "ttc.warning.recall"])
    runs = page[page.index("<h2>Runs</h2>"):page.index("<h2>Distance")]
    assert "distance error, median %" in runs and "distance.rel_err_median" not in runs and ">1.23<" in runs
    assert runs.count('class="hl"') == 1 and 'title="0: no real threat warned in time">0<' in runs
    assert "Regression check" not in page                      # no baseline given: no verdict
    runtime = page[page.index("<h2>Runtime breakdown"):]
    cells = runtime[runtime.index("<tbody>"):].split("</tr>")[0]
    assert "<td>2</td><td>–</td>" in cells and "a stage the sweep's pipeline does not run (ego_speed)" in runtime
