"""The annotated display: box colours follow TTC, the gauge follows risk, the input is untouched;
the warning banner and highlight follow the warning state; labels never overlap anything."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from monorarp.app.display import (BANNER_RED, GREEN, ORANGE, RED, YELLOW, draw_frame, layout_frame, place_labels,
                              rects_overlap, ttc_colour)
from monorarp.core.types import FrameResult, ObjectState, RiskEstimate, Track, WarningState


def _result(ttc: dict, risk: float, kind: str = "inverse_ttc") -> FrameResult:
    tracks = [Track(1, (99.5, 199.5, 179.5, 259.5)), Track(2, (399.5, 199.5, 479.5, 259.5))]
    states = {1: ObjectState(1, -2.0, 12.0, 0.0, -5.0), 2: ObjectState(2, 3.0, 30.0, 0.0, 1.0)}
    return FrameResult(index=3, t=0.2, detections=[], tracks=tracks, states=states,
                       risk=RiskEstimate(risk, ttc, kind), timings_ms={"total": 4.0})


def test_ttc_colour_thresholds():
    assert ttc_colour(None) == GREEN and ttc_colour(float("nan")) == GREEN
    assert ttc_colour(1.99) == ORANGE and ttc_colour(2.0) == YELLOW and ttc_colour(3.99) == YELLOW
    assert ttc_colour(4.0) == GREEN and ttc_colour(0.5, warning_s=0.4) == YELLOW
    assert all(ttc_colour(t) != RED for t in (0.1, 1.0, 1.99, 3.0, 9.0, None))   # red: the warned object only


def test_boxes_coloured_by_ttc_and_input_untouched():
    img = np.full((360, 640, 3), 90, np.uint8)
    before = img.copy()
    out = draw_frame(img, _result({1: 1.5, 2: None}, 1 / 1.5))
    assert np.array_equal(img, before) and out.shape == img.shape
    # Bottom edges of the boxes (row 259), away from the labels: track 1 orange (the cue), track 2 green.
    assert tuple(out[259, 140]) == ORANGE
    assert tuple(out[259, 440]) == GREEN
    assert not np.all(out == np.array(RED, np.uint8), axis=2).any()      # no warning: no red anywhere


def _gauge_fill(out: np.ndarray, colour) -> int:
    col = out[:, 640 - 4 - 5]                      # a column inside the gauge bar
    return int(np.all(col == np.array(colour, np.uint8), axis=1).sum())


def test_gauge_fill_scales_with_risk():
    img = np.full((360, 640, 3), 90, np.uint8)
    half = _gauge_fill(draw_frame(img, _result({1: 1.5}, 0.4)), YELLOW)     # 1/risk = 2.5 s -> yellow
    full = _gauge_fill(draw_frame(img, _result({1: 0.5}, 2.0)), ORANGE)     # clipped at full scale
    bar = int(360 * 0.85) - int(360 * 0.2)
    assert abs(half - 0.4 * bar) <= 3 and abs(full - bar) <= 3
    none = draw_frame(img, _result({}, 0.0))
    assert _gauge_fill(none, ORANGE) <= 1 and _gauge_fill(none, GREEN) == 0  # only the 1/warning_s tick
    prob = _gauge_fill(draw_frame(img, _result({}, 0.8, "probability")), ORANGE)
    assert abs(prob - 0.8 * bar) <= 3
    warned = replace(_result({1: 0.5}, 2.0), warning=WarningState(active=True, track_id=1))
    assert abs(_gauge_fill(draw_frame(img, warned), RED) - bar) <= 5         # red only while warning


# --- Warning state and label layout -------------------------------------------------------------


def _scene(w: int, h: int, rng: np.random.Generator, *, cluster: int = 0, n_random: int = 0,
           active: bool = False, ttc_none: bool = False) -> FrameResult:
    """``cluster`` boxes within a 60x20 px region near the horizon, ``n_random`` anywhere, one near box."""
    tracks, states, ttc = [], {}, {}
    x0, y0 = w / 2 - 30 + rng.uniform(-w / 4, w / 4), h / 2 - 10 + rng.uniform(-5, 5)
    for i in range(cluster):
        bw, bh = rng.uniform(3, 14), rng.uniform(3, 12)
        x1, y1 = x0 + rng.uniform(0, 60 - bw), y0 + rng.uniform(0, 20 - bh)
        tracks.append(Track(100 + i, (x1, y1, x1 + bw, y1 + bh)))
    for i in range(n_random):
        bw, bh = rng.uniform(4, w / 3), rng.uniform(4, h / 3)
        x1, y1 = rng.uniform(-bw / 2, w - bw / 2), rng.uniform(0, h - bh / 2)
        tracks.append(Track(200 + i, (x1, y1, min(w - 0.5, x1 + bw), min(h - 0.5, y1 + bh))))
    tracks.append(Track(7, (w * 0.4, h * 0.6, w * 0.6, h * 0.8)))
    for k, tr in enumerate(tracks):
        if rng.uniform() < 0.85:                                 # some tracks have no state yet
            states[tr.id] = ObjectState(tr.id, rng.uniform(-10, 10), rng.uniform(5, 120), 0.0, -1.0)
        ttc[tr.id] = None if rng.uniform() < 0.4 else float(rng.uniform(0.5, 9.0))
    ttc[7] = 1.2
    warning = WarningState(True, 7, None if ttc_none else 1.2, 0, 0.0, (7,)) if active else WarningState()
    return FrameResult(index=int(rng.integers(0, 100000)), t=float(rng.uniform(0, 1000)), detections=[],
                       tracks=tracks, states=states, risk=RiskEstimate(1 / 1.2, ttc), ego_speed=27.0,
                       timings_ms={"total": 12.5}, warning=warning)


def _check_layout(layout, w: int, h: int) -> int:
    placed = [lab.rect for lab in layout.labels if lab.rect is not None]
    for r in placed:
        assert 0 <= r[0] < r[2] <= w and 0 <= r[1] < r[3] <= h, r
        for o in layout.obstacles:
            assert not rects_overlap(r, o), (r, o)
    for i, a in enumerate(placed):
        for b in placed[i + 1:]:
            assert not rects_overlap(a, b), (a, b)
    return len(placed)


@pytest.mark.parametrize("w,h", [(640, 360), (1920, 1080)])
def test_labels_never_overlap_each_other_or_fixed_elements(w, h):
    rng = np.random.default_rng(w)
    for trial in range(30):
        active = trial % 2 == 0
        res = _scene(w, h, rng, cluster=15, n_random=int(rng.integers(0, 6)), active=active)
        layout = layout_frame((h, w, 3), res)
        assert (layout.banner is not None) == active and (layout.marker is not None) == active
        assert (layout.highlight is not None) == active and (layout.indicator is None) == active
        n = _check_layout(layout, w, h)
        if active:                       # the warned object's label comes first and sits next to it
            assert layout.labels[0].track_id == 7 and not layout.labels[0].leader
        # 15 clustered far vehicles, a few others and the near one: every label finds a place.
        assert n == len(res.tracks)
    # Dense random scenes (up to 40 boxes anywhere): no overlap even when some labels find no place.
    for trial in range(20):
        res = _scene(w, h, rng, cluster=int(rng.integers(0, 20)), n_random=int(rng.integers(0, 25)),
                     active=bool(trial % 2))
        assert _check_layout(layout_frame((h, w, 3), res), w, h) > 0


def test_tiny_image_keeps_the_rules():
    rng = np.random.default_rng(2)
    for active in (False, True):
        res = _scene(160, 90, rng, cluster=15, n_random=3, active=active)
        _check_layout(layout_frame((90, 160, 3), res), 160, 90)
        assert draw_frame(np.zeros((90, 160, 3), np.uint8), res).shape == (90, 160, 3)


def test_labels_are_drawn_where_the_layout_puts_them():
    res = _scene(640, 360, np.random.default_rng(5), cluster=15, active=True)
    out = draw_frame(np.full((360, 640, 3), 90, np.uint8), res)
    for lab in layout_frame(out.shape, res).labels:
        x1, y1, x2, y2 = lab.rect
        assert tuple(out[y1, x1]) == lab.colour and tuple(out[y2 - 1, x2 - 1]) == lab.colour   # its frame
        assert tuple(out[y1 + 1, x2 - 2]) == (0, 0, 0)                                        # black ground


def test_place_labels_prefers_above_then_moves_aside():
    box = (100, 100, 140, 120)
    (above,) = place_labels([(30, 10)], [box], (640, 360))
    assert above == (100, 88, 130, 98)                           # touching, above, left-aligned
    blocker = (0, 60, 640, 99)                                   # everything above the box is taken
    (moved,) = place_labels([(30, 10)], [box], (640, 360), [blocker])
    assert moved is not None and not rects_overlap(moved, blocker) and not rects_overlap(moved, box)
    # Two labels for one box never share pixels; a label that fits nowhere is None.
    a, b = place_labels([(30, 10), (30, 10)], [box, box], (640, 360))
    assert a != b and not rects_overlap(a, b)
    assert place_labels([(30, 10)], [box], (640, 360), [(0, 0, 640, 360)]) == [None]
    assert place_labels([(700, 10)], [box], (640, 360)) == [None]


def _red_fraction(img: np.ndarray, rect) -> float:
    x1, y1, x2, y2 = rect
    return float(np.all(img[y1:y2, x1:x2] == np.array(BANNER_RED, np.uint8), axis=-1).mean())


@pytest.mark.parametrize("w,h", [(640, 360), (1280, 720)])
def test_warning_banner_and_highlight_only_when_active(w, h):
    rng = np.random.default_rng(1)
    active = _scene(w, h, rng, cluster=12, active=True)
    inactive = replace(active, warning=WarningState())
    img = np.full((h, w, 3), 90, np.uint8)
    on, off = draw_frame(img, active), draw_frame(img, inactive)
    banner = layout_frame(img.shape, active).banner
    assert banner is not None and layout_frame(img.shape, inactive).banner is None
    assert banner[1] < h // 4 and abs((banner[0] + banner[2]) / 2 - w / 2) <= 1        # top centre
    assert _red_fraction(on, banner) > 0.5
    assert _red_fraction(off, banner) == 0.0 and _red_fraction(off, (0, 0, w, h)) == 0.0
    # The warned object's box (track 7) is framed thick red a few px outside; another box is not.
    band = max(3, h // 120) | 1
    c = 2 + band // 2

    def frame_pixels(out, box):
        x1, y1, x2, y2 = (int(round(box[0] + 0.5)), int(round(box[1] + 0.5)),
                          int(round(box[2] - 0.5)), int(round(box[3] - 0.5)))
        xm, ym = (x1 + x2) // 2, (y1 + y2) // 2
        return [tuple(out[y1 - c - d, xm]) for d in (-1, 0, 1)] + [tuple(out[ym, x1 - c - d]) for d in (-1, 0, 1)] \
            + [tuple(out[y2 + c, xm]), tuple(out[ym, x2 + c])]

    warned = next(t for t in active.tracks if t.id == 7)
    other = next(t for t in active.tracks if t.id == 100)
    assert all(p == RED for p in frame_pixels(on, warned.box))
    assert sum(p == RED for p in frame_pixels(off, warned.box)) <= 3      # at most a (red) label touching it
    assert sum(p == RED for p in frame_pixels(on, other.box)) <= 3
    # The marker above it is a red triangle.
    mx1, my1, mx2, my2 = layout_frame(img.shape, active).marker
    assert my2 <= warned.box[1] and tuple(on[(my1 + my2) // 2 - 1, (mx1 + mx2) // 2]) == RED
    # Without a TTC (hold time) the banner still shows; a warning for a track not in view has no marker.
    held = draw_frame(img, replace(active, warning=replace(active.warning, ttc=None)))
    assert _red_fraction(held, banner) > 0.5
    lost = replace(active, warning=replace(active.warning, track_id=999))
    assert layout_frame(img.shape, lost).marker is None and _red_fraction(draw_frame(img, lost), banner) > 0.5


def test_drawing_is_deterministic_and_independent_of_track_order():
    res = _scene(640, 360, np.random.default_rng(3), cluster=15, n_random=4, active=True)
    img = np.full((360, 640, 3), 90, np.uint8)
    first = draw_frame(img, res)
    assert np.array_equal(first, draw_frame(img, res))
    shuffled = replace(res, tracks=list(reversed(res.tracks)))
    assert np.array_equal(first, draw_frame(img, shuffled))


def test_the_warned_object_shows_the_warning_stages_ttc_the_others_the_cue():
    res = _scene(640, 360, np.random.default_rng(4), cluster=3, active=True)
    res = replace(res, risk=replace(res.risk, ttc={**res.risk.ttc, 7: 2.6, 100: 1.3}),   # the risk's own TTCs
                  warning=replace(res.warning, ttc=1.1))                                 # the warning's, for 7
    layout = layout_frame((360, 640, 3), res)
    labels = {lab.track_id: lab for lab in layout.labels}
    assert labels[7].lines[0] == "#7 FCW TTC 1.1s" and labels[7].colour == RED       # the banner's number, red
    assert labels[100].lines[0].endswith("TTC 1.3s") and "FCW" not in labels[100].lines[0]
    assert labels[100].colour == ORANGE                                               # the cue: 1.3 s < 2 s
    held = layout_frame((360, 640, 3), replace(res, warning=replace(res.warning, ttc=None)))
    assert next(lab for lab in held.labels if lab.track_id == 7).lines[0] == "#7 FCW"   # hold time: no TTC
    idle = layout_frame((360, 640, 3), replace(res, warning=WarningState()))
    seven = next(lab for lab in idle.labels if lab.track_id == 7)
    assert seven.lines[0] == "#7 TTC 2.6s" and seven.colour == YELLOW                   # no alert: the cue


def test_the_layout_modules_do_not_draw():
    import ast
    from pathlib import Path

    import monorarp.app.display as display

    root = Path(display.__file__).parent
    for name in ("content", "placement", "layout", "style"):
        tree = ast.parse((root / f"{name}.py").read_text())
        imported = {a.name.split(".")[0] for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names} \
            | {(n.module or "").split(".")[0] for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)}
        assert "cv2" not in imported, name


def test_legend_only_when_asked_and_labels_keep_clear_of_it():
    from monorarp.app.display.content import LEGEND

    img = np.full((360, 640, 3), 90, np.uint8)
    res = _result({1: 1.5, 2: None}, 1 / 1.5)
    assert layout_frame(img.shape, res).legend is None
    lay = layout_frame(img.shape, res, legend=True)
    x1, y1, x2, y2 = lay.legend
    assert x1 < 10 and y2 > 350 and x2 < 320 and y2 - y1 < 120      # bottom left, under half the width
    assert lay.legend in lay.obstacles and len(LEGEND) == 4
    plain, with_legend = draw_frame(img, res), draw_frame(img, res, legend=True)
    inside = (slice(y1, y2), slice(x1, x2))
    assert np.array_equal(plain[inside], img[inside]) and not np.array_equal(with_legend[inside], img[inside])
    # the legend's samples: a red (warned) box sample and a white text somewhere inside
    assert (with_legend[inside] == RED).all(axis=-1).any() and (with_legend[inside] == 255).all(axis=-1).any()


def test_missed_truth_is_dashed_and_labelled_matched_truth_is_not():
    from monorarp.app.display.content import missed_truth

    img = np.full((360, 640, 3), 90, np.uint8)
    res = _result({1: None, 2: None}, 0.0)
    matched = (101.0, 201.0, 180.0, 260.0)                 # on track 1
    missed = (250.0, 150.0, 330.0, 230.0)                  # no track there
    assert missed_truth([matched, missed], res.tracks) == [1] and missed_truth([missed], []) == [0]
    out = draw_frame(img, res, truth_boxes=[matched, missed])
    top = out[150, 250:330]
    grey = (top == (170, 170, 170)).all(axis=-1)
    assert 0.3 < grey.mean() < 0.8                          # dashes on the missed box's top edge
    above = out[130:150, 250:300]
    assert (above.min(axis=-1) > 120).any()                 # its "missed" text (grey, anti-aliased) above it
    assert (above == 0).all(axis=-1).mean() > 0.2           # on a black background
