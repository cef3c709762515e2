"""Forward-collision warning (FCW): per-object states -> warning episodes.

An object threatens when its rectangle reaches the ego's corridor within ``ttc_threshold_s`` at
constant relative velocity (or acceleration), each motion term counted only beyond its
uncertainty; implausible motion raises nothing, nor does a box that does not grow as the threat
requires (looming: at least a floor rate, and from ``looming_far_distance_m`` on ``looming_far_share``
of the closing speed over the distance; a vehicle turning in across the lane line is exempt; at every
distance, the registered patch's rate at least ``registered_share`` of it, unless moving sideways); no vehicle
ahead closes faster than the ego drives; a threat that persists for ``min_on_s`` (one whose
registered patch confirms its closing speed: ``confirmed_min_on_s``) starts an episode that lasts
until none has been seen for ``hold_s``. Units: m, m/s, s; ego frame of
:mod:`monorarp.core.camera`. The rules in full: docs/warning.md.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from monorarp.core.camera import CameraModel
from monorarp.risk.estimators import object_extents
from monorarp.risk.ttc import ego_extent, time_to_collision
from monorarp.core.types import ObjectState, RiskEstimate, WarningState
from monorarp.warning.config import WarningConfig, warning_config


def significant_lateral_velocity(v_x: np.ndarray, v_x_std: np.ndarray, sigmas: float) -> np.ndarray:
    """``sign(v_x) * max(0, |v_x| - sigmas * v_x_std)`` (m/s): the part of ``v_x`` its uncertainty cannot explain."""
    v_x, v_x_std = np.asarray(v_x, dtype=float), np.asarray(v_x_std, dtype=float)
    return np.sign(v_x) * np.maximum(0.0, np.abs(v_x) - sigmas * v_x_std)


class ForwardCollisionWarning:
    """``update(states, risk, t, ego_speed=None) -> WarningState``: the rules of the module docstring.

    Settings: :class:`~monorarp.warning.config.WarningConfig` (defaults, ranges, units and how the
    defaults were chosen), given as ``config`` and/or as keyword ``overrides`` of its fields (the
    names the registry's ``kwargs`` and YAML ``warning_kwargs`` use); a bad one raises
    :class:`~monorarp.warning.config.WarningConfigError` naming it. ``camera``: the run's camera,
    whose mounting offsets replace ``camera_forward_offset_m`` / ``camera_lateral_offset_m``.
    """

    uses_camera = True   # the registry passes the run's camera

    def __init__(self, *, camera: CameraModel | None = None, config: WarningConfig | None = None,
                 **overrides: Any) -> None:
        cfg = warning_config(config, overrides)
        if camera is not None:
            cfg = warning_config(cfg, {"camera_forward_offset_m": camera.forward_offset_m,
                                       "camera_lateral_offset_m": camera.lateral_offset_m})
        self.config = cfg
        self.reset()

    @property
    def config(self) -> WarningConfig:
        """The settings in use (the camera's offsets included)."""
        return self._config

    @config.setter
    def config(self, cfg: WarningConfig) -> None:
        self._config = cfg
        (x_lo, x_hi), self.ego_y = ego_extent(cfg.ego_length_m, cfg.ego_width_m, cfg.camera_forward_offset_m,
                                              cfg.camera_lateral_offset_m)
        self.ego_x = (x_lo - cfg.corridor_margin_m, x_hi + cfg.corridor_margin_m)   # the corridor (m)

    @property
    def ttc_threshold_s(self) -> float:
        """The alert threshold (s); settable (validated), e.g. raised to score the in-path TTC as a risk."""
        return self._config.ttc_threshold_s

    @ttc_threshold_s.setter
    def ttc_threshold_s(self, value: float) -> None:
        self.config = warning_config(self._config, {"ttc_threshold_s": value})

    def reset(self) -> None:
        """Start a new sequence: no episode, no pending threat."""
        self._episodes = 0
        self._active = False
        self._track: int | None = None
        self._onset_t: float | None = None
        self._threat_since: float | None = None   # first frame time of the current run of threat frames
        self._confirmed_since: float | None = None   # the same for confirmed threats
        self._last_threat_t: float | None = None
        self._last_t: float | None = None

    def threats(self, states: dict[int, ObjectState], ego_speed: float | None = None) -> dict[int, float]:
        """Track id -> in-path TTC (s) of every object under the threshold (module docstring).

        ``ego_speed`` (m/s, None: unknown): a vehicle ahead closes at most at the ego's speed (it
        stops, it does not come back), so with ``ego_speed_margin_mps`` set a closing speed is
        taken at most ``ego_speed + ego_speed_margin_mps``.
        """
        return self.assess_threats(states, ego_speed)[0]

    def assess_threats(self, states: dict[int, ObjectState],
                       ego_speed: float | None = None) -> tuple[dict[int, float], frozenset[int]]:
        """``(threats, confirmed)``: :meth:`threats`, and the ids among them whose registered patch
        confirms the closing speed the TTC assumes (``registered_rate`` less ``registered_sigmas`` of its
        sigma at least ``confirm_share`` of that closing speed over the distance): two independent cues
        agree, so such a threat needs to persist only ``confirmed_min_on_s``."""
        if not states:
            return {}, frozenset()
        c = self._config
        ids = list(states)
        s = list(states.values())
        d_x = np.array([o.d_x for o in s], dtype=float)
        d_y = np.array([o.d_y for o in s], dtype=float)
        if c.distance_sigmas:
            d_y = d_y - c.distance_sigmas * np.array([0.0 if o.d_y_std is None else o.d_y_std for o in s])
        v_y_std = np.array([0.0 if o.v_y_std is None else o.v_y_std for o in s], dtype=float)
        v_y = significant_lateral_velocity([o.v_y for o in s], v_y_std, c.longitudinal_sigmas)
        if c.ego_speed_margin_mps is not None and ego_speed is not None and np.isfinite(ego_speed):
            v_y = np.maximum(v_y, -(max(float(ego_speed), 0.0) + c.ego_speed_margin_mps))
        v_x_std = np.array([c.lateral_velocity_std_mps if o.v_x_std is None else o.v_x_std for o in s])
        v_x = significant_lateral_velocity([o.v_x for o in s], v_x_std, c.lateral_sigmas)
        refuted = np.zeros(len(s), dtype=bool)
        if c.registered_lateral_share is not None:
            # a sideways motion the patch's own shift does not show (its lateral speed in that direction,
            # plus registered_sigmas of its sigma, under the share of the filter's): no sideways motion
            lat = np.array([np.nan if o.registered_v_x is None else o.registered_v_x for o in s], dtype=float)
            lat_std = np.array([0.0 if o.registered_v_x_std is None else o.registered_v_x_std for o in s])
            refuted = (v_x != 0.0) & (lat * np.sign(v_x) + c.registered_sigmas * lat_std
                                      < c.registered_lateral_share * np.abs(v_x))   # NaN: not refuted
        age = np.array([np.inf if o.age_s is None else o.age_s for o in s], dtype=float)
        v_x = np.where(age >= c.min_lateral_age_s - 1e-9, v_x, 0.0)
        # an implausible lateral reading stays a sign of a faulty state, refuted or not
        plausible = (np.abs(v_x) <= c.max_lateral_speed_mps) & (-v_y <= c.max_closing_speed_mps)
        v_x = np.where(refuted, 0.0, v_x)
        plausible &= ~((age < c.young_far_age_s - 1e-9) & (d_y >= c.young_far_distance_m))
        if c.max_raw_lateral_speed_mps is not None:
            raw_v_x = np.array([o.v_x for o in s], dtype=float)
            plausible &= ~(np.abs(raw_v_x) > c.max_raw_lateral_speed_mps)
        x_lo, x_hi, y_lo, y_hi = object_extents(d_x, d_y, c.other_width_m, c.other_length_m)
        reg = np.array([np.nan if o.registered_rate is None else o.registered_rate for o in s], dtype=float)
        reg_std = np.array([0.0 if o.registered_rate_std is None else o.registered_rate_std for o in s])
        # a vehicle read moving sideways turns, and its patch changes with its yaw: it neither confirms nor vetoes
        sideways = (significant_lateral_velocity([o.v_x for o in s], v_x_std, c.registered_lateral_sigmas) != 0.0) \
            & ~refuted
        confirmed = (reg - c.registered_sigmas * reg_std >= c.confirm_share * np.maximum(-v_y, 0.0)
                     / np.maximum(d_y, 1.0)) & ~sideways   # NaN rate: not confirmed
        if c.registered_share is not None:
            need = c.registered_share * np.maximum(-np.array([o.v_y for o in s], dtype=float), 0.0) \
                / np.maximum(np.array([o.d_y for o in s], dtype=float), 1.0)
            # no rate: no veto
            plausible &= ~((reg + c.registered_sigmas * reg_std < need) & ~sideways)
        if c.looming_sigmas is not None:
            rate = np.array([np.nan if o.expansion_rate is None else o.expansion_rate for o in s], dtype=float)
            rate_std = np.array([0.0 if o.expansion_rate_std is None else o.expansion_rate_std for o in s])
            # a vehicle moving sideways (a cut-in) turns, and its box's width changes with its yaw:
            # the share of the claimed closing speed is asked of one that keeps its lane, of a far one
            # (whose range, and so its lateral reading, a pixel of bottom edge moves by metres), and of
            # one read moving sideways that is still beyond the lane line (looming_side_share)
            share = np.where(v_x == 0.0, c.looming_share, 0.0)
            far = d_y >= c.looming_far_distance_m
            share = np.where(far, np.maximum(share, c.looming_far_share), share)
            gap = np.maximum(np.maximum(x_lo - self.ego_x[1], self.ego_x[0] - x_hi), 0.0)
            if c.looming_side_share > 0:   # moving sideways but still beyond the lane line
                beyond = (v_x != 0.0) & (gap > (0.0 if c.looming_exempt_gap_m is None else c.looming_exempt_gap_m))
                share = np.where(beyond, np.maximum(share, c.looming_side_share), share)
            need = np.maximum(1.0 / (c.looming_factor * c.ttc_threshold_s),
                              share * np.maximum(-v_y, 0.0) / np.maximum(d_y, 1.0))
            veto = rate + c.looming_sigmas * rate_std < need   # no rate yet: no veto
            if c.looming_exempt_gap_m is not None:    # turning in across the lane line: no veto
                veto &= (v_x == 0.0) | far | (gap > c.looming_exempt_gap_m)
            plausible &= ~veto
        a_y = None
        if c.accel_sigmas is not None:
            a = np.array([0.0 if o.a_y is None else o.a_y for o in s], dtype=float)
            a_std = np.array([0.0 if o.a_y_std is None else o.a_y_std for o in s], dtype=float)
            a_y = significant_lateral_velocity(a, a_std, c.accel_sigmas)
        ttc = time_to_collision(x_lo, x_hi, y_lo, y_hi, v_x, v_y, self.ego_x, self.ego_y, c.ttc_threshold_s,
                                a_y=a_y)
        ttc = np.where(plausible, ttc, np.nan)
        threats = {i: float(v) for i, v in zip(ids, ttc) if np.isfinite(v) and v < c.ttc_threshold_s}
        return threats, frozenset(i for i, ok in zip(ids, confirmed) if ok and i in threats)

    def update(self, states: dict[int, ObjectState], risk: RiskEstimate | None = None,
               t: float = 0.0, ego_speed: float | None = None) -> WarningState:
        """The warning decision at frame time ``t`` (s), given the ego's speed (m/s) where known.
        ``risk`` is accepted for the common stage interface and not used: the alert's in-path TTC is
        this stage's own (docs/warning.md, "The warning's TTC and the risk stage's"); the result's
        ``ttc`` is that TTC of the object it alerts on."""
        t = float(t)
        if not np.isfinite(t):
            raise ValueError(f"frame time must be finite, got {t}")
        if self._last_t is not None and t < self._last_t:
            self.reset()      # time went backwards: a new sequence (e.g. a looped video)
        self._last_t = t
        threats, confirmed = self.assess_threats(states, ego_speed)
        c = self._config
        order = tuple(sorted(threats, key=lambda i: (threats[i], i)))
        if threats:
            if self._threat_since is None:
                self._threat_since = t
            self._last_threat_t = t
        else:
            self._threat_since = None
        if not confirmed:
            self._confirmed_since = None
        elif self._confirmed_since is None:
            self._confirmed_since = t
        eps = 1e-9
        persisted = threats and t - self._threat_since >= c.min_on_s - eps
        persisted = persisted or (c.confirmed_min_on_s is not None and confirmed
                                  and t - self._confirmed_since >= c.confirmed_min_on_s - eps)
        if not self._active and persisted:
            self._active, self._onset_t, self._track = True, t, order[0]
            self._episodes += 1
        elif self._active and not threats and t - self._last_threat_t >= c.hold_s - eps:
            self._active, self._onset_t, self._track = False, None, None
        if not self._active:
            return WarningState(active=False, threat_ids=order)
        if threats and (self._track not in threats or threats[order[0]] < threats[self._track]):
            self._track = order[0]
        return WarningState(active=True, track_id=self._track, ttc=threats.get(self._track),
                            episode=self._episodes - 1, onset_t=self._onset_t, threat_ids=order)
