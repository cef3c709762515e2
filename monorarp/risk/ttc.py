"""Constant-velocity time to collision between axis-aligned rectangles in the ego frame.

The paper (section IV-D) simulates vehicles forward at constant relative
velocity until a 10 s horizon or until their rectangles touch. For rectangles
aligned with the ego's axes that simulation has an exact closed form: on each
axis the intervals overlap during one time window; the rectangles collide
during the intersection of the two windows. This is that limit, vectorised.

Ego frame (see :mod:`monorarp.core.camera`): x lateral (+ right), y longitudinal
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


def closing_time(gap, v, a) -> np.ndarray:
    """First time t >= 0 (s) at which ``gap + v t + a t^2 / 2`` reaches 0 (inf: never); ``gap`` > 0 (m)."""
    gap, v, a = (np.asarray(x, dtype=float) for x in (gap, v, a))
    with np.errstate(divide="ignore", invalid="ignore"):
        linear = np.where(v < 0, -gap / v, np.inf)
        disc = v * v - 2.0 * a * gap
        root = np.sqrt(np.maximum(disc, 0.0))
        r1, r2 = (-v - root) / a, (-v + root) / a
        roots = np.stack([r1, r2])
        first = np.where(roots >= 0, roots, np.inf).min(axis=0)
    quadratic = np.where(disc >= 0, first, np.inf)
    return np.where(a == 0, linear, quadratic)


def time_to_collision(
    x_lo, x_hi, y_lo, y_hi, v_x, v_y,
    ego_x: tuple[float, float], ego_y: tuple[float, float],
    horizon_s: float = HORIZON_S, a_y=None,
) -> np.ndarray:
    """TTC (s) of each other rectangle with the ego rectangle; NaN when none within the horizon.

    ``x_lo..y_hi``: arrays, the other vehicles' extents in the ego frame now (m);
    ``v_x``/``v_y``: their velocities relative to the ego (m/s);
    ``ego_x``/``ego_y``: the ego's own (lo, hi) extents in the same frame (m).
    ``a_y``: optional relative longitudinal accelerations (m/s^2): a vehicle wholly ahead
    then closes along y at constant acceleration (:func:`closing_time`) and, once it
    touches, stays in contact. Rectangles already overlapping give 0.
    """
    x_lo, x_hi, y_lo, y_hi, v_x, v_y = (np.asarray(a, dtype=float) for a in (x_lo, x_hi, y_lo, y_hi, v_x, v_y))
    ex_in, ex_out = _overlap_window(x_lo, x_hi, v_x, *ego_x)
    ey_in, ey_out = _overlap_window(y_lo, y_hi, v_y, *ego_y)
    if a_y is not None:
        ahead = y_lo >= ego_y[1]
        t_acc = closing_time(np.maximum(y_lo - ego_y[1], 0.0), v_y, np.broadcast_to(np.asarray(a_y, float), v_y.shape))
        ey_in = np.where(ahead, t_acc, ey_in)
        ey_out = np.where(ahead & np.isfinite(t_acc), np.inf, ey_out)
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
