"""Sub-pixel refinement of a vehicle box's bottom edge from the image (classical, no training).

The bottom edge drives equation 3's distance (1 px there is ``d^2 / (h_c f)`` m), and the
detector's regressed edge is only good to about a pixel. Under a vehicle the image changes
abruptly from the vehicle's lowest parts (tyres, or the bumper close up) to the road, so the
edge can be read off the image itself:

1. In a band of rows ``y2 +- search`` around the detected bottom ``y2`` (``search`` grows with the
   box's height) and the box's columns, take the colour difference between vertically adjacent
   pixels, ``g(r, c) = |I(r+1, c) - I(r, c)|`` (Euclidean over B, G, R; an edge between rows
   ``r`` and ``r+1`` sits at ``y = r + 0.5``), and a threshold ``tau`` from the band's own noise
   level (``noise_k`` x the median of ``g``, at least ``noise_floor``).
2. Per column, its lowest *bottom transition*: ``g > tau`` from a pixel that differs from the
   column's last band row (what lies under the vehicle: road, or an occluder) by more than
   ``tau``, with ``above_min`` of the ``above`` pixels over it differing too, to a pixel that does
   not. A lane-marking speck (road just above it) is not one; a 1-px tyre under a body whose
   anti-aliased lower edge happens to match the road is.
3. The vehicle's lowest row is the ``min_cols``-th lowest of those (a single column does not
   decide); the columns whose transition lies there are the ones that reach the bottom (tyres).
4. In each such column the edge is located to a fraction of a pixel by the centroid of the
   colour differences across it (``+-window`` rows), each projected on the transition's colour
   direction, keeping the contiguous run of positive ones: an anti-aliased or blurred edge
   spreads over 2-3 differences that all point the same way, and their centroid is the edge's
   position for a box filter. The box's bottom is the median over those columns.
5. The refined edge replaces the detector's only if it lies within ``search`` of it; otherwise
   (no bottom transition, a band that does not fit in the image) the detector's edge stays.

Coordinates: continuous source pixels (:mod:`monorarp.types`, pixel centres at integers).
"""

from __future__ import annotations

import math
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
    min_height_px: float = 4.0     # boxes shorter than this are left alone
    above: int = 3                 # rows just above a bottom transition's last vehicle row ...
    above_min: int = 2             # ... of which this many must differ from the road too


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
    if not (hgt >= p.min_height_px and wid >= 2 and math.isfinite(x1 + y1 + x2 + y2)):
        return None
    s = min(max(p.search_frac * hgt, p.search_min_px), p.search_max_px)
    w = p.window
    r0 = math.floor(y2 - s) - w                     # first row of the band
    r1 = min(math.ceil(y2 + s) + w + 1, h_img - 1)  # last row (inclusive), cut at the image's last row
    inset = p.inset_frac * wid
    c0, c1 = max(math.ceil(x1 + inset), 0), min(math.floor(x2 - inset), w_img - 1)  # columns (inclusive)
    if r0 < 0 or r1 < y2 + 1.5 or c1 - c0 < 1:
        return None                                 # no room for the band inside the image
    band = image[r0:r1 + 1, c0:c1 + 1].astype(np.float32)          # (R, C, 3)
    diff = band[1:] - band[:-1]                    # (R-1, C, 3): transition at y = r0 + i + 0.5
    g2 = np.einsum("rck,rck->rc", diff, diff)     # squared colour difference (R-1, C)
    n_rows, n_cols = g2.shape
    k = g2.size // 2
    tau = max(p.noise_floor, p.noise_k * math.sqrt(float(np.partition(g2.ravel(), k)[k])))
    tau2 = tau * tau
    # what lies below the vehicle: per column, the band's last row (the road, or an occluder);
    # a vehicle's bottom is a transition from a pixel unlike it (with ``above_min`` of the ``above``
    # pixels over it unlike it too) to a pixel like it
    dev = band - band[-1]
    unlike = np.einsum("rck,rck->rc", dev, dev) > tau2                    # (R, C)
    u = unlike[:-1]
    n_above = np.zeros(u.shape, np.int8)                                   # rows i-1 .. i-above unlike it
    for j in range(1, p.above + 1):
        n_above[j:] += u[:-j]
    run = u & (n_above >= p.above_min)                                     # row i unlike the road too
    lo_i, hi_i = math.ceil(y2 - s - r0 - 0.5), math.floor(y2 + s - r0 - 0.5)   # transitions in y2 +- s
    strong = (g2 > tau2) & run & ~unlike[1:]
    strong[:max(lo_i, 0)] = False
    strong[hi_i + 1:] = False
    has = strong.any(0)
    need = max(p.min_cols, math.ceil(p.min_cols_frac * n_cols))
    if int(has.sum()) < need:
        return None
    lowest = np.where(has, n_rows - 1 - np.argmax(strong[::-1], axis=0), -1)   # (C,) row index
    bottom_i = np.partition(lowest, n_cols - need)[n_cols - need]             # the need-th lowest
    cols = np.flatnonzero(np.abs(lowest - bottom_i) <= p.cluster_px)
    li = lowest[cols]
    # centroid of the differences within +-window rows of each column's transition, projected on
    # the transition's colour direction: the contiguous run of positive ones around it
    rows = li[:, None] + np.arange(-w, w + 1)[None, :]                    # (M, 2w+1)
    d = diff[np.minimum(rows, n_rows - 1), cols[:, None]]                    # (M, 2w+1, 3) (rows >= 0)
    proj = np.einsum("mjk,mk->mj", d, d[:, w])                               # (M, 2w+1), > 0 at j = w
    if rows[:, -1].max() >= n_rows:                                          # band cut by the image's bottom
        proj *= rows < n_rows
    pos = proj > 0
    keep = np.concatenate([np.cumprod(pos[:, w::-1], axis=1)[:, :0:-1], np.cumprod(pos[:, w:], axis=1)], axis=1)
    wts = proj * keep
    ys = (wts * (r0 + rows + 0.5)).sum(1) / wts.sum(1)
    ys.sort()
    m = len(ys)
    y = float(ys[m // 2]) if m % 2 else 0.5 * float(ys[m // 2 - 1] + ys[m // 2])   # median
    if abs(y - y2) > s:
        return None
    return y
