"""OpenCV lens distortion ``(k1, k2, p1, p2, k3)`` on normalised image coordinates: distort, undistort, validity.

The model (OpenCV's ``projectPoints``): an ideal (pinhole) point ``(x, y) = (X / Z, Y / Z)`` of the camera
frame, ``r^2 = x^2 + y^2``, goes to ``x' = x g + 2 p1 x y + p2 (r^2 + 2 x^2)``, ``y' = y g + p1 (r^2 + 2 y^2)
+ 2 p2 x y`` with ``g = 1 + k1 r^2 + k2 r^4 + k3 r^6``; pixels ``u = fx x' + cx``, ``v = fy y' + cy``.

The polynomial folds back at some radius (barrel distortion, ``k1 < 0``, turns round at ``r ~ 1 /
sqrt(-3 k1)``): a camera is valid only if it does not fold inside its image (:func:`check`). Beyond the
*valid radius* :func:`valid_radius` (where the radial map's slope falls to :data:`MIN_SLOPE`) the radial map
is continued by its tangent line and the tangential terms are held at their value on that circle, so that
points far outside the image (a vehicle beside the ego) still project monotonically instead of folding back
into the image; inside it the model is OpenCV's exactly.
"""

from __future__ import annotations

import functools
import math

import numpy as np

ZERO = (0.0, 0.0, 0.0, 0.0, 0.0)
#: slope ``d r_d / d r`` of the radial map below which it counts as folding (the valid radius ends there)
MIN_SLOPE = 0.1
#: the largest ideal radius looked at (``tan(88.9 deg)``): a lens that has not folded by then never does here
R_CAP = 50.0
_ITERATIONS = 40


def coefficients(k) -> tuple[float, float, float, float, float]:
    """``(k1, k2, p1, p2, k3)`` as floats from 4 (``k3 = 0``) or 5 numbers; ValueError otherwise."""
    k = tuple(float(x) for x in k)
    if len(k) == 4:
        k = (*k, 0.0)
    if len(k) != 5:
        raise ValueError(f"distortion must be [k1, k2, p1, p2] or [k1, k2, p1, p2, k3], got {len(k)} numbers")
    return k


def _radial(r, k):
    """``(r_d, d r_d / d r)`` of the radial polynomial at ideal radius ``r``."""
    k1, k2, _, _, k3 = k
    r2 = r * r
    return r * (1 + r2 * (k1 + r2 * (k2 + r2 * k3))), 1 + r2 * (3 * k1 + r2 * (5 * k2 + r2 * 7 * k3))


@functools.lru_cache(maxsize=64)
def valid_radius(k: tuple) -> float:
    """The ideal radius up to which the radial map ``r -> r g(r)`` rises with slope above :data:`MIN_SLOPE`
    (:data:`R_CAP` when it never falls so low); inf without radial terms."""
    if k[0] == k[1] == k[4] == 0.0:
        return math.inf
    r = np.linspace(0.0, R_CAP, 200_001)
    with np.errstate(all="ignore"):
        slope = _radial(r, k)[1]
    slow = np.flatnonzero(~(slope > MIN_SLOPE))
    return float(r[slow[0] - 1]) if len(slow) else R_CAP


def _parts(x, y, k, R):
    """Radial factor ``g`` and tangential offsets at (x, y), with the continuation beyond radius ``R``."""
    k1, k2, p1, p2, k3 = k
    r = np.hypot(x, y)
    beyond = r > R
    if np.any(beyond):
        s = np.where(beyond, R / np.maximum(r, 1e-300), 1.0)
        xt, yt = x * s, y * s                          # the point held on the valid circle (tangential terms)
        rd_R, slope_R = _radial(R, k)
        with np.errstate(divide="ignore", invalid="ignore"):
            g_out = (rd_R + slope_R * (r - R)) / r
    else:
        xt, yt, g_out = x, y, 0.0
    r2 = x * x + y * y
    g = np.where(beyond, g_out, 1 + r2 * (k1 + r2 * (k2 + r2 * k3)))
    rt2 = xt * xt + yt * yt
    tx = 2 * p1 * xt * yt + p2 * (rt2 + 2 * xt * xt)
    ty = p1 * (rt2 + 2 * yt * yt) + 2 * p2 * xt * yt
    return g, tx, ty


def distort(xy: np.ndarray, k: tuple) -> np.ndarray:
    """(..., 2) ideal normalised points -> (..., 2) distorted normalised points (OpenCV's model)."""
    xy = np.asarray(xy, dtype=float)
    x, y = xy[..., 0], xy[..., 1]
    g, tx, ty = _parts(x, y, k, valid_radius(k))
    return np.stack([x * g + tx, y * g + ty], axis=-1)


def jacobian(x: np.ndarray, y: np.ndarray, k: tuple) -> np.ndarray:
    """(..., 2, 2) Jacobian of the OpenCV polynomial map (no continuation) at ideal points (x, y)."""
    k1, k2, p1, p2, k3 = k
    r2 = x * x + y * y
    g = 1 + r2 * (k1 + r2 * (k2 + r2 * k3))
    dg = k1 + r2 * (2 * k2 + r2 * 3 * k3)              # d g / d (r^2)
    j00 = g + 2 * x * x * dg + 2 * p1 * y + 6 * p2 * x
    j01 = 2 * x * y * dg + 2 * p1 * x + 2 * p2 * y
    j10 = 2 * x * y * dg + 2 * p1 * x + 2 * p2 * y
    j11 = g + 2 * y * y * dg + 6 * p1 * y + 2 * p2 * x
    return np.stack([np.stack([j00, j01], axis=-1), np.stack([j10, j11], axis=-1)], axis=-2)


def undistort(xy_d: np.ndarray, k: tuple) -> np.ndarray:
    """(..., 2) distorted normalised points -> (..., 2) ideal ones: Newton's method on :func:`distort`
    (its Jacobian taken on the valid circle beyond it), from the distorted point."""
    q = np.asarray(xy_d, dtype=float)
    R = valid_radius(k)
    p = q.copy()
    for _ in range(_ITERATIONS):
        res = distort(p, k) - q
        if not np.any(np.abs(res) > 1e-13):
            break
        r = np.hypot(p[..., 0], p[..., 1])
        s = np.where(r > R, R / np.maximum(r, 1e-300), 1.0)
        J = jacobian(p[..., 0] * s, p[..., 1] * s, k)
        det = J[..., 0, 0] * J[..., 1, 1] - J[..., 0, 1] * J[..., 1, 0]
        det = np.where(np.abs(det) > 1e-12, det, 1e-12)
        dx = (J[..., 1, 1] * res[..., 0] - J[..., 0, 1] * res[..., 1]) / det
        dy = (J[..., 0, 0] * res[..., 1] - J[..., 1, 0] * res[..., 0]) / det
        p = p - np.stack([dx, dy], axis=-1)
    return p


def border_points(width: int, height: int, step: float = 2.0) -> np.ndarray:
    """(N, 2) pixel points along the image's outer border (continuous coordinates, -0.5 .. size - 0.5)."""
    us = np.append(np.arange(-0.5, width - 0.5, step), width - 0.5)
    vs = np.append(np.arange(-0.5, height - 0.5, step), height - 0.5)
    return np.concatenate([np.stack([us, np.full_like(us, -0.5)], 1), np.stack([us, np.full_like(us, height - 0.5)], 1),
                           np.stack([np.full_like(vs, -0.5), vs], 1), np.stack([np.full_like(vs, width - 0.5), vs], 1)])


def check(width: int, height: int, fx: float, fy: float, cx: float, cy: float, k: tuple) -> str | None:
    """Why a camera with distortion ``k`` cannot be inverted over its image (one line), or None.

    The radial map must still rise (slope above :data:`MIN_SLOPE`) where the image's farthest corner lies,
    the map's Jacobian must keep its orientation over the image's ideal region, and undistorting the
    image's border then distorting it again must give it back within 1e-6 px.
    """
    with np.errstate(all="ignore"):       # absurd coefficients overflow: that is the answer, not a warning
        return _check(width, height, fx, fy, cx, cy, k)


@functools.lru_cache(maxsize=64)
def _check(width: int, height: int, fx: float, fy: float, cx: float, cy: float, k: tuple) -> str | None:
    corners = np.array([[-0.5, -0.5], [width - 0.5, -0.5], [-0.5, height - 0.5], [width - 0.5, height - 0.5]])
    rd_corner = float(np.hypot((corners[:, 0] - cx) / fx, (corners[:, 1] - cy) / fy).max())
    R = valid_radius(k)
    if math.isfinite(R) and _radial(R, k)[0] < rd_corner * (1 + 1e-9):
        return (f"distortion {list(k)} folds the image back: its radial map turns round at "
                f"{_radial(R, k)[0] * fx:.0f} px from the principal point, inside the image (its corner is "
                f"{rd_corner * fx:.0f} px away); it is not invertible there")
    border = border_points(width, height)
    d = np.stack([(border[:, 0] - cx) / fx, (border[:, 1] - cy) / fy], axis=1)
    ideal = undistort(d, k)
    back = distort(ideal, k)
    err = np.abs((back - d) * (fx, fy)).max()
    if not err < 1e-6:
        return f"distortion {list(k)} cannot be inverted at the image border (round trip off by {err:.3g} px)"
    # the Jacobian's determinant over the ideal region of the image (a polar grid out to its border)
    r_max = float(np.hypot(ideal[:, 0], ideal[:, 1]).max())
    rr, th = np.meshgrid(np.linspace(0, min(r_max, R), 200), np.linspace(0, 2 * math.pi, 360, endpoint=False))
    J = jacobian(rr * np.cos(th), rr * np.sin(th), k)
    det = J[..., 0, 0] * J[..., 1, 1] - J[..., 0, 1] * J[..., 1, 0]
    if not det.min() > 0:
        return f"distortion {list(k)} folds the image over itself (its tangential terms): it is not invertible"
    return None


def ideal_bounds(width: int, height: int, fx: float, fy: float, cx: float, cy: float, k: tuple
                 ) -> tuple[float, float, float, float]:
    """``(u0, v0, u1, v1)``: the extent (ideal pinhole pixels, same K) of the rays the distorted image sees."""
    border = border_points(width, height, step=1.0)
    ideal = undistort(np.stack([(border[:, 0] - cx) / fx, (border[:, 1] - cy) / fy], axis=1), k)
    u, v = ideal[:, 0] * fx + cx, ideal[:, 1] * fy + cy
    return float(u.min()), float(v.min()), float(u.max()), float(v.max())
