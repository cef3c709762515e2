"""Pooled robust slope of many tracks (pure maths).

Each track ``k`` is a set of observations ``(t, y)`` of one stationary road
feature; they all move with a common velocity ``dy/dt = slope`` but each has its
own offset. Weighted least squares with a common slope and one intercept per
track has the closed form ``slope = sum w (t - tb_k)(y - yb_k) / sum w (t - tb_k)^2``
(``tb_k``, ``yb_k``: the track's weighted means). Outliers are first removed
against a robust start (median of the tracks' successive-step slopes, per-track
median offsets), then by their normalised residual after each least-squares fit.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class SlopeFit:
    slope: float        # common dy/dt (m/s)
    sigma: float        # 1-sigma standard error of the slope (m/s), from the weights
    n_used: int         # observations kept
    n_tracks: int       # tracks with >= 2 kept observations


def pooled_slope(track: np.ndarray, t: np.ndarray, y: np.ndarray, sigma: np.ndarray,
                 reject: float = 4.0, iterations: int = 2) -> SlopeFit | None:
    """Common slope of ``y(t)`` across tracks (ids ``track``), ``sigma`` the 1-sigma error of each ``y``.

    Observations with ``|residual| > reject * sigma`` are dropped (``iterations`` refits).
    Returns None when no track keeps 2 observations or there is no time spread.
    """
    track = np.asarray(track)
    t = np.asarray(t, dtype=float)
    y = np.asarray(y, dtype=float)
    w_all = 1.0 / np.square(np.asarray(sigma, dtype=float))
    _, k = np.unique(track, return_inverse=True)
    keep = _robust_inliers(k, t, y, np.sqrt(w_all), reject)
    fit = None
    for it in range(iterations + 1):
        w = np.where(keep, w_all, 0.0)
        counts = np.bincount(k, weights=keep.astype(float))
        wsum = np.bincount(k, weights=w)
        good = (counts >= 2) & (wsum > 0)
        if good.sum() < 1:
            return None
        safe = np.where(good, wsum, 1.0)
        tb = np.bincount(k, weights=w * t) / safe
        yb = np.bincount(k, weights=w * y) / safe
        dt = t - tb[k]
        dy = y - yb[k]
        use = keep & good[k]
        sxx = float(np.sum(np.where(use, w * dt * dt, 0.0)))
        if sxx <= 0:
            return None
        slope = float(np.sum(np.where(use, w * dt * dy, 0.0)) / sxx)
        fit = SlopeFit(slope, float(1.0 / np.sqrt(sxx)), int(use.sum()), int(good.sum()))
        if it == iterations:
            break
        res = np.abs(dy - slope * dt) * np.sqrt(w_all)
        new_keep = keep & (res <= reject)
        if new_keep.sum() == keep.sum():
            break
        keep = new_keep
    return fit


def _robust_inliers(k: np.ndarray, t: np.ndarray, y: np.ndarray, inv_sigma: np.ndarray, reject: float) -> np.ndarray:
    """Observations within ``reject`` sigma of a robust common-slope fit (all of them if none can be made)."""
    order = np.lexsort((t, k))
    ks, ts, ys = k[order], t[order], y[order]
    step = (ks[1:] == ks[:-1]) & (ts[1:] > ts[:-1])
    if not step.any():
        return np.ones(t.size, dtype=bool)
    slope = float(np.median((ys[1:] - ys[:-1])[step] / (ts[1:] - ts[:-1])[step]))
    r = y - slope * t
    # Per-track median of r: sort by (track, r) and take each track's middle element.
    o = np.lexsort((r, k))
    counts = np.bincount(k)
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
    med = np.zeros(counts.size)
    has = counts > 0
    med[has] = r[o][starts[has] + counts[has] // 2]
    return np.abs(r - med[k]) * inv_sigma <= reject
