"""Noise models of the state estimator's range filters: the box measurements' and the motion's.

:class:`MeasurementNoise`: the variance (m^2) of a box's ``(d_x, d_y)`` reading, from its edges'
pixel noise through equations 3 and 4. :class:`ProcessNoise`: each ego axis's motion model (constant
velocity or acceleration, white acceleration or jerk) and, optionally, the box edge's slowly varying
error ``b`` (px) as a first-order Gauss-Markov state. :func:`prior_variance` and :func:`bias_variance`:
a new track's prior and that error's stationary variance. Ego frame: :mod:`monorarp.core.camera`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from monorarp.core.camera import CameraModel
from monorarp.core.kalman import motion_model


@dataclass(frozen=True)
class MeasurementNoise:
    """White noise of the box readings: edge std ``pixel_std`` (px; ``lateral_pixel_std`` for the
    lateral reading) and ``pixel_std_per_height`` times the box height (px per px) in quadrature,
    plus ``extra_px_var`` (px^2: a horizon row measured this frame, white noise too)."""

    camera: CameraModel
    pixel_std: float
    lateral_pixel_std: float
    pixel_std_per_height: float
    extra_px_var: float = 0.0

    def var(self, z: np.ndarray, box_h: np.ndarray | None = None) -> np.ndarray:
        """(M, 2) variances (m^2) of measured (d_x, d_y) ``z`` (M, 2) of boxes ``box_h`` (M,) px high.

        ``d d_y / d v = d_y^2 / (h_c F)`` (so the error grows as d^2); the lateral error adds the
        far edge's column error and the share of the distance error. None ``box_h``: no height term.
        """
        d_x, d_y = z[:, 0], np.maximum(z[:, 1], 0.1)
        rel = 0.0 if box_h is None else (self.pixel_std_per_height * np.nan_to_num(box_h, nan=0.0)) ** 2
        px = np.sqrt(self.pixel_std ** 2 + self.extra_px_var + rel)
        lat_px = np.sqrt(self.lateral_pixel_std ** 2 + self.extra_px_var + rel)
        s_y = d_y ** 2 / (self.camera.height_m * self.camera.fy) * px + 0.01
        s_x = d_y / self.camera.fx * lat_px + np.abs(d_x) / d_y * s_y + 0.01
        return np.stack([s_x, s_y], axis=1) ** 2


def prior_variance(motion: str, init_vel_std: float, init_acc_std: float) -> np.ndarray:
    """A new track's prior variances of (position, velocity[, acceleration]) per axis: the position's
    is the measurement's (0 here), velocity ``init_vel_std`` (m/s), acceleration ``init_acc_std``
    (m/s^2, ``"ca"`` only)."""
    n = 2 if motion == "cv" else 3
    return np.array([0.0, init_vel_std ** 2, init_acc_std ** 2][:n])


def bias_variance(bias_pixel_std: float | None, lateral_bias_pixel_std: float | None = None) -> np.ndarray | None:
    """(2,) stationary variances (px^2) of the box edge's slowly varying error on the (x, y) axes
    (``lateral_bias_pixel_std`` None: ``bias_pixel_std`` on both); None: no such error modelled."""
    if bias_pixel_std is None:
        return None
    lat = bias_pixel_std if lateral_bias_pixel_std is None else lateral_bias_pixel_std
    return np.array([float(lat), float(bias_pixel_std)]) ** 2


@dataclass(frozen=True)
class ProcessNoise:
    """Motion of each ego axis (x, y): ``motion`` ``"ca"`` (state p, v, a; white jerk, m/s^3) or ``"cv"``
    (p, v; white acceleration, m/s^2) with std ``axis_std`` per axis; with ``bias_var`` (px^2, per axis)
    the state ends with the edge error ``b``, decaying with time constant ``bias_tau_s`` (s)."""

    motion: str
    axis_std: tuple[float, float]
    bias_var: np.ndarray | None = None
    bias_tau_s: float = 1.0

    @property
    def n(self) -> int:
        """Kinematic states per axis (2 or 3)."""
        return 2 if self.motion == "cv" else 3

    @property
    def size(self) -> int:
        """States per axis: the kinematic ones and the edge error's, if modelled."""
        return self.n + (0 if self.bias_var is None else 1)

    def transition(self, dt: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Transition ``F`` and process noise ``Q``, each (M, 2, N, N), for per-track intervals ``dt`` (M,) s."""
        m, n, N = len(dt), self.n, self.size
        Fm, Qm = motion_model(self.motion, np.repeat(dt[:, None], 2, axis=1), 1.0)
        Qm = Qm * (np.array(self.axis_std) ** 2)[None, :, None, None]
        F, Q = np.zeros((m, 2, N, N)), np.zeros((m, 2, N, N))
        F[..., :n, :n], Q[..., :n, :n] = Fm, Qm
        if self.bias_var is not None:
            phi = np.exp(-dt / self.bias_tau_s)[:, None]
            F[..., n, n] = phi
            Q[..., n, n] = self.bias_var * (1.0 - phi ** 2)
        return F, Q
