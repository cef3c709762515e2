"""The real-world detector (YOLOX-Nano, COCO): decoding through the top-left letterbox, NMS, class mapping,
layout recognition and refusal, and the shipped model on a rendered frame."""

from __future__ import annotations

import hashlib
from pathlib import Path

import cv2
import numpy as np
import pytest

onnx = pytest.importorskip("onnx")


from monorarp.core.errors import UserError  # noqa: E402
from monorarp.detection.letterbox import Letterbox  # noqa: E402
from monorarp.detection.yolox import (COCO_VEHICLES, DEFAULT_MODEL, YoloxDetector, decode, n_cells,  # noqa: E402
                                      nms)
from monorarp.pipeline.detectors import load_detector  # noqa: E402

from onnx_models import constant_model  # noqa: E402

SHA256 = "695e750a5d5754bb5a8d5325643b59282191a7e7a564e435a415fd3c578eab14"




def cell_row(stride: int, col: int, row: int, size: int = 416) -> int:
    """Output row of grid cell (col, row) of ``stride`` (stride 8's grid first, row-major)."""
    before = sum((size // s) ** 2 for s in (8, 16, 32) if s < stride)
    return before + row * (size // stride) + col


def put(raw: np.ndarray, stride: int, col: int, row: int, xywh, obj: float, cls: int, prob: float) -> None:
    r = raw[0, cell_row(stride, col, row)]
    r[:4] = [xywh[0], xywh[1], np.log(xywh[2]), np.log(xywh[3])]
    r[4], r[5 + cls] = obj, prob


def synthetic_output() -> np.ndarray:
    raw = np.zeros((1, n_cells(416, 416), 85), np.float32)
    # stride 16, cell (10, 5): centre ((0.5 + 10) * 16, (0.25 + 5) * 16) = (168, 84), size (4 * 16, 2 * 16) = (64, 32)
    # -> canvas edges (136, 68, 200, 100); score 0.9 * 0.8 = 0.72
    put(raw, 16, 10, 5, (0.5, 0.25, 4.0, 2.0), 0.9, 2, 0.8)
    put(raw, 16, 11, 5, (0.0, 0.25, 4.0, 2.0), 0.9, 7, 0.5)      # truck, 0.45, IoU 0.78 with the car: NMS drops it
    put(raw, 8, 40, 30, (0.5, 0.5, 2.0, 3.0), 0.8, 3, 0.5)       # motorcycle, 0.40, centre (324, 244)
    put(raw, 32, 2, 2, (0.5, 0.5, 1.0, 2.0), 0.95, 0, 0.95)      # person: never a vehicle
    put(raw, 32, 8, 8, (0.5, 0.5, 1.0, 1.0), 0.95, 1, 0.95)      # bicycle: never a vehicle
    put(raw, 8, 5, 40, (0.5, 0.5, 2.0, 2.0), 0.5, 5, 0.5)        # bus under the threshold (0.25)
    return raw


def test_decode_hand_case_in_canvas_pixels():
    boxes, scores, cls = decode(synthetic_output()[0], 416, 416, 0.3)
    order = np.argsort(-scores)
    np.testing.assert_allclose(boxes[order[0]], [136, 68, 200, 100], atol=1e-4)
    np.testing.assert_allclose(boxes[order[2]], [316, 232, 332, 256], atol=1e-4)
    np.testing.assert_allclose(scores[order], [0.72, 0.45, 0.40], atol=1e-6)
    assert [int(c) for c in cls[order]] == [2, 7, 3]


def test_detector_through_the_top_left_letterbox(tmp_path):
    path = constant_model(tmp_path / "yolox.onnx", (1, 3, 416, 416), {"output": synthetic_output()})
    det = YoloxDetector(path, foveate=False)
    out = det.detect(np.zeros((624, 832, 3), np.uint8))     # scale 0.5 into 416x312, top-left, no padding above
    # source edges = canvas edges / 0.5; pixel-centre convention: minus 0.5
    assert [d.label for d in out] == ["car", "motorcycle"]
    np.testing.assert_allclose(out[0].box, (271.5, 135.5, 399.5, 199.5), atol=1e-4)
    np.testing.assert_allclose(out[1].box, (631.5, 463.5, 663.5, 511.5), atol=1e-4)
    assert [d.score for d in out] == pytest.approx([0.72, 0.40], abs=1e-6)
    assert type(load_detector(str(path))) is YoloxDetector        # recognised by its layout
    keep_all = YoloxDetector(path, foveate=False, nms_iou=0.8).detect(np.zeros((624, 832, 3), np.uint8))
    assert [d.label for d in keep_all] == ["car", "truck", "motorcycle"]


def test_top_left_letterbox_is_yolox_placement_and_inverts():
    lb = Letterbox.top_left(1242, 375, 416, 416)
    assert (lb.new_w, lb.new_h, lb.pad_x, lb.pad_y) == (int(1242 * (416 / 1242)), int(375 * (416 / 1242)), 0, 0)
    b = np.array([[10.0, 20.0, 300.5, 370.0]])
    np.testing.assert_allclose(lb.to_src(lb.to_dst(b), clip=False), b, atol=1e-9)
    canvas = lb.apply(np.full((375, 1242, 3), 7, np.uint8), 114, cv2.INTER_LINEAR)
    assert canvas.shape == (416, 416, 3) and canvas[lb.new_h:].min() == 114 and canvas[:lb.new_h, :lb.new_w].max() == 7


def test_nms_matches_opencv_and_a_closed_case():
    rng = np.random.default_rng(3)
    xy = rng.uniform(0, 300, (60, 2))
    boxes = np.concatenate([xy, xy + rng.uniform(10, 80, (60, 2))], axis=1)
    scores = rng.uniform(0, 1, 60)
    xywh = np.concatenate([boxes[:, :2], boxes[:, 2:] - boxes[:, :2]], axis=1)
    ref = np.asarray(cv2.dnn.NMSBoxes(xywh.tolist(), scores.astype(np.float32).tolist(), 0.0, 0.45)).reshape(-1)
    assert sorted(nms(boxes, scores, 0.45)) == sorted(ref)
    # closed case: B overlaps A by IoU 0.6 (dropped); C overlaps B by 0.6 but A by 0.33 only (kept: B is gone)
    a, b, c, d = [0, 0, 10, 10], [2.5, 0, 12.5, 10], [5, 0, 15, 10], [50, 50, 60, 60]
    assert list(nms(np.array([a, b, c, d], float), np.array([0.9, 0.8, 0.7, 0.1]), 0.5)) == [0, 2, 3]
    assert list(nms(np.zeros((0, 4)), np.zeros(0), 0.5)) == []


def test_class_mapping_keeps_vehicles_only():
    assert COCO_VEHICLES == {2: "car", 3: "motorcycle", 5: "bus", 7: "truck"}   # not 0 person, 1 bicycle
    raw = synthetic_output()[0]
    _, _, cls = decode(raw, 416, 416, 0.01)
    assert set(cls.tolist()) == {2, 3, 5, 7}
    _, _, cls = decode(raw, 416, 416, 0.01, {0: "person"})
    assert cls.tolist() == [0]


def test_a_layout_that_matches_nothing_is_refused_in_one_line(tmp_path):
    wrong_n = constant_model(tmp_path / "v5.onnx", (1, 3, 416, 416), {"output": np.zeros((1, 10647, 85))})
    for build in (lambda: load_detector(str(wrong_n)), lambda: YoloxDetector(wrong_n)):
        with pytest.raises(UserError) as e:
            build()
        msg = str(e.value)
        assert "\n" not in msg and "v5.onnx" in msg and "10647, 85" in msg


def test_the_cli_refuses_a_bad_layout_with_exit_2_and_writes_nothing(tmp_path, capsys):
    from monorarp.app.cli import main

    bad = constant_model(tmp_path / "bad.onnx", (1, 3, 416, 416), {"output": np.zeros((1, 3549, 7))})
    clip = tmp_path / "clip.mp4"
    writer = cv2.VideoWriter(str(clip), cv2.VideoWriter_fourcc(*"mp4v"), 15.0, (320, 180))
    for _ in range(3):
        writer.write(np.zeros((180, 320, 3), np.uint8))
    writer.release()
    out = tmp_path / "out"
    cam = tmp_path / "cam.yaml"
    cam.write_text("width: 320\nheight: 180\nhfov_deg: 60\nheight_m: 1.5\n")
    rc = main(["video", str(clip), "--camera", str(cam), "--detector", str(bad), "--out", str(out)])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and len(err.splitlines()) == 1 and "bad.onnx" in err and "unrecognised detector layout" in err
    assert not out.exists()


def test_eval_kitti_defaults_to_yolox_on_real_frames_and_centernet_on_exported_renders(tmp_path):
    from harness.commands.eval import default_detector

    assert default_detector(tmp_path) == "yolox"
    (tmp_path / "export.json").write_text('{"fps": 15}')
    assert default_detector(tmp_path) == "centernet"


@pytest.mark.skipif(not DEFAULT_MODEL.is_file(), reason="shipped model absent")
def test_shipped_model_is_the_documented_file():
    assert hashlib.sha256(DEFAULT_MODEL.read_bytes()).hexdigest() == SHA256
    assert (DEFAULT_MODEL.parent / "LICENSE-yolox_nano_coco.txt").read_text().count("Apache License") >= 1


# Frame 100 of udacity/CarND-LaneLines-P1 @ ce5681be7ef8140560c0e464ef2da611e40b4fc9, test_videos/solidWhiteRight.mp4
# (MIT licence, Udacity, Inc.: tests/data/LICENSE-udacity-CarND-LaneLines-P1.txt), JPEG quality 90.
REAL_FRAME = Path(__file__).resolve().parent / "data" / "solidWhiteRight_frame100.jpg"
# Boxes drawn by eye on that frame (x1, y1, x2, y2 px): the car cut by the left border, the red car, the white car.
REAL_CARS = [(0, 292, 97, 390), (153, 292, 229, 339), (415, 299, 444, 321)]


@pytest.mark.skipif(not DEFAULT_MODEL.is_file(), reason="shipped model absent")
@pytest.mark.parametrize("foveate", [False, True])
def test_shipped_model_finds_the_cars_of_a_real_frame(foveate):
    """The near cars to IoU > 0.6 (the white one at ~45 m needs the fovea), nothing in the sky or on the verge."""
    from monorarp.core.boxes import iou_matrix

    image = cv2.imread(str(REAL_FRAME))
    det = load_detector("yolox", foveate=foveate)
    assert det.foveate is foveate
    out = det.detect(image)
    boxes = np.array([d.box for d in out], float).reshape(-1, 4)
    best = iou_matrix(np.array(REAL_CARS, float), boxes).max(axis=1)
    want = REAL_CARS if foveate else REAL_CARS[:2]
    assert (best[:len(want)] > 0.6).all(), best
    assert all(d.label in ("car", "truck") for d in out)
    assert (boxes[:, 3] > 280).all() and (boxes[:, 0] < 520).all()   # below the horizon, left of the verge


def test_the_rendered_world_is_outside_what_the_coco_model_knows():
    """Why ``centernet`` stays the simulation default: the flat-shaded renders' cars are no COCO vehicles."""
    from harness.render.renderer import Renderer
    from harness.simulation.simulator import simulate
    from harness.world.scenario import parse_scenario

    scen = parse_scenario(SCENE)
    with Renderer(scen) as r:
        image = r.render(next(iter(simulate(scen, 1)))).image
    assert load_detector("yolox", score_threshold=0.05).detect(image) == []
    assert len(load_detector("centernet").detect(image)) >= 1


SCENE = {
    "name": "yolox_check", "seed": 11, "duration_s": 1.0, "fps": 15.0,
    "road": {"lanes": 3}, "ego": {"lane": 1, "speed_mps": 25.0},
    "traffic": {"vehicles_count": 0, "density": 1.0},
    "vehicles": [{"name": "ahead", "lane": 0, "distance_m": 12.0, "speed_mps": 25.0, "behaviour": "constant_speed"}],
    "camera": {"width": 960, "height": 540, "hfov_deg": 60, "height_m": 1.4, "pitch_deg": 1.0},
    "render": {"palette_seed": 5},
}
