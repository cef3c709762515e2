"""Ego speed from dashed-marking stripe ends followed on the ground plane (the default estimator).

Per frame: lane lines are found on the ground plane (:mod:`.lane_lines`), the
ends of their dashes located to a fraction of a row and mapped to distances
ahead (:mod:`.stripes`). Stripe ends are stationary on the road, so between
frames they all move towards the camera by the ego displacement ``d``. Matching
them is unambiguous modulo the marking period ``P``: the consensus of all
candidate displacements wrapped into ``[-0.1 P, 0.9 P)`` gives ``d``, each end
is then associated with the previous end of the same kind on the same line
that moved by ``d``. The speed is the common slope of all ends' distance over
time in a short window (weighted by their localisation error, with outlier
rejection, :mod:`.regression`). Time comes from the frame timestamps only.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

import numpy as np

from monorarp.core.camera import CameraModel
from monorarp.lanes.geometry import EgoSpeedError
from monorarp.lanes.lines import LaneLineFinder
from monorarp.ego_speed.regression import pooled_slope
from monorarp.ego_speed.stripes import StripeEdgeFinder, StripeEdges


def check_markings(stripe_length_m: float, period_m: float, window_s: float) -> None:
    """Raise :class:`EgoSpeedError` unless 0 < stripe length < period and the window (s) is positive."""
    if not (np.isfinite(stripe_length_m) and stripe_length_m > 0):
        raise EgoSpeedError(f"stripe_length_m must be a positive length in metres, got {stripe_length_m}")
    if not (np.isfinite(period_m) and period_m > stripe_length_m):
        raise EgoSpeedError(f"period_m must be longer than stripe_length_m ({stripe_length_m} m), got {period_m}")
    if not window_s > 0:
        raise EgoSpeedError(f"window_s must be positive, got {window_s}")


def check_image(image: np.ndarray, camera: CameraModel) -> None:
    if not isinstance(image, np.ndarray) or image.ndim not in (2, 3) or image.shape[:2] != (camera.height, camera.width):
        shape = getattr(image, "shape", None)
        raise EgoSpeedError(
            f"image of shape {shape} does not match the camera's {camera.width}x{camera.height} "
            "(expected (height, width[, 3]) uint8)"
        )


class FrameClock:
    """The time bookkeeping both lane-marking estimators share: a frame at an earlier time starts a new
    sequence (``reset``), one at the same time adds nothing, and an estimate older than ``max_gap_s``
    is none. Needs ``reset``, ``max_gap_s``, ``_last_t``, ``_speed`` and ``_speed_t`` on the estimator."""

    def _is_new_frame(self, t: float) -> bool:
        """Whether the frame at ``t`` (s) brings anything new; resets on a time going backwards."""
        if self._last_t is not None and t < self._last_t:
            self.reset()                                 # time went backwards: a new sequence
        elif self._last_t is not None and t == self._last_t:
            return False                                 # duplicate timestamp: nothing new
        self._last_t = t
        return True

    def _current(self, t: float) -> float | None:
        if self._speed is None or self._speed_t is None or t - self._speed_t > self.max_gap_s:
            return None
        return self._speed


@dataclass
class _Frame:
    t: float
    edges: StripeEdges
    ids: np.ndarray


class GroundTrackEgoSpeed(FrameClock):
    """Ego speed (m/s) from stripe ends tracked on the ground plane.

    ``camera``: the calibrated camera. ``stripe_length_m``/``period_m``: dash length
    and repeat distance (m). ``window_s``: regression window (s). ``y_near``/``y_far``:
    ground range used (m ahead of the camera). ``max_speed_mps``: faster estimates are
    rejected. ``max_gap_s``: after this long without tracked stripe ends the
    estimate becomes None. ``min_observations``: stripe-end observations needed in the window.
    """

    uses_camera = True   # the registry passes the run's camera

    def __init__(self, camera: CameraModel, stripe_length_m: float = 3.05, period_m: float = 12.19,
                 marking_width_m: float = 0.15, *, window_s: float = 0.6, y_near: float = 3.0,
                 y_far: float = 30.0, max_speed_mps: float = 70.0, max_gap_s: float = 0.5,
                 min_observations: int = 6, max_lines: int = 4, line_range_m: float = 7.0,
                 min_contrast: float = 20.0) -> None:
        check_markings(stripe_length_m, period_m, window_s)
        self.camera = camera
        self.period_m = float(period_m)
        self.window_s = float(window_s)
        self.max_speed_mps = float(max_speed_mps)
        self.max_gap_s = float(max_gap_s)
        self.min_observations = int(min_observations)
        self.max_lines = int(max_lines)
        self.line_range_m = float(line_range_m)
        self.line_finder = LaneLineFinder(camera, marking_width_m, y_near=max(y_near, 5.0),
                                          y_far=min(y_far, 25.0), x_range_m=line_range_m + 1.0,
                                          min_contrast=min_contrast)
        self.edge_finder = StripeEdgeFinder(camera, stripe_length_m, marking_width_m, y_near=y_near,
                                            y_far=y_far, min_contrast=min_contrast)
        self.reset()

    def reset(self) -> None:
        """Forget all history (lines, tracks, estimate)."""
        self.line_finder.reset()
        self._prev: _Frame | None = None
        self._obs: deque[tuple[float, np.ndarray, np.ndarray, np.ndarray]] = deque()
        self._next_id = 0
        self._last_t: float | None = None
        self._last_match_t: float | None = None
        self._speed: float | None = None
        self._speed_t: float | None = None
        self.lines = []
        self.last_edges = StripeEdges.empty()

    # ---------------------------------------------------------------- per frame
    def update(self, image_bgr: np.ndarray, t: float) -> float | None:
        """Feed one frame taken at ``t`` (s, the frame's timestamp); return the ego speed (m/s) or None."""
        check_image(image_bgr, self.camera)
        t = float(t)
        if not self._is_new_frame(t):
            return self._current(t)
        lines = [ln for ln in self.line_finder.update(image_bgr) if abs(ln.a) <= self.line_range_m]
        self.lines = lines[: self.max_lines]
        edges = self.edge_finder.find(image_bgr, self.lines)
        self.last_edges = edges
        ids = self._associate(edges, t)
        self._prev = _Frame(t, edges, ids)
        if len(edges):
            self._obs.append((t, edges.y, edges.sigma, ids))
        while self._obs and self._obs[0][0] < t - self.window_s - 1e-9:
            self._obs.popleft()
        self._estimate(t)
        return self._current(t)

    # ------------------------------------------------------------ association
    def _associate(self, edges: StripeEdges, t: float) -> np.ndarray:
        """Track ids for this frame's stripe ends (continuing the previous frame's where they match)."""
        ids = np.full(len(edges), -1, dtype=int)
        prev = self._prev
        if prev is not None and len(prev.edges) and len(edges):
            dt = t - prev.t
            pe = prev.edges
            same = (pe.kind[:, None] == edges.kind[None, :]) & (np.abs(pe.x[:, None] - edges.x[None, :]) < 0.5)
            d = pe.y[:, None] - edges.y[None, :]                     # forward displacement candidates
            d_pred = self._displacement(d, same, dt)
            if d_pred is not None:
                gate = np.minimum(0.2 + 3.0 * (pe.sigma[:, None] + edges.sigma[None, :]), 0.3 * self.period_m)
                res = np.abs(d - d_pred)
                ok = same & (res < gate)
                pi, ni = np.nonzero(ok)
                order = np.argsort(res[pi, ni])
                used_p, used_n = set(), set()
                for i, j in zip(pi[order], ni[order]):
                    if i in used_p or j in used_n:
                        continue
                    used_p.add(i)
                    used_n.add(j)
                    ids[j] = prev.ids[i]
                if used_n:
                    self._last_match_t = t
        new = ids < 0
        ids[new] = self._next_id + np.arange(new.sum())
        self._next_id += int(new.sum())
        return ids

    def _displacement(self, d: np.ndarray, same: np.ndarray, dt: float) -> float | None:
        """Ego displacement since the previous frame (m): consensus of candidates modulo the period."""
        P = self.period_m
        lo = -0.1 * P
        cand = lo + np.mod(d[same] - lo, P)
        cand = cand[cand <= self.max_speed_mps * dt]
        prior = None
        if self._speed is not None and self._speed_t is not None and self._prev is not None \
                and self._prev.t - self._speed_t <= self.max_gap_s:
            prior = self._speed * dt
        if cand.size == 0:
            return prior
        support = (np.abs(cand[:, None] - cand[None, :]) < 0.25).sum(axis=1)
        best = int(support.argmax())
        consensus = float(np.median(cand[np.abs(cand - cand[best]) < 0.25]))
        if prior is None:
            return consensus
        if support[best] < 2 or abs(consensus - prior) > 0.25 * abs(prior) + 0.3:
            return prior
        return consensus

    # --------------------------------------------------------------- estimate
    def _estimate(self, t: float) -> None:
        if len(self._obs) < 3:
            return
        ts = np.concatenate([np.full(o[1].size, o[0]) for o in self._obs])
        ys = np.concatenate([o[1] for o in self._obs])
        sg = np.concatenate([o[2] for o in self._obs])
        ids = np.concatenate([o[3] for o in self._obs])
        fit = pooled_slope(ids, ts, ys, sg)
        if fit is None or fit.n_used < self.min_observations:
            return
        v = -fit.slope
        if not -0.5 <= v <= self.max_speed_mps:
            return
        self._speed = max(v, 0.0)
        self._speed_t = t
