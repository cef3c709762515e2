"""The mosaic full view of wide frames (monorarp/detection/mosaic.py) and YOLOX through it: placement in
closed form, the canvas against cv2's own rendering of known rectangles, the cut/join rules on hand-made
boxes, decoding through a constant model, and the shipped model on a wide strip of a real frame."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from monorarp.detection.mosaic import Mosaic, join

KITTI = (1242, 375)


def test_plan_in_closed_form_and_only_where_it_gains():
    m = Mosaic.plan(*KITTI, 416, 416, gap_px=12)
    s = 404 / 750                                            # (416 - 12) / (2 * 375)
    assert (m.tile_w, m.new_w, m.new_h) == (int(416 / s), int(int(416 / s) * s), 202) == (772, 415, 202)
    assert (m.right_x0, m.bottom_y0) == (1242 - 772, 416 - 202)
    assert 2 * m.tile_w - 1242 == 302                        # the tiles overlap by 302 columns
    assert s / (416 / 1242) > 1.6                            # 1.6 x the letterbox's scale
    for size in ((960, 540), (1280, 720), (640, 360), (416, 416), (375, 1242)):
        assert Mosaic.plan(*size, 416, 416) is None          # 16:9 and narrower: the letterbox is as good
    wide = Mosaic.plan(3000, 300, 416, 416)                  # very wide: the overlap keeps 20 % of the width
    assert wide.tile_w == int(416 / (2 * 416 / (3000 * 1.2))) and 2 * wide.tile_w - 3000 >= 0.2 * 3000 - 1


def _rects_image(rects, w=1242, h=375):
    img = np.full((h, w, 3), 60, np.uint8)
    for x0, y0, x1, y1 in rects:
        img[y0:y1, x0:x1] = 255
    return img


def test_canvas_and_its_inverse_against_cv2_rendered_rectangles():
    m = Mosaic.plan(*KITTI, 416, 416)
    left, right, both = (100, 150, 200, 250), (1000, 160, 1100, 230), (580, 120, 660, 300)
    canvas = m.apply(_rects_image([left, right, both]), 114)
    assert canvas.shape == (416, 416, 3)
    assert (canvas[m.new_h:m.bottom_y0] == 114).all() and (canvas[:, m.new_w:] == 114).all()   # the gap
    n, _, stats, _ = cv2.connectedComponentsWithStats((canvas[:, :, 0] > 160).astype(np.uint8))
    found = np.array([[x, y, x + w, y + h] for x, y, w, h, _ in stats[1:]], float)  # edge convention
    assert n - 1 == 4                                        # the middle rectangle is in both tiles
    src, tile, cut = m.to_src(found)
    assert not cut.any()
    for rect, tiles in ((left, [0]), (right, [1]), (both, [0, 1])):
        want = np.array(rect, float) - 0.5                   # pixels x0..x1-1: extent [x0 - 0.5, x1 - 0.5]
        hit = np.flatnonzero(np.abs(src - want).max(axis=1) < 2.0)   # 1 canvas px = 1.86 source px
        assert sorted(tile[hit].tolist()) == tiles, (rect, src.round(1))


def test_a_rectangle_across_the_left_tiles_inner_side_is_cut_there_and_whole_in_the_right_tile():
    m = Mosaic.plan(*KITTI, 416, 416)
    rect = (700, 150, 900, 260)                              # the left tile ends at column 772
    canvas = m.apply(_rects_image([rect]), 114)
    _, _, stats, _ = cv2.connectedComponentsWithStats((canvas[:, :, 0] > 160).astype(np.uint8))
    found = np.array([[x, y, x + w, y + h] for x, y, w, h, _ in stats[1:]], float)
    src, tile, cut = m.to_src(found)
    assert sorted(zip(tile.tolist(), cut.tolist())) == [(0, True), (1, False)]
    boxes, idx = join(src, np.array([0.9, 0.8]), tile, cut)
    assert len(boxes) == 1 and tile[idx[0]] == 1             # the part is dropped, the whole box kept
    np.testing.assert_allclose(boxes[0], np.array(rect, float) - 0.5, atol=2.0)


def test_join_rules_on_hand_made_boxes():
    whole = [100.0, 100.0, 200.0, 160.0]
    part_covered = [150.0, 100.0, 199.0, 160.0]              # 100 % inside the whole box: dropped
    left_cut = [400.0, 80.0, 771.0, 300.0]                   # a car wider than the overlap, cut by both tiles
    right_cut = [470.0, 90.0, 850.0, 300.0]                  # rows 90..300 vs 80..300: 1-D IoU 210 / 220
    lone = [740.0, 10.0, 771.0, 40.0]                        # cut, no partner (row IoU 0 with right_cut)
    boxes = np.array([whole, part_covered, left_cut, right_cut, lone])
    scores = np.array([0.9, 0.5, 0.6, 0.7, 0.4])
    tile = np.array([0, 1, 0, 1, 0])
    cut = np.array([False, True, True, True, True])
    out, idx = join(boxes, scores, tile, cut)
    got = {tuple(b): int(i) for b, i in zip(out.tolist(), idx)}
    assert got == {tuple(whole): 0, (400.0, 80.0, 850.0, 300.0): 3, tuple(lone): 4}   # union scored by its best part
    # rows too different (1-D IoU 0.5 < 0.6): two boxes, not one
    out, _ = join(np.array([left_cut, [470.0, 190.0, 850.0, 300.0]]), np.array([0.6, 0.7]), np.array([0, 1]),
                  np.array([True, True]))
    assert len(out) == 2
    assert join(np.zeros((0, 4)), np.zeros(0), np.zeros(0, int), np.zeros(0, bool))[0].shape == (0, 4)


# --------------------------------------------------------------------------- the detector through the mosaic
onnx = pytest.importorskip("onnx")

from monorarp.detection.yolox import DEFAULT_MODEL, YoloxDetector, n_cells  # noqa: E402

from onnx_models import constant_model  # noqa: E402


def put_box(raw: np.ndarray, box, cls: int, score: float) -> None:
    """Write a canvas box (edge convention) into the stride-8 cell holding its centre (YOLOX's encoding)."""
    x1, y1, x2, y2 = box
    cx, cy = (x1 + x2) / 2, (y1 + y2) / 2
    col, row = int(cx // 8), int(cy // 8)
    r = raw[0, row * 52 + col]
    r[:4] = [cx / 8 - col, cy / 8 - row, np.log((x2 - x1) / 8), np.log((y2 - y1) / 8)]
    r[4], r[5 + cls] = 1.0, score


def test_detector_decodes_through_the_mosaic_and_joins_a_car_cut_by_both_tiles(tmp_path):
    m = Mosaic.plan(*KITTI, 416, 416)
    sx, sy, x0r, y0b = m.new_w / m.tile_w, m.new_h / 375, m.right_x0, m.bottom_y0
    raw = np.zeros((1, n_cells(416, 416), 85), np.float32)
    put_box(raw, (40, 60, 104, 92), 2, 0.8)                  # top tile: a car on the left
    put_box(raw, (300, y0b + 70, 340, y0b + 100), 7, 0.7)    # bottom tile: a truck on the right
    wide = (400.5 * sx, 40, 414, 120)                        # source 400..850 seen cut by both tiles
    put_box(raw, wide, 2, 0.6)
    put_box(raw, (2, y0b + 40, 380.5 * sx, y0b + 120), 2, 0.65)
    path = constant_model(tmp_path / "yolox.onnx", (1, 3, 416, 416), {"output": raw})
    out = YoloxDetector(path, foveate=False).detect(np.zeros((375, 1242, 3), np.uint8))
    by_label = sorted(((d.label, round(d.score, 4)), d.box) for d in out)
    want = {("car", 0.8): (40 / sx - 0.5, 60 / sy - 0.5, 104 / sx - 0.5, 92 / sy - 0.5),
            ("truck", 0.7): (300 / sx + x0r - 0.5, 70 / sy - 0.5, 340 / sx + x0r - 0.5, 100 / sy - 0.5),
            ("car", 0.65): (400.0, 40 / sy - 0.5, 850.0, 120 / sy - 0.5)}
    assert {k for k, _ in by_label} == set(want)
    for k, box in by_label:
        np.testing.assert_allclose(box, want[k], atol=1e-3)
    # mosaic off: the same raw boxes read through the letterbox (scale 416 / 1242), no join
    plain = YoloxDetector(path, foveate=False, mosaic=False).detect(np.zeros((375, 1242, 3), np.uint8))
    lx, ly = 416 / 1242, 125 / 375                           # Letterbox.top_left: 416 x int(375 * 416 / 1242)
    np.testing.assert_allclose(plain[0].box, (40 / lx - 0.5, 60 / ly - 0.5, 104 / lx - 0.5, 92 / ly - 0.5), atol=1e-3)
    assert not any(np.allclose(d.box, want[("car", 0.65)], atol=5) for d in plain)


def test_mosaic_settings_are_checked():
    with pytest.raises(ValueError):
        YoloxDetector(mosaic="yes")
    with pytest.raises(ValueError):
        YoloxDetector(mosaic_gap_px=300)


REAL_FRAME = Path(__file__).resolve().parent / "data" / "solidWhiteRight_frame100.jpg"   # see test_yolox.py
REAL_CARS = np.array([(0, 292, 97, 390), (153, 292, 229, 339), (415, 299, 444, 321)], float)


@pytest.mark.skipif(not DEFAULT_MODEL.is_file(), reason="shipped model absent")
def test_shipped_model_on_a_wide_strip_finds_the_far_car_only_through_the_mosaic():
    """Rows 170..469 of the real frame (960x300, KITTI's aspect): letterboxed at 0.43 the white car at ~45 m
    (29x22 px) is lost; the mosaic (0.67) finds it, and the two near cars, without the fovea."""
    from monorarp.core.boxes import iou_matrix

    strip = cv2.imread(str(REAL_FRAME))[170:470]
    want = REAL_CARS - [0, 170, 0, 170]
    best = {}
    for mosaic in (False, True):
        det = YoloxDetector(foveate=False, mosaic=mosaic)
        assert (det.mosaic_plan(960, 300) is not None) is mosaic
        boxes = np.array([d.box for d in det.detect(strip)], float).reshape(-1, 4)
        best[mosaic] = iou_matrix(want, boxes).max(axis=1)
    assert (best[True] > 0.6).all(), best[True]
    assert (best[False][:2] > 0.6).all() and best[False][2] < 0.3, best[False]
