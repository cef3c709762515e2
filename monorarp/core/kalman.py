"""Batched linear Kalman filtering primitives (numpy): motion models, predict, scalar update."""

from __future__ import annotations

import numpy as np


def motion_model(kind: str, dt: np.ndarray, noise_std: float) -> tuple[np.ndarray, np.ndarray]:
    """Transition ``F`` and process noise ``Q``, each (M, n, n), for per-item intervals ``dt`` (s).

    ``"cv"``: constant velocity, state (p, v), white acceleration of std ``noise_std`` (m/s^2).
    ``"ca"``: constant acceleration, state (p, v, a), white jerk of std ``noise_std`` (m/s^3).
    """
    dt = np.asarray(dt, dtype=float)
    one, zero = np.ones_like(dt), np.zeros_like(dt)
    if kind == "cv":
        F = np.stack([np.stack([one, dt], -1), np.stack([zero, one], -1)], -2)
        G = np.stack([dt * dt / 2, dt], -1)
    else:
        F = np.stack([np.stack([one, dt, dt * dt / 2], -1), np.stack([zero, one, dt], -1),
                      np.stack([zero, zero, one], -1)], -2)
        G = np.stack([dt ** 3 / 6, dt * dt / 2, dt], -1)
    return F, G[..., :, None] * G[..., None, :] * noise_std ** 2


def kf_predict(x: np.ndarray, P: np.ndarray, F: np.ndarray, Q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Batched prediction: x (..., n), P (..., n, n)."""
    return np.einsum("...ij,...j->...i", F, x), F @ P @ np.swapaxes(F, -1, -2) + Q


def kf_update(x: np.ndarray, P: np.ndarray, z: np.ndarray, r: np.ndarray,
              h: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Batched update with a scalar measurement ``z = h . x + noise`` (...) of variance ``r`` (...).

    ``h`` (..., n): the measurement row; None: ``[1, 0, ...]`` (the position).
    """
    if h is None:
        h = np.zeros(x.shape)
        h[..., 0] = 1.0
    ph = np.einsum("...ij,...j->...i", P, h)
    s = np.einsum("...i,...i->...", h, ph) + r
    k = ph / s[..., None]
    x = x + k * (z - np.einsum("...i,...i->...", h, x))[..., None]
    P = P - k[..., :, None] * ph[..., None, :]
    return x, P
