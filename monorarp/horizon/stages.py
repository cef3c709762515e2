"""The horizon stage: the current horizon row for equation 3, per frame (registry kind ``horizon``).

A stage is ``update(image, t) -> HorizonReading``; the state estimator then measures with the
camera pitched to that row (``pitch = atan((cy - row) / fy)``) instead of the calibrated one, and
widens its distance uncertainty by the reading's ``std_px``. No stage (the default) = the
calibrated horizon, exactly as before.

* ``calibrated``: the calibration's row every frame, with a stated one-sigma ``pitch_std_deg``
  (how far the true pitch wanders: mounting tolerance, suspension, vibration).
* ``online``: the row of this frame's lane-line vanishing point
  (:func:`monorarp.horizon.vanishing.vanishing_point` on LSD segments below the calibrated horizon),
  its one-sigma from the weighted least-squares fit of the segments' lines (plus
  ``floor_std_px``); a frame without a usable vanishing point (fewer than ``min_inliers``
  segments, none leaning one way, or a row more than ``max_offset_deg`` from the calibrated
  horizon) holds the last reading for up to ``hold_s`` with its uncertainty widened to
  ``fallback_pitch_std_deg``, then falls back to the calibrated row with that uncertainty.

Rows are image rows (px, OpenCV convention) of the forward vanishing point; on a flat straight
road with no roll that is the horizon of :attr:`monorarp.core.camera.CameraModel.horizon_row`.
"""

from __future__ import annotations

import math

import numpy as np

from monorarp.core.camera import CameraModel
from monorarp.core.ground_profile import GroundProfile, GroundReading
from monorarp.horizon.ground_profile import march_rows, smooth_profile
from monorarp.core.types import HorizonReading
from monorarp.horizon.vanishing import angular_residual, lane_segments, segment_lines, vanishing_point


def pitch_std_px(camera: CameraModel, pitch_std_deg: float) -> float:
    """A pitch uncertainty (deg) as a horizon-row uncertainty (px) at the calibrated pitch."""
    p, s = camera.pitch_rad, math.radians(pitch_std_deg)
    return camera.fy * (math.tan(p + s) - math.tan(p - s)) / 2


def row_std_px(seg: np.ndarray, u: float, v: float, inlier_deg: float = 1.5) -> float:
    """One-sigma (px) of the vanishing point's row from the line fit of its inlier segments.

    Each inlier segment's line gives the residual ``e = a u + b v + c`` (px, its distance from the
    point). A segment's direction error shrinks with its length ``l`` and its residual grows with
    the distance ``r`` from its midpoint to the point, so ``var(e) ~ r^2 / l``: weights
    ``w = l / r^2``. The covariance of (u, v) is ``s^2 (J^T W J)^-1`` with J rows ``(a, b)`` and
    ``s^2`` the weighted residual variance (n - 2 degrees of freedom).
    """
    lines, mid, length = segment_lines(seg)
    inl = angular_residual(lines, mid, u, v) < math.sin(math.radians(inlier_deg))
    if inl.sum() < 3:
        return math.inf
    a, b, c = lines[inl, 0], lines[inl, 1], lines[inl, 2]
    r2 = np.maximum((u - mid[inl, 0]) ** 2 + (v - mid[inl, 1]) ** 2, 1.0)
    e = a * u + b * v + c
    w = length[inl] / r2
    w = w / w.mean()
    s2 = float(np.sum(w * e * e) / (inl.sum() - 2))
    A = np.array([[np.sum(w * a * a), np.sum(w * a * b)], [np.sum(w * a * b), np.sum(w * b * b)]])
    try:
        cov = s2 * np.linalg.inv(A)
    except np.linalg.LinAlgError:
        return math.inf
    return math.sqrt(max(cov[1, 1], 0.0))


class CalibratedHorizon:
    """The calibration's horizon row every frame, with a stated pitch uncertainty (deg)."""

    uses_camera = True   # the registry passes the run's camera

    def __init__(self, camera: CameraModel, pitch_std_deg: float = 0.0) -> None:
        if not (math.isfinite(pitch_std_deg) and 0 <= pitch_std_deg < 10):
            raise ValueError(f"pitch_std_deg must be in [0, 10) deg, got {pitch_std_deg}")
        self.camera = camera
        self.reading = HorizonReading(camera.horizon_row, pitch_std_px(camera, pitch_std_deg), "calibrated")

    def update(self, image: np.ndarray, t: float) -> HorizonReading:
        return self.reading


class OnlineHorizon:
    """Per-frame horizon row from the lane lines' vanishing point (module docstring)."""

    uses_camera = True   # the registry passes the run's camera
    uses_seed = True     # a sweep passes the run's seed

    def __init__(self, camera: CameraModel, roi_margin_px: float = 10.0, min_inliers: int = 4,
                 max_offset_deg: float = 3.0, floor_std_px: float = 0.1, fallback_pitch_std_deg: float = 0.5,
                 hold_s: float = 0.5, seed: int = 0) -> None:
        for name, val in (("roi_margin_px", roi_margin_px), ("max_offset_deg", max_offset_deg),
                          ("floor_std_px", floor_std_px), ("fallback_pitch_std_deg", fallback_pitch_std_deg),
                          ("hold_s", hold_s)):
            if not (math.isfinite(val) and val >= 0):
                raise ValueError(f"{name} must be finite and >= 0, got {val}")
        if min_inliers < 3:
            raise ValueError(f"min_inliers must be >= 3, got {min_inliers}")
        self.camera = camera
        self.roi_top = min(max((camera.horizon_row + roi_margin_px) / camera.height, 0.0), 0.95)
        self.min_inliers = int(min_inliers)
        self.max_offset_px = pitch_std_px(camera, max_offset_deg)
        self.floor_std_px = float(floor_std_px)
        self.fallback_std_px = pitch_std_px(camera, fallback_pitch_std_deg)
        self.hold_s, self.seed = float(hold_s), int(seed)
        self.reset()

    def reset(self) -> None:
        self._rng = np.random.default_rng(self.seed)
        self._last: HorizonReading | None = None
        self._last_t = -math.inf

    def measure(self, image: np.ndarray) -> tuple[float, float] | None:
        """(row, std) px of this frame's vanishing point, or None when it has no usable one."""
        seg = lane_segments(image, roi_top=self.roi_top)
        vp = vanishing_point(seg, rng=self._rng)
        if (vp is None or vp.inliers < self.min_inliers or vp.left == 0 or vp.right == 0
                or abs(vp.v - self.camera.horizon_row) > self.max_offset_px):
            return None
        std = row_std_px(seg, vp.u, vp.v)
        if not math.isfinite(std):
            return None
        return vp.v, math.hypot(std, self.floor_std_px)

    def update(self, image: np.ndarray, t: float) -> HorizonReading:
        got = self.measure(image)
        if got is not None:
            self._last, self._last_t = HorizonReading(got[0], got[1], "vanishing_point"), float(t)
            return self._last
        if self._last is not None and float(t) - self._last_t <= self.hold_s:
            return HorizonReading(self._last.row, max(self._last.std_px, self.fallback_std_px), "held")
        return HorizonReading(self.camera.horizon_row, self.fallback_std_px, "calibrated")


class LaneWidthRanging:
    """The calibrated horizon plus this frame's road distance per row from the lane lines' spacing.

    The state estimator reads a box's distance from the :class:`~monorarp.core.ground_profile.GroundProfile`
    where the road is not the flat ground (:func:`monorarp.state.ground_contact.contact_ground`). Lines: the
    near road's (``LaneLineFinder`` between ``near_m`` and ``ref_far_m``, assumed flat, where each
    line's offset is re-measured), followed from the row of ``start_m`` up to ``max_rise_deg`` above the calibrated horizon (a climb's far road lies
    above it). ``fallback_grade_std``: the grade uncertainty (rise/run) of a box above the profile.
    """

    uses_camera = True   # the registry passes the run's camera

    def __init__(self, camera: CameraModel, marking_width_m: float = 0.15, near_m: float = 6.0,
                 ref_far_m: float = 25.0, start_m: float = 10.0, max_rise_deg: float = 3.0,
                 min_contrast: float = 12.0, fallback_grade_std: float = 0.02, line_range_m: float = 8.0) -> None:
        from monorarp.lanes.lines import LaneLineFinder

        for name, val in (("max_rise_deg", max_rise_deg), ("min_contrast", min_contrast),
                          ("fallback_grade_std", fallback_grade_std)):
            if not (math.isfinite(val) and val >= 0):
                raise ValueError(f"{name} must be finite and >= 0, got {val}")
        if not 0 < near_m < ref_far_m:
            raise ValueError(f"need 0 < near_m < ref_far_m, got {near_m}, {ref_far_m}")
        self.camera = camera
        self.finder = LaneLineFinder(camera, marking_width_m, y_near=near_m, y_far=ref_far_m, x_range_m=line_range_m)
        self.marking_width_m = float(marking_width_m)
        start, ref = (camera.project_ego(np.array([0.0, y, -camera.height_m]))[1] for y in (float(start_m), ref_far_m))
        self.v_start, self.v_ref = min(float(start), camera.height - 1.0), float(ref)
        self.v_stop = max(camera.horizon_row - pitch_std_px(camera, max_rise_deg), 0.0)
        self.min_contrast = float(min_contrast)
        self.fallback_grade_std = float(fallback_grade_std)

    def reset(self) -> None:
        self.finder.reset()

    def update(self, image: np.ndarray, t: float) -> GroundReading:
        from monorarp.lanes.geometry import to_gray

        lines = [(ln.a, ln.b) for ln in self.finder.update(image)]
        rows, s, _, open_end = march_rows(self.camera, to_gray(image), lines, self.v_start, self.v_ref,
                                          self.v_stop, self.marking_width_m, self.min_contrast)
        v, dist, sd = smooth_profile(self.camera, rows, s)
        return GroundReading(self.camera.horizon_row, 0.0, "calibrated",
                             GroundProfile(v, dist, sd, self.fallback_grade_std, open_end))
