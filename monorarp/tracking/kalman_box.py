"""Constant-velocity Kalman filter over boxes, as in SORT (Bewley et al. 2016), vectorised over tracks.

State per track ``(u, v, s, r, du, dv, ds)``: box centre ``u, v`` (px), area
``s`` (px^2), aspect ratio ``r = w / h`` (held constant), and the per-step
rates of ``u, v, s`` (px/step, px^2/step). One step = one call of
:meth:`BoxKalman.predict` (one frame), as in SORT's reference code. The
measurement is ``(u, v, s, r)`` of a detection box ``(x1, y1, x2, y2)``.

Noise settings are SORT's: measurement covariance ``diag(1, 1, 10, 10)``;
initial covariance ``diag(10, 10, 10, 10, 1e4, 1e4, 1e4)`` (rates unknown);
process noise ``diag(1, 1, 1, 1, 0.01, 0.01, 1e-4)``.
"""

from __future__ import annotations

import numpy as np

DIM_X, DIM_Z = 7, 4
F = np.eye(DIM_X)
F[0, 4] = F[1, 5] = F[2, 6] = 1.0
H = np.eye(DIM_Z, DIM_X)
R = np.diag([1.0, 1.0, 10.0, 10.0])
P0 = np.diag([10.0, 10.0, 10.0, 10.0, 1e4, 1e4, 1e4])
Q = np.diag([1.0, 1.0, 1.0, 1.0, 0.01, 0.01, 1e-4])


def boxes_to_z(boxes: np.ndarray) -> np.ndarray:
    """(N, 4) ``(x1, y1, x2, y2)`` -> (N, 4) measurements ``(u, v, s, r)``."""
    b = np.asarray(boxes, dtype=float).reshape(-1, 4)
    w = b[:, 2] - b[:, 0]
    h = b[:, 3] - b[:, 1]
    return np.stack([b[:, 0] + w / 2, b[:, 1] + h / 2, w * h, w / np.maximum(h, 1e-9)], axis=1)


def x_to_boxes(x: np.ndarray) -> np.ndarray:
    """(N, >=4) states -> (N, 4) boxes ``(x1, y1, x2, y2)``; a non-positive area gives a zero-size box."""
    x = np.atleast_2d(np.asarray(x, dtype=float))
    s = np.maximum(x[:, 2], 0.0)
    r = np.maximum(x[:, 3], 1e-9)
    w = np.sqrt(s * r)
    h = np.where(w > 0, s / np.maximum(w, 1e-12), 0.0)
    return np.stack([x[:, 0] - w / 2, x[:, 1] - h / 2, x[:, 0] + w / 2, x[:, 1] + h / 2], axis=1)


class BoxKalman:
    """The filters of all tracks in two arrays: means ``x`` (T, 7) and covariances ``P`` (T, 7, 7)."""

    def __init__(self) -> None:
        self.x = np.empty((0, DIM_X))
        self.P = np.empty((0, DIM_X, DIM_X))

    def __len__(self) -> int:
        return len(self.x)

    def add(self, boxes: np.ndarray) -> None:
        """Append one filter per box, at rest, with SORT's initial covariance."""
        z = boxes_to_z(boxes)
        x = np.zeros((len(z), DIM_X))
        x[:, :DIM_Z] = z
        self.x = np.concatenate([self.x, x])
        self.P = np.concatenate([self.P, np.broadcast_to(P0, (len(z), DIM_X, DIM_X))])

    def keep(self, mask: np.ndarray) -> None:
        self.x, self.P = self.x[mask], self.P[mask]

    def predict(self) -> np.ndarray:
        """Advance every filter one step; returns the predicted boxes (T, 4).

        As in SORT, an area rate that would make the area non-positive is zeroed first.
        """
        if not len(self.x):
            return np.empty((0, 4))
        bad = self.x[:, 2] + self.x[:, 6] <= 0
        self.x[bad, 6] = 0.0
        self.x = self.x @ F.T
        self.P = F @ self.P @ F.T + Q
        return x_to_boxes(self.x)

    def update(self, rows: np.ndarray, boxes: np.ndarray) -> None:
        """Correct filters ``rows`` with measured boxes (same order)."""
        rows = np.asarray(rows, dtype=int)
        if not len(rows):
            return
        z = boxes_to_z(boxes)
        x, P = self.x[rows], self.P[rows]
        y = z - x[:, :DIM_Z]
        S = P[:, :DIM_Z, :DIM_Z] + R                                   # H P H^T + R
        PHt = P[:, :, :DIM_Z]                                          # P H^T
        K = np.linalg.solve(S, PHt.transpose(0, 2, 1)).transpose(0, 2, 1)   # P H^T S^-1 (S symmetric)
        self.x[rows] = x + np.einsum("tij,tj->ti", K, y)
        I_KH = np.eye(DIM_X)[None] - K @ H[None]
        # Joseph form keeps P symmetric positive definite.
        self.P[rows] = I_KH @ P @ I_KH.transpose(0, 2, 1) + K @ R @ K.transpose(0, 2, 1)

    def boxes(self) -> np.ndarray:
        """Current (posterior or predicted) boxes (T, 4)."""
        return x_to_boxes(self.x) if len(self.x) else np.empty((0, 4))
