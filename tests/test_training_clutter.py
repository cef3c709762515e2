"""The procedural clutter augmentation (training.clutter): where it paints, where it never does, its seeding,
and how the training batch hands it the image window and the boxes."""

from __future__ import annotations

import numpy as np
import pytest

from training import clutter

H, W = 180, 320


def frame(seed: int = 0) -> np.ndarray:
    """A plain float BGR net-input image: sky, then road."""
    x = np.empty((H, W, 3), np.float32)
    x[:70] = (0.9, 0.75, 0.6)
    x[70:] = (0.4, 0.41, 0.43)
    return x + np.random.default_rng(seed).uniform(-0.02, 0.02, x.shape).astype(np.float32)


BOXES = np.array([[40.0, 80.0, 100.0, 130.0], [200.0, 60.0, 230.0, 85.0]])


def grown(box: np.ndarray) -> tuple[slice, slice]:
    x1, y1, x2, y2 = box
    gx, gy = clutter.GROW * (x2 - x1), clutter.GROW * (y2 - y1)
    return slice(int(y1 - gy), int(np.ceil(y2 + gy))), slice(int(x1 - gx), int(np.ceil(x2 + gx)))


def assert_vehicles_untouched(x: np.ndarray, x0: np.ndarray) -> None:
    """Every box of ``BOXES``, grown by the margin, is as it was."""
    for b in BOXES:
        rows, cols = grown(b)
        np.testing.assert_array_equal(x[rows, cols], x0[rows, cols])


def test_foliage_never_paints_a_vehicle_box_grown_by_the_margin_and_paints_elsewhere():
    painted = 0
    for seed in range(30):
        x0 = frame(seed)
        x = x0.copy()
        clutter.foliage(x, BOXES, np.random.default_rng(seed))
        assert_vehicles_untouched(x, x0)
        painted += int((np.abs(x - x0).max(axis=2) > 0.05).sum())
    assert painted > 0.05 * 30 * H * W      # patches cover a real share of the background


def test_shade_only_darkens_below_its_top_row_and_leaves_the_sky_rows():
    for seed in range(30):
        x0 = frame(seed)
        x = x0.copy()
        clutter.shade(x, np.random.default_rng(seed))
        np.testing.assert_array_equal(x[: int(0.1 * H)], x0[: int(0.1 * H)])   # top >= 0.15 H, ramp 0.1 H
        assert (x <= x0 + 1e-7).all()
        assert (x < 0.9 * x0).mean() > 0.05          # 20-70 % in shade, depth >= 0.3


def test_augment_is_seeded_and_p0_changes_nothing():
    a, b, c = frame(), frame(), frame()
    clutter.augment(a, BOXES, np.random.default_rng(7), 1.0)
    clutter.augment(b, BOXES, np.random.default_rng(7), 1.0)
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, frame())
    clutter.augment(c, BOXES, np.random.default_rng(7), 0.0)
    np.testing.assert_array_equal(c, frame())


def test_the_batch_hands_clutter_the_letterbox_content_window_and_its_boxes(monkeypatch):
    pytest.importorskip("torch")
    from training import train
    from training.data import Dataset

    # one 640x360 source frame letterboxed to 320x192: content rows 6..185
    img = np.full((1, 192, 320, 3), 114, np.uint8)
    boxes = np.array([[0, 80.0, 160.0, 200.0, 260.0, 0.0], [0, 400.0, 120.0, 460.0, 170.0, 1.0]])
    ds = Dataset(img, boxes, np.array([[640, 360]]), {})
    seen = []
    monkeypatch.setattr(clutter, "augment", lambda x, b, rng, p: seen.append((x.shape, b.copy(), p)))
    train.make_batch(ds, np.array([0]), np.random.default_rng(1), 4, True, 0.5)
    (shape, b, p), = seen
    assert shape == (180, 320, 3) and p == 0.5
    expect = (boxes[:, 1:5] + 0.5) / 2.0 - 0.5                 # source px -> window px (pixel centres at k)
    flipped = np.stack([319 - expect[:, 2], expect[:, 1], 319 - expect[:, 0], expect[:, 3]], 1)
    assert np.allclose(b, expect) or np.allclose(b, flipped)   # the required and the ignored box, as flipped
    seen.clear()
    train.make_batch(ds, np.array([0]), np.random.default_rng(1), 4, True)
    assert seen == []                                          # default: no clutter


@pytest.mark.parametrize("bad", ["1.5", "-0.1", "nan", "x"])
def test_train_refuses_a_clutter_probability_outside_0_1(bad, capsys):
    pytest.importorskip("torch")
    from training import train

    with pytest.raises(SystemExit) as e:
        train.main(["--data", "nowhere", "--out", "nowhere.pt", "--clutter", bad])
    assert e.value.code == 2 and "not a probability" in capsys.readouterr().err
