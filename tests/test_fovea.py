"""Foveated second pass: crop placement and the merge rules, on hand-made boxes."""

import numpy as np

from monorarp.detection.fovea import Fovea, merge


def test_crop_placement_at_twice_the_full_view_scale():
    # 640x360 frame, 320x192 net: full view at scale 0.5, fovea at 1.0 -> a 320x192 source crop
    f = Fovea.place(640, 360, 320, 192, centre_col=319.5, horizon_row=163.5, zoom=2.0, below=0.25)
    assert (f.w, f.h) == (320, 192)
    assert f.x0 == 160                          # centred on the principal column
    assert 0 <= f.y0 and f.y0 + f.h <= 360
    # the horizon lies a quarter of the way down the crop (within rounding)
    assert abs((163.5 - (f.y0 - 0.5)) / f.h - 0.25) < 0.01
    # crop boxes map back to source pixels by the crop's offset
    assert np.allclose(f.to_src([[0, 0, 10, 10]]), [[160, f.y0, 170, f.y0 + 10]])
    # no gain in resolution: no fovea
    assert Fovea.place(320, 192, 320, 192, 159.5, 90.0) is None


def _fovea():
    return Fovea(x0=160, y0=100, w=320, h=192, src_w=640, src_h=360)


def test_merge_rules():
    fov = _fovea()
    far_full = [300.0, 150.0, 320.0, 165.0]       # small box inside the crop, seen by both passes
    far_fov = [301.0, 151.0, 321.0, 166.0]
    ghost_full = [200.0, 160.0, 208.0, 168.0]     # inside the crop, unconfirmed by the fovea: dropped
    near_full = [0.0, 200.0, 150.0, 350.0]        # outside the crop: kept
    only_fov = [400.0, 140.0, 410.0, 148.0]       # fovea alone, above threshold: kept
    boxes, scores = merge(np.array([far_full, ghost_full, near_full]), np.array([0.6, 0.5, 0.9]),
                          np.array([far_fov, only_fov]), np.array([0.3, 0.7]), fov,
                          score_threshold=0.43, support=0.2, box="fovea")
    got = {tuple(np.round(b, 1)): s for b, s in zip(boxes, scores)}
    assert tuple(near_full) in got and got[tuple(near_full)] == 0.9
    assert tuple(far_fov) in got and got[tuple(far_fov)] == 0.6      # fused: fovea box, the higher score
    assert tuple(only_fov) in got
    assert tuple(ghost_full) not in got and tuple(far_full) not in got
    assert len(boxes) == 3
    assert list(scores) == sorted(scores, reverse=True)
    # plain union without support: the unconfirmed full-view box stays
    boxes_u, _ = merge(np.array([ghost_full]), np.array([0.5]), np.zeros((0, 4)), np.zeros(0), fov,
                       score_threshold=0.43, support=None)
    assert len(boxes_u) == 1


def test_mean_box_for_tall_boxes_and_crop_border_boxes_left_to_full_view():
    fov = _fovea()
    tall_full = np.array([[250.0, 120.0, 300.0, 170.0]])   # 50 px > 0.15 * 192: mean of the two
    tall_fov = np.array([[252.0, 122.0, 302.0, 172.0]])
    boxes, _ = merge(tall_full, np.array([0.8]), tall_fov, np.array([0.8]), fov, 0.43, support=0.2, box="auto")
    assert np.allclose(boxes, [[251.0, 121.0, 301.0, 171.0]])
    cut = np.array([[161.0, 150.0, 175.0, 160.0]])          # touches the crop's left edge: not the fovea's
    boxes, _ = merge(np.zeros((0, 4)), np.zeros(0), cut, np.array([0.9]), fov, 0.43, support=0.2)
    assert len(boxes) == 0
