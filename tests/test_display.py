"""The annotated display: box colours follow TTC, the gauge follows risk, the input is untouched."""

from __future__ import annotations

import numpy as np

from monorarp.display import GREEN, ORANGE, RED, YELLOW, draw_frame, ttc_colour
from monorarp.types import FrameResult, ObjectState, RiskEstimate, Track


def _result(ttc: dict, risk: float, kind: str = "inverse_ttc") -> FrameResult:
    tracks = [Track(1, (99.5, 199.5, 179.5, 259.5)), Track(2, (399.5, 199.5, 479.5, 259.5))]
    states = {1: ObjectState(1, -2.0, 12.0, 0.0, -5.0), 2: ObjectState(2, 3.0, 30.0, 0.0, 1.0)}
    return FrameResult(index=3, t=0.2, detections=[], tracks=tracks, states=states,
                       risk=RiskEstimate(risk, ttc, kind), timings_ms={"total": 4.0})


def test_ttc_colour_thresholds():
    assert ttc_colour(None) == GREEN and ttc_colour(float("nan")) == GREEN
    assert ttc_colour(1.99) == RED and ttc_colour(2.0) == ORANGE and ttc_colour(3.99) == ORANGE
    assert ttc_colour(4.0) == YELLOW and ttc_colour(0.5, warning_s=0.4) == ORANGE


def test_boxes_coloured_by_ttc_and_input_untouched():
    img = np.full((360, 640, 3), 90, np.uint8)
    before = img.copy()
    out = draw_frame(img, _result({1: 1.5, 2: None}, 1 / 1.5))
    assert np.array_equal(img, before) and out.shape == img.shape
    # Bottom edges of the boxes (row 259), away from the labels: track 1 red, track 2 green.
    assert tuple(out[259, 140]) == RED
    assert tuple(out[259, 440]) == GREEN


def _gauge_fill(out: np.ndarray, colour) -> int:
    col = out[:, 640 - 4 - 5]                      # a column inside the gauge bar
    return int(np.all(col == np.array(colour, np.uint8), axis=1).sum())


def test_gauge_fill_scales_with_risk():
    img = np.full((360, 640, 3), 90, np.uint8)
    half = _gauge_fill(draw_frame(img, _result({1: 1.5}, 0.4)), ORANGE)     # 1/risk = 2.5 s -> orange
    full = _gauge_fill(draw_frame(img, _result({1: 0.5}, 2.0)), RED)        # clipped at full scale
    bar = int(360 * 0.85) - int(360 * 0.2)
    assert abs(half - 0.4 * bar) <= 3 and abs(full - bar) <= 3
    none = draw_frame(img, _result({}, 0.0))
    assert _gauge_fill(none, RED) <= 1 and _gauge_fill(none, GREEN) == 0     # only the 1/warning_s tick
    prob = _gauge_fill(draw_frame(img, _result({}, 0.8, "probability")), RED)
    assert abs(prob - 0.8 * bar) <= 3
