"""``monorarp eval kitti``: hand-written KITTI files with known answers, KITTI AP against closed forms and
scikit-learn, the round trip ``monorarp export`` -> ``eval kitti --detector labels``, and bad input."""

from __future__ import annotations

import json
import math
from pathlib import Path

import cv2
import numpy as np
import pytest
import yaml

from harness.export import geometry as export_geo
from harness.export.kitti import calib_text
from harness.kitti_eval import geometry as geo
from harness.kitti_eval.reader import KittiInputError, open_dataset, parse_calib, parse_object_labels
from harness.scoring import kitti_ap as kap
from monorarp.app import cli
from monorarp.core.camera import CameraError, CameraModel
from synthetic import write_scenario

ROOT = Path(__file__).resolve().parents[1]
FX, CX, CY = 700.0, 199.5, 74.5          # hand-written camera: 400 x 150 px
W, H = 400, 150


main = cli.main


# ------------------------------------------------------------------------- hand-written data
def kitti_rig_calib(t_x: float = 0.06) -> str:
    """A real-rig-style calibration: P2 = K [I | (t_x, 0, 0)], Velodyne 0.8 m above the IMU, not on the road."""
    K = np.array([[FX, 0, CX], [0, FX, CY], [0, 0, 1.0]])
    P2 = np.hstack([K, (K @ np.array([t_x, 0, 0]))[:, None]])
    velo = np.array([[0, -1, 0, -0.004], [0, 0, -1, -0.076], [1, 0, 0, -0.27]], dtype=float)
    imu = np.array([[1, 0, 0, -0.81], [0, 1, 0, 0.32], [0, 0, 1, -0.80]], dtype=float)
    P0 = np.hstack([K, np.zeros((3, 1))])

    def fmt(m):
        return " ".join(f"{v:.12e}" for v in np.asarray(m).ravel())

    return (f"P0: {fmt(P0)}\nP1: {fmt(P0)}\nP2: {fmt(P2)}\nP3: {fmt(P2)}\nR0_rect: {fmt(np.eye(3))}\n"
            f"Tr_velo_to_cam: {fmt(velo)}\nTr_imu_to_velo: {fmt(imu)}\n")


#: (line, d_long, d_lat) on the rig above at 1.65 m, level: t = (0.06, 0, 0) moves every label 6 cm right.
HAND_LABELS = [
    # straight ahead, 20 m to the centre: rear face at 20 - l/2 = 18
    ("Car 0.00 0 -1.60 180.00 40.00 240.00 100.00 1.50 1.60 4.00 0.50 1.65 20.00 -1.5708", 18.0, 0.56),
    # crossing (ry = 0): the length lies along x, the near side at z - w/2
    ("Car 0.00 0 0.00 100.00 50.00 200.00 100.00 1.50 1.60 4.00 -3.00 1.65 25.00 0.0000", 24.2, -2.94),
    # yawed by 45 deg: nearest corner at z - (l/2 + w/2) sin 45
    ("Van 0.00 1 -0.80 250.00 60.00 300.00 90.00 2.00 1.60 4.00 2.00 1.65 30.00 -0.785398", 30 - 2.8 * math.sqrt(0.5),
     2.06),
    ("DontCare -1 -1 -10 10.00 10.00 50.00 30.00 -1 -1 -1 -1000 -1000 -1000 -10", math.nan, math.nan),
]


def write_object_dataset(root: Path, calib: str | None = None, labels: list[str] | None = None,
                         n: int = 2, size: tuple[int, int] = (W, H)) -> Path:
    for d in ("image_2", "label_2", "calib"):
        (root / d).mkdir(parents=True, exist_ok=True)
    for k in range(n):
        stem = f"{k:06d}"
        cv2.imwrite(str(root / "image_2" / f"{stem}.png"), np.full((size[1], size[0], 3), 90, np.uint8))
        (root / "label_2" / f"{stem}.txt").write_text(
            "\n".join(labels if labels is not None else [line for line, _, _ in HAND_LABELS]) + "\n")
        (root / "calib" / f"{stem}.txt").write_text(calib if calib is not None else kitti_rig_calib())
    return root


def test_calibration_matches_pykitti(tmp_path):
    pykitti_utils = pytest.importorskip("pykitti.utils")
    p = tmp_path / "calib.txt"
    p.write_text(kitti_rig_calib())
    ref = pykitti_utils.read_calib_file(str(p))
    ours = parse_calib(p)
    for key in ("P2", "Tr_velo_to_cam", "Tr_imu_to_velo"):
        np.testing.assert_allclose(ours[key].ravel(), ref[key], rtol=0, atol=0)
    K, t = geo.intrinsics(ours["P2"])
    np.testing.assert_allclose(t, [0.06, 0, 0], atol=1e-12)
    # pykitti's own decomposition of P2 (cam2 baseline) from the same file
    assert geo.mounting_from_calib(ours) is None          # a real rig: no height in it


def test_hand_labels_known_distances(tmp_path):
    lab = parse_object_labels(_write(tmp_path / "l.txt", "\n".join(line for line, _, _ in HAND_LABELS) + "\n"))
    calib = {"P2": np.hstack([np.array([[FX, 0, CX], [0, FX, CY], [0, 0, 1.0]]),
                              np.array([[FX * 0.06], [0.0], [0.0]])])}
    cam, t, info = geo.camera_from_calib(calib, W, H, camera_height_m=1.65)
    assert info["pitch_source"].startswith("level") and cam.pitch_rad == 0.0 and cam.height_m == 1.65
    real = slice(0, 3)
    d_long, d_lat = geo.rear_face_distance(lab.dimensions[real], lab.location[real], lab.rotation_y[real], cam, t)
    np.testing.assert_allclose(d_long, [h[1] for h in HAND_LABELS[real]], atol=2e-4)
    np.testing.assert_allclose(d_lat, [h[2] for h in HAND_LABELS[real]], atol=1e-9)
    # independent path: KITTI devkit's box corners (harness.export.geometry.kitti_box_corners), level camera
    corners = export_geo.kitti_box_corners(lab.dimensions[real, 0], lab.dimensions[real, 1], lab.dimensions[real, 2],
                                           lab.location[real] + t, lab.rotation_y[real])
    np.testing.assert_allclose(d_long, corners[:, :4, 2].min(axis=1), atol=1e-12)


def _write(p: Path, text: str) -> Path:
    p.write_text(text)
    return p


@pytest.mark.parametrize("pitch_deg", [0.0, 2.0, -3.0])
def test_mounting_read_back_from_export_calibration(tmp_path, pitch_deg):
    cam = CameraModel.from_fov(640, 360, 70, 1.3, math.radians(pitch_deg), lateral_offset_m=0.2, forward_offset_m=0.5)
    calib = parse_calib(_write(tmp_path / "c.txt", calib_text(cam)))
    got, t, info = geo.camera_from_calib(calib, 640, 360)
    assert info["height_source"].startswith("calibration") and info["pitch_source"].startswith("calibration")
    for f in ("fx", "fy", "cx", "cy", "height_m", "pitch_rad", "lateral_offset_m", "forward_offset_m"):
        assert getattr(got, f) == pytest.approx(getattr(cam, f), abs=1e-9), f
    np.testing.assert_allclose(t, 0, atol=1e-12)
    # a vehicle placed in the ego frame, 30 m ahead (rear face), yawed 10 deg: the label recovers it
    heading = math.radians(10)
    f = np.array([math.sin(heading), math.cos(heading)])
    n = np.array([-f[1], f[0]])
    centre = np.array([1.5, 30.0 + 2.25 * math.cos(heading) + 0.9 * abs(math.sin(heading))])
    foot = np.array([centre + sl * 2.25 * f + sw * 0.9 * n for sl, sw in ((1, 1), (1, -1), (-1, -1), (-1, 1))])
    ground = np.c_[foot, np.full(4, -cam.height_m)]
    roof = ground + [0, 0, 1.5]
    order = [3, 2, 1, 0]                     # rear-left, rear-right, front-right, front-left (corners_cam order)
    corners_cam = cam.ego_to_cam(np.vstack([ground[order], roof[order]]))
    box = export_geo.kitti_box(corners_cam[None])
    d_long, d_lat = geo.rear_face_distance(np.c_[box["h"], box["w"], box["l"]], box["location"], box["rotation_y"],
                                           got)
    assert d_long[0] == pytest.approx(foot[:, 1].min(), abs=1e-9)
    assert d_lat[0] == pytest.approx(centre[0], abs=1e-9)


def test_real_rig_needs_camera_height():
    calib = {"P2": np.hstack([np.eye(3), np.zeros((3, 1))]) * 1.0}
    calib["P2"][:, :3] = [[FX, 0, CX], [0, FX, CY], [0, 0, 1]]
    with pytest.raises(CameraError, match="--camera-height"):
        geo.camera_from_calib(calib, W, H, where="calib/000000.txt")
    cam, _, info = geo.camera_from_calib(calib, W, H, camera_height_m=1.65, horizon_row=70.0)
    assert cam.horizon_row == pytest.approx(70.0) and info["pitch_source"] == "--horizon-row"


# ------------------------------------------------------------------------------------- AP
def _tall(x: float, h: float = 60.0) -> list[float]:
    return [x, 20.0, x + 40.0, 20.0 + h]


def test_ap_closed_form():
    gts = np.array([_tall(0), _tall(50), _tall(100), _tall(150)])
    truth = kap.ImageTruth(["Car"] * 4, gts, np.zeros(4, int), np.zeros(4))
    # scores 0.9 TP, 0.8 FP (nowhere), 0.7 TP, 0.6 TP; the fourth car missed
    dets = np.array([gts[0], _tall(300), gts[1], gts[2]])
    d = kap.ImageDetections(dets, np.array([0.9, 0.8, 0.7, 0.6]), ["car"] * 4)
    r = kap.average_precision([truth], [d], "Car", "easy", 0.7)
    # PR points (p, r): (1, 1/4), (1/2, 1/4), (2/3, 1/2), (3/4, 3/4); interpolated p = 1 up to r = 1/4,
    # 3/4 up to r = 3/4, 0 beyond.  R40: 10 points at 1, 20 at 3/4, 10 at 0.  R11: 0, .1, .2 at 1; .3-.7 at 3/4.
    assert r["ap_r40"] == pytest.approx((10 * 1 + 20 * 0.75) / 40)
    assert r["ap_r11"] == pytest.approx((3 * 1 + 5 * 0.75) / 11)
    assert (r["valid"], r["tp"], r["fp"], r["ignored"]) == (4, 3, 1, 0)


def test_ap_ignore_rules():
    gts = np.array([_tall(0), _tall(50), _tall(100), [200, 20, 240, 50], [300, 10, 390, 70]])
    types = ["Car", "Van", "Car", "Car", "DontCare"]
    occ = np.array([0, 0, 2, 0, -1])
    truth = kap.ImageTruth(types, gts, occ, np.zeros(5))
    dets = np.array([gts[0], gts[1], gts[2], gts[3], [310, 20, 350, 60], [0, 100, 40, 140]])
    d = kap.ImageDetections(dets, np.array([0.9, 0.8, 0.7, 0.6, 0.5, 0.4]), ["car"] * 6)
    easy = kap.average_precision([truth], [d], "Car", "easy", 0.7)
    # easy: car 0 valid; the Van, the occluded car and the 30 px car are ignored and so are the detections on
    # them; the detection inside DontCare is ignored; the last one is a false positive
    assert (easy["valid"], easy["tp"], easy["fp"], easy["ignored"]) == (1, 1, 1, 4)
    assert easy["ap_r40"] == pytest.approx(1.0)
    hard = kap.average_precision([truth], [d], "Car", "hard", 0.7)
    assert (hard["valid"], hard["tp"], hard["fp"], hard["ignored"]) == (3, 3, 1, 2)
    # a 30 px detection on a valid 60 px car at IoU > 0.7 cannot exist; at 0.5: 60 px car, 40 px detection
    small = kap.ImageDetections(np.array([[0, 20, 40, 55]]), np.array([0.9]), ["car"])
    r = kap.average_precision([kap.ImageTruth(["Car"], np.array([_tall(0)]), np.zeros(1, int), np.zeros(1))],
                              [small], "Car", "easy", 0.5)
    assert (r["valid"], r["tp"], r["ignored"]) == (0, 0, 1)      # excused, as the devkit does


def test_ap_against_sklearn():
    metrics = pytest.importorskip("sklearn.metrics")
    rng = np.random.default_rng(7)
    truths, dets, outcomes, scores = [], [], [], []
    n_valid = 0
    for _ in range(30):
        n = int(rng.integers(1, 6))
        x = rng.uniform(0, 1000, n)
        gts = np.c_[x, np.full(n, 50.0), x + 60, np.full(n, 110.0)]
        hit = rng.random(n) < 0.7
        jit = rng.normal(0, 3.0, (n, 4))
        fp = int(rng.integers(0, 3))
        fx = rng.uniform(1100, 1500, fp)
        db = np.vstack([gts[hit] + jit[hit], np.c_[fx, np.full(fp, 50.0), fx + 60, np.full(fp, 110.0)]])
        sc = np.round(rng.random(len(db)), 1)            # ties on purpose
        tr = kap.ImageTruth(["Car"] * n, gts, np.zeros(n, int), np.zeros(n))
        de = kap.ImageDetections(db, sc, ["car"] * len(db))
        o, nv, _ = kap.match_image(tr, de, "Car", "moderate", 0.5)
        truths.append(tr), dets.append(de), outcomes.append(o), scores.append(sc)
        n_valid += nv
    ours = kap.average_precision(truths, dets, "Car", "moderate", 0.5)
    o, s = np.concatenate(outcomes), np.concatenate(scores)
    assert set(np.unique(o)) <= {0, 1}
    prec, rec, _ = metrics.precision_recall_curve(o, s)
    prec, rec = prec[:-1], rec[:-1]                        # sklearn's appended (precision 1, recall 0) point
    rec = rec * o.sum() / n_valid                          # sklearn's recall is over the detected positives
    for pts, key in ((kap.R40, "ap_r40"), (kap.R11, "ap_r11")):
        ref = np.mean([max([p for p, r in zip(prec, rec) if r >= q - 1e-12], default=0.0) for q in pts])
        assert ours[key] == pytest.approx(ref, abs=1e-12)


# ------------------------------------------------------------------------ CLI on hand data
def test_cli_on_hand_written_object_dataset(tmp_path, capsys):
    ds = write_object_dataset(tmp_path / "hand")
    out = tmp_path / "out"
    assert main(["eval", "kitti", str(ds), "--detector", "labels", "--camera-height", "1.65", "--out", str(out)]) == 0
    m = json.loads((out / "metrics.json").read_text())
    assert m["frames"] == 2 and m["dataset"]["kind"] == "object" and m["tracking"]["mota"] is None
    a = m["kitti_ap"]["iou_0.7"]
    assert a["easy"]["valid"] == 2 * 2 and a["easy"]["ap_r40"] == 1.0       # cars 0 and 1; the Van ignored
    # the labels oracle names the Van's detection "van": Car AP does not see it (neither TP, FP nor ignored)
    assert (a["moderate"]["valid"], a["moderate"]["tp"], a["moderate"]["fp"], a["moderate"]["ignored"]) == (4, 4, 0, 0)
    import csv

    rows = list(csv.DictReader((out / "per_object.csv").open()))
    assert len(rows) == 2 * len(HAND_LABELS)
    for r in rows:
        line = HAND_LABELS[int(r["label"].split(":")[1]) - 1]
        assert line[0].startswith(r["type"])
        if math.isnan(line[1]):
            assert r["d_long_gt"] == ""
        else:
            assert float(r["d_long_gt"]) == pytest.approx(line[1], abs=2e-4)
            assert float(r["d_lat_gt"]) == pytest.approx(line[2], abs=1e-6)
    assert main(["eval", "kitti", str(ds), "--detector", "labels", "--camera-height", "1.65", "--frames", "1",
                 "--out", str(out)]) == 0                     # a previous evaluation is replaced
    assert json.loads((out / "metrics.json").read_text())["frames"] == 1


# ----------------------------------------------------------------------------- round trip
def _scenario(tmp: Path) -> Path:
    data = yaml.safe_load((ROOT / "scenarios" / "highway_cruise.yaml").read_text())
    data["camera"] = {**(data.get("camera") or {}), "width": 640, "height": 360}
    return write_scenario(tmp / "highway_cruise.yaml", data)


@pytest.fixture(scope="module")
def round_trip(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("kitti_rt")
    run_dir = tmp / "run"
    assert main(["render", str(_scenario(tmp)), "--out", str(run_dir), "--frames", "8"]) == 0
    out = {"run": run_dir, "truth": [json.loads(x) for x in (run_dir / "ground_truth.jsonl").read_text().splitlines()]}
    for fmt in ("kitti", "kitti-tracking"):
        out[fmt] = tmp / fmt
        assert main(["export", str(run_dir), "--format", fmt, "--out", str(out[fmt])]) == 0
        ev = tmp / f"eval-{fmt}"
        assert main(["eval", "kitti", str(out[fmt]), "--detector", "labels", "--out", str(ev)]) == 0
        out[f"eval-{fmt}"] = ev
    return out


@pytest.mark.parametrize("fmt", ["kitti", "kitti-tracking"])
def test_round_trip_truth_and_perfect_scores(round_trip, fmt):
    import csv

    m = json.loads((round_trip[f"eval-{fmt}"] / "metrics.json").read_text())
    truth = round_trip["truth"]
    rows = [r for r in csv.DictReader((round_trip[f"eval-{fmt}"] / "per_object.csv").open()) if r["gt_id"]]
    assert len(rows) == sum(len(t["objects"]) for t in truth)
    worst_long = worst_lat = 0.0
    cam = CameraModel.load(round_trip["run"] / "camera.json")

    def label_box(o: dict) -> np.ndarray:     # KITTI's 2-D box of a truth object (the export's convention)
        ext = export_geo.projected_extent(np.array(o["corners_cam"], float)[None], cam)[0]
        return export_geo.kitti_2d_box(ext, o["box"], cam.width, cam.height)

    for r in rows:
        objs = truth[int(r["frame"])]["objects"]
        box = np.array([float(r[k]) for k in ("gt_x1", "gt_y1", "gt_x2", "gt_y2")])
        o = min(objs, key=lambda o: np.abs(label_box(o) - box).sum())
        assert np.abs(label_box(o) - box).max() <= 0.005 + 1e-9
        worst_long = max(worst_long, abs(float(r["d_long_gt"]) - o["d_long"]))
        worst_lat = max(worst_lat, abs(float(r["d_lat_gt"]) - o["d_lat"]))
    # labels carry 4 decimals (m): every coordinate is within 5e-5 m, a corner within ~2e-4 m
    assert worst_long < 2e-4 and worst_lat < 1e-4
    for thr in ("0.7", "0.5"):
        for d in ("easy", "moderate", "hard"):
            a = m["kitti_ap"][f"iou_{thr}"][d]
            assert a["valid"] > 0 and a["ap_r40"] == 1.0 and a["ap_r11"] == 1.0 and a["fp"] == 0, (thr, d, a)
    assert m["detection"]["precision"] == 1.0 and m["detection"]["recall"] == 1.0
    assert m["dataset"]["camera"][0]["mounting_in_calibration"] is True
    assert m["dataset"]["camera_model"]["pitch_rad"] == pytest.approx(cam.pitch_rad, abs=1e-9)
    assert (m["tracking"]["mota"] is None) == (fmt == "kitti")


def test_finite_difference_closed_form():
    f = np.array([3, 4, 5, 6, 9, 10, 20])
    t = f / 10.0
    x = 2.0 + 3.0 * t - 0.5 * t ** 2                 # v = 3 - t; central differences are exact on a quadratic
    v = geo.finite_difference(f, t, x)
    np.testing.assert_allclose(v[1:3], 3 - t[1:3], atol=1e-12)
    assert v[0] == pytest.approx((x[1] - x[0]) / 0.1) and v[3] == pytest.approx((x[3] - x[2]) / 0.1)
    assert v[4] == pytest.approx((x[5] - x[4]) / 0.1) == v[5]      # a run of two frames after a gap
    assert math.isnan(v[6])                                          # a run of one frame


def test_round_trip_velocity_on_tracking(round_trip):
    """Label velocities = differences of the true positions (to quantisation); the simulation's own velocities
    differ from position differences by its integration step (a few cm/s), reported, not hidden."""
    import csv

    truth = round_trip["truth"]
    fps = 1.0 / (truth[1]["t"] - truth[0]["t"])
    rows = [r for r in csv.DictReader((round_trip["eval-kitti-tracking"] / "per_object.csv").open()) if r["gt_id"]]
    by_id: dict[int, list] = {}
    for r in rows:
        by_id.setdefault(int(r["gt_id"]), []).append(r)
    n = 0
    for gid, rs in by_id.items():
        frames = np.array([int(r["frame"]) for r in rs])
        tid = gid                                  # KITTI tracking's track_id is the simulation's vehicle id
        d_true = np.array([next(o for o in truth[f]["objects"] if o["id"] == tid)["d_long"] for f in frames])
        x_true = np.array([next(o for o in truth[f]["objects"] if o["id"] == tid)["d_lat"] for f in frames])
        v_ref = geo.finite_difference(frames, frames / fps, d_true)
        u_ref = geo.finite_difference(frames, frames / fps, x_true)
        v = np.array([float(r["v_long_gt"]) if r["v_long_gt"] else np.nan for r in rs])
        u = np.array([float(r["v_lat_gt"]) if r["v_lat_gt"] else np.nan for r in rs])
        np.testing.assert_array_equal(np.isnan(v), np.isnan(v_ref))
        # 2e-4 m of label quantisation over one or two frame intervals
        np.testing.assert_allclose(v[~np.isnan(v)], v_ref[~np.isnan(v_ref)], atol=2e-4 * fps)
        np.testing.assert_allclose(u[~np.isnan(u)], u_ref[~np.isnan(u_ref)], atol=2e-4 * fps)
        n += int((~np.isnan(v)).sum())
    assert n > 20


def test_two_tracking_sequences_keep_ids_apart(round_trip, tmp_path):
    import shutil

    src = round_trip["kitti-tracking"]
    ds = tmp_path / "two"
    shutil.copytree(src, ds)
    shutil.copytree(ds / "image_02" / "0000", ds / "image_02" / "0001")
    shutil.copy(ds / "label_02" / "0000.txt", ds / "label_02" / "0001.txt")
    shutil.copy(ds / "calib" / "0000.txt", ds / "calib" / "0001.txt")
    one = json.loads((round_trip["eval-kitti-tracking"] / "metrics.json").read_text())
    assert main(["eval", "kitti", str(ds), "--detector", "labels", "--out", str(tmp_path / "ev")]) == 0
    two = json.loads((tmp_path / "ev" / "metrics.json").read_text())
    assert two["frames"] == 2 * one["frames"] and two["dataset"]["sequences"] == 2
    assert two["tracking"]["unique_objects"] == 2 * one["tracking"]["unique_objects"]
    assert two["tracking"]["id_switches"] == 2 * one["tracking"]["id_switches"]
    assert two["tracking"]["mota"] == pytest.approx(one["tracking"]["mota"])


# ------------------------------------------------------------------------------- bad input
def _bad_cases(tmp: Path) -> dict[str, tuple[Path, list[str], str]]:
    cases = {}
    d = write_object_dataset(tmp / "no_labels")
    import shutil

    shutil.rmtree(d / "label_2")
    cases["missing part"] = (d, [], "lacks label_2/")
    d = write_object_dataset(tmp / "misnamed")
    (d / "image_2" / "000001.png").rename(d / "image_2" / "img1.png")
    cases["misnamed image"] = (d, [], "img1.png: not a KITTI image name")
    d = write_object_dataset(tmp / "orphan")
    (d / "label_2" / "000001.txt").rename(d / "label_2" / "000007.txt")
    cases["label without image"] = (d, [], "000007.txt: no image")
    d = write_object_dataset(tmp / "fields")
    (d / "label_2" / "000001.txt").write_text(HAND_LABELS[0][0]
                                              + "\nCar 0.00 0 -1.60 180 40 240 100 1.5 1.6 4.0 0.5 1.65 20\n")
    cases["wrong field count"] = (d, [], "000001.txt: line 2: 14 fields")
    d = write_object_dataset(tmp / "nan_field")
    (d / "label_2" / "000000.txt").write_text("Car 0.00 0 -1.60 180 40 240 abc 1.5 1.6 4.0 0.5 1.65 20 0\n")
    cases["not a number"] = (d, [], "000000.txt: line 1: field y2")
    d = write_object_dataset(tmp / "no_p2")
    no_p2 = [x for x in kitti_rig_calib().splitlines() if not x.startswith("P2")]
    (d / "calib" / "000001.txt").write_text("\n".join(no_p2))
    cases["calib without P2"] = (d, [], "calib/000001.txt: no P2")
    d = write_object_dataset(tmp / "size", size=(160, 60), labels=[HAND_LABELS[3][0]])   # a box that fits
    cases["image size vs calibration"] = (d, [], "lies outside it")
    d = write_object_dataset(tmp / "height")
    cases["no camera height"] = (d, ["--no-height"], "--camera-height")
    return cases


def test_bad_input_one_line_exit_2_nothing_written(tmp_path, capsys):
    for name, (ds, extra, needle) in _bad_cases(tmp_path).items():
        out = tmp_path / f"out-{name.replace(' ', '_')}"
        args = ["eval", "kitti", str(ds), "--detector", "labels", "--out", str(out)]
        if "--no-height" not in extra:
            args += ["--camera-height", "1.65"]
        rc = main(args)
        err = capsys.readouterr().err.strip()
        assert rc == 2, name
        assert len(err.splitlines()) == 1 and needle in err, (name, err)
        assert "Traceback" not in err
        assert not out.exists(), name
        assert not list(tmp_path.glob(f".{out.name}*")), name


def test_export_image_of_another_size(round_trip, tmp_path, capsys):
    import shutil

    ds = tmp_path / "resized"
    shutil.copytree(round_trip["kitti"], ds)
    img = ds / "image_2" / "000003.png"
    cv2.imwrite(str(img), cv2.resize(cv2.imread(str(img)), (320, 180)))
    out = tmp_path / "out"
    rc = main(["eval", "kitti", str(ds), "--detector", "labels", "--out", str(out)])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and len(err.splitlines()) == 1 and "000003.png: 320x180 image" in err, err
    assert "another size than the calibration" in err, err      # not its label boxes, which lie outside it too
    assert not out.exists()


def test_bad_options(tmp_path, capsys):
    ds = write_object_dataset(tmp_path / "ok")
    for args, needle in ((["--camera-height", "-1"], "--camera-height"), (["--detector", "nosuch"], "nosuch"),
                         (["--frames", "0"], "--frames"), (["--detector", "missing.onnx"], "missing.onnx")):
        rc = main(["eval", "kitti", str(ds), "--out", str(tmp_path / "o"), *args])
        err = capsys.readouterr().err.strip()
        assert rc == 2 and len(err.splitlines()) == 1 and needle in err, (args, err)
        assert not (tmp_path / "o").exists()


def _one_line_error(capsys) -> str:
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err, err
    return err


def test_bad_export_manifest_is_refused_not_ignored(round_trip, tmp_path, capsys):
    """export.json's fps sets the frame times: one that is there but unreadable must not fall back to 10 Hz."""
    import shutil

    ds = tmp_path / "trk"
    shutil.copytree(round_trip["kitti-tracking"], ds)
    manifest = ds / "export.json"
    good = json.loads(manifest.read_text())
    out = tmp_path / "out"
    for text, needle in (("{", f"{manifest}: export manifest is not valid JSON ("),
                         ('{"fps": "abc"}', f"{manifest}: field fps must be a positive number (frames per second), "
                                            "got 'abc'"),
                         ('{"fps": -5}', "field fps must be a positive number (frames per second), got -5"),
                         ('{"fps": 0}', "field fps must be a positive number"),
                         ('{"fps": true}', "field fps must be a positive number"),
                         ('{"fps": 15, "fps": 10}', "key 'fps' given twice in one object"),
                         ("[15]", "export.json must hold a JSON object, got list"),
                         (json.dumps({**good, "camera": {"width": 640}}), "field camera: missing field 'height'")):
        manifest.write_text(text)
        for extra in ([], ["--fps", "12"]):      # checked also when --fps takes precedence
            rc = main(["eval", "kitti", str(ds), "--detector", "labels", "--out", str(out), *extra])
            err = _one_line_error(capsys)
            assert rc == 2 and needle in err, (text, err)
            assert not out.exists()
    manifest.unlink()                             # absent: KITTI's 10 Hz, as documented
    assert main(["eval", "kitti", str(ds), "--detector", "labels", "--out", str(out)]) == 0
    assert json.loads((out / "metrics.json").read_text())["config"]["fps_sequence"] == 10.0


def test_options_beyond_the_dataset_name_the_option(round_trip, tmp_path, capsys):
    ds, out = round_trip["kitti-tracking"], tmp_path / "out"
    for args, message in (
            (["--horizon-row", "-5"], "monorarp eval: error: --horizon-row: row -5 px lies outside the 640x360 image "
                                      "(0..359)"),
            (["--horizon-row", "1e9"], "monorarp eval: error: --horizon-row: row 1e+09 px lies outside the 640x360 "
                                       "image (0..359)"),
            (["--frames", "100"], f"monorarp eval: error: --frames: 100 exceeds the dataset's 8 frames in {ds}")):
        rc = main(["eval", "kitti", str(ds), "--detector", "labels", "--out", str(out), *args])
        assert rc == 2 and _one_line_error(capsys) == message
        assert not out.exists()
    obj = write_object_dataset(tmp_path / "obj")
    for tracker in ("kcf", "particle"):           # object datasets run no tracker: --tracker is refused there
        rc = main(["eval", "kitti", str(obj), "--detector", "labels", "--camera-height", "1.65", "--tracker", tracker,
                   "--out", str(out)])
        assert rc == 2 and _one_line_error(capsys) == (
            f"monorarp eval: error: --tracker: {obj} is a KITTI object dataset, whose images are scored one by one "
            "without a tracker; --tracker applies to tracking datasets (image_02/, label_02/)")
        assert not out.exists()
    assert main(["eval", "kitti", str(obj), "--detector", "labels", "--camera-height", "1.65", "--frames", "2",
                 "--out", str(out)]) == 0                 # all its frames; no --tracker: none runs


def test_open_dataset_accepts_training_parent(tmp_path):
    write_object_dataset(tmp_path / "kitti" / "training")
    ds = open_dataset(tmp_path / "kitti")
    assert ds.kind == "object" and ds.n_frames == 2
    with pytest.raises(KittiInputError, match="not a KITTI dataset"):
        open_dataset(tmp_path)


# ------------------------------------------------------------------- devkit parity (reference port)
def _random_dataset(seed: int, n_images: int = 400):
    rng = np.random.default_rng(seed)
    truths, dets, gts_ref, dts_ref = [], [], [], []
    for _ in range(n_images):
        n = int(rng.integers(0, 8))
        slots = rng.permutation(10)[:n]
        h = rng.uniform(15, 120, n)
        x1 = slots * 120.0 + rng.uniform(0, 20, n)
        boxes = np.c_[x1, 200 - h, x1 + h * 1.3, np.full(n, 200.0)]
        types = rng.choice(["Car", "Car", "Car", "Car", "Car", "Car", "Van", "DontCare", "Pedestrian"], n).tolist()
        occ = rng.choice([0, 0, 0, 1, 2], n)
        trunc = np.where(rng.random(n) < 0.6, 0.0, np.round(rng.uniform(0, 0.6, n), 2))
        db, ds = [], []
        for k in range(n):
            if types[k] in ("Car", "Van", "DontCare") and rng.random() < 0.85:
                b = boxes[k].copy()
                b[[0, 2]] += rng.normal(0, 0.04 * h[k], 2)
                b[[1, 3]] += rng.normal(0, 0.04 * h[k], 2)
                if types[k] == "DontCare":                    # a detection well inside the region
                    b = boxes[k] + np.array([0.1, 0.1, -0.1, -0.1]) * h[k]
                db.append(b)
                ds.append(rng.beta(5, 2))
        for _ in range(int(rng.poisson(0.8))):                 # false positives in the free slots
            x = (10 + rng.integers(0, 4)) * 120.0
            hh = rng.uniform(20, 100)
            db.append([x, 200 - hh, x + hh * 1.3, 200.0])
            ds.append(rng.beta(2, 5))
        db = np.array(db, dtype=float).reshape(-1, 4)
        ds = np.round(np.array(ds), 3)
        truths.append(kap.ImageTruth(types, boxes, occ, trunc))
        dets.append(kap.ImageDetections(db, ds, ["car"] * len(db)))
        gts_ref.append({"name": types, "bbox": boxes, "occluded": occ, "truncated": trunc})
        dts_ref.append({"name": ["Car"] * len(db), "bbox": db, "score": ds})
    return truths, dets, gts_ref, dts_ref


@pytest.mark.parametrize("seed", [0, 1])
def test_ap_close_to_the_devkit_port(seed):
    from kitti_devkit_reference import devkit_ap

    truths, dets, gts_ref, dts_ref = _random_dataset(seed)
    for d_idx, diff in enumerate(("easy", "moderate", "hard")):
        for thr in (0.7, 0.5):
            ours = kap.average_precision(truths, dets, "Car", diff, thr)
            r40, r11 = devkit_ap(gts_ref, dts_ref, "Car", d_idx, thr)
            assert ours["valid"] > 150
            assert ours["ap_r40_devkit"] == pytest.approx(r40, abs=1e-12), (diff, thr, ours, r40)
            assert ours["ap_r11_devkit"] == pytest.approx(r11, abs=1e-12), (diff, thr, ours, r11)
            # the definition differs from the devkit's nearest-recall sampling by at most one sample
            assert abs(ours["ap_r40"] - r40) <= 1 / 40 and abs(ours["ap_r11"] - r11) <= 1 / 11


def test_devkit_difference_on_40_cars():
    from kitti_devkit_reference import devkit_ap

    boxes = np.array([_tall(50.0 * k) for k in range(40)])
    truth = kap.ImageTruth(["Car"] * 40, boxes, np.zeros(40, int), np.zeros(40))
    det = kap.ImageDetections(boxes, np.linspace(0.99, 0.5, 40), ["car"] * 40)
    ours = kap.average_precision([truth], [det], "Car", "easy", 0.7)
    ref = devkit_ap([{"name": ["Car"] * 40, "bbox": boxes, "occluded": np.zeros(40), "truncated": np.zeros(40)}],
                    [{"name": ["Car"] * 40, "bbox": boxes, "score": det.scores}], "Car", 0, 0.7)
    assert ours["ap_r40"] == 1.0 and ref[0] == pytest.approx(0.975)      # documented in harness.scoring.kitti_ap
    assert ours["ap_r40_devkit"] == pytest.approx(ref[0]) and ours["ap_r11_devkit"] == pytest.approx(ref[1])


def test_score_threshold_keeps_more_detections_and_is_recorded(round_trip, tmp_path):
    """``--score-threshold`` replaces the detector's own: a low one keeps at least as many detections (AP then
    ranks the whole list) and the run records it; the default records none."""
    runs = {}
    for thr in (None, "0.05"):
        out = tmp_path / f"t{thr}"
        extra = [] if thr is None else ["--score-threshold", thr]
        assert main(["eval", "kitti", str(round_trip["kitti"]), "--detector", "centernet", "--out", str(out),
                     *extra]) == 0
        runs[thr] = json.loads((out / "metrics.json").read_text())
    low, own = runs["0.05"], runs[None]
    assert low["config"]["detector_score_threshold"] == 0.05 and own["config"]["detector_score_threshold"] is None
    assert low["counts"]["detections"] > own["counts"]["detections"] > 0
    assert low["detection"]["recall"] >= own["detection"]["recall"]


@pytest.mark.parametrize("args, needle", [(["--score-threshold", "1.5"], "0..1"),
                                          (["--score-threshold", "nan"], "0..1"),
                                          (["--detector", "labels", "--score-threshold", "0.1"], "no scores")])
def test_bad_score_threshold_one_line_nothing_written(args, needle, tmp_path, capsys):
    ds = write_object_dataset(tmp_path / "ok")
    rc = main(["eval", "kitti", str(ds), "--out", str(tmp_path / "o"), "--camera-height", "1.65", *args])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and len(err.splitlines()) == 1 and needle in err and "--score-threshold" in err, err
    assert not (tmp_path / "o").exists()
