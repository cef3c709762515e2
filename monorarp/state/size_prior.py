"""The size prior: a vehicle's distance from its box's height and width given its kind's size, fused with the
ground plane's (equation 3) by inverse variance.

A vehicle of height ``H`` (m) whose box is ``h`` px high stands ``fy H / h`` m along the optical axis: the box's
top (the roof) and bottom (the tyres' contact line) both lie about ``contact_offset_m`` beyond the rear face, so
the rear face is at ``d_h = fy H / h - contact_offset_m``. A box of a vehicle wholly in view spans the rear face
and, beside the centre column, the near side face to the front corner: with the edge angles ``a_l = (u1 - c_x) /
fx``, ``a_r = (u2 - c_x) / fx``, width ``W`` and length ``L``, ``d_w = (W + L n) / (a_r - a_l)`` where ``n`` is
``a_l`` right of the centre column, ``-a_r`` left of it, 0 for a box straddling it (only the rear face seen).
Each has its one-sigma from the kind's spread and the edges' pixel noise; the ground plane's one-sigma adds a
pitch / grade term that grows as ``Y^2 / h_c`` (:func:`monorarp.state.measurement.grade_gain`). A kind without a
prior (``Detection.label`` not in the table) keeps the ground plane's distance. Ego frame, boxes
``(x1, y1, x2, y2)`` px: :mod:`monorarp.core.camera`; the figures: docs/state_estimation.md.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from monorarp.core.camera import CameraModel

#: Vehicle kind (``Detection.label``: KITTI's ``car``/``van``/``truck`` of ``--detector labels``, the COCO-trained
#: detectors' ``car``/``truck``/``bus``) -> (height, height one-sigma, width, width one-sigma, length, length
#: one-sigma), m. The project's assumption from typical European dimensions (docs/state_estimation.md), not
#: fitted to any data: car height 1.50 +- 0.08 (hatchbacks to estates; SUVs reach 1.7), width over the body and
#: mirrors' reach seen from behind 1.75 +- 0.08; van 2.0 +- 0.3 (a people carrier 1.8 to a panel van 2.5); truck
#: 3.2 +- 0.6 (a light truck 2.5 to the 4.0 m legal limit), width 2.45 +- 0.1 (2.55 m limit); bus 3.1 +- 0.2.
SIZE_PRIORS: dict[str, tuple[float, float, float, float, float, float]] = {
    "car": (1.50, 0.08, 1.75, 0.08, 4.3, 0.4),
    "van": (2.00, 0.30, 1.95, 0.12, 5.0, 0.6),
    "truck": (3.20, 0.60, 2.45, 0.10, 8.0, 3.0),
    "bus": (3.10, 0.20, 2.55, 0.05, 12.0, 1.5),
}


def priors_of(labels: Sequence[str], table: Mapping[str, Sequence[float]]) -> np.ndarray:
    """(M, 6) each label's prior row of ``table`` (:data:`SIZE_PRIORS`' layout; case-insensitive), NaN for a kind
    without one."""
    out = np.full((len(labels), 6), np.nan)
    for k, lab in enumerate(labels):
        row = table.get(str(lab).lower())
        if row is not None:
            out[k] = row
    return out


def height_distance(camera: CameraModel, boxes: np.ndarray, height_m: np.ndarray, height_std_m: np.ndarray,
                    edge_std_px: float, contact_offset_m: float) -> tuple[np.ndarray, np.ndarray]:
    """(M,) rear-face distance ``fy H / h - contact_offset_m`` (m) of each box ``h`` px high and its one-sigma
    (m; the height's spread and two edges of ``edge_std_px`` each, in quadrature). NaN where the box has no
    height or ``H`` is NaN."""
    b = np.asarray(boxes, dtype=float).reshape(-1, 4)
    h = b[:, 3] - b[:, 1]
    with np.errstate(invalid="ignore", divide="ignore"):
        z = np.where(h > 0, camera.fy * height_m / h, np.nan)
        rel = np.hypot(height_std_m / height_m, np.sqrt(2.0) * edge_std_px / h)
    return z - contact_offset_m, z * rel


def width_distance(camera: CameraModel, boxes: np.ndarray, width_m: np.ndarray, width_std_m: np.ndarray,
                   length_m: np.ndarray, length_std_m: np.ndarray, edge_std_px: float
                   ) -> tuple[np.ndarray, np.ndarray]:
    """(M,) rear-face distance ``(W + L n) / (a_r - a_l)`` (m, module docstring) of each box from its width and
    its one-sigma (m; the width's, the length's through ``n`` and two edges of ``edge_std_px``). NaN where the
    box has no width or the prior is NaN."""
    b = np.asarray(boxes, dtype=float).reshape(-1, 4)
    a_l, a_r = (b[:, 0] - camera.cx) / camera.fx, (b[:, 2] - camera.cx) / camera.fx
    n = np.where(a_l > 0, a_l, np.where(a_r < 0, -a_r, 0.0))
    span = a_r - a_l
    with np.errstate(invalid="ignore", divide="ignore"):
        z = np.where(span > 0, (width_m + length_m * n) / span, np.nan)
        std = np.sqrt(width_std_m ** 2 + (n * length_std_m) ** 2 + 2.0 * (z * edge_std_px / camera.fx) ** 2) / span
    return z, std


def fuse(values: Sequence[np.ndarray], stds: Sequence[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Inverse-variance fusion, per element, of the readings ``values`` with one-sigmas ``stds`` (each (M,)):
    ``sum(v / s^2) / sum(1 / s^2)`` and ``sum(1 / s^2)^-1/2``; a NaN reading (or one with a NaN or non-positive
    sigma) takes no part; NaN where none does."""
    v = np.array([np.asarray(x, dtype=float) for x in values])
    s = np.array([np.asarray(x, dtype=float) for x in stds])
    good = np.isfinite(v) & np.isfinite(s) & (s > 0)
    w = np.where(good, 1.0 / np.where(good, s, 1.0) ** 2, 0.0)
    total = w.sum(axis=0)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = np.where(total > 0, (w * np.where(good, v, 0.0)).sum(axis=0) / total, np.nan)
        std = np.where(total > 0, 1.0 / np.sqrt(total), np.nan)
    return mean, std


def ground_fit(v: np.ndarray, x: np.ndarray, v_std: np.ndarray, height_m: float, height_std_m: float,
               pitch_std: float) -> tuple[np.ndarray, np.ndarray]:
    """The frame's ground plane from its vehicles, left one out for each: ``(theta, cov)`` of shapes (M, 2) and
    (M, 2, 2), ``theta[i] = (h, p)`` fitted to every vehicle but ``i``.

    Vehicle ``j`` whose bottom edge lies ``v_j`` rad below the calibrated horizon (``(y2 - r0) / fy``) and whose
    contact line is ``1 / x_j`` m ahead (from its size) says ``v_j = h x_j + p``: ``h`` the camera's height over
    the ground under the vehicles (m), ``p`` the pitch of that ground against the calibration (rad, + the road
    falls away / the camera pitched up). Weighted least squares with one-sigmas ``v_std`` (rad; NaN: the vehicle
    takes no part) and the prior ``h = height_m +- height_std_m``, ``p = 0 +- pitch_std``: with no other vehicle
    the answer is the prior, the flat ground of the calibration."""
    ok = np.isfinite(v) & np.isfinite(x) & np.isfinite(v_std) & (v_std > 0)
    w = np.where(ok, 1.0 / np.where(ok, v_std, 1.0) ** 2, 0.0)
    a = np.stack([np.where(ok, x, 0.0), np.where(ok, 1.0, 0.0)], axis=1)       # (M, 2) design rows
    vv = np.where(ok, v, 0.0)
    prior_info = np.diag([1.0 / height_std_m ** 2, 1.0 / max(pitch_std, 1e-9) ** 2])
    prior_vec = prior_info @ np.array([height_m, 0.0])
    info_j = w[:, None, None] * a[:, :, None] * a[:, None, :]                   # (M, 2, 2)
    vec_j = (w * vv)[:, None] * a                                              # (M, 2)
    info = prior_info + info_j.sum(axis=0) - info_j                            # leave-one-out
    vec = prior_vec + vec_j.sum(axis=0) - vec_j
    cov = np.linalg.inv(info)
    return np.einsum("mij,mj->mi", cov, vec), cov

