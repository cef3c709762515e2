"""scripts/replay_risk.py: the adverse-manoeuvre risk replayed from a run's per-object states equals the
estimator on those states, and is pooled with the scorecard's labels."""

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "scripts"))

from replay_risk import frame_states, replay  # noqa: E402

from monorarp.core.camera import CameraModel  # noqa: E402
from monorarp.risk.estimators import ManoeuvreTTCRisk  # noqa: E402
from monorarp.core.types import ObjectState  # noqa: E402

CAM = CameraModel.from_fov(640, 360, 60, 1.3, forward_offset_m=0.5)
OBJ_COLS = "frame,t,gt_id,track_id,d_long_gt,d_y_est,d_lat_gt,d_x_est,v_long_gt,v_y_est,v_lat_gt,v_x_est,expansion_rate,expansion_rate_std"


def _run(root: Path, name: str, closing: float) -> Path:
    """A 20-frame run at 10 fps: a lead 20 m ahead closing at ``closing`` m/s (estimated 10 % fast),
    its looming rate true (with a sigma over the risk's 0.5 /s bound in the first 3 frames, a young
    filter's), a car in the next lane, and a collision in the last frame."""
    d = root / name
    d.mkdir(parents=True)
    (d / "camera.json").write_text(json.dumps(CAM.to_dict()))
    rows = ["frame,t,risk,risk_kind,baseline_ttc_risk,fcw_ttc_risk,manoeuvre_ttc_risk,risk_event,true_min_ttc"]
    obj = [OBJ_COLS]
    for k in range(20):
        d_lead = 20.0 - closing * k / 10
        rows.append(f"{k},{k / 10},0.1,inverse_ttc,,0.0,,{int(k == 19)},")
        obj.append(f"{k},{k / 10},1,7,{d_lead},{d_lead},0.0,0.1,{-closing},{-1.1 * closing},0.0,0.2,{closing / d_lead},"
                   f"{0.8 if k < 3 else 0.05}")
        obj.append(f"{k},{k / 10},2,,12.0,,3.5,,0.0,,0.0,,,")          # seen in truth only
    (d / "per_frame.csv").write_text("\n".join(rows) + "\n")
    (d / "per_object.csv").write_text("\n".join(obj) + "\n")
    return d


def test_the_replayed_risk_is_the_estimator_on_the_runs_states(tmp_path):
    d = _run(tmp_path / "runs", "risk__Brake__t0", closing=4.0)
    est = frame_states(d, 20)
    assert est[3] == {7: ObjectState(7, 0.1, 18.8, 0.2, -4.4, expansion_rate=4.0 / 18.8, expansion_rate_std=0.05)}
    truth = frame_states(d, 20, truth=True)
    assert set(truth[3]) == {1, 2} and truth[3][2].d_x == 3.5 and truth[3][1].expansion_rate is None
    (run,) = replay(tmp_path / "runs", [(4.0, 1.0, 0.6, 0.5), (0.0, 0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 0.5)])
    times = np.arange(20) / 10
    stage = ManoeuvreTTCRisk(hold_s=0.6, camera=CAM)
    np.testing.assert_allclose(run["manoeuvre_b4_l1_h0.6_w0.5"], [stage.assess(s, t).risk for s, t in zip(est, times)])
    # no manoeuvre: the constant-velocity 1/TTC of a lead read closing at 4.4 m/s, its rear at 20 - 0.4 k m,
    # the ego's front 4.5 / 2 - 0.5 m ahead of the camera
    gap = 20.0 - 0.4 * np.arange(20) - (4.5 / 2 - 0.5)
    np.testing.assert_allclose(run["manoeuvre_b0_l0_h0_w0"], 4.4 / gap)
    mixed = np.where(np.arange(20) < 3, 4.4, 4.2)   # half the filter's, half the looming's 4.0; the filter's alone first
    np.testing.assert_allclose(run["manoeuvre_b0_l0_h0_w0.5"], mixed / gap)
    (unbounded,) = replay(tmp_path / "runs", [(0.0, 0.0, 0.0, 0.5, None), (0.0, 0.0, 0.0, 0.5, 1.0)])
    np.testing.assert_allclose(unbounded["manoeuvre_b0_l0_h0_w0.5_snone"], 4.2 / gap)   # the young rate used too
    np.testing.assert_allclose(unbounded["manoeuvre_b0_l0_h0_w0.5_s1"], 4.2 / gap)
    (true_run,) = replay(tmp_path / "runs", [(4.0, 1.0, 0.6, 0.5)], truth=True)
    stage.reset()
    np.testing.assert_allclose(true_run["manoeuvre_b4_l1_h0.6_w0.5"], [stage.assess(s, t).risk for s, t in zip(truth, times)])


def test_the_registered_patchs_rate_is_read_and_replayed(tmp_path):
    d = _run(tmp_path / "runs", "risk__Brake__t0", closing=4.0)
    lines = (d / "per_object.csv").read_text().splitlines()
    reg = [lines[0] + ",registered_rate,registered_rate_std"]
    for line in lines[1:]:      # the patch reads 5 m/s of closing (its rate at the lead's distance), sigma 0.01 /s
        f = line.split(",")
        reg.append(line + (f",{5.0 / float(f[4])},0.01" if f[3] else ",,"))
    (d / "per_object.csv").write_text("\n".join(reg) + "\n")
    est = frame_states(d, 20)
    assert est[3][7].registered_rate == pytest.approx(5.0 / 18.8) and est[3][7].registered_rate_std == 0.01
    (run,) = replay(tmp_path / "runs", [(0.0, 0.0, 0.0, 0.5, 0.5, 0.0), (0.0, 0.0, 0.0, 0.5, 0.5, 0.5)])
    gap = 20.0 - 0.4 * np.arange(20) - (4.5 / 2 - 0.5)
    mixed = np.where(np.arange(20) < 3, 4.4, 4.2)
    np.testing.assert_allclose(run["manoeuvre_b0_l0_h0_w0.5_s0.5_r0"], mixed / gap)
    np.testing.assert_allclose(run["manoeuvre_b0_l0_h0_w0.5_s0.5_r0.5"], (mixed + 5.0) / 2 / gap)


def test_runs_are_split_by_name_and_scored_with_the_scorecards_labels(tmp_path):
    for name, closing in (("risk__Brake__t0", 4.0), ("risk__Brake__t1", 6.0), ("risk__Nominal__seed3", 0.0)):
        _run(tmp_path / "runs", name, closing)
    assert len(replay(tmp_path / "runs", [(4.0, 1.0, 0.6, 0.5)], only="__t0")) == 1
    assert len(replay(tmp_path / "runs", [(4.0, 1.0, 0.6, 0.5)], exclude="__t0")) == 2
    out = subprocess.run([sys.executable, "scripts/replay_risk.py", str(tmp_path / "runs"), "--brake", "4", "6",
                          "--max-std", "0.5", "none", "--registered", "0", "0.5"],
                         capture_output=True, text=True, cwd=Path(__file__).resolve().parents[1], check=True).stdout
    assert out.startswith("3 runs, estimated states") and "manoeuvre_b6_l1_h0.45_w0.5_s0.5" in out and "2s" in out
    assert "manoeuvre_b4_l1_h0.45_w0.5_snone_r0.5" in out and "manoeuvre_b4_l1_h0.45_w0.5_s0.5_r0 " in out


def test_a_missing_folder_is_one_line_and_exit_1(tmp_path):
    p = subprocess.run([sys.executable, "scripts/replay_risk.py", str(tmp_path / "nope")], capture_output=True,
                       text=True, cwd=Path(__file__).resolve().parents[1])
    assert p.returncode == 1 and p.stderr.strip() == f"replay_risk: {tmp_path / 'nope'}: no such folder"


def test_a_run_without_its_files_or_a_bad_setting_is_one_line_and_exit_1(tmp_path):
    d = _run(tmp_path / "runs", "risk__Brake__t0", closing=4.0)
    root = Path(__file__).resolve().parents[1]
    bad = subprocess.run([sys.executable, "scripts/replay_risk.py", str(tmp_path / "runs"), "--brake", "-1"],
                         capture_output=True, text=True, cwd=root)
    assert bad.returncode == 1 and bad.stderr.count("\n") == 1 and "brake_mps2 must be >= 0" in bad.stderr
    (d / "camera.json").unlink()
    gone = subprocess.run([sys.executable, "scripts/replay_risk.py", str(tmp_path / "runs")],
                          capture_output=True, text=True, cwd=root)
    assert gone.returncode == 1 and gone.stderr.count("\n") == 1 and "camera.json" in gone.stderr
