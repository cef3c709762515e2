"""Lane-width ranging: the road's distance at each image row without assuming flat ground (pure maths).

The painted lines of a straight road keep their lateral ground positions ``x_k = a_k + b_k y`` (ego
frame, m; measured on the near, flat road by :class:`monorarp.lanes.lines.LaneLineFinder`)
whatever the road's height does further ahead. With no roll, an image row ``v`` sees one cross-section
of the road at camera depth ``Z`` (m along the optical axis), where line ``k`` appears at column

    u_k - c_x = f_x x_k / Z = s a_k + f_x b_k r_y(v),    s = f_x / Z (px per lateral metre),

``r_y(v)`` the ego ``y`` of the camera ray ``((0, (v - c_y) / f_y, 1)``. One least-squares ``s`` per row
from every line found on it gives the road's ego distance ``Y(v) = f_x r_y(v) / s`` at that row: no
ground plane, only a constant lane layout. :func:`march_rows` follows the lines row by row from the
near field up to the horizon (each line searched around its predicted column as a bright ridge),
:func:`smooth_profile` fits ``s(v)`` locally (it is piecewise linear in ``v`` on a road of piecewise
constant grade) and states each row's one-sigma: the
:class:`~monorarp.core.ground_profile.GroundProfile` the ``lane_width`` horizon stage hands on (how the
state estimator uses it: :mod:`monorarp.state.ground_contact`). The method and its measured figures:
docs/road_profile.md.
"""

from __future__ import annotations

import numpy as np

from monorarp.core.camera import CameraModel


def ray_y(camera: CameraModel, v: np.ndarray) -> np.ndarray:
    """Ego ``y`` of the camera-frame vector ``(0, (v - c_y) / f_y, 1)`` for rows ``v`` (its depth is 1)."""
    R = camera.R_cam_from_ego                         # ego = cam @ R (CameraModel.cam_to_ego)
    return (np.asarray(v, dtype=float) - camera.cy) / camera.fy * R[1, 1] + R[2, 1]


def ridge_peak(row: np.ndarray, u0: float, half_window: float, flank_px: float,
               min_contrast: float) -> float | None:
    """Sub-pixel column of the strongest bright ridge within ``u0 +- half_window`` of one gray row.

    Ridge response at column ``j``: ``g[j] - max(g[j - f], g[j + f])`` (levels, ``f = flank_px``), so a
    step edge (asphalt to shoulder) gives none. The column is the response-weighted centroid of the
    run of columns around the strongest one whose response exceeds a fifth of it (a wide marking's
    plateau, a thin one's one or two antialiased columns). None: no response of ``min_contrast`` levels.
    """
    n = row.size
    f = int(round(flank_px))
    lo, hi = int(np.floor(u0 - half_window)), int(np.ceil(u0 + half_window))
    lo, hi = max(lo, f + 1), min(hi, n - f - 2)
    if hi < lo:
        return None
    pad = f
    j = np.arange(max(lo - pad, f), min(hi + pad, n - f - 1) + 1)
    r = row[j] - np.maximum(row[j - f], row[j + f])
    inner = (j >= lo) & (j <= hi)
    k = int(np.flatnonzero(inner)[np.argmax(r[inner])])
    if r[k] < min_contrast:
        return None
    half = 0.2 * r[k]
    i0, i1 = k, k
    while i0 > 0 and r[i0 - 1] > half:
        i0 -= 1
    while i1 < r.size - 1 and r[i1 + 1] > half:
        i1 += 1
    w = r[i0:i1 + 1]
    return float(np.sum(w * j[i0:i1 + 1]) / np.sum(w))


def row_scale(a: np.ndarray, b: np.ndarray, u: np.ndarray, k: np.ndarray, cx: float, fx_ry: float,
              s_pred: float, agree: float = 0.04, single_tol: float = 0.04,
              multi_tol: float = 0.15) -> tuple[float | None, int]:
    """``s`` (px per lateral metre) of one row from columns ``u`` found for lines ``k`` (``x = a + b y``).

    Each line gives ``s_k = (u - c_x - f_x r_y b_k) / a_k``. The largest group of lines agreeing
    within ``agree`` (relative) with one of them gives the least-squares ``s``; it is taken when two
    or more lines agree and it is within ``multi_tol`` of the prediction ``s_pred``, or when one line
    alone is within ``single_tol`` of it (a lone ridge may be a vehicle's). (None, 0) otherwise.
    """
    ak = a[k]
    use = np.abs(ak) > 0.5
    if not use.any():
        return None, 0
    ak, rhs = ak[use], (u - cx - fx_ry * b[k])[use]
    s_k = rhs / ak
    groups = [np.abs(s_k - sk) <= agree * sk for sk in s_k]
    best = max(groups, key=lambda g: (int(g.sum()), -abs(float(np.median(s_k[g])) - s_pred)))
    s_ls = float(np.sum(ak[best] * rhs[best]) / np.sum(ak[best] ** 2))
    n = int(best.sum())
    tol = multi_tol if n >= 2 else single_tol
    return (s_ls, n) if abs(s_ls - s_pred) <= tol * s_pred else (None, 0)


def flat_scale(camera: CameraModel, v: float) -> float:
    """``s`` (px per lateral metre) of the flat ground at row ``v`` (NaN at or above the horizon)."""
    y = camera.ground_point_from_pixel(np.array([camera.cx]), np.array([v]))[0, 1]
    return float(camera.fx * ray_y(camera, np.array([v]))[0] / y) if np.isfinite(y) else float("nan")


def find_lines(camera: CameraModel, g: np.ndarray, a: np.ndarray, b: np.ndarray, v: float, s_pred: float,
               marking_width_m: float, min_contrast: float, search_m: float) -> tuple[np.ndarray, np.ndarray]:
    """Columns (px) and indices of the lines ``x = a + b y`` found on row ``v`` of gray image ``g``."""
    ry = float(ray_y(camera, np.array([v]))[0])
    hw = max(1.5, search_m * s_pred)
    flank = max(1.5, marking_width_m * s_pred / 2 + 1.5)
    found_u, found_k = [], []
    for k in range(a.size):
        u = ridge_peak(g[int(v)], camera.cx + s_pred * a[k] + camera.fx * b[k] * ry, hw, flank, min_contrast)
        if u is not None:
            found_u.append(u)
            found_k.append(k)
    return np.array(found_u, dtype=float), np.array(found_k, dtype=int)


def march_rows(camera: CameraModel, gray: np.ndarray, lines: list[tuple[float, float]], v_start: float,
               v_ref: float, v_stop: float, marking_width_m: float = 0.15, min_contrast: float = 12.0,
               search_m: float = 0.35, max_miss_rows: int = 20,
               min_spacing_px: float = 6.0) -> tuple[np.ndarray, np.ndarray, np.ndarray, bool]:
    """Follow ground lines ``x = a + b y`` (m) from row ``v_start`` up to ``v_stop`` (px, ``v_stop < v_start``).

    The rows from ``v_start`` to ``v_ref`` are the reference: the near road, taken as flat, where each
    line's lateral offset ``a`` is re-measured (the median of ``(u - c_x - f_x r_y b) / s_flat`` over
    the rows it is found on), so the far rows' ``s`` shares the near rows' column measurement.
    Above ``v_ref``, per integer row: predict ``s`` (px per lateral metre) from the rows below,
    search each line around its predicted column (``search_m`` either side, at least 1.5 px) and take
    :func:`row_scale` of the lines found (its tolerances grow by a quarter per row missed since the
    last accepted one: the prediction drifts as it extrapolates). Stops after ``max_miss_rows`` rows in a row without an
    accepted ``s``, or once neighbouring lines are under ``min_spacing_px`` apart. Returns rows, ``s``,
    lines per row (the reference rows with ``s_flat`` and their line counts) and whether it stopped
    having lost lines that were still apart (1.5 ``min_spacing_px`` or more at the last row found: an
    open end, :class:`monorarp.core.ground_profile.GroundProfile`).
    """
    a = np.array([ln[0] for ln in lines], dtype=float)
    b = np.array([ln[1] for ln in lines], dtype=float)
    if a.size == 0:
        return np.zeros(0), np.zeros(0), np.zeros(0, dtype=int), True
    rows_out, s_out, n_out = [], [], []
    offsets: list[list[float]] = [[] for _ in a]
    v = float(np.floor(v_start))
    while v > v_ref:
        s_f = flat_scale(camera, v)
        u, k = find_lines(camera, gray, a, b, v, s_f, marking_width_m, min_contrast, search_m)
        ry = float(ray_y(camera, np.array([v]))[0])
        for ui, ki in zip(u, k):
            offsets[ki].append((ui - camera.cx - camera.fx * b[ki] * ry) / s_f)
        rows_out.append(v)
        s_out.append(s_f)
        n_out.append(k.size)
        v -= 1.0
    a = np.array([np.median(o) if len(o) >= 3 else ak for o, ak in zip(offsets, a)])
    spacing = float(np.min(np.diff(np.sort(a)))) if a.size > 1 else float(abs(a[0]))
    s_pred = flat_scale(camera, v)
    slope = (s_out[-2] - s_out[-1]) if len(s_out) >= 2 else np.nan    # ds/dv from the rows below
    miss = 0
    while v >= v_stop and np.isfinite(s_pred) and s_pred * spacing >= min_spacing_px and miss < max_miss_rows:
        ry = float(ray_y(camera, np.array([v]))[0])
        u, k = find_lines(camera, gray, a, b, v, s_pred, marking_width_m, min_contrast, search_m)
        grow = 1.0 + miss / 4.0          # the prediction drifts over rows without lines
        s_row, n_found = row_scale(a, b, u, k, camera.cx, camera.fx * ry, s_pred,
                                   single_tol=0.04 * grow, multi_tol=0.15 * grow)
        if s_row is None:
            miss += 1
        else:
            miss = 0
            step = (s_out[-1] - s_row) / (rows_out[-1] - v) if s_out else np.nan
            if np.isfinite(step):
                slope = step if not np.isfinite(slope) else slope + 0.3 * (step - slope)
            rows_out.append(v)
            s_out.append(s_row)
            n_out.append(n_found)
        # prediction for the next row up
        s_pred = s_out[-1] - slope * (rows_out[-1] - (v - 1.0)) if s_out and np.isfinite(slope) \
            else flat_scale(camera, v - 1.0)
        v -= 1.0
    lost = miss > 0 and len(s_out) > 0 and s_out[-1] * spacing >= 1.5 * min_spacing_px   # lines lost while apart
    return np.array(rows_out), np.array(s_out), np.array(n_out, dtype=int), bool(lost)


def smooth_profile(camera: CameraModel, rows: np.ndarray, s: np.ndarray, half_window: int = 4,
                   floor_rel: float = 0.01, min_rows: int = 4) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Rows (increasing), road distance ``Y = f_x r_y / s`` (m) and its one-sigma (m) from a local fit.

    ``s(v)`` is fitted by a straight line over the rows within ``half_window`` of each row (it is
    piecewise linear on a road of piecewise constant grade); the one-sigma of the fitted ``s`` is the
    fit's residual spread over the square root of the rows used and, in quadrature, how far a local
    quadratic fit's value lies from it (the straight line's error where the grade changes within the
    window), with ``floor_rel`` of ``s`` at least; ``sigma_Y = Y sigma_s / s``. Rows with fewer than ``min_rows`` neighbours are dropped.
    """
    order = np.argsort(rows)
    rows, s = np.asarray(rows, float)[order], np.asarray(s, float)[order]
    out_v, out_s, out_sd = [], [], []
    for i, v in enumerate(rows):
        near = np.abs(rows - v) <= half_window
        if near.sum() < min_rows:
            continue
        x, y = rows[near] - v, s[near]
        A = np.stack([np.ones_like(x), x, x * x], axis=1)
        coef, *_ = np.linalg.lstsq(A[:, :2], y, rcond=None)
        quad, *_ = np.linalg.lstsq(A, y, rcond=None) if near.sum() >= 5 else (coef, None)
        res = y - A[:, :2] @ coef
        dof = max(int(near.sum()) - 2, 1)
        sd = float(np.hypot(np.sqrt(np.sum(res * res) / dof) / np.sqrt(near.sum()), quad[0] - coef[0]))
        out_v.append(v)
        out_s.append(coef[0])
        out_sd.append(max(sd, floor_rel * coef[0]))
    v, sf, sd = np.array(out_v), np.array(out_s), np.array(out_sd)
    if v.size == 0:
        return v, v, v
    Y = camera.fx * ray_y(camera, v) / sf
    return v, Y, Y * sd / sf
