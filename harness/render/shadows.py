"""Sun shadows of vehicles on the ground, as polygons in a vehicle's model frame.

A vehicle's shadow is the ground footprint of its body swept along the sunlight: the convex hull of
the body box's bottom corners and of its top corners projected along the light onto the ground
(z = 0 of the model frame: the road under the vehicle). Beneath it, darker, the contact shadow: the
footprint itself, where the sky's light does not reach either (the dark band under a real car, the
cue a real detector keys on at a box's bottom edge).

A shadow is drawn as a black, alpha-blended polygon ``SHADOW_LIFT_M`` above the ground; its alpha is
the share of the ground's light it removes (:func:`shadow_alpha`), in sRGB.
"""

from __future__ import annotations

import math

import numpy as np

SHADOW_LIFT_M = 0.03          # above the ground: clear of the road's depth at the ranges a shadow is seen
CONTACT_LIFT_M = 0.035
CONTACT_INSET_M = 0.1         # the contact shadow's inset from the footprint's edges
CONTACT_ALPHA = 0.55          # the share of the sky's light the body keeps off the ground under it
GAMMA = 2.2


def _convex_hull_2d(points: np.ndarray) -> np.ndarray:
    """Counter-clockwise convex hull (K, 2) of (N, 2) points (Andrew's monotone chain)."""
    pts = np.unique(np.asarray(points, dtype=float), axis=0)
    if len(pts) < 3:
        return pts

    def cross(o, a, b) -> float:
        return float((a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0]))

    def half(seq):
        out: list = []
        for p in seq:
            while len(out) >= 2 and cross(out[-2], out[-1], p) <= 1e-12:
                out.pop()
            out.append(p)
        return out

    lower, upper = half(pts), half(pts[::-1])
    return np.array(lower[:-1] + upper[:-1])


def _fan(polygon: np.ndarray, z: float) -> np.ndarray:
    """(K, 2) convex counter-clockwise polygon -> (K - 2, 3, 3) upward-facing triangles at height z."""
    k = len(polygon)
    idx = np.stack([np.zeros(k - 2, int), np.arange(1, k - 1), np.arange(2, k)], axis=1)
    tri = polygon[idx]
    return np.concatenate([tri, np.full((*tri.shape[:2], 1), z)], axis=-1)


def cast_shadow(length: float, width: float, height: float, light_model: np.ndarray) -> np.ndarray:
    """Triangles (F, 3, 3), model frame, of the shadow a ``length`` x ``width`` x ``height`` (m) box
    standing on z = 0 casts for light travelling along ``light_model`` (unit, model frame).
    Empty (0, 3, 3) when the light does not come from above."""
    light = np.asarray(light_model, dtype=float)
    if light[2] > -1e-3:
        return np.zeros((0, 3, 3))
    hl, hw = length / 2, width / 2
    foot = np.array([[-hl, -hw], [hl, -hw], [hl, hw], [-hl, hw]])
    reach = height / -light[2]                       # ray length from the top to the ground
    tops = foot + reach * light[:2]
    return _fan(_convex_hull_2d(np.vstack([foot, tops])), SHADOW_LIFT_M)


def contact_shadow(length: float, width: float) -> np.ndarray:
    """Triangles (2, 3, 3), model frame, of the darker patch right under the body."""
    hl, hw = length / 2 - CONTACT_INSET_M, width / 2 - CONTACT_INSET_M
    return _fan(np.array([[-hl, -hw], [hl, -hw], [hl, hw], [-hl, hw]]), CONTACT_LIFT_M)


def shadow_alpha(ambient: float, intensity: float, sun_elevation_rad: float, strength: float) -> float:
    """Alpha (0..1) of a black polygon that darkens lit level ground to its shadowed value.

    Lit ground reflects ``ambient + intensity / pi * sin(elevation)`` (shading.shade's model), shadowed
    ground ``ambient + (1 - strength) * intensity / pi * sin(elevation)``; the sRGB ratio is the linear
    ratio to 1 / 2.2, and blending black at alpha a multiplies by 1 - a.
    """
    direct = intensity / math.pi * max(0.0, math.sin(sun_elevation_rad))
    lit, shaded = ambient + direct, ambient + (1.0 - strength) * direct
    if lit <= 0:
        return 0.0
    return float(1.0 - (shaded / lit) ** (1.0 / GAMMA))
