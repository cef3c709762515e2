"""The paper's lane-marking ego-speed estimator (Phillips et al. 2019, section VI-A), made robust.

1. OpenCV's line segment detector (LSD) runs on the road below the horizon.
   Segments that point at the vanishing point and have a much brighter side
   (a white marking's left or right border) are kept; each votes for the
   marking centre's lateral ground position (camera model), in a decaying
   histogram. The reference lines are the nearest peaks left and right of the
   camera.
2. At a fixed image row on each reference line (``ref_distance_m`` ahead) the
   marking contrast is sampled every frame; a hysteresis threshold turns it into
   paint present / absent and records the time of each appearance.
3. Speed = known period / time between successive appearances. Robust form: the
   appearance intervals of both sides in the last ``window_s`` are pooled, each
   interval counted as ``round(dt / median dt)`` periods (a missed dash counts
   two), and speed = period x periods / total time — unlike a median of single
   intervals this is not locked to whole numbers of frames.

Time comes from the frame timestamps only.
"""

from __future__ import annotations

from collections import deque

import cv2
import numpy as np

from monorarp.core.camera import CameraModel
from monorarp.lanes.geometry import EgoSpeedError, row_of_distance, row_scale
from monorarp.ego_speed.ground_track import FrameClock, check_image, check_markings


class _Side:
    """Appearance events at the fixed point of one reference line."""

    def __init__(self) -> None:
        self.x: float | None = None          # lateral position of the reference line (m)
        self.on: bool | None = None          # None until the first sample (no event on start-up)
        self.appear: deque[float] = deque()
        self.contrast_hist: deque[float] = deque(maxlen=90)

    def clear_events(self) -> None:
        self.on = None
        self.appear.clear()


class LsdPeriodEgoSpeed(FrameClock):
    """Ego speed (m/s) from the time between dash appearances at a fixed point (the paper's method).

    ``ref_distance_m``: distance ahead (m) of the fixed point on each reference line.
    ``window_s``: appearances older than this are forgotten. ``min_contrast``: gray
    levels by which paint must outshine the road. ``roi_far_m``: LSD runs on the
    image rows seeing the ground up to this distance.
    """

    uses_camera = True   # the registry passes the run's camera

    def __init__(self, camera: CameraModel, stripe_length_m: float = 3.05, period_m: float = 12.19,
                 marking_width_m: float = 0.15, *, ref_distance_m: float = 8.0, window_s: float = 3.0,
                 roi_far_m: float = 40.0, min_contrast: float = 30.0, max_speed_mps: float = 70.0,
                 min_segment_px: float = 8.0, vp_tol_px: float | None = None, decay: float = 0.8,
                 max_gap_s: float = 2.0) -> None:
        check_markings(stripe_length_m, period_m, window_s)
        v_ref = float(row_of_distance(camera, ref_distance_m))
        if not (ref_distance_m > 0 and camera.horizon_row < v_ref <= camera.height - 1):
            raise EgoSpeedError(f"ref_distance_m={ref_distance_m} m is not visible on the ground in this camera's image")
        self.camera = camera
        self.period_m = float(period_m)
        self.stripe_length_m = float(stripe_length_m)
        self.marking_width_m = float(marking_width_m)
        self.window_s = float(window_s)
        self.min_contrast = float(min_contrast)
        self.max_speed_mps = float(max_speed_mps)
        self.min_segment_px = float(min_segment_px)
        self.max_gap_s = float(max_gap_s)
        self.decay = float(decay)
        self.vp_tol_px = float(vp_tol_px) if vp_tol_px is not None else 0.05 * camera.width
        self.ref_distance_m = float(ref_distance_m)
        self.v_ref = int(round(v_ref))
        self.ref_scale = float(row_scale(camera, np.array(float(self.v_ref))))
        self.roi_top = int(np.clip(np.ceil(row_of_distance(camera, roi_far_m)), 0, camera.height - 2))
        self.lsd = cv2.createLineSegmentDetector()
        self.x_bin = 0.1
        self.x_edges = np.arange(-8.0, 8.0 + 1e-9, self.x_bin)
        self.reset()

    def reset(self) -> None:
        """Forget all history."""
        self.hist = np.zeros(self.x_edges.size - 1)
        self.sides = {"left": _Side(), "right": _Side()}
        self._last_t: float | None = None
        self._speed: float | None = None
        self._speed_t: float | None = None
        self.segments = np.zeros((0, 4))

    # ---------------------------------------------------------------- per frame
    def update(self, image_bgr: np.ndarray, t: float) -> float | None:
        """Feed one frame taken at ``t`` (s, its timestamp); return the ego speed (m/s) or None."""
        check_image(image_bgr, self.camera)
        t = float(t)
        if not self._is_new_frame(t):
            return self._current(t)
        gray = image_bgr if image_bgr.ndim == 2 else cv2.cvtColor(image_bgr, cv2.COLOR_BGR2GRAY)
        self._vote(gray)
        self._choose_reference_lines()
        for side in self.sides.values():
            if side.x is not None:
                self._sample(gray, side, t)
        self._estimate(t)
        return self._current(t)

    # ----------------------------------------------------- step 1: reference lines
    def _vote(self, gray: np.ndarray) -> None:
        cam = self.camera
        roi = gray[self.roi_top:]
        found = self.lsd.detect(roi)[0]
        self.hist *= self.decay
        if found is None:
            self.segments = np.zeros((0, 4))
            return
        seg = found.reshape(-1, 4).astype(float)
        seg[:, [1, 3]] += self.roi_top
        u1, v1, u2, v2 = seg.T
        du, dv = u2 - u1, v2 - v1
        length = np.hypot(du, dv)
        ok = (length >= self.min_segment_px) & (np.abs(dv) >= 0.15 * length)
        # Points at the vanishing point: extend to the horizon row.
        with np.errstate(divide="ignore", invalid="ignore"):
            u_h = u1 + (cam.horizon_row - v1) * du / dv
        ok &= np.abs(u_h - cam.cx) <= self.vp_tol_px
        # Bright on one side: sample 2.5 px either side of the midpoint along the normal.
        um, vm = (u1 + u2) / 2, (v1 + v2) / 2
        nu, nv = dv / np.maximum(length, 1e-9), -du / np.maximum(length, 1e-9)
        nu, nv = np.where(nu < 0, -nu, nu), np.where(nu < 0, -nv, nv)      # normal pointing to +u (right)
        h, w = gray.shape

        def at(uu, vv):
            return gray[np.clip(np.round(vv).astype(int), 0, h - 1), np.clip(np.round(uu).astype(int), 0, w - 1)].astype(float)

        right = at(um + 2.5 * nu, vm + 2.5 * nv)
        left = at(um - 2.5 * nu, vm - 2.5 * nv)
        diff = right - left
        ok &= np.abs(diff) >= self.min_contrast
        ok &= vm > cam.horizon_row + 1
        seg, diff, um, vm, length = seg[ok], diff[ok], um[ok], vm[ok], length[ok]
        self.segments = seg
        if not seg.size:
            return
        x_border = cam.ground_point_from_pixel(um, vm)[..., 0]
        # A left border (paint on its right) lies half a marking width left of the centre.
        x_centre = x_border + np.where(diff > 0, 0.5, -0.5) * self.marking_width_m
        self.hist += np.histogram(x_centre, bins=self.x_edges, weights=length)[0]

    def _choose_reference_lines(self) -> None:
        hist = self.hist
        if hist.max() <= 0:
            return
        centres = (self.x_edges[:-1] + self.x_edges[1:]) / 2
        smooth = np.convolve(hist, [0.25, 0.5, 0.25], mode="same")
        thr = 0.15 * smooth.max()
        peak = (smooth >= thr) & (smooth >= np.roll(smooth, 1)) & (smooth >= np.roll(smooth, -1))
        for name, sel in (("left", centres < -0.5), ("right", centres > 0.5)):
            idx = np.flatnonzero(peak & sel)
            side = self.sides[name]
            if idx.size == 0:
                continue
            i = idx[np.argmax(centres[idx])] if name == "left" else idx[np.argmin(centres[idx])]
            j = np.arange(max(0, i - 1), min(hist.size, i + 2))
            x = float((smooth[j] * centres[j]).sum() / smooth[j].sum())
            if side.x is None or abs(x - side.x) > 0.75:
                side.clear_events()          # a new reference line (start-up or lane change)
                side.x = x
            else:
                side.x += 0.2 * (x - side.x)

    # -------------------------------------------------- step 2: the fixed point
    def _sample(self, gray: np.ndarray, side: _Side, t: float) -> None:
        s = self.ref_scale
        u = self.camera.cx + side.x * s
        half = max(1, int(round(0.5 * self.marking_width_m * s)) + 1)
        flank = int(round(0.45 * s))
        h, w = gray.shape
        if not (flank + half <= u < w - flank - half):
            return
        v, ui = self.v_ref, int(round(u))
        paint = float(gray[v - 1: v + 2, ui - half: ui + half + 1].max(axis=1).mean())
        road = 0.5 * (float(gray[v - 1: v + 2, ui - flank].mean()) + float(gray[v - 1: v + 2, ui + flank].mean()))
        c = paint - road
        side.contrast_hist.append(c)
        level = float(np.percentile(side.contrast_hist, 90)) if len(side.contrast_hist) >= 5 else c
        thr_on = max(self.min_contrast, 0.5 * level)
        thr_off = 0.6 * thr_on
        if side.on is None:
            side.on = c >= thr_on
        elif not side.on and c >= thr_on:
            side.on = True
            side.appear.append(t)
        elif side.on and c < thr_off:
            side.on = False
        while side.appear and side.appear[0] < t - self.window_s:
            side.appear.popleft()

    # ------------------------------------------------------ step 3: the speed
    def _estimate(self, t: float) -> None:
        min_dt = self.period_m / self.max_speed_mps
        dts = [np.diff(np.array(s.appear)) for s in self.sides.values() if len(s.appear) >= 2]
        if not dts:
            return
        dt = np.concatenate(dts)
        dt = dt[dt >= min_dt]
        if dt.size == 0:
            return
        med = float(np.median(dt))
        n = np.round(dt / med)
        ok = (n >= 1) & (np.abs(dt / np.maximum(n, 1) - med) <= 0.3 * med)
        periods = float(n[ok].sum())
        if periods < 2:
            return
        v = self.period_m * periods / float(dt[ok].sum())
        if v <= self.max_speed_mps:
            self._speed = v
            self._speed_t = t
