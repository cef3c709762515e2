"""Camera calibration from a clip: horizon row, focal length and mounting height from lane markings.

Geometry (square pixels, no roll, camera at height ``h`` pitched down by ``theta``,
``c = cos(theta)``, horizon row ``v_h``, vanishing-point column ``u_0``; ``d = v - v_h``):

* a painted line at lateral offset ``X`` images as ``(u - u_0) / d = c X / h`` — its slope
  ``s`` gives ``X / h`` whatever the focal length, so the ego lane's two lines give
  ``ds = c W / h`` (``W`` the lane width);
* a ground point ``Y`` ahead images at ``1 / d = q`` with ``Y = (f h / c^2) q - h tan(theta)``:
  along a line, dashed markings of period ``P`` (m) repeat with period ``P c^2 / (f h)`` in ``q``.

Each frame is resampled onto the grid ``(s, q)`` (a bird's-eye view in units of ``h``,
needing neither ``f`` nor ``h``). Lane lines are the ridges of constant ``s``; the
autocorrelation along a dashed one gives its period ``T`` in ``q``, so ``K = f h / c^2 = P / T``.
With ``W`` given: ``h = c W / ds`` and ``f = K c^2 / h``; with ``h`` given: ``f = K c^2 / h`` and
``W = h ds / c``. Frames are taken in blocks; the per-block values are combined by their median
and their one-sigma is the scaled MAD over blocks / sqrt(blocks). Pixels: OpenCV convention.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass

import cv2
import numpy as np

from monorarp.core.camera import CameraModel
from monorarp.core.errors import UserError
from monorarp.horizon.vanishing import HorizonError, combine_rows, lane_segments, vanishing_point

US_LANE_WIDTH_M = 3.66      # 12 ft
US_STRIPE_PERIOD_M = 12.19  # 10 ft stripe + 30 ft gap


class CalibrationError(UserError, ValueError):
    """The clip gives no calibration (no lane lines, no dashed markings)."""


@dataclass(frozen=True)
class Value:
    """An estimate and its one-sigma (same unit)."""

    value: float
    sigma: float


@dataclass(frozen=True)
class CalibrationEstimate:
    """What a clip says about its camera (px, m, deg); ``height_given``: ``height_m`` was stated."""

    width: int
    height: int
    horizon_row: Value       # px
    vp_column: float         # px
    focal_px: Value
    hfov_deg: Value
    height_m: Value
    lane_width_m: Value
    height_given: bool
    lane_ratio: Value        # c W / h: the ego lane lines' slope difference
    period_scale: Value      # K = f h / c^2 (px m)
    frames_seen: int
    frames_vp: int           # frames with a vanishing point
    blocks_lanes: int        # blocks with both ego lane lines
    blocks_dashes: int       # blocks with a dashed-line period

    def camera(self) -> CameraModel:
        """The camera file's model: principal point at the image centre, square pixels."""
        f = self.focal_px.value
        cy = (self.height - 1) / 2.0
        return CameraModel(self.width, self.height, f, f, (self.width - 1) / 2.0, cy, self.height_m.value,
                           math.atan((cy - self.horizon_row.value) / f))


def _robust(values: list[float]) -> Value:
    """Median of per-block values, one-sigma = 1.4826 MAD / sqrt(n) (MAD floored by 1 % of the median's
    scale over sqrt(n) to stay honest with two or three blocks that happen to agree)."""
    x = np.asarray(values, float)
    med = float(np.median(x))
    mad = 1.4826 * float(np.median(np.abs(x - med)))
    if len(x) < 2:
        return Value(med, abs(med) * 0.05)
    return Value(med, max(mad, 0.01 * abs(med)) / math.sqrt(len(x)))


# ----------------------------------------------------------------------- the (s, q) view
@dataclass(frozen=True)
class Grid:
    """The (s, q) resampling grid: ``s`` lateral (X / h), ``q`` = 1 / (v - v_h) (1/px)."""

    s: np.ndarray
    q: np.ndarray

    @classmethod
    def for_image(cls, height: int, horizon_row: float, *, s_max: float = 3.0, ds: float = 0.01,
                  near_frac: float = 0.97, far_frac: float = 0.025, n_q: int = 600) -> "Grid":
        d_near = near_frac * (height - 1) - horizon_row
        d_far = max(far_frac * height, 8.0)
        if not d_near > 2 * d_far:
            raise CalibrationError(f"the horizon at row {horizon_row:.1f} px leaves too little road in a "
                                   f"{height}-row image to measure lane markings")
        return cls(np.arange(-s_max, s_max + ds / 2, ds), np.linspace(1.0 / d_near, 1.0 / d_far, n_q))


def ground_view(gray: np.ndarray, grid: Grid, horizon_row: float, vp_column: float) -> np.ndarray:
    """``gray`` resampled onto ``grid``: shape (len(q), len(s)), float32; outside the image NaN."""
    q, s = grid.q[:, None], grid.s[None, :]
    map_v = np.broadcast_to(horizon_row + 1.0 / q, (q.size, s.size)).astype(np.float32)
    map_u = (vp_column + s / q).astype(np.float32)
    out = cv2.remap(gray.astype(np.float32), map_u, map_v, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT,
                    borderValue=np.nan)
    return out


def ridges(view: np.ndarray, ds: float, width_s: float = 0.5) -> np.ndarray:
    """Bright lines narrower than ``width_s`` (units of h) along s: white top-hat, NaN -> 0."""
    k = max(3, int(round(width_s / ds)) | 1)
    v = np.nan_to_num(view, nan=0.0)
    opened = cv2.morphologyEx(v, cv2.MORPH_OPEN, np.ones((1, k), np.uint8))
    out = v - opened
    out[~np.isfinite(view)] = 0.0
    return out


def _peak_refine(y: np.ndarray, i: int) -> float:
    """Sub-sample position of the maximum at ``i`` (parabola through three samples)."""
    if 0 < i < len(y) - 1:
        a, b, c = y[i - 1], y[i], y[i + 1]
        den = a - 2 * b + c
        if den < 0:
            return i + 0.5 * (a - c) / den
    return float(i)


def ego_lines(profile: np.ndarray, s: np.ndarray, *, min_abs_s: float = 0.15, rel: float = 0.25,
              max_abs_s: float = 2.5) -> tuple[float, float] | None:
    """The ego lane's lines (s_left < 0 < s_right) in a column profile of ridge strength: the peaks
    nearest s = 0 on each side above ``rel`` times the profile's highest one; None if a side has none."""
    p = cv2.GaussianBlur(profile.astype(np.float32)[None, :], (0, 0), sigmaX=2.0)[0]
    top = float(p.max())
    if not top > 0:
        return None
    is_peak = (p[1:-1] > p[:-2]) & (p[1:-1] >= p[2:]) & (p[1:-1] >= rel * top)
    idx = np.flatnonzero(is_peak) + 1
    pos = np.array([s[0] + _peak_refine(p, i) * (s[1] - s[0]) for i in idx])
    left = pos[(pos < -min_abs_s) & (pos > -max_abs_s)]
    right = pos[(pos > min_abs_s) & (pos < max_abs_s)]
    if not len(left) or not len(right):
        return None
    return float(left.max()), float(right.min())


def line_profile(ridge: np.ndarray, s: np.ndarray, s_line: float, half: float = 0.06) -> np.ndarray:
    """Ridge strength along q on the line at ``s_line`` (max over ``+-half``), shape (len(q),)."""
    sel = np.abs(s - s_line) <= half
    return ridge[:, sel].max(axis=1)


def is_dashed(profile: np.ndarray, *, max_on: float = 0.7, max_gap_level: float = 0.3) -> bool:
    """A line profile with gaps: under ``max_on`` of it above half its 95th percentile, and its 10th
    percentile under ``max_gap_level`` of that (a solid line is on almost everywhere)."""
    top = float(np.percentile(profile, 95))
    if not top > 0:
        return False
    return bool(np.mean(profile > 0.5 * top) < max_on and np.percentile(profile, 10) < max_gap_level * top)


def autocorrelation(x: np.ndarray) -> np.ndarray:
    """Unbiased normalised autocorrelation of a 1-D signal less its quadratic trend (a line fading with
    distance), lags 0..len-1."""
    n = len(x)
    t = np.linspace(-1.0, 1.0, n)
    x = x - np.polyval(np.polyfit(t, x, 2), t)
    f = np.fft.rfft(x, 2 * n)
    r = np.fft.irfft(f * np.conj(f))[:n] / (n - np.arange(n))
    return r / r[0] if r[0] > 0 else np.zeros(n)


def dash_period(acf: np.ndarray, *, max_frac: float = 0.7, min_corr: float = 0.2) -> float | None:
    """Lag (samples) of a dashed line's period in its autocorrelation ``acf``: after the first dip below
    zero, the first local maximum reaching half the highest one there (within ``max_frac`` of the
    span); None if that highest one is below ``min_corr`` (a solid line, noise)."""
    n = int(max_frac * len(acf))
    neg = np.flatnonzero(acf[:n] < 0)
    if not len(neg) or n - int(neg[0]) < 3:
        return None
    lo = int(neg[0])
    a = acf[lo:n]
    top = float(a.max())
    if top < min_corr:
        return None
    for i in range(1, len(a) - 1):
        if a[i] >= 0.5 * top and a[i] >= a[i - 1] and a[i] > a[i + 1]:
            return lo + _peak_refine(a, i)
    return None


# ------------------------------------------------------------------------------ the clip
def _gray(img: np.ndarray) -> np.ndarray:
    return img if img.ndim == 2 else cv2.cvtColor(img, cv2.COLOR_BGR2GRAY)


def calibrate(images: Iterable[np.ndarray], *, lane_width_m: float = US_LANE_WIDTH_M,
              height_m: float | None = None, stripe_period_m: float = US_STRIPE_PERIOD_M,
              block: int = 10) -> CalibrationEstimate:
    """Estimate the camera of ``images`` (BGR or grey, one size) from its lane markings.

    ``height_m`` given: the focal length from it, the lane width implied; else the height from
    ``lane_width_m``. Raises :class:`CalibrationError` (no vanishing point, no ego lane lines, no
    dashed markings). Deterministic.
    """
    if not (lane_width_m > 0 and stripe_period_m > 0 and (height_m is None or height_m > 0)):
        raise CalibrationError("lane width, stripe period and height must be positive")
    rng = np.random.default_rng(0)
    grays: list[np.ndarray] = []
    vp: list[tuple[float, float] | None] = []
    for img in images:
        if grays and img.shape[:2] != grays[0].shape:
            raise CalibrationError(f"frame {len(grays)} is {img.shape[1]}x{img.shape[0]}, the first "
                                   f"{grays[0].shape[1]}x{grays[0].shape[0]}")
        g = _gray(img)
        grays.append(g)
        p = vanishing_point(lane_segments(g), rng=rng)
        ok = p is not None and p.inliers >= 3 and p.left > 0 and p.right > 0 and 0 <= p.v <= g.shape[0] - 1
        vp.append((p.u, p.v) if ok else None)
    if not grays:
        raise CalibrationError("no frames")
    H, W = grays[0].shape
    found = [(i, x) for i, x in enumerate(vp) if x is not None]
    if not found:
        raise HorizonError(f"no lane lines converging to a vanishing point in {len(grays)} frame(s); "
                           "calibration needs a straight road with visible lane markings")
    row, _ = combine_rows(np.array([x[1] for _, x in found]))
    u_med = float(np.median([x[0] for _, x in found]))
    n_blocks = max(1, len(grays) // block)
    rows_b = [combine_rows(np.array(r))[0] for b in range(n_blocks)
              if (r := [x[1] for i, x in found if i * n_blocks // len(grays) == b])]
    horizon = Value(row, _robust(rows_b).sigma if len(rows_b) > 1 else 1.0)

    grid = Grid.for_image(H, row)
    ds = float(grid.s[1] - grid.s[0])
    ratios: list[float] = []
    periods: list[float] = []
    for b in range(n_blocks):
        members = [i for i in range(len(grays)) if i * n_blocks // len(grays) == b]
        rid = []
        for i in members:
            u0 = vp[i][0] if vp[i] is not None else u_med
            rid.append(ridges(ground_view(grays[i], grid, row, u0), ds))
        profile = np.mean([r.mean(axis=0) for r in rid], axis=0)
        lines = ego_lines(profile, grid.s)
        if lines is None:
            continue
        ratios.append(lines[1] - lines[0])
        acfs = [autocorrelation(p) for r in rid for s_line in lines
                if is_dashed(p := line_profile(r, grid.s, s_line))]
        lag = dash_period(np.mean(acfs, axis=0)) if len(acfs) >= max(1, len(members) // 2) else None
        if lag is not None:
            periods.append(lag * float(grid.q[1] - grid.q[0]))
    if not ratios:
        raise CalibrationError(f"no lane lines on both sides of the camera in {len(grays)} frame(s); "
                               "calibration needs visible lane markings")
    if not periods:
        raise CalibrationError(f"no dashed lane markings found in {len(grays)} frame(s); the focal length "
                               "needs the period of dashed lines")
    ratio = _robust(ratios)
    K = _robust([stripe_period_m / t for t in periods])
    return _solve(W, H, horizon, u_med, ratio, K, lane_width_m, height_m, len(grays), len(found),
                  len(ratios), len(periods))


def _solve(width: int, height: int, horizon: Value, u0: float, ratio: Value, K: Value, lane_width_m: float,
           height_m: float | None, seen: int, n_vp: int, n_lanes: int, n_dash: int) -> CalibrationEstimate:
    """Height, focal length, field of view and lane width from ``ratio`` (c W / h) and ``K`` (f h / c^2),
    iterating the pitch's cosine c; one-sigmas propagated to first order (W or h taken as exact)."""
    cy = (height - 1) / 2.0
    c = 1.0
    for _ in range(5):
        if height_m is None:
            h = c * lane_width_m / ratio.value
        else:
            h = height_m
        f = K.value * c * c / h
        c = math.cos(math.atan((cy - horizon.value) / f))
    rk, rr = K.sigma / K.value, ratio.sigma / ratio.value
    if height_m is None:
        f_rel, h_rel, w_rel = math.hypot(rk, rr), rr, 0.0
        lane = Value(lane_width_m, 0.0)
    else:
        f_rel, h_rel, w_rel = rk, 0.0, rr
        lane = Value(h * ratio.value / c, h * ratio.value / c * w_rel)
    half = (width / 2.0) / f
    hfov = 2 * math.degrees(math.atan(half))
    hfov_sigma = 2 * math.degrees(half / (1 + half * half)) * f_rel
    return CalibrationEstimate(width, height, horizon, u0, Value(f, f * f_rel), Value(hfov, hfov_sigma),
                               Value(h, h * h_rel), lane, height_m is not None, ratio, K, seen, n_vp,
                               n_lanes, n_dash)
