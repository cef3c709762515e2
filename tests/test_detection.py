"""Detectors: YOLO export decoding, CenterNet decoding, bad models, the committed model on a rendered frame."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

onnx = pytest.importorskip("onnx")

from monorarp.pipeline.detectors import load_detector
from monorarp.detection.centernet import CenterNetDetector
from monorarp.detection.yolo import YoloDetector  # noqa: E402
from monorarp.detection.centernet import DEFAULT_MODEL  # noqa: E402
from monorarp.core.errors import UserError  # noqa: E402

from onnx_models import constant_model  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]




# ------------------------------------------------------------------- YOLO
def yolo_raw(n_anchors: int = 50) -> np.ndarray:
    """(1, 84, N) with hand-placed candidates in 640x640 letterbox input pixels (edge convention)."""
    p = np.zeros((84, n_anchors), np.float32)
    p[:4, :] = [[10], [10], [4], [4]]           # filler anchors: all class scores 0
    cands = [  # cx, cy, w, h, class, score
        (320, 320, 100, 60, 2, 0.90),   # car                      -> kept
        (322, 321, 100, 60, 2, 0.80),   # same car, lower score    -> suppressed by NMS
        (320, 320, 100, 60, 7, 0.70),   # truck on it: other class -> kept (class-wise NMS)
        (100, 200, 40, 40, 5, 0.60),    # bus                      -> kept
        (400, 400, 50, 50, 0, 0.95),    # person                   -> not a vehicle
        (200, 400, 30, 30, 2, 0.10),    # car below threshold      -> dropped
        (600, 150, 100, 40, 2, 0.50),   # car reaching into the pad and past the right edge -> clipped
    ]
    for k, (cx, cy, w, h, c, s) in enumerate(cands):
        p[:4, k] = cx, cy, w, h
        p[4 + c, k] = s
        if c == 2:
            p[4 + 7, k] = s / 3             # lower truck score on the same anchor: argmax must pick car
    return p[None]


# 1280x720 -> 640x360 letterboxed in 640x640: scale 0.5, 140 px pad on top.
# source (continuous, pixel centres at integers) = (net_edge - pad) / 0.5 - 0.5
YOLO_EXPECTED = [
    ((270 / 0.5 - 0.5, (290 - 140) / 0.5 - 0.5, 370 / 0.5 - 0.5, (350 - 140) / 0.5 - 0.5), 0.90, "car"),
    ((539.5, 299.5, 739.5, 419.5), 0.70, "truck"),
    ((159.5, 79.5, 239.5, 159.5), 0.60, "bus"),
    ((1099.5, -0.5, 1279.5, -0.5 + (170 - 140) / 0.5), 0.50, "car"),   # y1 -20.5 and x2 1299.5 clipped
]


@pytest.mark.parametrize("transposed", [False, True])
def test_yolo_decoding_nms_and_letterbox(tmp_path, transposed):
    raw = yolo_raw()
    if transposed:
        raw = raw.transpose(0, 2, 1).copy()
    path = constant_model(tmp_path / "yolo.onnx", (1, 3, 640, 640), {"output0": raw})
    det = YoloDetector(path, conf_threshold=0.25, iou_threshold=0.45)
    out = det.detect(np.zeros((720, 1280, 3), np.uint8))
    assert [d.label for d in out] == [e[2] for e in YOLO_EXPECTED]
    for d, (box, score, _) in zip(out, YOLO_EXPECTED):
        np.testing.assert_allclose(d.box, box, atol=1e-4)
        assert d.score == pytest.approx(score, abs=1e-6)
    assert type(load_detector(str(path))) is YoloDetector


def test_yolo_wrong_layout_is_user_error(tmp_path):
    nms_export = constant_model(tmp_path / "nms.onnx", (1, 3, 640, 640), {"output0": np.zeros((1, 300, 6))})
    with pytest.raises(UserError, match=r"nms\.onnx.*\(1, 84, N\)"):
        YoloDetector(nms_export)
    with pytest.raises(UserError, match="unrecognised detector layout"):
        load_detector(str(nms_export))
    seg = constant_model(tmp_path / "two.onnx", (1, 3, 640, 640),
                         {"output0": np.zeros((1, 84, 10)), "output1": np.zeros((1, 32, 160, 160))})
    with pytest.raises(UserError, match="one YOLO output"):
        YoloDetector(seg)
    bad_input = constant_model(tmp_path / "gray.onnx", (1, 1, 640, 640), {"output0": np.zeros((1, 84, 10))})
    with pytest.raises(UserError, match=r"gray\.onnx.*\(1,3,H,W\)"):
        YoloDetector(bad_input)


def test_missing_and_unreadable_models_are_user_errors(tmp_path):
    with pytest.raises(UserError, match=r"nope\.onnx: model file not found"):
        load_detector(str(tmp_path / "nope.onnx"))
    junk = tmp_path / "junk.onnx"
    junk.write_bytes(b"this is not a protobuf \x00\x01\x02" * 10)
    with pytest.raises(UserError, match=r"junk\.onnx: not a valid ONNX model"):
        YoloDetector(junk)
    with pytest.raises(UserError, match=r"junk\.onnx"):
        CenterNetDetector(junk)
    with pytest.raises(UserError):
        load_detector("no-such-detector-name")


# -------------------------------------------------------------- CenterNet
def test_centernet_decoding_and_letterbox(tmp_path):
    """Hand-placed heatmap peak + edge distances -> box in source pixels."""
    h, w, s = 48, 80, 4
    hm = np.zeros((1, 1, h, w), np.float32)
    lt = np.zeros((1, 4, h, w), np.float32)
    box = np.array([71.5, 33.5, 93.5, 61.5])          # in the 320x192 net input
    for di in (-1, 0, 1):                            # the 3x3 neighbours predict the same box
        for dj in (-1, 0, 1):
            i, j = 10 + di, 20 + dj
            cx, cy = s * j + 1.5, s * i + 1.5
            lt[0, :, i, j] = cx - box[0], cy - box[1], box[2] - cx, box[3] - cy
            hm[0, 0, i, j] = 0.9 if (di, dj) == (0, 0) else 0.5
    hm[0, 0, 30, 60] = 0.2                           # below the threshold
    path = constant_model(tmp_path / "cn.onnx", (1, 3, 192, 320), {"heatmap": hm, "ltrb": lt}, "image")
    det = load_detector(str(path), score_threshold=0.3)
    assert type(det) is CenterNetDetector
    out = det.detect(np.zeros((360, 640, 3), np.uint8))   # 640x360 -> 320x180, 6 px bands top and bottom
    assert len(out) == 1
    # x = (x' + 0.5) / 0.5 - 0.5 ; y = (y' - 6 + 0.5) / 0.5 - 0.5
    np.testing.assert_allclose(out[0].box, (143.5, 55.5, 187.5, 111.5), atol=1e-4)
    assert out[0].score == pytest.approx(0.9)


def test_centernet_wrong_output_shape_is_user_error(tmp_path):
    path = constant_model(tmp_path / "cn_bad.onnx", (1, 3, 192, 320),
                          {"heatmap": np.zeros((1, 1, 24, 40)), "ltrb": np.zeros((1, 4, 24, 40))}, "image")
    with pytest.raises(UserError, match=r"cn_bad\.onnx: expected outputs heatmap \[1, 1, 48, 80\]"):
        CenterNetDetector(path)


def test_sessions_are_shared_until_the_file_changes(tmp_path):
    """Detectors on the same file share one onnxruntime session; a rewritten file is loaded afresh."""
    h, w = 48, 80
    hm, lt = np.zeros((1, 1, h, w), np.float32), np.zeros((1, 4, h, w), np.float32)
    path = constant_model(tmp_path / "cn.onnx", (1, 3, 192, 320), {"heatmap": hm, "ltrb": lt}, "image")
    a, b = CenterNetDetector(path), CenterNetDetector(path)
    assert a.session is b.session
    assert CenterNetDetector(path, intra_op_num_threads=2).session is not a.session
    hm[0, 0, 10, 20] = 0.9
    constant_model(tmp_path / "new.onnx", (1, 3, 192, 320), {"heatmap": hm, "ltrb": lt + 8}, "image").replace(path)
    c = CenterNetDetector(path)
    assert c.session is not a.session
    assert len(c.detect(np.zeros((360, 640, 3), np.uint8))) == 1 and a.detect(np.zeros((360, 640, 3), np.uint8)) == []


# -------------------------------------------------------------------- AP
def test_average_precision_hand_example():
    sys.path.insert(0, str(ROOT))
    from training.ap import ap_at

    gts = [np.array([[0, 0, 10, 10], [20, 20, 30, 30]], float), np.array([[0, 0, 10, 10]], float)]
    dets = [np.array([[0, 0, 10, 10], [50, 50, 60, 60], [20, 20, 30, 31]], float),
            np.array([[1, 0, 10, 10], [0, 0, 10, 10]], float)]
    scores = [np.array([0.9, 0.8, 0.3]), np.array([0.7, 0.6])]
    # sorted: 0.9 TP, 0.8 FP, 0.7 TP (IoU 0.9), 0.6 FP (duplicate), 0.3 TP (IoU 100/110)
    # precision 1, 1/2, 2/3, 2/4, 3/5 at recall 1/3, 1/3, 2/3, 2/3, 1
    # interpolated: recall 0->1/3 at 1, 1/3->2/3 at 2/3, 2/3->1 at 3/5
    expected = (1 / 3) * 1 + (1 / 3) * (2 / 3) + (1 / 3) * (3 / 5)
    assert ap_at(dets, scores, gts, 0.5) == pytest.approx(expected)
    # at IoU 0.95 only the exact boxes match: 0.9 TP, 0.8 FP, 0.7 FP (IoU 0.9), 0.6 TP, 0.3 FP
    expected95 = (1 / 3) * 1 + (1 / 3) * (2 / 4)
    assert ap_at(dets, scores, gts, 0.95) == pytest.approx(expected95)
    # ignoring the box the FP at 0.8 hits removes it: precision 1, 2/3 -> 1, 1, ...
    ign = [np.array([[50, 50, 60, 60]], float), np.zeros((0, 4))]
    expected_ign = (1 / 3) * 1 + (1 / 3) * 1 + (1 / 3) * (3 / 4)
    assert ap_at(dets, scores, gts, 0.5, ign) == pytest.approx(expected_ign)


# ------------------------------------------------- committed model, rendered frame
SCENE = {
    "name": "detector_check", "seed": 11, "duration_s": 2.0, "fps": 15.0,
    "road": {"lanes": 3}, "ego": {"lane": 1, "speed_mps": 25.0},
    "traffic": {"vehicles_count": 6, "density": 1.0},
    "vehicles": [
        {"name": "near", "lane": 0, "distance_m": 9.0, "speed_mps": 25.0, "behaviour": "constant_speed"},
        {"name": "left", "lane": -1, "distance_m": 18.0, "speed_mps": 25.0, "behaviour": "constant_speed"},
        {"name": "right", "lane": 1, "distance_m": 22.0, "speed_mps": 25.0, "behaviour": "constant_speed",
         "length_m": 12.0, "width_m": 2.5},
        {"name": "far", "lane": -1, "distance_m": 50.0, "speed_mps": 25.0, "behaviour": "constant_speed"},
    ],
    "camera": {"width": 640, "height": 360, "hfov_deg": 70, "height_m": 1.4, "pitch_deg": 2.0},
    "render": {"palette_seed": 5},
}


@pytest.mark.skipif(not DEFAULT_MODEL.is_file(), reason=f"committed model {DEFAULT_MODEL.name} not there yet")
def test_committed_centernet_finds_rendered_vehicles():
    """AP@0.5 >= 0.8 against the harness's ground-truth boxes (visibility >= 0.5 and >= 8 px tall required;
    other visible vehicles ignored)."""
    from harness.world.ground_truth import frame_truth
    from harness.render.renderer import Renderer
    from harness.world.scenario import parse_scenario
    from harness.simulation.simulator import simulate

    sys.path.insert(0, str(ROOT))
    from training.ap import ap_at, match

    scen = parse_scenario(SCENE)
    det = load_detector("centernet")
    weak_det = load_detector("centernet", weak_score_threshold=0.3)
    assert isinstance(det, CenterNetDetector)
    dets, scores, gts, igns, n_weak = [], [], [], [], 0
    with Renderer(scen) as r:
        for w in list(simulate(scen, 16))[::5]:
            fr = r.render(w)
            truth = frame_truth(w, scen.camera.model(), fr)
            boxes = np.array([o.box for o in truth.objects], float).reshape(-1, 4)
            vis = np.array([o.visibility for o in truth.objects])
            req = (vis >= 0.5) & (boxes[:, 3] - boxes[:, 1] >= 8)
            out = det.detect(fr.image)
            both = weak_det.detect(fr.image, weak=True)      # the same strong boxes, plus weak ones under the threshold
            assert [d for d in both if not d.weak] == out
            assert all(0.3 <= d.score < det.score_threshold for d in both if d.weak)
            n_weak += sum(d.weak for d in both)
            dets.append(np.array([d.box for d in out], float).reshape(-1, 4))
            scores.append(np.array([d.score for d in out]))
            gts.append(boxes[req])
            igns.append(boxes[~req])
    assert sum(len(g) for g in gts) >= 12          # the placed vehicles are all in view
    print(f"weak detections: {n_weak}")
    ap = ap_at(dets, scores, gts, 0.5, igns)
    assert ap >= 0.8, f"AP@0.5 = {ap:.3f}"
    # the bottom edge (what the distance estimator reads) of the matched boxes is within a few px
    m = match(dets, scores, gts, 0.5, igns)
    err = np.array([dets[i][d, 3] - gts[i][j, 3] for i, d, j in m.pairs])
    assert np.median(np.abs(err)) <= 2.0


def test_centernet_weak_detections(tmp_path):
    """Peaks between the weak and the decision threshold come back marked weak, only when asked for."""
    h, w, s = 48, 80, 4
    hm = np.zeros((1, 1, h, w), np.float32)
    lt = np.zeros((1, 4, h, w), np.float32)
    for (i, j), score in (((10, 20), 0.9), ((30, 60), 0.4), ((40, 10), 0.2)):
        cx, cy = s * j + 1.5, s * i + 1.5
        lt[0, :, i, j] = 10.0                         # a 20x20 box around the cell centre
        hm[0, 0, i, j] = score
    path = constant_model(tmp_path / "cn.onnx", (1, 3, 192, 320), {"heatmap": hm, "ltrb": lt}, "image")
    (tmp_path / "cn.json").write_text('{"score_threshold": 0.5, "weak_score_threshold": 0.3}')
    det = CenterNetDetector(path)
    assert det.weak_score_threshold == 0.3
    img = np.zeros((192, 320, 3), np.uint8)
    plain, both = det.detect(img), det.detect(img, weak=True)
    assert [(d.score, d.weak) for d in plain] == [(pytest.approx(0.9), False)]
    assert [(d.score, d.weak) for d in both] == [(pytest.approx(0.9), False), (pytest.approx(0.4), True)]
    assert both[0] == plain[0]
    assert CenterNetDetector(path, weak_score_threshold=0.5).detect(img, weak=True) == plain   # at the threshold: none
    assert len(CenterNetDetector(path, weak_score_threshold=0.1).detect(img, weak=True)) == 3
    with pytest.raises(ValueError, match="weak_score_threshold must be in"):
        CenterNetDetector(path, weak_score_threshold=1.5)
    (tmp_path / "cn.json").write_text('{"score_threshold": 0.5, "weak_score_threshold": 2}')
    with pytest.raises(UserError, match=r"cn\.json: invalid detector metadata: weak_score_threshold 2\.0"):
        CenterNetDetector(path)


def test_shipped_model_gives_weak_detections_only_when_configured():
    assert CenterNetDetector().weak_score_threshold is None              # opt-in (docs/tracking.md)
    img = np.zeros((192, 320, 3), np.uint8)
    assert not any(d.weak for d in CenterNetDetector().detect(img, weak=True))


def _rendered_frames(n: int) -> tuple[list[np.ndarray], object]:
    from harness.render.renderer import Renderer
    from harness.world.scenario import parse_scenario
    from harness.simulation.simulator import simulate

    scen = parse_scenario(SCENE)
    with Renderer(scen) as r:
        return [r.render(w).image for w in list(simulate(scen, 3 * n))[::3]], scen.camera.model()


def test_parallel_passes_give_the_same_detections_with_the_fovea_on_the_helper_thread():
    with pytest.raises(ValueError, match="parallel_passes"):
        CenterNetDetector(parallel_passes="yes")
    images, cam = _rendered_frames(3)
    serial = CenterNetDetector(camera=cam, parallel_passes=False)
    parallel = CenterNetDetector(camera=cam)
    assert parallel.parallel_passes and parallel.fovea(640, 360)[0] is not None
    threads: list[str] = []
    raw = parallel.raw

    def recording_raw(*args, **kw):
        import threading

        threads.append(threading.current_thread().name)
        return raw(*args, **kw)

    parallel.raw = recording_raw
    for image in images:
        b0, s0 = serial.detect_arrays(image, threshold=0.2)
        b1, s1 = parallel.detect_arrays(image, threshold=0.2)
        assert len(b0) >= 3
        np.testing.assert_array_equal(b0, b1)
        np.testing.assert_array_equal(s0, s1)
    assert threads.count("MainThread") == len(images)
    assert sum(t.startswith("monorarp-second-pass") for t in threads) == len(images)


def _detect_in_child(image, cam, queue) -> None:
    boxes, _ = CenterNetDetector(camera=cam).detect_arrays(image)
    queue.put(boxes)


@pytest.mark.skipif(sys.platform != "linux", reason="fork start method")
def test_a_forked_process_gets_its_own_second_pass_thread():
    """A child forked after the parent used the helper thread does not inherit it: without its own it would hang."""
    import multiprocessing

    images, cam = _rendered_frames(1)
    want, _ = CenterNetDetector(camera=cam).detect_arrays(images[0])      # the parent's helper thread now exists
    ctx = multiprocessing.get_context("fork")
    queue = ctx.Queue()
    child = ctx.Process(target=_detect_in_child, args=(images[0], cam, queue))
    child.start()
    try:
        got = queue.get(timeout=60)
    finally:
        child.join(timeout=10)
        if child.is_alive():
            child.kill()
    np.testing.assert_array_equal(got, want)
