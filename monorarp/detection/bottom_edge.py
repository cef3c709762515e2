"""Sub-pixel refinement of a vehicle box's bottom edge from the image (classical, no training).

The bottom edge drives equation 3's distance (1 px there is ``d^2 / (h_c f)`` m); under a vehicle
the image changes abruptly to the road, so the edge (``y2``, continuous source pixels) is read off
the image to a fraction of a pixel and replaces the detector's only within ``search`` of it.
The method step by step: docs/bottom_edge.md.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from monorarp.core.boxes import BORDER_TOL_PX


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
    max_cols: int = 32             # wider boxes: this many evenly spaced columns
    border_px: float = BORDER_TOL_PX   # a box with no edge found whose bottom is this close to the
                                       # image's bottom border is cut by it: its bottom becomes the border


def refine_bottom(image: np.ndarray, boxes: np.ndarray,
                  params: BottomEdgeParams = BottomEdgeParams()) -> tuple[np.ndarray, np.ndarray]:
    """Refined copy of ``boxes`` (K, 4) and a (K,) bool mask of those whose bottom edge moved.

    ``image``: (H, W, 3) uint8 BGR, the image the boxes are in (continuous source pixels).
    Only ``y2`` changes. Boxes whose band does not fit in the image, or where no clear edge is
    found, keep the detector's edge, except next to the image's bottom border: a box with no edge
    found whose bottom lies within ``min(s, border_px)`` of the border is cut by it (the vehicle
    goes on below the image) and ends at the border, ``H - 0.5``. All boxes are processed
    together: each box's band is gathered into a fixed (rows, columns) grid (columns evenly
    sampled, at most ``max_cols``; rows and columns outside its band masked), so the cost hardly
    grows with the box count.
    """
    p = params
    out = np.array(boxes, dtype=np.float64).reshape(-1, 4)
    moved = np.zeros(len(out), dtype=bool)
    h_img, w_img = image.shape[:2]
    finite = np.isfinite(out).all(1)
    x1, y1, x2, y2 = np.where(finite[:, None], out, 0.0).T
    hgt, wid = y2 - y1, x2 - x1
    ok = finite & (hgt >= p.min_height_px) & (wid >= 2)
    if not ok.any():
        return out, moved
    k_ok = np.flatnonzero(ok)
    x1, y2, hgt, wid = x1[k_ok], y2[k_ok], hgt[k_ok], wid[k_ok]
    w = p.window
    s = np.clip(p.search_frac * hgt, p.search_min_px, p.search_max_px)            # (K,) search half-height
    r0 = np.floor(y2 - s).astype(np.int64) - w                                      # band's first row
    last = np.minimum(np.ceil(y2 + s).astype(np.int64) + w + 1, h_img - 1)          # band's last row
    inset = p.inset_frac * wid
    c0 = np.maximum(np.ceil(x1 + inset), 0).astype(np.int64)
    c1 = np.minimum(np.floor(x1 + wid - inset), w_img - 1).astype(np.int64)
    fits = (r0 >= 0) & (last >= y2 + 1.5) & (c1 - c0 >= 1)
    n_r = int(np.ceil(p.search_max_px)) * 2 + 2 * w + 4                             # rows of the grid
    n_band = np.clip(last - r0 + 1, 2, n_r)              # (K,) rows in the band (boxes that do not fit: masked)
    n_c = np.clip(c1 - c0 + 1, 1, p.max_cols)                                       # (K,) sampled columns
    n_grid_c = int(n_c.max())
    jj = np.arange(n_grid_c)
    col_ok = jj[None, :] < n_c[:, None]                                             # (K, C)
    cols = c0[:, None] + (jj[None, :] * (c1 - c0 + 1)[:, None]) // n_c[:, None]
    rows = r0[:, None] + np.arange(n_r)[None, :]                                    # (K, R)
    band = image[np.clip(rows, 0, h_img - 1)[:, :, None], np.clip(cols, 0, w_img - 1)[:, None, :]]
    band = band.astype(np.float32)                                                  # (K, R, C, 3)
    diff = band[:, 1:] - band[:, :-1]                     # (K, R-1, C, 3): transition at y = row + 0.5
    g2 = np.einsum("krcx,krcx->krc", diff, diff)          # squared colour difference
    in_band = np.arange(n_r - 1)[None, :] < (n_band - 1)[:, None]                 # (K, R-1) transitions
    region = in_band[:, :, None] & col_ok[:, None, :]
    med = _masked_median(g2.reshape(len(k_ok), -1), region.reshape(len(k_ok), -1))
    tau = np.maximum(p.noise_floor, p.noise_k * np.sqrt(med))
    tau2 = (tau * tau)[:, None, None]
    # what lies below the vehicle: per column, the band's last row (the road, or an occluder);
    # a vehicle's bottom is a transition from a pixel unlike it (with ``above_min`` of the
    # ``above`` pixels over it unlike it too) to a pixel like it
    below = np.take_along_axis(band, (n_band - 1)[:, None, None, None], axis=1)   # (K, 1, C, 3)
    dev = band - below
    unlike = np.einsum("krcx,krcx->krc", dev, dev) > tau2                           # (K, R, C)
    u = unlike[:, :-1]
    n_above = np.zeros(u.shape, np.int8)
    for j in range(1, p.above + 1):
        n_above[:, j:] += u[:, :-j]
    i_idx = np.arange(n_r - 1)[None, :]
    lo_i = np.ceil(y2 - s - r0 - 0.5)[:, None]                                      # transitions in y2 +- s
    hi_i = np.floor(y2 + s - r0 - 0.5)[:, None]
    t_ok = (i_idx >= lo_i) & (i_idx <= hi_i) & in_band
    strong = (g2 > tau2) & u & (n_above >= p.above_min) & ~unlike[:, 1:] & t_ok[:, :, None] & col_ok[:, None, :]
    has = strong.any(1)                                                              # (K, C)
    need = np.maximum(p.min_cols, np.ceil(p.min_cols_frac * n_c)).astype(np.int64)
    enough = fits & (has.sum(1) >= need)
    lowest = np.where(has, n_r - 2 - np.argmax(strong[:, ::-1], axis=1), -1)      # (K, C) row index
    srt = -np.sort(-lowest, axis=1)                                                  # descending
    bottom_i = np.take_along_axis(srt, np.minimum(need, n_grid_c)[:, None] - 1, axis=1)   # need-th lowest
    sel = has & (np.abs(lowest - bottom_i) <= p.cluster_px)                          # (K, C)
    # per column: centroid of the differences within +-window rows of its transition, projected on
    # the transition's colour direction, over the contiguous run of positive ones around it
    rr = np.maximum(lowest, 0)[:, :, None] + np.arange(-w, w + 1)[None, None, :]    # (K, C, 2w+1)
    r_in = (rr >= 0) & (rr < (n_band - 1)[:, None, None])
    rr = np.clip(rr, 0, n_r - 2)
    d = diff[np.arange(len(k_ok))[:, None, None], rr, np.arange(n_grid_c)[None, :, None]]   # (K, C, 2w+1, 3)
    proj = np.einsum("kcjx,kcx->kcj", d, d[:, :, w]) * r_in
    pos = proj > 0
    keep = np.concatenate([np.cumprod(pos[..., w::-1], axis=-1)[..., :0:-1], np.cumprod(pos[..., w:], axis=-1)],
                          axis=-1)
    wts = proj * keep
    with np.errstate(invalid="ignore", divide="ignore"):
        ys = (wts * (r0[:, None, None] + rr + 0.5)).sum(-1) / wts.sum(-1)            # (K, C)
    sel &= np.isfinite(ys)
    enough &= sel.any(1)
    y = _masked_median(ys, sel)
    accept = enough & (np.abs(y - y2) <= s)
    out[k_ok[accept], 3] = y[accept]
    # no edge found next to the image's bottom border: the vehicle goes on below it (truncated)
    cut = ~accept & (y2 >= h_img - 0.5 - np.minimum(s, p.border_px)) & (y2 < h_img - 0.5)
    out[k_ok[cut], 3] = h_img - 0.5
    moved[k_ok[accept | cut]] = True
    return out, moved


def _masked_median(a: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """Row-wise median of ``a`` (K, N) over ``mask`` (K, N); inf where a row has no element."""
    b = np.where(mask, a, np.inf)
    b.sort(axis=1)
    n = mask.sum(1)
    lo = np.take_along_axis(b, np.maximum(n - 1, 0)[:, None] // 2, axis=1)[:, 0]
    hi = np.take_along_axis(b, np.minimum(n // 2, b.shape[1] - 1)[:, None], axis=1)[:, 0]
    return 0.5 * (lo + hi)
