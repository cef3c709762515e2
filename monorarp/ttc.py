"""Constant-velocity time to collision between axis-aligned rectangles in the ego frame.

The paper (section IV-D) simulates vehicles forward at constant relative
velocity until a 10 s horizon or until their rectangles touch. For rectangles
aligned with the ego's axes that simulation has an exact closed form: on each
axis the intervals overlap during one time window; the rectangles collide
during the intersection of the two windows. This is that limit, vectorised.

Ego frame (see :mod:`monorarp.camera`): x lateral (+ right), y longitudinal
(+ ahead), origin at the camera; velocities are relative to the ego (m/s).
"""

from __future__ import annotations

import numpy as np

HORIZON_S = 10.0


def _overlap_window(lo: np.ndarray, hi: np.ndarray, v: np.ndarray, ego_lo: float, ego_hi: float):
    """Times [enter, exit] during which [lo + v t, hi + v t] overlaps [ego_lo, ego_hi]."""
    with np.errstate(divide="ignore", invalid="ignore"):
        t1 = (ego_hi - lo) / v      # other's low edge crosses ego's high edge
        t2 = (ego_lo - hi) / v      # other's high edge crosses ego's low edge
    moving = v != 0
    enter = np.where(moving, np.minimum(t1, t2), -np.inf)
    exit_ = np.where(moving, np.maximum(t1, t2), np.inf)
    overlapping_now = (lo < ego_hi) & (hi > ego_lo)
    # Not moving: overlap forever if overlapping now, never otherwise.
    enter = np.where(~moving & ~overlapping_now, np.inf, enter)
    exit_ = np.where(~moving & ~overlapping_now, -np.inf, exit_)
    return enter, exit_


def time_to_collision(
    x_lo, x_hi, y_lo, y_hi, v_x, v_y,
    ego_x: tuple[float, float], ego_y: tuple[float, float],
    horizon_s: float = HORIZON_S,
) -> np.ndarray:
    """TTC (s) of each other rectangle with the ego rectangle; NaN when none within the horizon.

    ``x_lo..y_hi``: arrays, the other vehicles' extents in the ego frame now (m);
    ``v_x``/``v_y``: their velocities relative to the ego (m/s);
    ``ego_x``/``ego_y``: the ego's own (lo, hi) extents in the same frame (m).
    Rectangles already overlapping give 0.
    """
    x_lo, x_hi, y_lo, y_hi, v_x, v_y = (np.asarray(a, dtype=float) for a in (x_lo, x_hi, y_lo, y_hi, v_x, v_y))
    ex_in, ex_out = _overlap_window(x_lo, x_hi, v_x, *ego_x)
    ey_in, ey_out = _overlap_window(y_lo, y_hi, v_y, *ego_y)
    enter = np.maximum(ex_in, ey_in)
    leave = np.minimum(ex_out, ey_out)
    hit = (enter < leave) & (leave > 0) & (enter <= horizon_s)
    return np.where(hit, np.maximum(enter, 0.0), np.nan)


def ego_extent(length_m: float, width_m: float, forward_offset_m: float, lateral_offset_m: float):
    """The ego's own footprint (x_lo, x_hi), (y_lo, y_hi) in the ego frame.

    The camera sits ``forward_offset_m`` ahead of and ``lateral_offset_m`` right of
    the ego vehicle's centre, so the centre is at (-lateral, -forward).
    """
    cx, cy = -lateral_offset_m, -forward_offset_m
    return (cx - width_m / 2, cx + width_m / 2), (cy - length_m / 2, cy + length_m / 2)
