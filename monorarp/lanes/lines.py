"""Find painted lane lines on the ground plane from a few image rows (no lateral prior).

Each sampled row is resampled to a uniform lateral ground grid (``dx`` m), where
a marking of known width is a bright ridge of constant width at every distance.
Ridge points ``(x, y)`` vote in a Hough space of ground lines ``x = a + b*y``
(``a`` lateral offset at the camera, m; ``b`` slope, i.e. the lines' yaw
relative to the ego heading), accumulated over frames with exponential decay
so dashed lines (painted on ~25% of their length) build up as well as solid ones.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from monorarp.core.camera import CameraModel
from monorarp.lanes.geometry import EgoSpeedError, row_distance, row_of_distance, row_scale, to_gray


@dataclass(frozen=True)
class LaneLine:
    """A ground line ``x = a + b*y`` in the ego frame (m); ``strength`` is its decayed vote count."""

    a: float
    b: float
    strength: float

    def x_at(self, y: np.ndarray) -> np.ndarray:
        return self.a + self.b * np.asarray(y)


def window_means(values: np.ndarray, windows: list[tuple[int, int]]) -> list[np.ndarray]:
    """For each ``(lo, hi)``: the mean of ``values[:, j+lo : j+hi+1]`` for every column j of a 2-D array.

    Columns whose window would leave the array get 0.
    """
    rows, n = values.shape
    c = np.zeros((rows, n + 1), dtype=np.float32)
    np.cumsum(values, axis=1, dtype=np.float32, out=c[:, 1:])
    j0 = max(0, -min(lo for lo, _ in windows))
    j1 = n - max(0, max(hi for _, hi in windows))
    out = []
    for lo, hi in windows:
        m = np.zeros((rows, n), dtype=np.float32)
        m[:, j0:j1] = (c[:, j0 + hi + 1: j1 + hi + 1] - c[:, j0 + lo: j1 + lo]) * np.float32(1.0 / (hi - lo + 1))
        out.append(m)
    return out


class LaneLineFinder:
    """Lane lines from bright ridges on ``n_rows`` image rows between ``y_near`` and ``y_far`` (m ahead).

    ``min_contrast`` (8-bit gray levels) is how much brighter than the road on both
    sides a marking must be; ``decay`` is the per-frame memory of the accumulator.
    """

    def __init__(self, camera: CameraModel, marking_width_m: float = 0.15, *, y_near: float = 5.0,
                 y_far: float = 25.0, n_rows: int = 24, x_range_m: float = 8.0, dx: float = 0.05,
                 max_slope: float = 0.06, n_slopes: int = 13, decay: float = 0.85, min_contrast: float = 20.0,
                 min_separation_m: float = 1.5) -> None:
        if not 0.02 <= marking_width_m <= 1.0:
            raise EgoSpeedError(f"marking_width_m must be in [0.02, 1.0] m, got {marking_width_m}")
        if not 0.0 < decay < 1.0:
            raise EgoSpeedError(f"decay must be in (0, 1), got {decay}")
        v_near = min(row_of_distance(camera, y_near), camera.height - 1.0)
        v_far = row_of_distance(camera, y_far)
        if not v_far < v_near:
            raise EgoSpeedError(f"no ground rows between {y_near} m and {y_far} m for this camera")
        rows = np.unique(np.round(np.linspace(v_near, v_far, n_rows)))
        self.rows_y = row_distance(camera, rows)
        self.x_grid = np.arange(-x_range_m, x_range_m + dx / 2, dx)
        scale = row_scale(camera, rows)
        self._map_x = (camera.cx + self.x_grid[None, :] * scale[:, None]).astype(np.float32)
        self._map_y = np.repeat(rows[:, None], self.x_grid.size, axis=1).astype(np.float32)
        self._inside = (self._map_x >= 0) & (self._map_x <= camera.width - 1)
        half = max(1, int(round(marking_width_m / dx / 2)))
        gap = max(1, int(round(0.1 / dx)))
        flank = max(2, int(round(0.3 / dx)))
        self._centre = (-half + 1 if half > 1 else 0, half - 1 if half > 1 else 0)
        self._left = (-half - gap - flank, -half - gap)
        self._right = (half + gap, half + gap + flank)
        self._nms = half + 1
        self.min_contrast = float(min_contrast)
        self.decay = float(decay)
        self.slopes = np.linspace(-max_slope, max_slope, n_slopes)
        self.a_bin = 0.1
        self.a_edges0 = -x_range_m
        self.n_a = int(round(2 * x_range_m / self.a_bin)) + 1
        self.min_sep_bins = max(1, int(round(min_separation_m / self.a_bin)))
        # A dashed line fills ~25% of rows; expect ~n_rows/4 votes per frame, x 1/(1-decay) at steady state.
        self.min_strength = 0.2 * (len(rows) / 4.0) / (1.0 - decay)
        self.acc = np.zeros((n_slopes, self.n_a), dtype=np.float32)

    def reset(self) -> None:
        self.acc[:] = 0.0

    def ridge_points(self, image: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Ridge points on the sampled rows: lateral ``x`` (m), distance ``y`` (m), contrast (levels)."""
        g = to_gray(cv2.remap(image, self._map_x, self._map_y, cv2.INTER_LINEAR))
        centre, left, right = window_means(g, [self._centre, self._left, self._right])
        r = np.where(self._inside, centre - np.maximum(left, right), 0.0).astype(np.float32)
        local_max = cv2.dilate(r, np.ones((1, 2 * self._nms + 1), np.uint8))
        peak = (r >= self.min_contrast) & (r >= local_max)
        ri, ci = np.nonzero(peak)
        return self.x_grid[ci], self.rows_y[ri], r[ri, ci]

    def update(self, image: np.ndarray) -> list[LaneLine]:
        """Vote with this frame's ridge points; return the current lines, nearest to the camera first."""
        x, y, _ = self.ridge_points(image)
        self.acc *= self.decay
        if x.size:
            a = x[None, :] - self.slopes[:, None] * y[None, :]
            ia = np.round((a - self.a_edges0) / self.a_bin).astype(int)
            ok = (ia >= 0) & (ia < self.n_a)
            flat = (np.arange(self.slopes.size)[:, None] * self.n_a + ia)[ok]
            self.acc += np.bincount(flat, minlength=self.acc.size).reshape(self.acc.shape)
        return self.lines()

    def lines(self) -> list[LaneLine]:
        """Local maxima of the accumulator above ``min_strength``, sorted by |a|."""
        best_slope = self.acc.argmax(axis=0)
        prof = self.acc[best_slope, np.arange(self.n_a)]
        k = self.min_sep_bins
        local_max = cv2.dilate(prof.astype(np.float32)[None, :], np.ones((1, 2 * k + 1), np.uint8))[0]
        peaks = np.flatnonzero((prof >= self.min_strength) & (prof >= local_max))
        out = []
        kept: list[int] = []
        for i in peaks[np.argsort(-prof[peaks])]:
            if any(abs(i - j) <= k for j in kept):        # plateaus: keep one bin of each
                continue
            kept.append(int(i))
            # Sub-bin refinement: vote-weighted mean over the peak's +-1 bins at its slope.
            s = best_slope[i]
            j = np.arange(max(0, i - 1), min(self.n_a, i + 2))
            w = self.acc[s, j]
            a = self.a_edges0 + self.a_bin * float((w * j).sum() / w.sum())
            out.append(LaneLine(a=a, b=float(self.slopes[s]), strength=float(prof[i])))
        out.sort(key=lambda ln: abs(ln.a))
        return out
