"""Stripe ends of dashed markings along lane lines, located on the ground plane.

For every lane line the road is sampled at every image row between the near
and far distances (so no resolution is lost), at the line and at two flanks
``flank_m`` to each side. The marking contrast profile is
``max(line samples) - mean(flank samples)`` (gray levels). Its crossings of half
the marking contrast are the stripe ends; their row is interpolated to a
fraction of a pixel and mapped to a ground distance through the camera model.

Edge kinds: ``NEAR`` = the stripe's near end (road -> paint going away from the
camera), ``FAR`` = its far end (paint -> road).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from monorarp.core.camera import CameraModel
from monorarp.lanes.geometry import GroundRows, row_distance, to_gray
from monorarp.lanes.lines import LaneLine

NEAR, FAR = 0, 1


@dataclass(frozen=True)
class StripeEdges:
    """Stripe ends found in one frame (arrays of equal length).

    ``y``: distance ahead (m); ``x``: lateral position of their line (m);
    ``kind``: NEAR/FAR; ``line``: index into the frame's line list;
    ``sigma``: 1-sigma localisation error (m) from the ground length of one row.
    """

    y: np.ndarray
    x: np.ndarray
    kind: np.ndarray
    line: np.ndarray
    sigma: np.ndarray

    @classmethod
    def empty(cls) -> "StripeEdges":
        z = np.zeros(0)
        return cls(z, z, z.astype(int), z.astype(int), z)

    def __len__(self) -> int:
        return int(self.y.size)


class StripeEdgeFinder:
    """Samples contrast profiles along lane lines and extracts validated stripe ends.

    ``stripe_length_m`` is the painted length of one dash; stripes whose visible
    length disagrees with it by more than ``length_tol`` (fraction) are not used
    (solid lines, vehicles, glare). ``edge_sigma_px`` is the assumed localisation
    error of one stripe end in image rows.
    """

    def __init__(self, camera: CameraModel, stripe_length_m: float, marking_width_m: float = 0.15, *,
                 y_near: float = 3.0, y_far: float = 30.0, flank_m: float = 0.45, min_contrast: float = 20.0,
                 length_tol: float = 0.45, edge_sigma_px: float = 0.35) -> None:
        self.camera = camera
        self.rows = GroundRows.build(camera, y_near, y_far)
        self.stripe_length_m = float(stripe_length_m)
        hw = marking_width_m / 2
        self.centre_offsets = np.array([-hw, -hw / 2, 0.0, hw / 2, hw])
        self.flank_offsets = np.array([-flank_m, flank_m])
        self.min_contrast = float(min_contrast)
        self.length_tol = float(length_tol)
        self.edge_sigma_px = float(edge_sigma_px)

    def profiles(self, image: np.ndarray, lines: list[LaneLine]) -> tuple[np.ndarray, np.ndarray]:
        """Contrast profiles (n_lines, n_rows) nearest row first, and their validity mask."""
        r = self.rows
        offs = np.concatenate([self.centre_offsets, self.flank_offsets])
        a = np.array([ln.a for ln in lines])[:, None, None]
        b = np.array([ln.b for ln in lines])[:, None, None]
        x = a + b * r.y[None, None, :] + offs[None, :, None]            # (L, O, R) ground lateral, m
        u = self.camera.cx + x * r.scale[None, None, :]
        map_x = u.reshape(-1, r.v.size).astype(np.float32)
        map_y = np.broadcast_to(r.v[None, :], map_x.shape).astype(np.float32)
        g = to_gray(cv2.remap(image, map_x, map_y, cv2.INTER_LINEAR)).reshape(u.shape)
        nc = self.centre_offsets.size
        contrast = g[:, :nc].max(axis=1) - g[:, nc:].mean(axis=1)
        valid = ((u >= 0) & (u <= self.camera.width - 1)).all(axis=1)
        return contrast, valid

    def find(self, image: np.ndarray, lines: list[LaneLine]) -> StripeEdges:
        """Validated stripe ends on ``lines`` in ``image`` (BGR or gray)."""
        if not lines:
            return StripeEdges.empty()
        c, valid = self.profiles(image, lines)
        n_lines, n = c.shape
        r = self.rows
        # Marking contrast of each line: the 95th percentile of its valid samples.
        cnt = valid.sum(axis=1)
        ranked = -np.sort(np.where(valid, -c, np.inf), axis=1)
        level = ranked[np.arange(n_lines), np.maximum(0, (0.05 * (cnt - 1)).astype(int))]
        usable = (cnt >= 8) & (level >= 2 * self.min_contrast)
        thr = 0.5 * level[:, None]
        on = (c > thr) & valid & usable[:, None]
        # Runs of paint: starts/ends pair up in row-major order.
        pad = np.zeros((n_lines, n + 2), dtype=bool)
        pad[:, 1:-1] = on
        ls, s = np.nonzero(on & ~pad[:, :-2])
        _, e = np.nonzero(on & ~pad[:, 2:])
        if ls.size == 0:
            return StripeEdges.empty()
        has_near = (s > 0) & valid[ls, np.maximum(s - 1, 0)]
        has_far = (e < n - 1) & valid[ls, np.minimum(e + 1, n - 1)]
        i_near = np.maximum(s - 1, 0)                    # crossing between samples i and i+1
        i_far = np.minimum(e, n - 2)
        v_near, y_near = self._cross(c[ls], thr[ls, 0], i_near)
        v_far, y_far = self._cross(c[ls], thr[ls, 0], i_far)
        lo = np.where(has_near, y_near, r.y[s])
        hi = np.where(has_far, y_far, r.y[e])
        length = hi - lo
        L, tol = self.stripe_length_m, self.length_tol
        both = has_near & has_far
        good = np.where(both, np.abs(length - L) <= tol * L, (has_near | has_far) & (length <= (1 + tol) * L))
        keep_near, keep_far = good & has_near, good & has_far
        v = np.concatenate([v_near[keep_near], v_far[keep_far]])
        if v.size == 0:
            return StripeEdges.empty()
        line = np.concatenate([ls[keep_near], ls[keep_far]])
        kind = np.concatenate([np.full(keep_near.sum(), NEAR), np.full(keep_far.sum(), FAR)])
        rows_i = np.concatenate([s[keep_near], e[keep_far]])
        y = row_distance(self.camera, v)                 # exact, one batched call
        a = np.array([ln.a for ln in lines])[line]
        b = np.array([ln.b for ln in lines])[line]
        return StripeEdges(y, a + b * y, kind, line, self.edge_sigma_px * r.dy_dv[rows_i])

    def _cross(self, c: np.ndarray, thr: np.ndarray, i: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Where profiles ``c[k]`` cross ``thr[k]`` between samples i[k] and i[k]+1: (row px, approx. distance m)."""
        r = self.rows
        k = np.arange(i.size)
        c0, c1 = c[k, i], c[k, i + 1]
        with np.errstate(divide="ignore", invalid="ignore"):
            f = np.clip(np.where(c1 != c0, (thr - c0) / (c1 - c0), 0.5), 0.0, 1.0)
        return r.v[i] + f * (r.v[i + 1] - r.v[i]), r.y[i] + f * (r.y[i + 1] - r.y[i])
