"""End to end: simulate -> render -> oracle detector -> pipeline -> scoring, and `monorarp run`.

The noise-free oracle gives the pipeline the exact ground-truth boxes, so
tracking must be perfect and the distance error is only what the box's pixel
rows explain: the bottom edge ``y2`` of a tight box lies within half a pixel of
the row where the vehicle's lowest visible point (rear tyres' contact line, or
the rear bumper's lower edge when very close) projects. The bound is computed
from the camera and the meshes' real dimensions (rear overhang, clearance), so
it includes any mismatch with what the state estimator assumes.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from harness.world.vehicles import vehicle_layout
from harness.run.runner import run_scenario
from harness.run.outputs import OUTPUT_NAMES
from harness.world.scenario import parse_scenario
from harness.scoring.records import read_csv
from monorarp.core.camera import CameraModel
from monorarp.app.cli import main
from monorarp.pipeline import registry
from monorarp.state.estimator import StateEstimator
from monorarp.app.video.writer import read_video
from synthetic import tiny_scenario, vehicle

N_FRAMES = 12
SCENARIO = tiny_scenario("run_test", 3, [vehicle("lead", 0, 12, 22), vehicle("left", -1, 20, 26),
                                          vehicle("right", 1, 27, 24)])
ORACLE = {"detector": {"name": "oracle"}, "tracker": {"name": "particle"},
          "state": {"name": "geometric", "kwargs": {"velocity": "difference"}}}
REQUIRED = ["frames", "distance.rel_err_median", "distance.abs_err_median_m", "lateral.abs_err_median_m",
            "rel_velocity.abs_err_median_mps", "ttc.warning.threshold_s", "ttc.warning.precision",
            "ttc.warning.recall", "tracking.mota", "tracking.idf1", "tracking.id_switches", "detection.precision",
            "detection.recall", "runtime_ms.detector", "runtime_ms.tracker", "runtime_ms.state", "runtime_ms.risk",
            "runtime_ms.total", "fps"]


@pytest.fixture(scope="module")
def scenario():
    return parse_scenario(SCENARIO)


@pytest.fixture(scope="module")
def runs(scenario, tmp_path_factory):
    base = tmp_path_factory.mktemp("runs")
    sync = run_scenario(scenario, ORACLE, n_frames=N_FRAMES, out_dir=base / "sync")
    threaded = run_scenario(scenario, ORACLE, n_frames=N_FRAMES, out_dir=base / "threaded", threaded=True,
                            annotate=False, write_frames=False)
    return base, sync, threaded


def _get(d, dotted):
    for k in dotted.split("."):
        d = d[k]
    return d


def _distance_bound(camera: CameraModel, est: StateEstimator, d_long: float, length: float, width: float) -> float:
    """Largest |d_y - d_long| the estimator can make from a bottom edge within 0.5 px of the true one."""
    lay = vehicle_layout(length, width)
    h = camera.height_m
    contact = camera.project_ego(np.array([0.0, d_long + lay.rear_overhang, -h]))[1]
    bumper = camera.project_ego(np.array([0.0, d_long, -h + lay.clearance]))[1]
    v = max(contact, bumper)                       # the lower of the two in the image is the box bottom
    rows = np.array([v - 0.5, v + 0.5])
    d = est.measure(np.stack([np.full(2, camera.cx - 5), rows - 10, np.full(2, camera.cx + 5), rows], 1))[:, 1]
    return float(np.max(np.abs(d - d_long)))


def test_oracle_run_is_perfect_up_to_pixel_quantisation(runs, scenario):
    base, m, _ = runs
    assert m["frames"] == N_FRAMES
    assert m["tracking"]["mota"] == 1.0 and m["tracking"]["idf1"] == 1.0
    assert m["tracking"]["id_switches"] == 0 and m["tracking"]["objects"] == 3 * N_FRAMES
    assert m["detection"]["precision"] == 1.0 and m["detection"]["recall"] == 1.0
    camera = scenario.camera.model()
    est = StateEstimator(camera)
    truth = {(t["frame"], o["id"]): o for t in map(json.loads, (base / "sync/ground_truth.jsonl").open())
             for o in t["objects"]}
    checked = 0
    for r in read_csv(base / "sync" / "per_object.csv"):
        assert r.matched and r.iou == 1.0                       # the oracle's boxes are the truth's
        o = truth[(r.frame, r.gt_id)]
        bound = _distance_bound(camera, est, r.d_long_gt, o["length"], o["width"])
        assert abs(r.d_y_est - r.d_long_gt) <= bound + 1e-9, (r.frame, r.gt_id, r.d_y_est, r.d_long_gt, bound)
        assert bound < 0.06 * r.d_long_gt                        # the bound is not vacuous
        checked += 1
    assert checked == 3 * N_FRAMES
    assert m["distance"]["count"] == checked


def test_threaded_and_sync_give_identical_scores(runs):
    base, sync, threaded = runs

    def strip(m):
        m = json.loads(json.dumps(m, default=float))
        for k in ("runtime_ms", "fps", "wall_time_s"):
            m.pop(k)
        m["config"].pop("threaded")
        return m

    assert strip(sync) == strip(threaded)
    assert (base / "sync/per_object.csv").read_bytes() == (base / "threaded/per_object.csv").read_bytes()
    assert (base / "sync/ground_truth.jsonl").read_bytes() == (base / "threaded/ground_truth.jsonl").read_bytes()


def test_output_files_are_well_formed(runs, scenario):
    base, m, _ = runs
    out = base / "sync"
    assert sorted(p.name for p in out.iterdir()) == sorted(OUTPUT_NAMES)
    metrics = json.loads((out / "metrics.json").read_text(), parse_constant=lambda c: pytest.fail(f"non-JSON {c}"))
    for key in REQUIRED:
        v = _get(metrics, key)
        assert v is None or isinstance(v, (int, float)), key
    for b in ("0-10", "10-20", "20-40", "40-80"):
        assert set(metrics["distance"]["by_range"][b]) >= {"rel_err_median", "count"}
    assert metrics["distance"]["by_range"]["40-80"]["rel_err_median"] is None       # nothing that far
    assert metrics["config"]["scenario"] == "run_test" and metrics["config"]["components"]["detector"] == "oracle"
    assert CameraModel.load(out / "camera.json") == scenario.camera.model()
    assert len((out / "ground_truth.jsonl").read_text().splitlines()) == N_FRAMES
    for name in ("frames.mp4", "annotated.mp4"):
        frames = list(read_video(out / name))
        assert len(frames) == N_FRAMES and frames[0].image.shape[:2] == (180, 320)
    # The annotation is drawn: annotated frames differ from the plain ones.
    plain, ann = next(read_video(out / "frames.mp4")), next(read_video(out / "annotated.mp4"))
    assert np.abs(plain.image.astype(int) - ann.image.astype(int)).mean() > 1.0
    header = (out / "per_object.csv").read_text().splitlines()[0].split(",")
    assert {"frame", "t", "gt_id", "track_id", "d_long_gt", "d_y_est", "ttc_gt", "ttc_est", "iou"} <= set(header)


# --------------------------------------------------------------------------- the command
@pytest.fixture()
def scenario_file(tmp_path):
    import yaml

    p = tmp_path / "s.yaml"
    p.write_text(yaml.safe_dump(SCENARIO))
    return p


@pytest.mark.parametrize("extra, message", [
    (["--detector", "oracle", "--tracker", "no_such_tracker"], "unknown tracker 'no_such_tracker'"),
    (["--detector", "missing_model.onnx"], "missing_model.onnx: model file not found"),
    (["--detector", "centernet", "--oracle-jitter", "1"], "need --detector oracle"),
    (["--detector", "oracle", "--oracle-miss-rate", "2"], "miss rate"),
    (["--detector", "oracle", "--refine-bottom", "on"], "--refine-bottom applies to the CenterNet detector"),
    (["--frames", "0"], "--frames"),
    (["--frames", "16"], "--frames: 16 exceeds the scenario's 15 frames (duration_s * fps)"),   # 1 s x 15 fps
])
def test_bad_input_exits_2_and_writes_nothing(scenario_file, tmp_path, capsys, extra, message):
    out = tmp_path / "out"
    rc = main(["run", str(scenario_file), "--out", str(out), *extra])
    assert rc == 2
    err = capsys.readouterr().err.strip()
    assert message in err and len(err.splitlines()) == 1
    assert not out.exists()


def test_bad_scenario_exits_2(tmp_path, capsys):
    p = tmp_path / "bad.yaml"
    p.write_text("name: x\ncamera: {width: -3}\n")
    assert main(["run", str(p), "--out", str(tmp_path / "o")]) == 2
    assert "camera.width" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


class _Failing:
    def __init__(self):
        self.n = 0

    def detect(self, image):
        self.n += 1
        if self.n == 4:
            raise RuntimeError("boom")
        return []


def test_failure_midway_leaves_nothing(scenario, tmp_path, request):
    registry.add("detector", "_test_fails_on_frame_3", _Failing)
    request.addfinalizer(lambda: registry.remove("detector", "_test_fails_on_frame_3"))
    out = tmp_path / "out"
    with pytest.raises(RuntimeError, match="boom"):
        run_scenario(scenario, {"detector": {"name": "_test_fails_on_frame_3"}}, n_frames=6, out_dir=out)
    assert not out.exists() and list(tmp_path.iterdir()) == []


def test_cli_run_prints_summary(scenario_file, tmp_path, capsys):
    out = tmp_path / "cli"
    assert main(["run", str(scenario_file), "--detector", "oracle", "--frames", "4", "--no-video",
                 "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "TABLE II" in text and "MOTA" in text and "20-40 m" in text
    assert sorted(p.name for p in out.iterdir()) == ["camera.json", "ground_truth.jsonl", "metrics.json",
                                                     "per_frame.csv", "per_object.csv"]
    assert json.loads((out / "metrics.json").read_text())["frames"] == 4
    assert not math.isnan(json.loads((out / "metrics.json").read_text())["tracking"]["mota"])


# ------------------------------------------------------------------ lane speed and risk scoring
def test_lane_speed_and_risk_scored_on_a_braking_lead(tmp_path):
    """lead_braking with the brake at 1 s, 4 s at 320x180, non-US markings (3 m every 9 m)."""
    from pathlib import Path

    import yaml

    d = yaml.safe_load((Path(__file__).resolve().parents[1] / "scenarios" / "lead_braking.yaml").read_text())
    d.update(duration_s=4.0, camera={"width": 320, "height": 180})
    d["road"]["markings"] = {"stripe_length_m": 3.0, "period_m": 9.0}
    d["events"][0]["at_s"] = 1.0
    sc = parse_scenario(d)
    cfg = {**ORACLE, "risk": {"name": "monte_carlo", "kwargs": {"n_rollouts": 100}},
           "ego_speed": {"name": "ground_track"}}
    m = run_scenario(sc, cfg, out_dir=tmp_path / "o", annotate=False, write_frames=False, gps_speed=True)
    for key in ["lane_speed.rel_err_median", "lane_speed.abs_err_median_mps", "lane_speed.valid_fraction",
                "risk.auroc", "risk.brier", "risk.baseline_ttc.auroc", "risk.baseline_ttc.brier",
                "runtime_ms.ego_speed"]:
        _get(m, key)
    ls, rk = m["lane_speed"], m["risk"]
    # The estimator was told the scenario's markings; with the US period (12.19 m) it would read 35% fast.
    assert m["config"]["component_kwargs"]["ego_speed"]["period_m"] == 9.0
    assert ls["method"] == "ground_track" and ls["valid_fraction"] > 0.5
    assert ls["rel_err_median"] < 0.05
    assert rk["positives"] > 0 and rk["frames_scored"] + rk["excluded_past_end"] == m["frames"] == 60
    assert 0.0 <= rk["brier"] <= 1.0 and 0.0 <= rk["baseline_ttc"]["brier"] <= 1.0
    assert rk["kind"] == "probability" and rk["baseline_ttc"]["kind"] == "inverse_ttc"
    assert sum(rk["ego_speed_sources"].values()) == 60 and rk["ego_speed_sources"]["risk_default"] == 0
    rows = (tmp_path / "o" / "per_frame.csv").read_text().splitlines()
    assert rows[0].split(",")[:4] == ["frame", "t", "ego_speed_est", "ego_speed_gt"] and len(rows) == 61
    # The near miss is in the ground truth: the frames just before it are labelled positive.
    col = rows[0].split(",").index("risk_label")
    labels = [r.split(",")[col] for r in rows[1:]]
    assert labels[-1] == "1"
