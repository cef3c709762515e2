"""``monorarp export``: KITTI object, KITTI tracking and MOTChallenge datasets from the harness.

One small render (``highway_cruise`` at 320x180, a few frames: near, far, truncated and
occluded vehicles) is exported in every format; the files are read back with readers this
project did not write where PyPI has one (``pykitti`` for KITTI calibration and tracking
labels, ``motmetrics.io.loadtxt`` for MOTChallenge) and with a plain parser of KITTI's
official 15-field label format written here from the devkit's description. Every exported
3-D box is rebuilt as KITTI's devkit does (``compute_box_3d``), projected with the exported
``P2`` and compared with ``cv2.projectPoints``, with the exported 2-D box and with the
ground truth's own 3-D corners.
"""

from __future__ import annotations

import configparser
import json
import math
from pathlib import Path

import cv2
import numpy as np
import pytest
import yaml

from harness.export import geometry as geo
from harness.export.mot import mot_to_box
from harness.scoring.rules import EvalConfig, counted_mask
from harness.world.truth import FrameTruth
from monorarp.core.camera import CameraModel
from monorarp.app.cli import main

ROOT = Path(__file__).resolve().parents[1]
W, H = 320, 180
N_FRAMES = 6
KITTI_TYPES = {"Car", "Van", "Truck", "Pedestrian", "Person_sitting", "Cyclist", "Tram", "Misc", "DontCare"}


def _small(tmp: Path, name: str, pitch_deg: float | None = None) -> Path:
    data = yaml.safe_load((ROOT / "scenarios" / name).read_text())
    cam = dict(data.get("camera") or {})
    cam.update(width=W, height=H)
    if pitch_deg is not None:
        cam["pitch_deg"] = pitch_deg
    data["camera"] = cam
    path = tmp / name
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    """A render dir (``monorarp render``) and its three exports, plus a KITTI export straight from the scenario."""
    tmp = tmp_path_factory.mktemp("export")
    scen = _small(tmp, "highway_cruise.yaml")
    run_dir = tmp / "run"
    assert main(["render", str(scen), "--out", str(run_dir), "--frames", str(N_FRAMES)]) == 0
    out = {"scenario": scen, "run": run_dir}
    for fmt in ("kitti", "kitti-tracking"):
        out[fmt] = tmp / fmt
        assert main(["export", str(run_dir), "--format", fmt, "--out", str(out[fmt])]) == 0
    out["mot"] = tmp / "mot"
    assert main(["export", str(run_dir), "--format", "mot", "--out", str(out["mot"]), "--detector", "oracle"]) == 0
    out["kitti_from_scenario"] = tmp / "kitti_scen"
    assert main(["export", str(scen), "--format", "kitti", "--out", str(out["kitti_from_scenario"]),
                 "--frames", "3"]) == 0
    out["truth"] = [FrameTruth.from_json(json.loads(line))
                    for line in (run_dir / "ground_truth.jsonl").read_text().splitlines()]
    out["camera"] = CameraModel.load(run_dir / "camera.json")
    return out


# ------------------------------------------------------------------ independent readers
def parse_kitti_label(line: str) -> dict:
    """KITTI object label, the devkit's 15 fields (readme.txt of the object development kit)."""
    v = line.split()
    assert len(v) == 15, f"{len(v)} fields: {line!r}"
    return {"type": v[0], "truncated": float(v[1]), "occluded": int(v[2]), "alpha": float(v[3]),
            "bbox": [float(x) for x in v[4:8]], "dimensions": [float(x) for x in v[8:11]],
            "location": [float(x) for x in v[11:14]], "rotation_y": float(v[14])}


def compute_box_3d(obj: dict) -> np.ndarray:
    """(8, 3) corners as the KITTI devkit's ``computeBox3D`` builds them (rotation about y only)."""
    h, w, l = obj["dimensions"]
    ry = obj["rotation_y"]
    R = np.array([[math.cos(ry), 0, math.sin(ry)], [0, 1, 0], [-math.sin(ry), 0, math.cos(ry)]])
    x = [l / 2, l / 2, -l / 2, -l / 2, l / 2, l / 2, -l / 2, -l / 2]
    y = [0, 0, 0, 0, -h, -h, -h, -h]
    z = [w / 2, -w / 2, -w / 2, w / 2, w / 2, -w / 2, -w / 2, w / 2]
    return (R @ np.array([x, y, z])).T + np.array(obj["location"])


def parse_calib_plain(path: Path) -> dict[str, np.ndarray]:
    """KITTI calib lines, ``key: numbers`` (object) or ``key numbers`` (tracking's R_rect, Tr_velo_cam, ...)."""
    out = {}
    for line in path.read_text().splitlines():
        key, rest = (line.split(":", 1) if ":" in line else line.split(" ", 1))
        out[key.strip()] = np.array([float(x) for x in rest.split()])
    return out


# ------------------------------------------------------------------------------ KITTI object
def test_kitti_object_layout_and_label_fields(exported):
    root, truth, cam = exported["kitti"], exported["truth"], exported["camera"]
    assert sorted(p.name for p in root.iterdir()) == ["calib", "export.json", "image_2", "label_2"]
    for d, ext in (("image_2", ".png"), ("label_2", ".txt"), ("calib", ".txt")):
        assert sorted(p.name for p in (root / d).iterdir()) == [f"{k:06d}{ext}" for k in range(N_FRAMES)]
    n_lines = n_hidden = 0
    for k, tr in enumerate(truth):
        img = cv2.imread(str(root / "image_2" / f"{k:06d}.png"))
        assert img.shape == (H, W, 3)
        labels = [parse_kitti_label(x) for x in (root / "label_2" / f"{k:06d}.txt").read_text().splitlines()]
        assert len(labels) == len(tr.objects)
        n_lines += len(labels)
        for lab, obj in zip(labels, tr.objects):
            assert lab["type"] in KITTI_TYPES and lab["type"] in ("Car", "Truck")
            assert 0.0 <= lab["truncated"] <= 1.0 and lab["occluded"] in (0, 1, 2, 3)
            assert -math.pi <= lab["alpha"] <= math.pi and -math.pi <= lab["rotation_y"] <= math.pi
            x1, y1, x2, y2 = lab["bbox"]
            assert -0.5 <= x1 < x2 <= W - 0.5 and -0.5 <= y1 < y2 <= H - 0.5
            # KITTI's 2-D box: the cv2.projectPoints extent of the 3-D box, clipped to the image (an occluded
            # vehicle's box covers its hidden part), holding every visible pixel.
            uv, _ = cv2.projectPoints(np.array(obj.corners_cam, float), np.zeros(3), np.zeros(3), cam.K, None)
            uv = uv.reshape(-1, 2)
            want = np.r_[np.maximum(uv.min(0), -0.5), np.minimum(uv.max(0), [W - 0.5, H - 0.5])]
            want = np.r_[np.minimum(want[:2], obj.box[:2]), np.maximum(want[2:], obj.box[2:])]
            assert lab["bbox"] == pytest.approx(want, abs=0.005)
            n_hidden += obj.visibility < 0.9 and (x2 - x1) * (y2 - y1) > 1.2 * (obj.box[2] - obj.box[0]) * (
                obj.box[3] - obj.box[1])
            h, w, l = lab["dimensions"]
            assert (h, w, l) == pytest.approx((np.linalg.norm(np.subtract(obj.corners_cam[4], obj.corners_cam[0])),
                                               obj.width, obj.length), abs=1e-4)
            assert lab["location"][2] > 0
            # Same direction of travel as the ego: rotation_y near -pi/2 (KITTI's convention).
            assert abs(lab["rotation_y"] + math.pi / 2) < 0.5
            # alpha = rotation_y - atan2(x, z) of the location (KITTI's observation angle).
            a = lab["rotation_y"] - math.atan2(lab["location"][0], lab["location"][2])
            assert math.isclose(math.remainder(a - lab["alpha"], 2 * math.pi), 0.0, abs_tol=2e-4)
            if obj.visibility >= 0.999:
                assert lab["occluded"] == 0
    assert n_lines > 3 * N_FRAMES and n_hidden >= 1
    manifest = json.loads((root / "export.json").read_text())
    assert manifest["format"] == "kitti" and manifest["frames"] == N_FRAMES


def test_kitti_calibration_read_by_pykitti(exported):
    pykitti_utils = pytest.importorskip("pykitti.utils")
    cam = exported["camera"]
    for k in range(N_FRAMES):
        c = pykitti_utils.read_calib_file(str(exported["kitti"] / "calib" / f"{k:06d}.txt"))
        assert set(c) == {"P0", "P1", "P2", "P3", "R0_rect", "Tr_velo_to_cam", "Tr_imu_to_velo"}
        P2 = c["P2"].reshape(3, 4)
        np.testing.assert_allclose(P2, np.hstack([cam.K, np.zeros((3, 1))]), atol=1e-9)
        np.testing.assert_allclose(c["R0_rect"].reshape(3, 3), np.eye(3))
        # Tr_velo_to_cam maps a levelled frame (x forward, y left, z up) into the pitched camera:
        Tr = c["Tr_velo_to_cam"].reshape(3, 4)
        forward_in_cam = Tr[:, :3] @ [1.0, 0.0, 0.0]
        # pitched down: the level forward direction points up (-y) in the camera
        assert math.atan2(-forward_in_cam[1], forward_in_cam[2]) == pytest.approx(cam.pitch_rad, abs=1e-9)
        np.testing.assert_allclose(Tr[:, :3] @ [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0], atol=1e-12)   # left = -x
        Ti = c["Tr_imu_to_velo"].reshape(3, 4)
        np.testing.assert_allclose(Ti[:, 3], [-cam.forward_offset_m, cam.lateral_offset_m, -cam.height_m])


def test_projected_3d_boxes_match_opencv_the_2d_boxes_and_the_true_corners(exported):
    root, truth, cam = exported["kitti"], exported["truth"], exported["camera"]
    bound = 2 * math.sin(abs(cam.pitch_rad) / 2)
    checked = 0
    for k, tr in enumerate(truth):
        P2 = parse_calib_plain(root / "calib" / f"{k:06d}.txt")["P2"].reshape(3, 4)
        K = P2[:, :3]
        labels = [parse_kitti_label(x) for x in (root / "label_2" / f"{k:06d}.txt").read_text().splitlines()]
        for lab, obj in zip(labels, tr.objects):
            corners = compute_box_3d(lab)
            hom = (P2 @ np.c_[corners, np.ones(8)].T).T
            uv = hom[:, :2] / hom[:, 2:]
            cv_uv, _ = cv2.projectPoints(corners.reshape(-1, 1, 3), np.zeros(3), np.zeros(3), K, None)
            np.testing.assert_allclose(uv, cv_uv.reshape(-1, 2), atol=1e-6)
            # The rebuilt box is the true one up to the camera's pitch (KITTI has no pitch of the box).
            true = np.array(obj.corners_cam)[geo.KITTI_CORNER_ORDER]
            r = np.linalg.norm(true - true[:4].mean(axis=0), axis=1)
            assert np.all(np.linalg.norm(corners - true, axis=1) <= bound * r + 2e-3)
            if lab["occluded"] == 0 and lab["truncated"] == 0 and obj.visibility >= 0.999:
                x1, y1, x2, y2 = lab["bbox"]
                u0, v0 = uv.min(axis=0)
                u1, v1 = uv.max(axis=0)
                # Left and right: the body's sides, to a pixel. Top and bottom: the box's corners lie
                # outside the car's curved mesh (roof behind the rear face, tyres ahead of it).
                assert abs(u0 - x1) <= 1.5 and abs(u1 - x2) <= 1.5, (k, obj.id, (u0, v0, u1, v1), lab["bbox"])
                tol_v = max(1.5, 0.1 * (y2 - y1))
                assert abs(v0 - y1) <= tol_v and abs(v1 - y2) <= tol_v, (k, obj.id, (u0, v0, u1, v1), lab["bbox"])
                checked += 1
    assert checked >= N_FRAMES


def test_zero_pitch_boxes_are_exact():
    """With a level camera KITTI's box model holds the true box exactly."""
    from harness.world.geometry import box_corners_ego

    cam = CameraModel.from_fov(640, 360, 70.0, height_m=1.3, pitch_rad=0.0)
    yaw = 0.3                                                         # heading, rad, to the right of straight ahead
    fwd, right = np.array([math.sin(yaw), math.cos(yaw)]), np.array([math.cos(yaw), -math.sin(yaw)])
    centre, half_l, half_w = np.array([-1.7, 12.5]), 2.4, 0.95
    # corners_cam order: rear-left, rear-right, front-right, front-left (the vehicle's own left/right).
    foot = np.array([[centre + sl * half_l * fwd + sw * half_w * right
                      for sl, sw in ((-1, -1), (-1, 1), (1, 1), (1, -1))]])
    corners = cam.ego_to_cam(box_corners_ego(foot, np.array([1.5]), cam))[0]
    b = geo.kitti_box(corners[None])
    rebuilt = geo.kitti_box_corners(b["h"], b["w"], b["l"], b["location"], b["rotation_y"])[0]
    np.testing.assert_allclose(rebuilt, corners[geo.KITTI_CORNER_ORDER], atol=1e-9)
    assert b["location"][0][1] == pytest.approx(1.3)                  # the ground is camera height below


def test_truncation_and_near_plane_clipping():
    cam = CameraModel.from_fov(200, 100, 90.0, height_m=1.0)
    assert geo.truncation([[-0.5 - 50, 10, 49.5, 20]], 200, 100)[0] == pytest.approx(0.5)
    assert geo.truncation([[10, 10, 20, 20]], 200, 100)[0] == 0.0
    # A box reaching behind the camera: its extent is that of its part in front of the near plane.
    ring = [(-1.0, -2.0), (1.0, -2.0), (1.0, 3.0), (-1.0, 3.0)]         # (x, z): from 2 m behind to 3 m ahead
    box = np.array([[x, y, z] for y in (1.0, 0.0) for x, z in ring])    # ground ring, then roof ring
    ext = geo.projected_extent(box[None], cam)[0]
    # x = -1..1 and y = 0..1 clipped at z = 0.1 m; y = 0 at z = 3 m projects to the centre row.
    near = 1 / geo.Z_NEAR_M
    np.testing.assert_allclose(ext, [cam.cx - cam.fx * near, cam.cy, cam.cx + cam.fx * near, cam.cy + cam.fy * near])
    assert np.isnan(geo.projected_extent((box - [0, 0, 10])[None], cam)).all()


def test_scenario_and_run_dir_exports_agree(exported):
    """The labels are the same whether the frames are rendered now or decoded from the run's video."""
    a, b = exported["kitti_from_scenario"], exported["kitti"]
    for k in range(3):
        assert (a / "label_2" / f"{k:06d}.txt").read_text() == (b / "label_2" / f"{k:06d}.txt").read_text()
        assert (a / "calib" / f"{k:06d}.txt").read_text() == (b / "calib" / f"{k:06d}.txt").read_text()
    scen_img = cv2.imread(str(a / "image_2" / "000001.png")).astype(int)
    run_img = cv2.imread(str(b / "image_2" / "000001.png")).astype(int)
    assert np.abs(scen_img - run_img).mean() < 3.0                    # H.264 at crf 18 vs the exact render


# --------------------------------------------------------------------------- KITTI tracking
def test_kitti_tracking_labels_calib_and_seqmap(exported):
    root, truth = exported["kitti-tracking"], exported["truth"]
    assert sorted(p.name for p in root.iterdir()) == ["calib", "evaluate_tracking.seqmap.training", "export.json",
                                                       "image_02", "label_02"]
    assert len(list((root / "image_02" / "0000").glob("*.png"))) == N_FRAMES
    lines = (root / "label_02" / "0000.txt").read_text().splitlines()
    expected = [(tr.frame, o.id) for tr in truth for o in tr.objects]
    assert [(int(x.split()[0]), int(x.split()[1])) for x in lines] == expected
    obj_labels = {(k, i): parse_kitti_label(" ".join(line.split()[2:]))
                  for (k, i), line in zip(expected, lines)}
    assert all(v["truncated"] in (0.0, 1.0, 2.0) for v in obj_labels.values())
    calib = parse_calib_plain(root / "calib" / "0000.txt")
    assert set(calib) == {"P0", "P1", "P2", "P3", "R_rect", "Tr_velo_cam", "Tr_imu_velo"}
    assert (root / "evaluate_tracking.seqmap.training").read_text().split() == ["0000", "empty", "000000",
                                                                               f"{N_FRAMES:06d}"]
    # pykitti's tracking-label parser reads the same rows and boxes.
    tracking = pytest.importorskip("pykitti.tracking")
    df = tracking.KittiTrackingLabels(str(root / "label_02" / "0000.txt"), split_on_reappear=False)._df
    assert len(df) == len(lines)
    assert set(df["class"]) <= {"Car", "Truck"}
    ours = np.array([v["bbox"] for v in obj_labels.values()])
    np.testing.assert_allclose(df[["x1", "y1", "x2", "y2"]].to_numpy(float), ours, atol=1e-3)
    np.testing.assert_allclose(df["z"].to_numpy(float), [v["location"][2] for v in obj_labels.values()], atol=1e-3)


# --------------------------------------------------------------------------------- MOT
@pytest.mark.filterwarnings("ignore:Operation with tuple is deprecated")     # inside motmetrics.io on pandas 3
def test_mot_gt_and_det_round_trip_through_motmetrics(exported):
    mm_io = pytest.importorskip("motmetrics.io")
    root, truth = exported["mot"], exported["truth"]
    seq = root / "run"                                                 # render dirs name the sequence by the directory
    assert sorted(p.name for p in seq.iterdir()) == ["det", "gt", "img1", "seqinfo.ini"]
    ini = configparser.ConfigParser()
    ini.read(seq / "seqinfo.ini")
    s = ini["Sequence"]
    assert (s["name"], s["imDir"], int(s["seqLength"]), int(s["imWidth"]), int(s["imHeight"]), s["imExt"]) == \
        ("run", "img1", N_FRAMES, W, H, ".jpg")
    assert float(s["frameRate"]) == pytest.approx(15.0)
    assert sorted(p.name for p in (seq / "img1").iterdir()) == [f"{k:06d}.jpg" for k in range(1, N_FRAMES + 1)]

    gt = mm_io.loadtxt(str(seq / "gt" / "gt.txt"), fmt="mot15-2D")
    expected = {(tr.frame + 1, o.id): (o, c) for tr in truth
                for o, c in zip(tr.objects, counted_mask(tr.objects, EvalConfig()))}
    assert sorted(gt.index) == sorted(expected)
    for (frame, oid), row in gt.iterrows():
        o, counted = expected[(frame, oid)]
        # motmetrics subtracts 1 from MOT's 1-based X, Y: X is the 0-based index of the first pixel column.
        assert (row["X"] - 0.5, row["Y"] - 0.5) == pytest.approx(o.box[:2], abs=0.006)
        assert mot_to_box(row["X"] + 1, row["Y"] + 1, row["Width"], row["Height"]) == pytest.approx(o.box, abs=0.006)
        assert row["Confidence"] == int(counted) and row["ClassId"] == 3
        assert row["Visibility"] == pytest.approx(o.visibility, abs=1e-4)

    # The oracle detector's boxes are the counted-enough truth boxes: det.txt must hold exactly them.
    det = mm_io.loadtxt(str(seq / "det" / "det.txt"), fmt="mot15-2D")
    assert len(det) > 0 and (det.index.get_level_values("Id") == -1).all()
    det_boxes = sorted((int(f), *np.round(mot_to_box(r["X"] + 1, r["Y"] + 1, r["Width"], r["Height"]), 2))
                       for (f, _), r in det.iterrows())
    truth_boxes = sorted((tr.frame + 1, *np.round(o.box, 2)) for tr in truth for o in tr.objects
                         if o.visibility >= 0.3 and o.box[3] - o.box[1] >= 4.0)   # the oracle's rule
    assert det_boxes == truth_boxes


# --------------------------------------------------------------------------- bad input
def _no_temp_left(parent: Path) -> bool:
    return not any(p.name.startswith(".") and ".tmp-" in p.name for p in parent.iterdir())


def test_bad_input_one_line_exit_2_nothing_written(exported, tmp_path, capsys):
    run_dir = exported["run"]
    novideo = tmp_path / "novideo"
    novideo.mkdir()
    for name in ("camera.json", "ground_truth.jsonl"):
        (novideo / name).write_bytes((run_dir / name).read_bytes())
    notes = tmp_path / "notes.txt"
    notes.write_text("hello")
    cases = [
        ([str(novideo), "--format", "kitti"], "frames.mp4 is missing"),
        ([str(tmp_path / "missing"), "--format", "mot"], "no such run directory"),
        ([str(tmp_path / "missing.yaml"), "--format", "mot"], "no such scenario file"),
        ([str(notes), "--format", "kitti"], "neither a run directory nor a scenario file"),
        ([str(run_dir), "--format", "kitti", "--frames", str(N_FRAMES + 1)], "exceeds"),
        ([str(run_dir), "--format", "kitti", "--frames", "0"], "positive"),
        ([str(run_dir), "--format", "kitti", "--detector", "centernet"], "only --format mot"),
        ([str(run_dir), "--format", "mot", "--detector", "no_such_detector"], "no_such_detector"),
        ([str(tmp_path), "--format", "kitti"], "not a run directory"),
    ]
    for args, needle in cases:
        out = tmp_path / "out"
        rc = main(["export", *args, "--out", str(out)])
        err = capsys.readouterr().err
        assert rc == 2, (args, err)
        assert needle in err and len(err.strip().splitlines()) == 1, (args, err)
        assert not out.exists() and _no_temp_left(tmp_path), args


def test_foreign_output_directory_is_refused_and_left_alone(exported, tmp_path, capsys):
    out = tmp_path / "mine"
    out.mkdir()
    (out / "thesis.tex").write_text("keep me")
    rc = main(["export", str(exported["run"]), "--format", "kitti", "--out", str(out), "--frames", "1"])
    assert rc == 2 and "refusing" in capsys.readouterr().err
    assert [p.name for p in out.iterdir()] == ["thesis.tex"] and _no_temp_left(tmp_path)


def test_a_previous_export_is_replaced_by_another_format(exported, tmp_path):
    out = tmp_path / "ds"
    assert main(["export", str(exported["run"]), "--format", "kitti", "--out", str(out), "--frames", "2"]) == 0
    assert main(["export", str(exported["run"]), "--format", "kitti-tracking", "--out", str(out), "--frames", "2"]) == 0
    assert not (out / "label_2").exists() and (out / "label_02" / "0000.txt").is_file()


def test_a_truck_alongside_with_its_centre_behind_the_camera_is_a_dontcare_region(tmp_path):
    """A 16.3 m artic in the next lane, its rear 10 m behind the camera: its ground-face centre is behind the
    camera (no KITTI 3-D label can hold it), so it is exported as a DontCare region of its 2-D box, and the
    export stays readable by the KITTI reader, which refuses a location at z <= 0."""
    from harness.export.exporter import export
    from harness.export.source import open_source
    from harness.kitti_eval.reader import open_dataset
    from harness.world.scenario import parse_scenario

    scen = parse_scenario({
        "name": "alongside", "seed": 2, "duration_s": 1.0, "fps": 10.0, "road": {"lanes": 3},
        "ego": {"lane": 1, "speed_mps": 25.0}, "traffic": {"vehicles_count": 0},
        "vehicles": [{"name": "artic", "lane": 1, "distance_m": -10.0, "speed_mps": 25.0,
                      "behaviour": "constant_speed", "body": "artic", "length_m": 16.3, "width_m": 2.55},
                     {"name": "lead", "lane": 0, "distance_m": 20.0, "speed_mps": 25.0, "behaviour": "constant_speed"}],
        "camera": {"width": 640, "height": 360, "hfov_deg": 90, "height_m": 1.4, "pitch_deg": 0.0}})
    path = tmp_path / "s.yaml"
    path.write_text(json.dumps(scen.model_dump(mode="json")))
    out = tmp_path / "k"
    export(open_source(path, 1), "kitti", out, progress=False)
    lines = [ln.split() for ln in (out / "label_2" / "000000.txt").read_text().splitlines()]
    assert sorted(ln[0] for ln in lines) == ["Car", "DontCare"]
    dc = next(ln for ln in lines if ln[0] == "DontCare")
    assert [float(v) for v in dc[8:15]] == [-1, -1, -1, -1000, -1000, -1000, -10]
    x1, y1, x2, y2 = map(float, dc[4:8])
    assert x1 > 320 and x2 - x1 > 50                       # the truck's front, at the image's right side
    ds = open_dataset(out)                                   # readable: no z <= 0 location
    assert ds.n_frames == 1 and not ds.skipped
