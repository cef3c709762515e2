"""Risk estimator (section IV-D, equation 5): ``risk = max over vehicles of 1 / TTC``.

Each vehicle is a rectangle of assumed size (``other_width_m`` x
``other_length_m``) whose rear face is at ``d_y`` and whose centre line is at
``d_x``; the ego is a rectangle of ``ego_width_m`` x ``ego_length_m`` around its
centre, which lies ``camera_forward_offset_m`` behind and
``camera_lateral_offset_m`` left of the camera (the ego-frame origin). Both move
at constant relative velocity; TTC is the first time the rectangles touch within
``horizon_s`` (10 s), in closed form by :func:`monorarp.risk.ttc.time_to_collision`.
TTC is floored at ``min_ttc_s`` so the risk stays finite (rectangles already
overlapping give ``1 / min_ttc_s``). Risk is 0 when no vehicle is on a
collision course. Units: m, m/s, s; risk in 1/s.

**TTC uncertainty** (``RiskEstimate.ttc_std``): first-order propagation of the state's
one-sigma distance and closing-speed uncertainties through the longitudinal gap
``g / c`` (``g`` = TTC x closing speed ``c = -v_y``):
``sigma_ttc = sqrt((sigma_d / c)^2 + (TTC sigma_v / c)^2)``; for objects with a TTC and both sigmas.

**Significant velocity** (``velocity_sigmas`` k, default None: off; on where frames are real,
:data:`monorarp.app.options.REAL_FRAMES_RISK`): the TTC is taken at the part of each velocity component
its uncertainty cannot explain, ``sign(v) max(0, |v| - k sigma_v)``, with ``sigma_v`` at least
``sqrt(2) sigma_d / age_s`` (:func:`significant_velocity`): a velocity within k sigmas of zero gives no
approach on that axis, one beyond gives the closed-form TTC of what is left.
"""

from __future__ import annotations

from collections import deque
from dataclasses import replace

import numpy as np

from monorarp.core.camera import CameraModel
from monorarp.risk.ttc import HORIZON_S, ego_extent, time_to_collision
from monorarp.core.types import ObjectState, RiskEstimate


def object_extents(d_x: np.ndarray, d_y: np.ndarray, width_m: float, length_m: float):
    """Rectangles (x_lo, x_hi, y_lo, y_hi) of vehicles with rear face at ``d_y`` and centre line ``d_x``."""
    d_x, d_y = np.asarray(d_x, dtype=float), np.asarray(d_y, dtype=float)
    return d_x - width_m / 2, d_x + width_m / 2, d_y, d_y + length_m


class TTCRiskEstimator:
    """``assess(states, t) -> RiskEstimate`` (equation 5, per-object TTC exposed).

    ``camera``: if given, its mounting offsets are used for
    ``camera_forward_offset_m`` / ``camera_lateral_offset_m``.
    """

    uses_camera = True   # the registry passes the run's camera

    def __init__(self, other_width_m: float = 1.8, other_length_m: float = 4.5, ego_width_m: float = 1.8,
                 ego_length_m: float = 4.5, camera_forward_offset_m: float = 0.0,
                 camera_lateral_offset_m: float = 0.0, horizon_s: float = HORIZON_S,
                 min_ttc_s: float = 0.1, velocity_sigmas: float | None = None,
                 camera: CameraModel | None = None) -> None:
        if min_ttc_s <= 0 or horizon_s <= 0:
            raise ValueError(f"min_ttc_s and horizon_s must be positive, got {min_ttc_s}, {horizon_s}")
        if velocity_sigmas is not None and not (np.isfinite(velocity_sigmas) and velocity_sigmas >= 0):
            raise ValueError(f"velocity_sigmas must be >= 0 or None, got {velocity_sigmas}")
        self.velocity_sigmas = None if velocity_sigmas is None else float(velocity_sigmas)
        if camera is not None:
            camera_forward_offset_m, camera_lateral_offset_m = camera.forward_offset_m, camera.lateral_offset_m
        self.other_width_m, self.other_length_m = float(other_width_m), float(other_length_m)
        self.horizon_s, self.min_ttc_s = float(horizon_s), float(min_ttc_s)
        self.ego_x, self.ego_y = ego_extent(ego_length_m, ego_width_m, camera_forward_offset_m,
                                            camera_lateral_offset_m)

    def reset(self) -> None:
        """Stateless; present for the common component interface."""

    def ttc(self, states: dict[int, ObjectState]) -> dict[int, float | None]:
        """Per-object TTC (s), None when not on a collision course within the horizon."""
        if not states:
            return {}
        ids = list(states)
        arr = np.array([[s.d_x, s.d_y, *self.velocity(s)] for s in states.values()], dtype=float)
        x_lo, x_hi, y_lo, y_hi = object_extents(arr[:, 0], arr[:, 1], self.other_width_m, self.other_length_m)
        ttc = time_to_collision(x_lo, x_hi, y_lo, y_hi, arr[:, 2], arr[:, 3], self.ego_x, self.ego_y,
                                self.horizon_s)
        return {i: (None if np.isnan(v) else float(v)) for i, v in zip(ids, ttc)}

    def velocity(self, s: ObjectState) -> tuple[float, float]:
        """``(v_x, v_y)`` (m/s) the TTC is taken at: the state's, or with ``velocity_sigmas`` its significant part."""
        return (s.v_x, s.v_y) if self.velocity_sigmas is None else significant_velocity(s, self.velocity_sigmas)

    def assess(self, states: dict[int, ObjectState], t: float | None = None,
               ego_speed: float | None = None) -> RiskEstimate:
        """Scene risk at frame time ``t``; ``t`` and ``ego_speed`` are unused (constant-velocity TTC on
        relative velocities needs neither a clock nor the ego's speed)."""
        ttc = self.ttc(states)
        finite = [v for v in ttc.values() if v is not None]
        risk = max((1.0 / max(v, self.min_ttc_s) for v in finite), default=0.0)
        return RiskEstimate(risk=float(risk), ttc=ttc, ttc_std=ttc_std(states, ttc))


def significant_velocity(s: ObjectState, sigmas: float) -> tuple[float, float]:
    """``(v_x, v_y)`` (m/s), each ``sign(v) max(0, |v| - sigmas sigma_v)``: the part its uncertainty cannot explain.

    ``sigma_v`` is the state's one-sigma (None: the component as is), at least ``sqrt(2) sigma_d / age_s``
    (``sigma_d`` the one-sigma of the same axis's distance): the error of a velocity read from two
    distances ``age_s`` apart whose errors do not average out. A restarted filter's own sigma assumes
    independent frame errors and soon falls below that, while a new box's error persists for many
    frames (docs/pipeline.md). Age 0: no velocity on an axis with a distance sigma; no age: no floor.
    """
    out = []
    for v, v_std, d_std in ((s.v_x, s.v_x_std, s.d_x_std), (s.v_y, s.v_y_std, s.d_y_std)):
        if v_std is None:
            out.append(float(v))
            continue
        std = float(v_std)
        if d_std is not None and s.age_s is not None:
            std = max(std, np.inf if s.age_s <= 0 else np.sqrt(2.0) * float(d_std) / float(s.age_s))
        out.append(float(np.sign(v) * max(0.0, abs(v) - (sigmas * std if sigmas > 0 else 0.0))))
    return out[0], out[1]


def ttc_std(states: dict[int, ObjectState], ttc: dict[int, float | None]) -> dict[int, float]:
    """Track id -> one-sigma TTC (s) from ``d_y_std`` and ``v_y_std`` (module docstring)."""
    out = {}
    for i, t in ttc.items():
        s = states.get(i)
        if t is None or s is None or s.d_y_std is None or s.v_y_std is None:
            continue
        c = max(-s.v_y, 1e-3)
        out[i] = float(np.hypot(s.d_y_std / c, t * s.v_y_std / c))
    return out


class ManoeuvreTTCRisk(TTCRiskEstimator):
    """``assess(states, t) -> RiskEstimate``: 1/TTC under adverse-manoeuvre hypotheses.

    Each vehicle is taken to make one of two manoeuvres now, whichever brings contact first: brake
    at ``brake_mps2`` in its lane (relative to the ego, which keeps its speed: the non-reacting driver
    of the FCW protocols), or move sideways towards the ego's centre line at ``lateral_mps`` at its
    closing speed. Its measured lateral velocity, the noisiest reading, is not used. The TTC of the
    rectangles under each (:func:`monorarp.risk.ttc.time_to_collision`, with a constant relative
    acceleration for the braking) scores the risk as ``max 1 / TTC`` (1/s, the paper's equation 5
    otherwise). It is the "what if it brakes / turns in" question of worst-case risk measures (the
    reachable sets of Lefevre et al. 2014): a close follower scores before its lead brakes, a slower
    car beside the ego before it turns in, which constant-velocity 1/TTC cannot. Defaults 4 m/s^2
    (firm braking, 0.4 g) and 1 m/s (a lane change's lateral speed); docs/manoeuvre_risk.md says how these
    and the settings below were chosen (scenarios/fcw/risk_tuning.yaml) and what they score.

    **Closing speed**: the filter's (``-v_y``) mixed with the looming cue's (``expansion_rate x d_y``,
    the box's growth rate: :mod:`monorarp.state.expansion`) as ``(1 - looming_weight) x filter + looming_weight
    x looming`` (0.5); the filter's alone where the state has no expansion rate, or one whose one-sigma
    is over ``looming_max_std`` (0.5 /s: a rate only predicted, as for a box cut by a side border,
    whose constant-closing-speed prediction grows without bound, or one just started). The range
    filter lags a lead that starts braking; the mix reacts sooner. Where the registered patch's rate
    (``ObjectState.registered_rate``, :mod:`monorarp.state.scale_change`, at most ``registered_max_std`` 0.05 /s
    one-sigma) is known, that mix is mixed again with its closing speed ``registered_rate x d_y`` at
    ``registered_weight`` (0.5): filter, box growth and patch weigh 1 : 1 : 2. The patch's rate is the
    most precise of the three from frame to frame (docs/manoeuvre_risk.md, fourteenth round); 0 turns it off.

    **Peak hold**: the scene risk reported at time ``t`` is the highest of the frames in
    ``[t - hold_s, t]`` (0.45 s; 0 turns it off; frames without a time are not held). A vehicle whose
    track drops out for a few frames, or whose reading flickers off a collision course, keeps its
    score until the window has passed it. The per-object ``ttc`` stays the current frame's. The hold
    is the stage's only state: :meth:`reset` clears it, and a time earlier than the last one starts
    it afresh.
    """

    def __init__(self, brake_mps2: float = 4.0, lateral_mps: float = 1.0, hold_s: float = 0.45,
                 looming_weight: float = 0.5, looming_max_std: float | None = 0.5,
                 registered_weight: float = 0.5, registered_max_std: float | None = 0.05,
                 camera: CameraModel | None = None, **kw) -> None:
        """``kw``: the sizes, offsets, horizon and floor of :class:`TTCRiskEstimator`."""
        super().__init__(camera=camera, **kw)
        for name, v in (("brake_mps2", brake_mps2), ("lateral_mps", lateral_mps), ("hold_s", hold_s)):
            if not (np.isfinite(v) and v >= 0):
                raise ValueError(f"{name} must be >= 0, got {v}")
        if not 0 <= looming_weight <= 1:
            raise ValueError(f"looming_weight must be in [0, 1], got {looming_weight}")
        self.brake_mps2, self.lateral_mps, self.hold_s = float(brake_mps2), float(lateral_mps), float(hold_s)
        self.looming_weight = float(looming_weight)
        if looming_max_std is not None and not looming_max_std > 0:
            raise ValueError(f"looming_max_std must be > 0 or None, got {looming_max_std}")
        self.looming_max_std = None if looming_max_std is None else float(looming_max_std)
        if not 0 <= registered_weight <= 1:
            raise ValueError(f"registered_weight must be in [0, 1], got {registered_weight}")
        if registered_max_std is not None and not registered_max_std > 0:
            raise ValueError(f"registered_max_std must be > 0 or None, got {registered_max_std}")
        self.registered_weight = float(registered_weight)
        self.registered_max_std = None if registered_max_std is None else float(registered_max_std)
        self._recent: deque[tuple[float, float]] = deque()    # (t s, risk 1/s) of the frames in the hold window

    def reset(self) -> None:
        """Forget the hold window (a new sequence)."""
        self._recent.clear()

    def assess(self, states: dict[int, ObjectState], t: float | None = None,
               ego_speed: float | None = None) -> RiskEstimate:
        """Scene risk at frame time ``t`` (s): the held ``max 1 / TTC`` (class docstring)."""
        estimate = super().assess(states, t, ego_speed)
        if self.hold_s == 0 or t is None:
            return estimate
        if self._recent and t < self._recent[-1][0]:
            self._recent.clear()
        self._recent.append((float(t), estimate.risk))
        while self._recent[0][0] < t - self.hold_s - 1e-9:
            self._recent.popleft()
        return replace(estimate, risk=max(r for _, r in self._recent))

    def ttc(self, states: dict[int, ObjectState]) -> dict[int, float | None]:
        """Per-object TTC (s), the sooner of the two manoeuvres'; None when neither makes contact within the horizon."""
        if not states:
            return {}
        ids = list(states)
        arr = np.array([[s.d_x, s.d_y, self.closing_velocity(s)] for s in states.values()], dtype=float)
        x_lo, x_hi, y_lo, y_hi = object_extents(arr[:, 0], arr[:, 1], self.other_width_m, self.other_length_m)
        still = np.zeros(len(ids))
        braking = time_to_collision(x_lo, x_hi, y_lo, y_hi, still, arr[:, 2], self.ego_x, self.ego_y, self.horizon_s,
                                    a_y=np.full(len(ids), -self.brake_mps2))
        towards = -np.sign(arr[:, 0] - sum(self.ego_x) / 2) * self.lateral_mps
        turning = time_to_collision(x_lo, x_hi, y_lo, y_hi, towards, arr[:, 2], self.ego_x, self.ego_y, self.horizon_s)
        ttc = np.fmin(braking, turning)
        return {i: (None if np.isnan(v) else float(v)) for i, v in zip(ids, ttc)}

    def closing_velocity(self, s: ObjectState) -> float:
        """Relative longitudinal velocity ``v_y`` (m/s, negative = closing) the hypotheses start from: the
        filter's (:meth:`velocity`) mixed with the looming cue's ``-expansion_rate x d_y``, then with the registered patch's
        ``-registered_rate x d_y`` (class docstring); a rate without a one-sigma counts as within its bound."""
        v_y = self.velocity(s)[1]
        if _trusted(s.expansion_rate, s.expansion_rate_std, self.looming_max_std) and self.looming_weight > 0:
            v_y = (1 - self.looming_weight) * v_y - self.looming_weight * s.expansion_rate * s.d_y
        if _trusted(s.registered_rate, s.registered_rate_std, self.registered_max_std) and self.registered_weight > 0:
            v_y = (1 - self.registered_weight) * v_y - self.registered_weight * s.registered_rate * s.d_y
        return v_y


def _trusted(rate: float | None, rate_std: float | None, max_std: float | None) -> bool:
    """A looming rate (1/s) is known, and its one-sigma (none: trusted) within ``max_std`` (None: any)."""
    if rate is None:
        return False
    return max_std is None or rate_std is None or bool(rate_std <= max_std)
