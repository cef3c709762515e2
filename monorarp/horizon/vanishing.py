"""Horizon row (and camera pitch) from the lane lines' vanishing point.

On a flat road every painted line parallel to the direction of travel meets
the others at one vanishing point on the horizon (in the image of a camera
with no roll the horizon is the row ``v = cy - fy tan(pitch)``). Per frame:

1. ``cv2.createLineSegmentDetector`` finds segments in the lower part of the
   image (``roi_top`` = fraction of the height where the search starts, 0.5 =
   the lower half);
2. lane-like segments are kept: long enough, and leaning left (``du/dv < 0``,
   a line left of the vanishing point) or right, between ``min_angle_deg`` and
   ``max_angle_deg`` from the horizontal (drops bumpers, roof lines, poles);
3. RANSAC over (left, right) pairs finds the intersection most segments point
   at (angular residual: the angle between a segment and the ray from its
   midpoint to the point), then iteratively reweighted least squares (Cauchy
   weights on the angular residual, length weights) refines it.

Over many frames the rows of the per-frame vanishing points are combined
robustly (median, then the mean of those within 3 scaled MADs). Only the row
is used: a lane change or yaw moves the vanishing point along the horizon,
not off it. Pixels in OpenCV convention (pixel centres at integers).
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass

import cv2
import numpy as np

from monorarp.core.errors import UserError


class HorizonError(UserError, ValueError):
    """The horizon could not be estimated (no usable lane lines)."""


@dataclass(frozen=True)
class VanishingPoint:
    u: float          # px
    v: float          # px
    inliers: int      # segments pointing at it
    left: int         # left-leaning inliers
    right: int        # right-leaning inliers


@dataclass(frozen=True)
class HorizonEstimate:
    """Horizon row (px, in the frames' resolution), the pitch it implies and how it was found."""

    row: float
    pitch_rad: float | None     # None when no camera intrinsics were given
    frames_used: int
    frames_seen: int
    spread_px: float            # scaled MAD of the per-frame rows (px)
    u: float                    # median column of the per-frame vanishing points (px)

    @property
    def pitch_deg(self) -> float | None:
        return None if self.pitch_rad is None else math.degrees(self.pitch_rad)


def pitch_from_horizon(row: float, fy: float, cy: float) -> float:
    """Camera pitch (rad, positive = tilted down) that puts the horizon at ``row``."""
    return math.atan((cy - row) / fy)


# --------------------------------------------------------------------------- segments
_LSD = None


def _lsd():
    global _LSD
    if _LSD is None:
        _LSD = cv2.createLineSegmentDetector()
    return _LSD


def lane_segments(image_bgr: np.ndarray, roi_top: float = 0.5, min_length_frac: float = 0.02,
                  min_angle_deg: float = 12.0, max_angle_deg: float = 88.0) -> np.ndarray:
    """Lane-like LSD segments ``(N, 4)`` as ``x1, y1, x2, y2`` (px), each ordered with ``y1 < y2``.

    ``min_length_frac``: minimum length as a fraction of the image width.
    """
    gray = image_bgr if image_bgr.ndim == 2 else cv2.cvtColor(image_bgr, cv2.COLOR_BGR2GRAY)
    h, w = gray.shape
    top = int(np.clip(round(roi_top * h), 0, h - 2))
    found = _lsd().detect(gray[top:])[0]
    if found is None:
        return np.zeros((0, 4))
    seg = found.reshape(-1, 4).astype(float)
    seg[:, [1, 3]] += top
    swap = seg[:, 1] > seg[:, 3]
    seg[swap] = seg[swap][:, [2, 3, 0, 1]]
    dx, dy = seg[:, 2] - seg[:, 0], seg[:, 3] - seg[:, 1]
    length = np.hypot(dx, dy)
    angle = np.degrees(np.arctan2(dy, np.abs(dx)))   # 0 = horizontal, 90 = vertical
    keep = (length >= max(4.0, min_length_frac * w)) & (angle >= min_angle_deg) & (angle <= max_angle_deg)
    return seg[keep]


# ---------------------------------------------------------------------- vanishing point
def segment_lines(seg: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Unit-normal homogeneous lines (N, 3), midpoints (N, 2), lengths (N,)."""
    p1 = np.column_stack([seg[:, 0:2], np.ones(len(seg))])
    p2 = np.column_stack([seg[:, 2:4], np.ones(len(seg))])
    lines = np.cross(p1, p2)
    lines /= np.hypot(lines[:, 0], lines[:, 1])[:, None]
    mid = (seg[:, 0:2] + seg[:, 2:4]) / 2
    return lines, mid, np.hypot(seg[:, 2] - seg[:, 0], seg[:, 3] - seg[:, 1])


def angular_residual(lines: np.ndarray, mid: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """sin of the angle between each segment and the ray from its midpoint to (u, v); shape (..., N)."""
    u, v = np.asarray(u, float)[..., None], np.asarray(v, float)[..., None]
    d = np.abs(lines[:, 0] * u + lines[:, 1] * v + lines[:, 2])
    r = np.hypot(u - mid[:, 0], v - mid[:, 1])
    return d / np.maximum(r, 1e-9)


def vanishing_point(seg: np.ndarray, *, inlier_deg: float = 1.5, max_pairs: int = 400, irls_iters: int = 10,
                    rng: np.random.Generator | None = None) -> VanishingPoint | None:
    """The point most lane-like segments ``(N, 4)`` (from :func:`lane_segments`) converge to.

    None when there is no left-leaning and right-leaning pair meeting above the
    segments, or fewer than 3 segments agree. Deterministic for a given ``rng``
    (default: seeded 0).
    """
    if len(seg) < 2:
        return None
    lines, mid, length = segment_lines(seg)
    leans_left = (seg[:, 2] - seg[:, 0]) * (seg[:, 3] - seg[:, 1]) < 0   # u grows as v falls: left of the VP
    L, R = np.flatnonzero(leans_left), np.flatnonzero(~leans_left)
    if len(L) == 0 or len(R) == 0:
        return None
    ii, jj = np.meshgrid(L, R, indexing="ij")
    ii, jj = ii.ravel(), jj.ravel()
    if len(ii) > max_pairs:
        rng = rng if rng is not None else np.random.default_rng(0)
        pick = rng.choice(len(ii), size=max_pairs, replace=False)
        ii, jj = ii[pick], jj[pick]
    x = np.cross(lines[ii], lines[jj])
    ok = np.abs(x[:, 2]) > 1e-12
    if not ok.any():
        return None
    u, v = x[ok, 0] / x[ok, 2], x[ok, 1] / x[ok, 2]
    top = np.minimum(seg[ii[ok], 1], seg[jj[ok], 1])
    ok2 = v < top                                           # the VP lies above both segments
    if not ok2.any():
        return None
    u, v = u[ok2], v[ok2]
    thr = math.sin(math.radians(inlier_deg))
    res = angular_residual(lines, mid, u, v)               # (pairs, N)
    score = ((res < thr) * length).sum(axis=1)
    best = int(np.argmax(score))
    u0, v0 = float(u[best]), float(v[best])
    inl = res[best] < thr
    if inl.sum() < 3:
        return None
    # IRLS on the inliers: minimise sum w (a u + b v + c)^2 with w = length / r^2 * Cauchy(angle).
    a, b, c = lines[inl, 0], lines[inl, 1], lines[inl, 2]
    m, ln = mid[inl], length[inl]
    for _ in range(irls_iters):
        r2 = np.maximum((u0 - m[:, 0]) ** 2 + (v0 - m[:, 1]) ** 2, 1.0)
        e = (a * u0 + b * v0 + c) / np.sqrt(r2)
        w = ln / r2 / (1.0 + (e / thr) ** 2)
        A = np.array([[np.sum(w * a * a), np.sum(w * a * b)], [np.sum(w * a * b), np.sum(w * b * b)]])
        rhs = -np.array([np.sum(w * a * c), np.sum(w * b * c)])
        if abs(np.linalg.det(A)) < 1e-12 * max(1.0, np.abs(A).max() ** 2):
            break
        u1, v1 = np.linalg.solve(A, rhs)
        done = abs(u1 - u0) < 1e-3 and abs(v1 - v0) < 1e-3
        u0, v0 = float(u1), float(v1)
        if done:
            break
    final = angular_residual(lines, mid, u0, v0) < thr
    return VanishingPoint(u0, v0, int(final.sum()), int((final & leans_left).sum()), int((final & ~leans_left).sum()))


# ------------------------------------------------------------------------- many frames
def combine_rows(rows: np.ndarray) -> tuple[float, float]:
    """Robust row from per-frame rows: mean of those within 3 scaled MADs of the median; (row, spread px)."""
    rows = np.asarray(rows, float)
    med = float(np.median(rows))
    mad = 1.4826 * float(np.median(np.abs(rows - med)))
    keep = np.abs(rows - med) <= max(3 * mad, 0.5)
    return float(rows[keep].mean()), mad


def estimate_horizon(images: Iterable[np.ndarray], fy: float | None = None, cy: float | None = None, *,
                     roi_top: float = 0.5, min_inliers: int = 3) -> HorizonEstimate:
    """Horizon row over ``images`` (BGR or grey); the pitch too when ``fy``, ``cy`` (px) are given.

    A frame counts when its vanishing point has at least ``min_inliers``
    segments, at least one leaning each way, and lies inside the image's rows.
    Raises :class:`HorizonError` when no frame does.
    """
    rng = np.random.default_rng(0)
    us, vs = [], []
    seen = 0
    height = None
    for img in images:
        seen += 1
        height = img.shape[0]
        vp = vanishing_point(lane_segments(img, roi_top=roi_top), rng=rng)
        if vp is None or vp.inliers < min_inliers or vp.left == 0 or vp.right == 0 or not 0 <= vp.v <= height - 1:
            continue
        us.append(vp.u)
        vs.append(vp.v)
    if not vs:
        raise HorizonError(f"no lane lines converging to a vanishing point in {seen} frame(s); "
                           "the horizon needs a straight road with visible lane markings")
    row, spread = combine_rows(np.array(vs))
    pitch = pitch_from_horizon(row, fy, cy) if fy is not None and cy is not None else None
    return HorizonEstimate(row=row, pitch_rad=pitch, frames_used=len(vs), frames_seen=seen,
                           spread_px=spread, u=float(np.median(us)))
