"""Per-track velocity filters of the state estimator: a Kalman filter per ego axis, or the paper's differencing.

Both keep, per track id, the last state and its frame time (s) and turn this frame's measured ``d_y``
and lateral terms (:mod:`monorarp.state.measurement`) into ``(d_x, d_y, v_x, v_y)`` (m, m/s, ego frame
of :mod:`monorarp.core.camera`). :class:`KalmanTracks`: batched over tracks and axes, with the noise
models of :mod:`monorarp.state.noise`, restarts on a jump, an optional Huber innovation and the
registered scale as a second range measurement (:func:`fuse_scale`). :class:`DifferenceTracks`:
``v = (d_k - d_{k-1}) / (t_k - t_{k-1})``.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from monorarp.core.camera import CameraModel
from monorarp.core.kalman import kf_predict, kf_update
from monorarp.state.geometry import lateral_from_terms
from monorarp.state.noise import MeasurementNoise, ProcessNoise


class TrackHistory:
    """Per track id: the filter's last state (``state``) and the frame time of its last update (``t``, s)."""

    def __init__(self) -> None:
        self.reset()

    def reset(self) -> None:
        """Forget every track."""
        self.state: dict[int, tuple[np.ndarray, np.ndarray] | np.ndarray] = {}
        self.t: dict[int, float] = {}

    def forget(self, track_id: int) -> None:
        """Forget one track."""
        self.state.pop(track_id)
        self.t.pop(track_id)

    def unseen(self, t: float, forget_s: float) -> list[int]:
        """Ids last updated more than ``forget_s`` (s) before frame time ``t`` (s)."""
        return [k for k, tk in self.t.items() if t - tk > forget_s]

    def known(self, ids: Sequence[int]) -> np.ndarray:
        """(M,) bool: the track has a state."""
        return np.array([i in self.state for i in ids])


class DifferenceTracks(TrackHistory):
    """The paper: v = (d_k - d_{k-1}) / (t_k - t_{k-1}); 0 at initialisation."""

    def update(self, ids: Sequence[int], d_y: np.ndarray, terms: np.ndarray, known: np.ndarray, ok: np.ndarray,
               t: float) -> np.ndarray:
        """(M, 4) ``(d_x, d_y, v_x, v_y)`` of tracks ``ids`` from measured ``d_y`` (M,) and lateral ``terms``
        (M, 3); a coordinate the box does not give is held at its last value (velocity 0 on that axis).
        Tracks ``ok`` keep the result as their state at ``t`` (s)."""
        prev = np.array([self.state[i] if k else (np.nan, np.nan) for i, k in zip(ids, known)]).reshape(-1, 2)
        y = np.where(np.isfinite(d_y), d_y, prev[:, 1])
        x = lateral_from_terms(terms, y)
        x = np.where(np.isfinite(x), x, prev[:, 0])
        z = np.stack([x, y], axis=1)
        dt = np.array([t - self.t[i] if k else 0.0 for i, k in zip(ids, known)])
        with np.errstate(divide="ignore", invalid="ignore"):
            v = np.where((dt > 0)[:, None] & known[:, None], (z - prev) / dt[:, None], 0.0)
        for i, zi, good in zip(ids, z, ok):
            if good:
                self.state[i], self.t[i] = zi, t
        return np.concatenate([z, v], axis=1)

    def rescale(self, track_id: int, ratio: float, lateral_shift: float) -> None:
        """Re-express a track's last state under a changed distance model: ``d_y`` times ``ratio``, ``d_x`` plus
        ``lateral_shift`` (m) (:meth:`KalmanTracks.rescale`)."""
        x, y = self.state[track_id]
        self.state[track_id] = np.array([x + lateral_shift, y * ratio])


def fuse_scale(x: np.ndarray, P: np.ndarray, scale: np.ndarray, scale_std: np.ndarray, dt: np.ndarray,
               usable: np.ndarray, gate_sigmas: float, inflation: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """The longitudinal filters (``x[:, 1]``, state ``(d, v, a)``) updated with each vehicle's registered
    scale ``s = d_prev / d`` since the previous frame (:mod:`monorarp.state.scale_change`), one-sigma
    ``scale_std`` times ``inflation``.

    Over the frame interval ``dt`` the distance changed by ``d_prev - d = -(v dt - a dt^2 / 2)``, so
    ``0 = (s - 1) d + v dt - a dt^2 / 2 + e d`` with ``e`` the scale's error: a linear measurement
    ``h = (s - 1, dt, -dt^2 / 2)`` of value 0 and variance ``(d scale_std)^2``. It is skipped where its
    innovation exceeds ``gate_sigmas`` of its spread (a patch that holds another vehicle, or a car
    whose yaw changes its image), and where not ``usable``.
    """
    good = usable & np.isfinite(scale) & np.isfinite(scale_std) & (dt > 0)
    if not good.any():
        return x, P
    xy, Py = x[:, 1], P[:, 1]
    h = np.stack([np.nan_to_num(scale - 1.0), dt, -dt * dt / 2.0], axis=1)
    r = (np.maximum(xy[:, 0], 0.1) * np.nan_to_num(scale_std, nan=1.0) * inflation) ** 2
    innov = -np.einsum("mi,mi->m", h, xy)
    S = np.einsum("mi,mij,mj->m", h, Py, h) + r
    good &= innov ** 2 <= gate_sigmas ** 2 * S
    xu, Pu = kf_update(xy, Py, np.zeros(len(xy)), r, h)
    x, P = x.copy(), P.copy()
    x[good, 1], P[good, 1] = xu[good], Pu[good]
    return x, P


class KalmanTracks(TrackHistory):
    """A Kalman filter per track and ego axis, vectorised over both (arrays of shape (M, 2, n)).

    ``process``: the motion and its noise (:class:`~monorarp.state.noise.ProcessNoise`); ``prior_var``:
    a new track's prior variances (:func:`~monorarp.state.noise.prior_variance`); ``reinit_sigmas``: a
    measurement that many sigmas of its innovation away from the prediction (either axis) restarts the
    filter at the measurement with the wide prior, as a new sighting (``born``: per track, the frame time
    its filter (re)started, s); ``robust_sigmas``: Huber beyond that many sigmas (None: off);
    ``fusion_sigmas`` and ``fusion_inflation``: the gate and sigma factor of :func:`fuse_scale`.
    """

    def __init__(self, process: ProcessNoise, prior_var: np.ndarray, reinit_sigmas: float = 5.0,
                 robust_sigmas: float | None = None, fusion_sigmas: float | None = None,
                 fusion_inflation: float = 1.0) -> None:
        self.process, self.prior_var = process, prior_var
        self.reinit_sigmas, self.robust_sigmas = reinit_sigmas, robust_sigmas
        self.fusion_sigmas, self.fusion_inflation = fusion_sigmas, fusion_inflation
        super().__init__()

    def reset(self) -> None:
        super().reset()
        self.born: dict[int, float] = {}

    def forget(self, track_id: int) -> None:
        super().forget(track_id)
        self.born.pop(track_id, None)

    def rescale(self, track_id: int, ratio: float, lateral_shift: float) -> None:
        """Re-express a track's filter under a changed distance model (a new vehicle kind for the size prior), at
        its last update time and without a restart: the longitudinal distance, velocity and acceleration times
        ``ratio`` (the new model's distance over the old one's on the same box; their covariance by ``ratio^2``),
        so the time to contact ``d / v`` is kept; the lateral position plus ``lateral_shift`` (m, the lateral
        reading's change with the distance), the lateral velocity kept. A linear map of the state: it commutes
        with the prediction, so the next frame's innovation test judges the new model's reading as any other."""
        x, P = self.state[track_id]
        n, N = self.process.n, x.shape[1]
        s = np.r_[np.full(n, ratio), np.ones(N - n)]          # the edge-error state (px) is kept
        x, P = x.copy(), P.copy()
        x[1] *= s
        P[1] *= s[:, None] * s[None, :]
        x[0, 0] += lateral_shift
        self.state[track_id] = (x, P)

    def update(self, ids: Sequence[int], d_y: np.ndarray, terms: np.ndarray, coasting: np.ndarray,
               known: np.ndarray, ok: np.ndarray, t: float, camera: CameraModel, noise: MeasurementNoise,
               near_limit_m: float, cut_bottom: np.ndarray | None = None, box_h: np.ndarray | None = None,
               scale: tuple[np.ndarray, np.ndarray] | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
        """Predict to frame time ``t`` (s) and update with the measured ``d_y`` (M,) and lateral ``terms`` (M, 3).

        Returns the (M, 4) states ``(d_x, d_y, v_x, v_y)``, their (M, 4) one-sigma
        uncertainties from the filter's covariance (m, m/s), and with the ``"ca"`` model the
        (M, 2) longitudinal acceleration and its one-sigma uncertainty (m/s^2; else None).
        ``coasting`` tracks are predicted only; tracks ``ok`` keep the result as their state.

        With the edge error ``b`` (``process.bias_var``) the measurement is ``z = p + J b + w`` with
        ``J`` the metres per pixel of that edge (``d_y / F`` for a column, ``d_y^2 / (h_c F)`` for the
        bottom row) and ``w`` the white part (``noise``, boxes ``box_h`` px high). An edge drifting for
        a fraction of a second then reads as either motion or bias, and the velocity's covariance says so.

        A box cut by the image's bottom border (``cut_bottom``) gives no distance, but bounds it: the
        vehicle's rear is nearer than ``near_limit_m`` (:func:`monorarp.state.measurement.near_limit_m`)
        and not behind the camera. The predicted distance is clamped into ``[0, near_limit_m]`` there
        (velocity and acceleration along y zeroed at 0), so a vehicle that stays that close
        (e.g. after a crash) is not extrapolated through the ego.

        ``scale``: this frame's registered ``(scale, scale_std)`` per track, fused after the boxes
        (:func:`fuse_scale`, ``"ca"`` without edge error only); None: not fused.
        """
        m, n = len(ids), self.process.n
        nb = 0 if self.process.bias_var is None else 1
        bias_var = self.process.bias_var
        N = n + nb
        x, P = np.zeros((m, 2, N)), np.zeros((m, 2, N, N))
        for j, (i, k) in enumerate(zip(ids, known)):
            if k:
                x[j], P[j] = self.state[i]
        dt = np.array([t - self.t[i] if k else 0.0 for i, k in zip(ids, known)])
        F, Q = self.process.transition(dt)
        x, P = kf_predict(x, P, F, Q)
        # Measurements; the lateral one uses the predicted distance where the box gives none.
        y_ref = np.where(np.isfinite(d_y), d_y, x[:, 1, 0])
        z = np.stack([lateral_from_terms(terms, y_ref), d_y], axis=1)
        has = np.isfinite(z)
        zf = np.where(has, z, x[:, :, 0])
        r = noise.var(np.nan_to_num(zf, nan=1.0), box_h)
        h = np.zeros((m, 2, N))
        h[..., 0] = 1.0
        if nb:
            d = np.maximum(np.nan_to_num(zf[:, 1], nan=1.0), 0.1)
            h[..., n] = np.stack([d / camera.fx, d * d / (camera.height_m * camera.fy)], axis=1)
        hx = np.einsum("...i,...i->...", h, x)
        S = np.einsum("...i,...ij,...j->...", h, P, h) + r
        # A jump far beyond the innovation's spread: another vehicle's box, restart (class docstring).
        nis = np.where(has, (zf - hx) ** 2 / S, 0.0)
        fresh = ~known | (known & ~coasting & (nis > self.reinit_sigmas ** 2).any(axis=1))
        for j in np.flatnonzero(fresh & ok):
            self.born[ids[j]] = t
            # first sighting: at the measurement, at rest (the paper's v = 0), wide prior; p = z - J b
            x[j] = 0.0
            x[j, :, 0] = zf[j]
            P[j] = np.diag(np.r_[self.prior_var, [0.0] * nb])[None] + 0.0
            P[j, :, 0, 0] = r[j]
            if nb:
                P[j, :, n, n] = bias_var
                P[j, :, 0, 0] += h[j, :, n] ** 2 * bias_var
                P[j, :, 0, n] = P[j, :, n, 0] = -h[j, :, n] * bias_var
        if self.robust_sigmas is not None:
            # Huber: an innovation beyond robust_sigmas counts as if its spread were that large
            c2 = self.robust_sigmas ** 2
            r = np.where(~fresh[:, None] & (nis > c2), r + S * (nis / c2 - 1.0), r)
        upd = (~fresh & ~coasting)[:, None] & has
        xu, Pu = kf_update(x, P, np.nan_to_num(zf), r, h)
        x, P = np.where(upd[..., None], xu, x), np.where(upd[..., None, None], Pu, P)
        if scale is not None and n == 3 and not nb:
            x, P = fuse_scale(x, P, scale[0], scale[1], dt, ~fresh & ~coasting & known, self.fusion_sigmas,
                              self.fusion_inflation)
        if cut_bottom is not None:
            blind = cut_bottom & known & ~np.isfinite(d_y)
            x[blind, 1, 0] = np.minimum(x[blind, 1, 0], near_limit_m)
            behind = blind & (x[:, 1, 0] < 0.0)
            x[behind, 1, 0] = 0.0
            x[behind, 1, 1:n] = 0.0
        for j, i in enumerate(ids):
            if ok[j]:
                self.state[i], self.t[i] = (x[j], P[j]), t
        std = np.sqrt(np.maximum(np.concatenate([P[:, :, 0, 0], P[:, :, 1, 1]], axis=1), 0.0))
        acc = None if n < 3 else np.stack([x[:, 1, 2], np.sqrt(np.maximum(P[:, 1, 2, 2], 0.0))], axis=1)
        return np.concatenate([x[:, :, 0], x[:, :, 1]], axis=1), std, acc
