"""The procedural negatives (training.negatives): figures the right size and shape where the rules put them,
never over a vehicle, facades on the image's sides; seeding; the batch's hand-over and its ordering."""

from __future__ import annotations

import numpy as np
import pytest

from training import clutter, negatives

from tests.test_training_clutter import BOXES, H, W, assert_vehicles_untouched, frame


@pytest.mark.parametrize("cyclist", [False, True])
def test_a_figure_is_as_tall_as_asked_stands_on_its_bottom_row_and_is_a_person_not_a_box(cyclist):
    for seed in range(10):
        col, alpha = negatives.figure(60.0, np.random.default_rng(seed), cyclist)
        assert col.shape[:2] == alpha.shape and 0.0 <= alpha.min() and alpha.max() <= 1.0 + 1e-6
        rows = np.flatnonzero(alpha.max(axis=1) > 0.5)
        assert 55 <= rows[-1] - rows[0] + 1 <= 62                 # head to feet (wheels): the height asked
        assert rows[-1] >= alpha.shape[0] - 2                     # on the ground
        fill = (alpha > 0.5).mean()
        assert 0.1 < fill < (0.45 if cyclist else 0.6)            # a silhouette with gaps, not a filled box
        if not cyclist:
            h, w = alpha.shape
            assert 0.2 < w / h < 0.7                              # upright: narrower than tall


def test_people_never_paint_a_vehicle_box_grown_by_the_margin_and_do_paint():
    painted = 0
    for seed in range(40):
        x0 = frame(seed)
        x = x0.copy()
        negatives.people(x, BOXES, np.random.default_rng(seed))
        assert_vehicles_untouched(x, x0)
        painted += int((np.abs(x - x0).max(axis=2) > 0.05).any())
    assert painted >= 30                                          # most draws find room for someone


def test_people_beside_a_vehicle_stand_on_its_bottom_row_at_its_scale():
    box = np.array([[100.0, 90.0, 140.0, 120.0]])                 # 30 px tall, bottom row 120
    bottoms, heights = [], []
    for seed in range(60):
        x0 = frame(seed)
        x = x0.copy()
        negatives.people(x, box, np.random.default_rng(seed))
        rows = np.flatnonzero((np.abs(x - x0).max(axis=2) > 0.05).any(axis=1))
        if len(rows):
            bottoms.append(rows[-1])
            heights.append(rows[-1] - rows[0] + 1)
    bottoms, heights = np.array(bottoms), np.array(heights)
    near = (bottoms > 110) & (bottoms < 125)                      # beside the vehicle: 80 % of draws
    assert near.mean() > 0.5
    assert 30 <= np.median(heights[near]) <= 46                  # 1.0-1.4 x 30 px, +-10 %
    assert np.mean((heights[near] >= 25) & (heights[near] <= 50)) > 0.9   # (the rest: the 20 % placed anywhere)


def test_facade_stays_out_of_vehicles_and_hangs_on_a_side_above_the_ground():
    for seed in range(30):
        x0 = frame(seed)
        x = x0.copy()
        negatives.facade(x, BOXES, np.random.default_rng(seed))
        assert_vehicles_untouched(x, x0)
        changed = np.abs(x - x0).max(axis=2) > 0.02
        assert changed.any()
        assert not changed[int(0.75 * H) + 1:].any()              # the wall ends above the bottom quarter
        cols = np.flatnonzero(changed.any(axis=0))
        assert cols[-1] - cols[0] + 1 <= 0.5 * W + 1              # at most half the width


def test_augment_is_seeded_and_p0_changes_nothing():
    a, b, c = frame(), frame(), frame()
    negatives.augment(a, BOXES, np.random.default_rng(7), 1.0)
    negatives.augment(b, BOXES, np.random.default_rng(7), 1.0)
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, frame())
    rng = np.random.default_rng(7)
    negatives.augment(c, BOXES, rng, 0.0)
    np.testing.assert_array_equal(c, frame())


def test_the_batch_draws_negatives_before_clutter_and_only_when_asked(monkeypatch):
    pytest.importorskip("torch")
    from training import train
    from training.data import Dataset

    img = np.full((1, 192, 320, 3), 114, np.uint8)
    boxes = np.array([[0, 80.0, 160.0, 200.0, 260.0, 0.0]])
    ds = Dataset(img, boxes, np.array([[640, 360]]), {})
    seen = []
    monkeypatch.setattr(negatives, "augment", lambda x, b, rng, p: seen.append(("negatives", x.shape, p)))
    monkeypatch.setattr(clutter, "augment", lambda x, b, rng, p: seen.append(("clutter", x.shape, p)))
    train.make_batch(ds, np.array([0]), np.random.default_rng(1), 4, True, 0.5, 0.25)
    assert seen == [("negatives", (180, 320, 3), 0.25), ("clutter", (180, 320, 3), 0.5)]
    seen.clear()
    train.make_batch(ds, np.array([0]), np.random.default_rng(1), 4, True, 0.5)
    assert seen == [("clutter", (180, 320, 3), 0.5)]              # default: no negatives, and no draw for them
