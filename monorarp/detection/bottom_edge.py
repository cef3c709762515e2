"""Sub-pixel refinement of a vehicle box's bottom edge from the image (classical, no training).

The bottom edge drives equation 3's distance (1 px there is ``d^2 / (h_c f)`` m), and the
detector's regressed edge is only good to about a pixel. Under a vehicle the image changes
abruptly from the vehicle's lowest parts (tyres, or the bumper close up) to the road, so the
edge can be read off the image itself:

1. In a band of rows ``y2 +- search`` around the detected bottom ``y2`` (``search`` grows with the
   box's height) and the box's columns, take the colour difference between vertically adjacent
   pixels, ``g(r, c) = |I(r+1, c) - I(r, c)|`` (Euclidean over B, G, R; an edge between rows
   ``r`` and ``r+1`` sits at ``y = r + 0.5``).
2. Per column, its lowest *strong* transition (``g`` above a threshold set from the band's own
   noise level): where that column stops seeing the vehicle.
3. The vehicle's lowest row is the ``min_cols``-th lowest of those (a single noisy column does
   not decide); the columns whose lowest transition is within ``cluster_px`` of it are the
   ones that reach the bottom (the tyres).
4. In each such column the edge is located to a fraction of a pixel by the centroid of the
   colour differences across it (``+-window`` rows), each projected on the edge's own colour
   direction and clipped at 0: an anti-aliased or blurred edge spreads over 2-3 differences
   that all point the same way, and their centroid is the edge's position for a box filter.
   The box's bottom is the median over those columns.
5. The refined edge replaces the detector's only if it lies within ``search`` of it and the
   edge's contrast is ``min_contrast`` times the noise threshold; otherwise the detector's stays.

Coordinates: continuous source pixels (:mod:`monorarp.types`, pixel centres at integers).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class BottomEdgeParams:
    """Tuning of :func:`refine_bottom` (pixels of the source image)."""

    search_frac: float = 0.06      # half-height of the search band, as a fraction of the box height
    search_min_px: float = 2.0     # ... at least
    search_max_px: float = 5.0     # ... at most
    inset_frac: float = 0.04       # columns ignored at each side (box edges are oblique / mixed)
    min_cols: int = 2              # columns that must see the bottom transition
    min_cols_frac: float = 0.06    # ... or this fraction of the box's columns, whichever is more
    cluster_px: float = 0.0        # columns within this of the lowest transition are "at the bottom"
    window: int = 2                # rows either side of a column's transition used for its centroid
    noise_k: float = 4.0           # threshold = noise_k x the band's median |difference| ...
    noise_floor: float = 12.0      # ... and at least this (8-bit colour-difference norm)
    min_contrast: float = 1.0      # refined edge's mean strength must be this x the threshold
    min_height_px: float = 4.0     # boxes shorter than this are left alone


def refine_bottom(image: np.ndarray, boxes: np.ndarray,
                  params: BottomEdgeParams = BottomEdgeParams()) -> tuple[np.ndarray, np.ndarray]:
    """Refined copy of ``boxes`` (K, 4) and a (K,) bool mask of those whose bottom edge moved.

    ``image``: (H, W, 3) uint8 BGR, the image the boxes are in (continuous source pixels).
    Only ``y2`` changes. Boxes whose band leaves the image, or where no clear edge is found,
    keep the detector's edge.
    """
    out = np.array(boxes, dtype=np.float64).reshape(-1, 4)
    moved = np.zeros(len(out), dtype=bool)
    for k, b in enumerate(out):
        y = _refine_one(image, b, params)
        if y is not None:
            out[k, 3] = y
            moved[k] = True
    return out, moved


def _refine_one(image: np.ndarray, box: np.ndarray, p: BottomEdgeParams) -> float | None:
    x1, y1, x2, y2 = (float(v) for v in box)
    h_img, w_img = image.shape[:2]
    hgt, wid = y2 - y1, x2 - x1
    if not (hgt >= p.min_height_px and wid >= 2 and np.isfinite(box).all()):
        return None
    s = float(np.clip(p.search_frac * hgt, p.search_min_px, p.search_max_px))
    r0 = int(np.floor(y2 - s)) - p.window          # first row of the band
    r1 = int(np.ceil(y2 + s)) + p.window + 1       # last row (inclusive)
    inset = p.inset_frac * wid
    c0, c1 = int(np.ceil(x1 + inset)), int(np.floor(x2 - inset))   # columns (inclusive)
    if r0 < 0 or r1 > h_img - 1 or c0 < 0 or c1 > w_img - 1 or c1 - c0 < 1:
        return None                                 # cut by the image border: leave it
    band = image[r0:r1 + 1, c0:c1 + 1].astype(np.float32)          # (R, C, 3)
    diff = band[1:] - band[:-1]                    # (R-1, C, 3): transition at y = r0 + i + 0.5
    g = np.sqrt((diff * diff).sum(-1))             # (R-1, C)
    tau = max(p.noise_floor, p.noise_k * float(np.median(g)))
    # only transitions whose position lies in y2 +- s can be "the" bottom
    ys = r0 + np.arange(g.shape[0]) + 0.5
    valid = (ys >= y2 - s) & (ys <= y2 + s)
    strong = (g > tau) & valid[:, None]
    n_rows, n_cols = g.shape
    has = strong.any(0)
    need = max(p.min_cols, int(np.ceil(p.min_cols_frac * n_cols)))
    if has.sum() < need:
        return None
    lowest = np.where(has, n_rows - 1 - np.argmax(strong[::-1], axis=0), -1)   # (C,) row index
    low_sorted = np.sort(lowest[has])[::-1]
    bottom_i = low_sorted[need - 1]                # the need-th lowest transition
    cols = np.flatnonzero(has & (lowest >= bottom_i - p.cluster_px) & (lowest <= bottom_i + p.cluster_px))
    li = lowest[cols]
    # centroid of the projected differences within +-window rows of each column's transition
    offs = np.arange(-p.window, p.window + 1)
    rows = np.clip(li[:, None] + offs[None, :], 0, n_rows - 1)            # (M, 2w+1)
    d = diff[rows, cols[:, None]]                                            # (M, 2w+1, 3)
    e = diff[li, cols]                                                       # (M, 3) edge direction
    e = e / np.maximum(np.linalg.norm(e, axis=1, keepdims=True), 1e-6)
    wts = np.clip((d * e[:, None, :]).sum(-1), 0, None)                     # (M, 2w+1)
    inside = (li[:, None] + offs[None, :] >= 0) & (li[:, None] + offs[None, :] < n_rows)
    wts = wts * inside
    # a second edge of the same sign more than one row away is another edge: keep the run around 0
    wts = _contiguous_run(wts, p.window)
    pos = (wts * (r0 + rows + 0.5)).sum(1) / np.maximum(wts.sum(1), 1e-9)
    strength = g[li, cols]
    if float(strength.mean()) < p.min_contrast * tau:
        return None
    y = float(np.median(pos))
    if abs(y - y2) > s:
        return None
    return y


def _contiguous_run(wts: np.ndarray, centre: int) -> np.ndarray:
    """Zero every weight outside the run of positive weights that contains column ``centre``."""
    pos = wts > 0
    keep = np.zeros_like(pos)
    keep[:, centre] = pos[:, centre]
    for j in range(centre + 1, wts.shape[1]):
        keep[:, j] = keep[:, j - 1] & pos[:, j]
    for j in range(centre - 1, -1, -1):
        keep[:, j] = keep[:, j + 1] & pos[:, j]
    return wts * keep
