"""The forward-collision warning stage's settings: :class:`WarningConfig` (units: m, m/s, s).

Every setting of :class:`monorarp.warning.fcw.ForwardCollisionWarning` with its default, its valid
range (a field constraint) and a one-line description; the rules they tune: docs/warning.md.
:func:`warning_config` builds one from keyword overrides (the registry's ``kwargs``, YAML
``warning_kwargs``, ``scripts/tune_warning.py``) and refuses a bad value with one line naming the field.

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

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from pydantic import BaseModel, ConfigDict, Field

from monorarp.core.errors import UserError
from monorarp.core.settings import with_overrides
from monorarp.warning.thresholds import FCW_THRESHOLD_S


class WarningConfigError(UserError, ValueError):
    """A bad warning setting (unknown name, wrong type, out of range); its message is one line naming it."""


class WarningConfig(BaseModel):
    """Settings of the forward-collision warning stage (module docstring for how the defaults were chosen).

    Every number must be finite; a field typed ``float | None`` turns its rule off with None.
    """

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False, frozen=True)

    # Threshold and episodes
    ttc_threshold_s: float = Field(FCW_THRESHOLD_S, gt=0, description=(
        "alert threshold (s): an in-path TTC below it is a threat (monorarp.warning.thresholds)"))
    min_on_s: float = Field(0.1, ge=0, description="how long (s, frame time) a threat must persist before the alert")
    confirmed_min_on_s: float | None = Field(0.0, ge=0, description=(
        "persistence (s) for a threat its registered patch confirms; None: min_on_s for all"))
    confirm_share: float = Field(1.0, gt=0, description=(
        "share of the closing speed over the distance (1/s) the patch's rate must reach to confirm"))
    hold_s: float = Field(1.0, ge=0, description="how long (s) the alert stays on after the last threat")

    # Motion margins and plausibility
    lateral_sigmas: float = Field(3.0, ge=0, description="lateral velocity counted beyond this many of its sigmas")
    lateral_velocity_std_mps: float = Field(0.5, ge=0, description=(
        "lateral-velocity sigma (m/s) where the state gives none"))
    longitudinal_sigmas: float = Field(0.5, ge=0, description="closing speed counted beyond this many of its sigmas")
    accel_sigmas: float | None = Field(2.0, ge=0, description=(
        "closing acceleration counted beyond this many of its sigmas; None: constant velocity"))
    distance_sigmas: float = Field(0.0, description=(
        "rear face taken at d_y - k d_y_std (k, any sign; 0: the estimate itself)"))
    min_lateral_age_s: float = Field(0.0, ge=0, description="track age (s) before its lateral velocity counts")
    max_lateral_speed_mps: float = Field(3.0, ge=0, description=(
        "significant lateral speed (m/s) above which the motion is implausible: no threat"))
    max_raw_lateral_speed_mps: float | None = Field(6.0, gt=0, description=(
        "estimated lateral speed (m/s, before its margin) above which: no threat; None: off"))
    max_closing_speed_mps: float = Field(45.0, ge=0, description="closing speed (m/s) above which: no threat")
    ego_speed_margin_mps: float | None = Field(1.0, ge=0, description=(
        "closing speed capped at the ego speed plus this (m/s); None: no cap"))
    young_far_age_s: float = Field(0.3, ge=0, description=(
        "a track younger than this (s) at young_far_distance_m or beyond is no threat yet"))
    young_far_distance_m: float = Field(20.0, ge=0, description="distance (m) from which young_far_age_s applies")

    # Looming (box width) and the registered patch
    looming_sigmas: float | None = Field(1.0, ge=0, description=(
        "box expansion rate plus this many sigmas must reach the need; None: no looming veto"))
    looming_factor: float = Field(2.5, gt=0, description="looming floor 1 / (factor x ttc_threshold_s) (1/s)")
    looming_share: float = Field(0.0, ge=0, le=1, description=(
        "share of closing speed over distance (1/s) a vehicle keeping its lane must widen at; 0: off"))
    looming_far_share: float = Field(0.6, ge=0, le=1, description="the same share for a far vehicle")
    looming_far_distance_m: float = Field(35.0, ge=0, description="distance (m) from which a vehicle is far")
    looming_exempt_gap_m: float | None = Field(0.5, ge=0, description=(
        "a vehicle moving sideways within this gap (m) of the corridor is turning in: no looming veto; None: none"))
    looming_side_share: float = Field(0.6, ge=0, le=1, description=(
        "the share for a vehicle moving sideways beyond that gap"))
    registered_share: float | None = Field(0.6, ge=0, le=1, description=(
        "share of closing speed over distance (1/s) the registered patch must grow at; None: no veto"))
    registered_sigmas: float = Field(1.0, ge=0, description="sigmas of the patch's rate (and lateral speed) allowed")
    registered_lateral_sigmas: float = Field(2.0, ge=0, description=(
        "lateral sigmas beyond which a vehicle moves sideways: its patch neither confirms nor vetoes"))
    registered_lateral_share: float | None = Field(None, ge=0, le=1, description=(
        "share of a sideways speed the patch's own shift must show, or it counts as none; None: off"))

    # Geometry (ego frame of monorarp.core.camera)
    other_width_m: float = Field(1.8, gt=0, description="assumed width (m) of another vehicle")
    other_length_m: float = Field(4.5, gt=0, description="assumed length (m) of another vehicle")
    ego_width_m: float = Field(1.8, gt=0, description="ego width (m)")
    ego_length_m: float = Field(4.5, gt=0, description="ego length (m)")
    corridor_margin_m: float = Field(0.0, description="ego corridor widened by this (m) on each side")
    camera_forward_offset_m: float = Field(0.0, description=(
        "ego centre this far (m) behind the camera; the run's camera, when given, sets it"))
    camera_lateral_offset_m: float = Field(0.0, description=(
        "ego centre this far (m) left of the camera; the run's camera, when given, sets it"))


def warning_config(base: WarningConfig | None = None, overrides: Mapping[str, Any] | None = None) -> WarningConfig:
    """``base`` (default: the defaults) with ``overrides`` validated in; :class:`WarningConfigError` if bad."""
    return with_overrides(WarningConfig, base, overrides, "warning", WarningConfigError)
