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

import numpy as np

from monorarp.core.camera import CameraModel
from monorarp.risk.estimators import object_extents
from monorarp.risk.ttc import ego_extent, time_to_collision
from monorarp.core.types import ObjectState, RiskEstimate, WarningState
from monorarp.warning.thresholds import FCW_THRESHOLD_S

#: Default warning threshold (s): see :class:`ForwardCollisionWarning`.
DEFAULT_TTC_THRESHOLD_S = FCW_THRESHOLD_S


def significant_lateral_velocity(v_x: np.ndarray, v_x_std: np.ndarray, sigmas: float) -> np.ndarray:
    """``sign(v_x) * max(0, |v_x| - sigmas * v_x_std)`` (m/s): the part of ``v_x`` its uncertainty cannot explain."""
    v_x, v_x_std = np.asarray(v_x, dtype=float), np.asarray(v_x_std, dtype=float)
    return np.sign(v_x) * np.maximum(0.0, np.abs(v_x) - sigmas * v_x_std)


class ForwardCollisionWarning:
    """``update(states, risk, t, ego_speed=None) -> WarningState``: the rules of the module docstring.

    Defaults chosen with ``scripts/tune_warning.py`` on ``scenarios/fcw/tuning.yaml`` (speeds,
    gaps and seeds in no scorecard suite nor CI): threshold 3.0 s (the strictest standard
    conflict, NHTSA LVD, requires the warning at a true TTC >= 2.4 s; the estimate lags, and
    2.7 s gave first warnings at 2.0-2.2 s on the braking lead without the acceleration term);
    ``lateral_sigmas`` 3 (the filter's lateral-velocity sigma is overconfident: |error|/sigma
    has a 90th percentile of 2.3-2.5 on the tuning set's nominal runs, against 1.64 for a
    calibrated Gaussian); ``accel_sigmas`` 2 (the braking lead's first warning 2.18 s -> 2.83-3.44 s,
    at the cost of more false alarms: 4 -> 6 in 3 min of nominal traffic). ``None``: no
    acceleration term. ``longitudinal_sigmas`` 0.5, ``looming_sigmas`` 1, ``ego_speed_margin_mps``
    1: the third round (docs/warning_tuning.md; 32 min of nominal traffic, 16 conflicts);
    ``looming_share`` 0 (off): the fourth round's 0.6 cut false alarms but delayed braking leads and
    cut-ins on the suites and CI (docs/warning_tuning.md, Fourth round), so it is opt-in.
    ``looming_far_share`` 0.6 from ``looming_far_distance_m`` 35 m on (every vehicle that far, where a
    pixel of bottom edge is metres of range) and ``looming_exempt_gap_m`` 0.5 (a vehicle moving
    sideways within 0.5 m of the corridor, i.e. across the lane line, is turning in: its box width
    changes with its yaw, so no looming veto): the fifth round (docs/warning_tuning.md, Fifth round).
    ``looming_side_share`` 0.6: a vehicle moving sideways but still beyond that gap (in its own lane,
    read drifting in) must widen at 0.6 of its closing speed over its distance, as a far one must: the
    sixth round (docs/warning_tuning.md, Sixth round). ``young_far_age_s`` 0.3 at ``young_far_distance_m``
    20 m and beyond: a track whose filter is younger than that is no threat yet (a far box's first
    readings, a short first box and the filter's wide prior, read 10-15 m/s of closing); nearer, where
    a cut-in's filter restarts as the turning car's box changes shape, none is asked (docs/warning_noise.md,
    Eighth round). ``registered_share`` 0.6 with ``registered_sigmas`` 1: a vehicle whose registered
    patch (``ObjectState.registered_rate``, :mod:`monorarp.state.scale_change`) grows at less than 0.6 of
    its claimed closing speed over its distance, by more than one sigma, is no threat, unless it is
    read moving sideways beyond ``registered_lateral_sigmas`` (2) of its lateral sigma (a turning car's
    patch changes with its yaw); a rate that precise lags a braking lead by a frame or so, where the box
    width's lags by several (docs/warning_noise.md, Ninth round). None: no such veto.
    ``confirmed_min_on_s`` 0 with ``confirm_share`` 1: a threat whose patch grows at least as fast as the
    closing speed its TTC assumes, by more than ``registered_sigmas``, needs no persistence: two independent
    cues agree, and the range filter lags a braking lead (docs/warning_confirm.md). None: ``min_on_s`` for all.
    With the state stage's opt-in fusion of the patch's scale (``fusion_sigmas``) the two cues are one: set it
    to None there (docs/scale_fusion.md).
    ``registered_lateral_share`` (opt-in, None): a significant sideways speed whose patch moves in that
    direction, plus ``registered_sigmas`` of its sigma, at less than this share of it counts as none
    (``ObjectState.registered_v_x``); 0.5 removed a false track and delayed a cut-in (docs/warning_confirm.md).
    """

    uses_camera = True   # the registry passes the run's camera

    def __init__(self, ttc_threshold_s: float = DEFAULT_TTC_THRESHOLD_S, min_on_s: float = 0.1,
                 hold_s: float = 1.0, lateral_sigmas: float = 3.0, lateral_velocity_std_mps: float = 0.5,
                 longitudinal_sigmas: float = 0.5, max_lateral_speed_mps: float = 3.0,
                 max_closing_speed_mps: float = 45.0, accel_sigmas: float | None = 2.0,
                 corridor_margin_m: float = 0.0, min_lateral_age_s: float = 0.0, other_width_m: float = 1.8, other_length_m: float = 4.5,
                 ego_width_m: float = 1.8, ego_length_m: float = 4.5, camera_forward_offset_m: float = 0.0,
                 camera_lateral_offset_m: float = 0.0, camera: CameraModel | None = None,
                 distance_sigmas: float = 0.0, max_raw_lateral_speed_mps: float | None = 6.0,
                 looming_sigmas: float | None = 1.0, looming_factor: float = 2.5, looming_share: float = 0.0,
                 looming_far_share: float = 0.6, looming_far_distance_m: float = 35.0,
                 looming_exempt_gap_m: float | None = 0.5, looming_side_share: float = 0.6,
                 ego_speed_margin_mps: float | None = 1.0, young_far_age_s: float = 0.3,
                 young_far_distance_m: float = 20.0, registered_share: float | None = 0.6,
                 registered_sigmas: float = 1.0, registered_lateral_sigmas: float = 2.0,
                 confirmed_min_on_s: float | None = 0.0, confirm_share: float = 1.0,
                 registered_lateral_share: float | None = None) -> None:
        for name, v in (("ttc_threshold_s", ttc_threshold_s), ("other_width_m", other_width_m),
                        ("other_length_m", other_length_m), ("ego_width_m", ego_width_m),
                        ("ego_length_m", ego_length_m)):
            if not (np.isfinite(v) and v > 0):
                raise ValueError(f"{name} must be positive, got {v}")
        for name, v in (("min_on_s", min_on_s), ("hold_s", hold_s), ("lateral_sigmas", lateral_sigmas),
                        ("longitudinal_sigmas", longitudinal_sigmas), ("max_lateral_speed_mps", max_lateral_speed_mps),
                        ("max_closing_speed_mps", max_closing_speed_mps),
                        ("lateral_velocity_std_mps", lateral_velocity_std_mps), ("min_lateral_age_s", min_lateral_age_s),
                        ("young_far_age_s", young_far_age_s), ("young_far_distance_m", young_far_distance_m)):
            if not (np.isfinite(v) and v >= 0):
                raise ValueError(f"{name} must be >= 0, got {v}")
        if not np.isfinite(distance_sigmas):
            raise ValueError(f"distance_sigmas must be finite, got {distance_sigmas}")
        self.distance_sigmas = float(distance_sigmas)
        if looming_sigmas is not None and not (np.isfinite(looming_sigmas) and looming_sigmas >= 0):
            raise ValueError(f"looming_sigmas must be >= 0 or None, got {looming_sigmas}")
        if not (np.isfinite(looming_factor) and looming_factor > 0):
            raise ValueError(f"looming_factor must be positive, got {looming_factor}")
        self.looming_sigmas = None if looming_sigmas is None else float(looming_sigmas)
        self.looming_factor = float(looming_factor)
        if not (np.isfinite(looming_share) and 0 <= looming_share <= 1):
            raise ValueError(f"looming_share must be in [0, 1], got {looming_share}")
        self.looming_share = float(looming_share)
        if not (np.isfinite(looming_far_share) and 0 <= looming_far_share <= 1):
            raise ValueError(f"looming_far_share must be in [0, 1], got {looming_far_share}")
        if not (np.isfinite(looming_far_distance_m) and looming_far_distance_m >= 0):
            raise ValueError(f"looming_far_distance_m must be >= 0, got {looming_far_distance_m}")
        self.looming_far_share, self.looming_far_distance_m = float(looming_far_share), float(looming_far_distance_m)
        if looming_exempt_gap_m is not None and not (np.isfinite(looming_exempt_gap_m) and looming_exempt_gap_m >= 0):
            raise ValueError(f"looming_exempt_gap_m must be >= 0 or None, got {looming_exempt_gap_m}")
        self.looming_exempt_gap_m = None if looming_exempt_gap_m is None else float(looming_exempt_gap_m)
        if not (np.isfinite(looming_side_share) and 0 <= looming_side_share <= 1):
            raise ValueError(f"looming_side_share must be in [0, 1], got {looming_side_share}")
        self.looming_side_share = float(looming_side_share)
        if registered_share is not None and not (np.isfinite(registered_share) and 0 <= registered_share <= 1):
            raise ValueError(f"registered_share must be in [0, 1] or None, got {registered_share}")
        if not (np.isfinite(registered_sigmas) and registered_sigmas >= 0):
            raise ValueError(f"registered_sigmas must be >= 0, got {registered_sigmas}")
        self.registered_share = None if registered_share is None else float(registered_share)
        self.registered_sigmas = float(registered_sigmas)
        if not (np.isfinite(registered_lateral_sigmas) and registered_lateral_sigmas >= 0):
            raise ValueError(f"registered_lateral_sigmas must be >= 0, got {registered_lateral_sigmas}")
        self.registered_lateral_sigmas = float(registered_lateral_sigmas)
        if confirmed_min_on_s is not None and not (np.isfinite(confirmed_min_on_s) and confirmed_min_on_s >= 0):
            raise ValueError(f"confirmed_min_on_s must be >= 0 or None, got {confirmed_min_on_s}")
        if not (np.isfinite(confirm_share) and confirm_share > 0):
            raise ValueError(f"confirm_share must be positive, got {confirm_share}")
        self.confirmed_min_on_s = None if confirmed_min_on_s is None else float(confirmed_min_on_s)
        self.confirm_share = float(confirm_share)
        if registered_lateral_share is not None and not (np.isfinite(registered_lateral_share)
                                                         and 0 <= registered_lateral_share <= 1):
            raise ValueError(f"registered_lateral_share must be in [0, 1] or None, got {registered_lateral_share}")
        self.registered_lateral_share = None if registered_lateral_share is None else float(registered_lateral_share)
        if ego_speed_margin_mps is not None and not (np.isfinite(ego_speed_margin_mps) and ego_speed_margin_mps >= 0):
            raise ValueError(f"ego_speed_margin_mps must be >= 0 or None, got {ego_speed_margin_mps}")
        self.ego_speed_margin_mps = None if ego_speed_margin_mps is None else float(ego_speed_margin_mps)
        if max_raw_lateral_speed_mps is not None and not (np.isfinite(max_raw_lateral_speed_mps)
                                                          and max_raw_lateral_speed_mps > 0):
            raise ValueError(f"max_raw_lateral_speed_mps must be > 0 or None, got {max_raw_lateral_speed_mps}")
        self.max_raw_lateral_speed_mps = None if max_raw_lateral_speed_mps is None else float(max_raw_lateral_speed_mps)
        if camera is not None:
            camera_forward_offset_m, camera_lateral_offset_m = camera.forward_offset_m, camera.lateral_offset_m
        self.ttc_threshold_s, self.min_on_s, self.hold_s = float(ttc_threshold_s), float(min_on_s), float(hold_s)
        self.lateral_sigmas, self.lateral_velocity_std_mps = float(lateral_sigmas), float(lateral_velocity_std_mps)
        self.longitudinal_sigmas = float(longitudinal_sigmas)
        self.min_lateral_age_s = float(min_lateral_age_s)
        self.young_far_age_s, self.young_far_distance_m = float(young_far_age_s), float(young_far_distance_m)
        if accel_sigmas is not None and not (np.isfinite(accel_sigmas) and accel_sigmas >= 0):
            raise ValueError(f"accel_sigmas must be >= 0 or None, got {accel_sigmas}")
        self.accel_sigmas = None if accel_sigmas is None else float(accel_sigmas)
        self.max_lateral_speed_mps = float(max_lateral_speed_mps)
        self.max_closing_speed_mps = float(max_closing_speed_mps)
        self.other_width_m, self.other_length_m = float(other_width_m), float(other_length_m)
        (x_lo, x_hi), self.ego_y = ego_extent(ego_length_m, ego_width_m, camera_forward_offset_m,
                                              camera_lateral_offset_m)
        self.ego_x = (x_lo - corridor_margin_m, x_hi + corridor_margin_m)
        self.reset()

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
        ids = list(states)
        s = list(states.values())
        d_x = np.array([o.d_x for o in s], dtype=float)
        d_y = np.array([o.d_y for o in s], dtype=float)
        if self.distance_sigmas:
            d_y = d_y - self.distance_sigmas * np.array([0.0 if o.d_y_std is None else o.d_y_std for o in s])
        v_y_std = np.array([0.0 if o.v_y_std is None else o.v_y_std for o in s], dtype=float)
        v_y = significant_lateral_velocity([o.v_y for o in s], v_y_std, self.longitudinal_sigmas)
        if self.ego_speed_margin_mps is not None and ego_speed is not None and np.isfinite(ego_speed):
            v_y = np.maximum(v_y, -(max(float(ego_speed), 0.0) + self.ego_speed_margin_mps))
        v_x_std = np.array([self.lateral_velocity_std_mps if o.v_x_std is None else o.v_x_std for o in s])
        v_x = significant_lateral_velocity([o.v_x for o in s], v_x_std, self.lateral_sigmas)
        refuted = np.zeros(len(s), dtype=bool)
        if self.registered_lateral_share is not None:
            # a sideways motion the patch's own shift does not show (its lateral speed in that direction,
            # plus registered_sigmas of its sigma, under the share of the filter's): no sideways motion
            lat = np.array([np.nan if o.registered_v_x is None else o.registered_v_x for o in s], dtype=float)
            lat_std = np.array([0.0 if o.registered_v_x_std is None else o.registered_v_x_std for o in s])
            refuted = (v_x != 0.0) & (lat * np.sign(v_x) + self.registered_sigmas * lat_std
                                      < self.registered_lateral_share * np.abs(v_x))   # NaN: not refuted
        age = np.array([np.inf if o.age_s is None else o.age_s for o in s], dtype=float)
        v_x = np.where(age >= self.min_lateral_age_s - 1e-9, v_x, 0.0)
        # an implausible lateral reading stays a sign of a faulty state, refuted or not
        plausible = (np.abs(v_x) <= self.max_lateral_speed_mps) & (-v_y <= self.max_closing_speed_mps)
        v_x = np.where(refuted, 0.0, v_x)
        plausible &= ~((age < self.young_far_age_s - 1e-9) & (d_y >= self.young_far_distance_m))
        if self.max_raw_lateral_speed_mps is not None:
            raw_v_x = np.array([o.v_x for o in s], dtype=float)
            plausible &= ~(np.abs(raw_v_x) > self.max_raw_lateral_speed_mps)
        x_lo, x_hi, y_lo, y_hi = object_extents(d_x, d_y, self.other_width_m, self.other_length_m)
        reg = np.array([np.nan if o.registered_rate is None else o.registered_rate for o in s], dtype=float)
        reg_std = np.array([0.0 if o.registered_rate_std is None else o.registered_rate_std for o in s])
        # a vehicle read moving sideways turns, and its patch changes with its yaw: it neither confirms nor vetoes
        sideways = (significant_lateral_velocity([o.v_x for o in s], v_x_std, self.registered_lateral_sigmas) != 0.0) \
            & ~refuted
        confirmed = (reg - self.registered_sigmas * reg_std >= self.confirm_share * np.maximum(-v_y, 0.0)
                     / np.maximum(d_y, 1.0)) & ~sideways   # NaN rate: not confirmed
        if self.registered_share is not None:
            need = self.registered_share * np.maximum(-np.array([o.v_y for o in s], dtype=float), 0.0) \
                / np.maximum(np.array([o.d_y for o in s], dtype=float), 1.0)
            # no rate: no veto
            plausible &= ~((reg + self.registered_sigmas * reg_std < need) & ~sideways)
        if self.looming_sigmas is not None:
            rate = np.array([np.nan if o.expansion_rate is None else o.expansion_rate for o in s], dtype=float)
            rate_std = np.array([0.0 if o.expansion_rate_std is None else o.expansion_rate_std for o in s])
            # a vehicle moving sideways (a cut-in) turns, and its box's width changes with its yaw:
            # the share of the claimed closing speed is asked of one that keeps its lane, of a far one
            # (whose range, and so its lateral reading, a pixel of bottom edge moves by metres), and of
            # one read moving sideways that is still beyond the lane line (looming_side_share)
            share = np.where(v_x == 0.0, self.looming_share, 0.0)
            far = d_y >= self.looming_far_distance_m
            share = np.where(far, np.maximum(share, self.looming_far_share), share)
            gap = np.maximum(np.maximum(x_lo - self.ego_x[1], self.ego_x[0] - x_hi), 0.0)
            if self.looming_side_share > 0:   # moving sideways but still beyond the lane line
                beyond = (v_x != 0.0) & (gap > (0.0 if self.looming_exempt_gap_m is None else self.looming_exempt_gap_m))
                share = np.where(beyond, np.maximum(share, self.looming_side_share), share)
            need = np.maximum(1.0 / (self.looming_factor * self.ttc_threshold_s),
                              share * np.maximum(-v_y, 0.0) / np.maximum(d_y, 1.0))
            veto = rate + self.looming_sigmas * rate_std < need   # no rate yet: no veto
            if self.looming_exempt_gap_m is not None:    # turning in across the lane line: no veto
                veto &= (v_x == 0.0) | far | (gap > self.looming_exempt_gap_m)
            plausible &= ~veto
        a_y = None
        if self.accel_sigmas is not None:
            a = np.array([0.0 if o.a_y is None else o.a_y for o in s], dtype=float)
            a_std = np.array([0.0 if o.a_y_std is None else o.a_y_std for o in s], dtype=float)
            a_y = significant_lateral_velocity(a, a_std, self.accel_sigmas)
        ttc = time_to_collision(x_lo, x_hi, y_lo, y_hi, v_x, v_y, self.ego_x, self.ego_y, self.ttc_threshold_s,
                                a_y=a_y)
        ttc = np.where(plausible, ttc, np.nan)
        threats = {i: float(v) for i, v in zip(ids, ttc) if np.isfinite(v) and v < self.ttc_threshold_s}
        return threats, frozenset(i for i, c in zip(ids, confirmed) if c and i in threats)

    def update(self, states: dict[int, ObjectState], risk: RiskEstimate | None = None,
               t: float = 0.0, ego_speed: float | None = None) -> WarningState:
        """The warning decision at frame time ``t`` (s), given the ego's speed (m/s) where known.
        ``risk`` is not needed (the TTC is recomputed with the discounted lateral velocity) and
        accepted for the common stage interface."""
        t = float(t)
        if not np.isfinite(t):
            raise ValueError(f"frame time must be finite, got {t}")
        if self._last_t is not None and t < self._last_t:
            self.reset()      # time went backwards: a new sequence (e.g. a looped video)
        self._last_t = t
        threats, confirmed = self.assess_threats(states, ego_speed)
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
        persisted = threats and t - self._threat_since >= self.min_on_s - eps
        persisted = persisted or (self.confirmed_min_on_s is not None and confirmed
                                  and t - self._confirmed_since >= self.confirmed_min_on_s - eps)
        if not self._active and persisted:
            self._active, self._onset_t, self._track = True, t, order[0]
            self._episodes += 1
        elif self._active and not threats and t - self._last_threat_t >= self.hold_s - eps:
            self._active, self._onset_t, self._track = False, None, None
        if not self._active:
            return WarningState(active=False, threat_ids=order)
        if threats and (self._track not in threats or threats[order[0]] < threats[self._track]):
            self._track = order[0]
        return WarningState(active=True, track_id=self._track, ttc=threats.get(self._track),
                            episode=self._episodes - 1, onset_t=self._onset_t, threat_ids=order)
