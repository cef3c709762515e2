"""Image expansion rate of tracked boxes: ``d ln(box width) / dt`` (1/s), the looming cue.

A vehicle's box width is ``W f / Z`` (``W`` its visible width, ``Z`` its depth), so the rate of
change of its logarithm is ``-dZ/dt / Z``: closing speed over distance, the inverse of the time
to contact at constant velocity. It needs neither the ground plane nor the horizon nor the
vehicle's size, and it shares no edge with equation 3 (the bottom edge), so it is an independent
check on the distance filter's closing speed: a far box whose bottom edge steps down by 2 px
reads as 10-30 m/s of closing speed, and its height grows with it, but its width does not.

Per track a Kalman filter on ``ln w`` (state: log width, rate), measurement noise from
``pixel_std`` on each of the two side edges. The rate's process noise is white: ``process_std``
(1/s^2), or, given the track's distance ``Z`` (m) and ``accel_std`` (m/s^2), the change of the
rate that an unknown relative acceleration makes, ``accel_std / Z`` (``d rate/dt = a/Z + rate^2``;
a far car's rate hardly moves, a near one's quickly). With ``constant_speed`` the prediction
is exact for a constant closing speed (``rate -> rate / (1 - rate dt)``, the ``rate^2`` term;
extended Kalman), so a steady approach is followed without lag; a box cut by a side border, a coasting
box or one under 2 px gives no measurement (the filter predicts); the caller restarts a track's
filter when its box moved to another vehicle (the distance filter's restart).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from monorarp.core.kalman import kf_predict, kf_update, motion_model


MIN_DISTANCE_M = 2.0       # distances below this scale the process noise as this one


def _predict_constant_speed(x: np.ndarray, P: np.ndarray, dt: np.ndarray, Q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Extended-Kalman prediction of (ln w, rate) at a constant closing speed: ``Z -> Z - v dt``, so
    ``rate -> rate / (1 - rate dt)`` and ``ln w -> ln w - ln(1 - rate dt)`` (``rate dt`` held below 0.5)."""
    g = 1.0 - np.minimum(x[:, 1] * dt, 0.5)
    xn = np.stack([x[:, 0] - np.log(g), x[:, 1] / g], axis=1)
    F = np.zeros_like(P)
    F[:, 0, 0], F[:, 0, 1], F[:, 1, 1] = 1.0, dt / g, 1.0 / (g * g)
    return xn, F @ P @ np.swapaxes(F, -1, -2) + Q


class ExpansionFilter:
    """``update(ids, boxes, valid, t) -> (rate, rate_std)`` per box (1/s; NaN before a first measurement).

    Parameters:
        pixel_std: one-sigma (px) of each of the box's side edges.
        process_std: white change of the rate (1/s^2) where the distance is not given (or
            ``accel_std`` is None): the rate of a vehicle met at constant speed grows as
            ``rate^2`` (0.25 /s^2 at 2 s to contact, 1 at 1 s).
        accel_std: one-sigma (m/s^2) of the relative acceleration; with a track's distance the
            rate's process noise is ``accel_std / Z`` (None: ``process_std`` always).
        constant_speed: predict with the exact constant-closing-speed motion instead of a
            constant rate.
        init_rate_std: prior one-sigma of the rate (1/s) at a track's first measurement.
        forget_s: a track unseen for this long (s) is forgotten.
    """

    def __init__(self, pixel_std: float = 0.5, process_std: float = 1.0, init_rate_std: float = 1.0,
                 forget_s: float = 1.0, accel_std: float | None = None, constant_speed: bool = False) -> None:
        for name, v in (("pixel_std", pixel_std), ("process_std", process_std), ("init_rate_std", init_rate_std),
                        ("forget_s", forget_s)):
            if not (np.isfinite(v) and v > 0):
                raise ValueError(f"{name} must be positive, got {v}")
        self.pixel_std, self.process_std = float(pixel_std), float(process_std)
        self.init_rate_std = float(init_rate_std)
        self.forget_s = float(forget_s)
        if accel_std is not None and not (np.isfinite(accel_std) and accel_std > 0):
            raise ValueError(f"accel_std must be positive or None, got {accel_std}")
        self.accel_std = None if accel_std is None else float(accel_std)
        self.constant_speed = bool(constant_speed)
        self.reset()

    def reset(self) -> None:
        """Forget every track."""
        self._state: dict[int, tuple[np.ndarray, np.ndarray, float]] = {}   # id -> (x (2,), P (2, 2), t)

    def update(self, ids: Sequence[int], boxes: np.ndarray, valid: np.ndarray, t: float,
               restart: np.ndarray | None = None, distance: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Rates and one-sigmas (1/s) of the (M, 4) ``boxes`` of tracks ``ids`` at frame time ``t`` (s).

        ``valid`` (M,): the box's width is a measurement (not cut, not coasting); ``restart`` (M,):
        start these tracks afresh (a new sighting); ``distance`` (M,): each track's distance (m;
        NaN: unknown), which scales the process noise (``accel_std``).
        """
        for tid in [k for k, (_, _, tk) in self._state.items() if t - tk > self.forget_s]:
            del self._state[tid]
        m = len(ids)
        rate, std = np.full(m, np.nan), np.full(m, np.nan)
        if m == 0:
            return rate, std
        h = np.asarray(boxes, dtype=float)[:, 2] - np.asarray(boxes, dtype=float)[:, 0]   # width, px
        valid = np.asarray(valid, dtype=bool) & np.isfinite(h) & (h >= 2.0)
        known = np.array([i in self._state for i in ids])
        x, P = np.zeros((m, 2)), np.zeros((m, 2, 2))
        dt = np.zeros(m)
        for j, i in enumerate(ids):
            if known[j]:
                x[j], P[j], tk = self._state[i]
                dt[j] = t - tk
        q = np.full(m, self.process_std)
        if self.accel_std is not None and distance is not None:
            z_m = np.asarray(distance, dtype=float)
            near = np.isfinite(z_m) & (z_m > 0)
            q[near] = self.accel_std / np.maximum(z_m[near], MIN_DISTANCE_M)
        F, Q = motion_model("cv", dt, 1.0)
        Q = Q * (q * q)[:, None, None]
        if self.constant_speed:
            x, P = _predict_constant_speed(x, P, dt, Q)
        else:
            x, P = kf_predict(x, P, F, Q)
        z = np.log(np.where(valid, h, 1.0))
        r = (np.sqrt(2.0) * self.pixel_std / np.where(valid, h, 1.0)) ** 2
        restart = np.zeros(m, dtype=bool) if restart is None else np.asarray(restart, dtype=bool)
        fresh = valid & (~known | restart)
        xu, Pu = kf_update(x, P, z, r)
        upd = valid & ~fresh
        x, P = np.where(upd[:, None], xu, x), np.where(upd[:, None, None], Pu, P)
        x[fresh] = np.stack([z[fresh], np.zeros(int(fresh.sum()))], axis=1)
        P[fresh] = np.array([[0.0, 0.0], [0.0, self.init_rate_std ** 2]])
        P[fresh, 0, 0] = r[fresh]
        for j, i in enumerate(ids):
            if known[j] or valid[j]:
                self._state[i] = (x[j], P[j], float(t))
                rate[j], std[j] = x[j, 1], np.sqrt(max(P[j, 1, 1], 0.0))
        return rate, std
