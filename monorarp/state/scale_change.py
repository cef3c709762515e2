"""Scale change of a vehicle's image between two frames, by registering its appearance (the looming cue).

A box's width gives the image scale of a vehicle to within the detector's edge noise (about 1 px a
side: 2-3 % of a 60 px box, every frame). Registering the vehicle's whole patch instead uses every
pixel of its texture and silhouette: the previous frame's patch ``T`` (the box, widened by ``margin``
of its size) is matched in the current image ``I`` under a scaling about the patch centre and a
shift, ``I(c + s (p - c) + u) ~ T(p)``, by Gauss-Newton on ``(s, u_x, u_y)`` (Lucas-Kanade with a
similarity warp without rotation), started from the boxes' own ratio and shift.

``s = w_t / w_(t-1) = Z_(t-1) / Z_t`` for a vehicle at depth ``Z``; at a constant closing speed,
``(s - 1) / dt`` is the expansion rate ``closing speed / Z_t`` at the current frame exactly
(:class:`RateWindow` averages it over a few frames: the state stage's ``registered_rate``). The shift
moves the patch centre sideways: with the scale and the depth it gives the vehicle's lateral displacement
(:func:`lateral_displacement`; the state stage's ``registered_v_x``). Images: 2-D float32 grey levels,
pixels; boxes ``(x1, y1, x2, y2)``, pixels.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np

from monorarp.state.geometry import occluded

MIN_PATCH_PX = 8          # a box narrower or lower than this is not registered
INTERPOLATIONS = {"linear": cv2.INTER_LINEAR, "cubic": cv2.INTER_CUBIC}   # of the current image at the warped points


@dataclass(frozen=True)
class ScaleChange:
    """Result of :func:`register_scale`: ``scale`` (current / previous size), its one-sigma from the
    fit's residual, the fit's shift (px) and whether it converged inside the limits."""

    scale: float
    scale_std: float
    shift: tuple[float, float]
    ok: bool


def _patch(box: tuple[float, float, float, float], margin: float, top: float, shape: tuple[int, int]) -> tuple[int, int, int, int]:
    x1, y1, x2, y2 = box
    y1 = y1 + top * (y2 - y1)
    mx, my = margin * (x2 - x1), margin * (y2 - y1)
    return (int(max(0, np.floor(x1 - mx))), int(max(0, np.floor(y1 - my))),
            int(min(shape[1], np.ceil(x2 + mx))), int(min(shape[0], np.ceil(y2 + my))))


def gradient_stack(gray: np.ndarray) -> np.ndarray:
    """(H, W, 3) float32: the grey image and its x and y gradients (grey levels per pixel), for
    :func:`register_scale` (computed once per frame)."""
    g = np.asarray(gray, dtype=np.float32)
    return np.dstack([g, cv2.Sobel(g, cv2.CV_32F, 1, 0, ksize=3, scale=0.125),
                      cv2.Sobel(g, cv2.CV_32F, 0, 1, ksize=3, scale=0.125)])


def _solve3(a: np.ndarray, b: np.ndarray) -> tuple[float, float, float] | None:
    """``a^-1 b`` for a 3 x 3 ``a`` by Cramer's rule (a tenth of ``np.linalg.solve``'s call cost); None when
    ``a`` is singular."""
    (a00, a01, a02), (a10, a11, a12), (a20, a21, a22) = a.tolist()
    b0, b1, b2 = b.tolist()
    c0, c1, c2 = a11 * a22 - a12 * a21, a12 * a20 - a10 * a22, a10 * a21 - a11 * a20
    det = a00 * c0 + a01 * c1 + a02 * c2
    if not np.isfinite(det) or det == 0.0:
        return None
    x0 = (b0 * c0 + a01 * (a12 * b2 - b1 * a22) + a02 * (b1 * a21 - a11 * b2)) / det
    x1 = (a00 * (b1 * a22 - a12 * b2) + b0 * c1 + a02 * (a10 * b2 - b1 * a20)) / det
    x2 = (a00 * (a11 * b2 - b1 * a21) + a01 * (b1 * a20 - a10 * b2) + b0 * c2) / det
    return x0, x1, x2


def register_scale(prev: np.ndarray, cur: np.ndarray, box_prev, box_cur, margin: float = 0.0, top: float = 0.3,
                   max_points: int = 1200, iterations: int = 8, max_change: float = 0.3, tol: float = 1e-4,
                   origin: tuple[int, int] = (0, 0), interpolation: str = "linear") -> ScaleChange:
    """Scale of the vehicle in ``box_prev`` of the grey image ``prev`` as seen in ``cur``, the
    :func:`gradient_stack` of the current frame (module docstring). ``top``: the top fraction of the
    box left out (roof and rear window, further away than the rear face); ``max_points``: the patch
    is sampled on a grid coarse enough for at most about this many points.

    ``box_cur``: its box in ``cur`` (the start of the fit). ``max_change``: a fitted scale further
    than this from 1 (relative), or a shift of more than half the patch, is not ``ok``. ``origin``: the
    image pixel ``(x, y)`` that is ``cur[0, 0]`` (a stack of a part of the frame, :func:`region`).
    ``interpolation``: of ``cur`` at the warped points, a key of :data:`INTERPOLATIONS`; bilinear pulls a
    small scale towards 1 on sharp edges (it blurs by an amount that varies with the sub-pixel phase).
    """
    interp = INTERPOLATIONS[interpolation]
    X1, Y1, X2, Y2 = _patch(box_prev, margin, top, prev.shape)
    bad = ScaleChange(float("nan"), float("nan"), (float("nan"), float("nan")), False)
    if X2 - X1 < MIN_PATCH_PX or Y2 - Y1 < MIN_PATCH_PX:
        return bad
    step = max(1, int(np.ceil(np.sqrt((X2 - X1) * (Y2 - Y1) / max_points))))
    ys, xs = np.mgrid[Y1:Y2:step, X1:X2:step].astype(np.float32)
    tmpl = prev[Y1:Y2:step, X1:X2:step]
    cx, cy = (X1 + X2 - 1) / 2.0, (Y1 + Y2 - 1) / 2.0
    ox, oy = origin
    rx, ry = xs - cx, ys - cy
    wp, wc = box_prev[2] - box_prev[0], box_cur[2] - box_cur[0]
    s = float(wc / wp) if wp > 0 and wc > 0 else 1.0
    ux = float((box_cur[0] + box_cur[2] - box_prev[0] - box_prev[2]) / 2)
    uy = float((box_cur[1] + box_cur[3] - box_prev[1] - box_prev[3]) / 2)
    stack = cur
    n = tmpl.size
    rxf, ryf = rx.ravel(), ry.ravel()
    J = np.empty((n, 3), dtype=np.float64)     # d residual / d (scale, shift x, shift y), per point
    for _ in range(iterations):
        mx, my = (cx - ox + ux + s * rx).astype(np.float32), (cy - oy + uy + s * ry).astype(np.float32)
        w = cv2.remap(stack, mx, my, interp, borderMode=cv2.BORDER_REPLICATE).reshape(n, 3)
        r = tmpl.ravel() - w[:, 0]
        J[:, 1], J[:, 2] = w[:, 1], w[:, 2]
        J[:, 0] = J[:, 1] * rxf + J[:, 2] * ryf
        A = J.T @ J
        d = _solve3(A + 1e-9 * np.trace(A) * np.eye(3), J.T @ r)
        if d is None:
            return bad
        s, ux, uy = s + d[0], ux + d[1], uy + d[2]
        if abs(d[0]) < tol and abs(d[1]) < 0.01 and abs(d[2]) < 0.01:
            break
    mx, my = (cx - ox + ux + s * rx).astype(np.float32), (cy - oy + uy + s * ry).astype(np.float32)
    r = tmpl - cv2.remap(stack[..., 0], mx, my, interp, borderMode=cv2.BORDER_REPLICATE)
    sigma2 = float(np.mean(r * r)) * n / max(n - 3, 1)
    try:
        cov = sigma2 * np.linalg.inv(A)
    except np.linalg.LinAlgError:
        return bad
    s_std = float(np.sqrt(max(cov[0, 0], 0.0)))
    ok = (np.isfinite(s) and abs(s - 1.0) <= max_change and abs(ux) <= (X2 - X1) / 2 and abs(uy) <= (Y2 - Y1) / 2
          and np.isfinite(s_std))
    return ScaleChange(float(s), s_std, (float(ux), float(uy)), bool(ok))


def lateral_displacement(centre_x, shift_x, scale, depth_m, fx: float, cx: float) -> np.ndarray:
    """Lateral displacement (m, camera x: right) of a vehicle point between two frames, from the image
    column ``centre_x`` (px) of its patch centre in the earlier frame, the patch's fitted ``shift_x`` (px)
    and ``scale`` (earlier depth / later depth), and its earlier depth ``depth_m`` (m): a point at column
    ``u`` and depth ``Z`` is at ``X = (u - cx) Z / fx``, and at ``Z / scale`` in the later frame."""
    centre_x, shift_x, scale, depth_m = (np.asarray(a, dtype=float) for a in (centre_x, shift_x, scale, depth_m))
    return depth_m / fx * ((centre_x + shift_x - cx) / scale - (centre_x - cx))


#: a region of the image narrower or lower than this (px) is not registered (boxes off the image)
MIN_REGION_PX = 3


def region(boxes: np.ndarray, shape: tuple[int, ...], grow: float = 0.5) -> tuple[int, int, int, int]:
    """``(x0, y0, x1, y1)`` px: the part of an image of ``shape`` holding the (N, 4) ``boxes``, each grown
    by ``grow`` of its size on every side (room for the fit's scale and shift), for :func:`gradient_stack`."""
    b = np.asarray(boxes, dtype=float).reshape(-1, 4)
    gw, gh = grow * (b[:, 2] - b[:, 0]), grow * (b[:, 3] - b[:, 1])
    x0, y0 = int(max(0, np.floor((b[:, 0] - gw).min()))), int(max(0, np.floor((b[:, 1] - gh).min())))
    x1, y1 = int(min(shape[1], np.ceil((b[:, 2] + gw).max()))), int(min(shape[0], np.ceil((b[:, 3] + gh).max())))
    return x0, y0, max(x1, x0), max(y1, y0)


class LoomingRegistration:
    """``update(image, ids, boxes, valid) -> (scale, scale_std, centre_x, shift_x)`` per track: each
    vehicle's image scale since its previous frame (:func:`register_scale`), and the column of its patch
    centre in that frame with the patch's fitted shift (px of the full frame), NaN where there is none.

    A track is registered when its box was a measurement (``valid``: not coasting, not cut) in this
    frame and in the previous one, and no nearer vehicle's box covers more than ``max_overlap`` of
    it in either (its patch would hold the other vehicle). ``pixel_std`` (px): the one-sigma of the
    scale is ``pixel_std / width`` (width of the previous box, px) -- the fit's own residual
    understates it (aliasing and shading are not white noise): 0.2 px from the shipped detector's
    and particle tracker's boxes on CCRb, CCRs and LVD runs (docs/warning_noise.md, Ninth round).
    A frame wider than ``max_width`` (px) is registered reduced by the smallest integer factor that
    brings it within (1920 -> 640): a scale needs no more pixels than the 640 px frames it was measured
    on, and 1080p costs 9x as much (the sigma is then of the reduced box's width). None: never reduced.
    """

    def __init__(self, pixel_std: float = 0.2, max_overlap: float = 0.05, top: float = 0.3,
                 max_width: int | None = 640, interpolation: str = "linear") -> None:
        if not (np.isfinite(pixel_std) and pixel_std > 0):
            raise ValueError(f"pixel_std must be positive, got {pixel_std}")
        if not (np.isfinite(top) and 0 <= top < 1):
            raise ValueError(f"top must be in [0, 1), got {top}")
        if interpolation not in INTERPOLATIONS:
            raise ValueError(f"interpolation must be one of {sorted(INTERPOLATIONS)}, got {interpolation!r}")
        if max_width is not None and max_width < 2 * MIN_PATCH_PX:
            raise ValueError(f"max_width must be at least {2 * MIN_PATCH_PX} px or None, got {max_width}")
        self.pixel_std, self.max_overlap, self.top = float(pixel_std), float(max_overlap), float(top)
        self.max_width, self.interpolation = max_width, interpolation
        self.reset()

    def reset(self) -> None:
        """Forget the previous frame."""
        self._prev: np.ndarray | None = None
        self._boxes: dict[int, np.ndarray] = {}

    def reduction(self, width: int) -> int:
        """The integer factor a frame ``width`` px wide is reduced by before registering (1: none)."""
        return 1 if self.max_width is None else max(1, -(-int(width) // self.max_width))

    def update(self, image: np.ndarray, ids: Sequence[int], boxes: np.ndarray,
               valid: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Scales, their one-sigmas, patch centre columns and shifts (px) of the (M, 4) ``boxes`` of tracks
        ``ids`` in ``image`` (H x W x 3 RGB or H x W grey) against the previous call's frame."""
        boxes = np.asarray(boxes, dtype=float).reshape(-1, 4)
        m = len(ids)
        scale, std, centre, shift = (np.full(m, np.nan) for _ in range(4))
        gray = image if image.ndim == 2 else cv2.cvtColor(image, cv2.COLOR_RGB2GRAY)
        k = self.reduction(gray.shape[1])
        if k > 1:
            gray = cv2.resize(gray, (gray.shape[1] // k, gray.shape[0] // k), interpolation=cv2.INTER_AREA)
            boxes = boxes / k
        gray = gray.astype(np.float32)
        usable = np.asarray(valid, dtype=bool) & np.isfinite(boxes).all(axis=1) & ~occluded(boxes, self.max_overlap)
        todo = [j for j, i in enumerate(ids) if usable[j] and i in self._boxes]
        x0 = y0 = x1 = y1 = 0
        if todo and self._prev is not None and self._prev.shape == gray.shape:
            x0, y0, x1, y1 = region(np.concatenate([boxes[todo], [self._boxes[ids[j]] for j in todo]]), gray.shape)
        if x1 - x0 >= MIN_REGION_PX and y1 - y0 >= MIN_REGION_PX:    # else the boxes lie (almost) off the image
            stack = gradient_stack(gray[y0:y1, x0:x1])      # the gradients where the patches are, not everywhere
            for j in todo:
                prev_box = self._boxes[ids[j]]
                r = register_scale(self._prev, stack, prev_box, boxes[j], top=self.top, origin=(x0, y0),
                                   interpolation=self.interpolation)
                if r.ok:
                    scale[j] = r.scale
                    std[j] = r.scale * self.pixel_std / max(prev_box[2] - prev_box[0], 1.0)
                    x1, _, x2, _ = _patch(prev_box, 0.0, self.top, gray.shape)
                    centre[j], shift[j] = (x1 + x2 - 1) / 2.0 * k, r.shift[0] * k
        self._prev = gray
        self._boxes = {i: boxes[j] for j, i in enumerate(ids) if usable[j]}
        return scale, std, centre, shift


class RateWindow:
    """``update(ids, scale, scale_std, t) -> (rate, rate_std)``: per track, the mean of the registration
    rates ``(scale - baseline) / dt`` (1/s) of its frames within the last ``window_s`` (s) and its one-sigma
    (the per-frame sigmas ``scale_std / dt`` taken independent); NaN unless this frame was registered
    and at least ``min_samples`` frames are in the window. ``dt``: time since the previous call (s).
    ``baseline`` 0 averages per-frame displacements into a speed (:func:`lateral_displacement`, m -> m/s).
    """

    def __init__(self, window_s: float = 0.2, min_samples: int = 2, baseline: float = 1.0) -> None:
        if not (np.isfinite(window_s) and window_s > 0):
            raise ValueError(f"window_s must be positive, got {window_s}")
        if min_samples < 1:
            raise ValueError(f"min_samples must be >= 1, got {min_samples}")
        self.window_s, self.min_samples, self.baseline = float(window_s), int(min_samples), float(baseline)
        self.reset()

    def reset(self) -> None:
        """Forget every track."""
        self._t: float | None = None
        self._samples: dict[int, list[tuple[float, float, float]]] = {}   # id -> [(t, rate, rate_std)]

    def update(self, ids: Sequence[int], scale: np.ndarray, scale_std: np.ndarray,
               t: float) -> tuple[np.ndarray, np.ndarray]:
        """Rates and one-sigmas (1/s) of tracks ``ids`` given this frame's scales (NaN: none) at time ``t`` (s)."""
        dt = None if self._t is None else t - self._t
        self._t = t
        rate, std = np.full(len(ids), np.nan), np.full(len(ids), np.nan)
        for j, i in enumerate(ids):
            kept = [x for x in self._samples.get(i, ()) if t - x[0] < self.window_s - 1e-9]
            if dt is not None and dt > 0 and np.isfinite(scale[j]) and np.isfinite(scale_std[j]):
                kept.append((t, (float(scale[j]) - self.baseline) / dt, float(scale_std[j]) / dt))
            self._samples[i] = kept
            if kept and kept[-1][0] == t and len(kept) >= self.min_samples:
                r = np.array([x[1] for x in kept])
                s = np.array([x[2] for x in kept])
                rate[j], std[j] = r.mean(), np.sqrt(np.sum(s * s)) / len(r)
        for i in [k for k, v in self._samples.items() if not v or t - v[-1][0] >= self.window_s]:
            del self._samples[i]
        return rate, std
