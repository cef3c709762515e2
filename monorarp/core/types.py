"""Typed records passed between pipeline stages (the paper's Table I).

Images are ``uint8`` arrays of shape (H, W, 3) in **BGR** order (OpenCV's).
Boxes are ``(x1, y1, x2, y2)`` in continuous pixel coordinates, OpenCV
convention (pixel centres at integer coordinates): a box covering pixel
columns 10..19 has ``x1 = 9.5`` and ``x2 = 19.5``.
Distances and velocities are in the ego frame of :mod:`monorarp.core.camera`:
``d_x`` lateral offset of the vehicle's centre (m, + right), ``d_y``
longitudinal distance to its rear face (m, + ahead), ``v_x``/``v_y`` its
velocity minus the ego's (m/s). The stage contracts (``Detector`` ... ``HorizonStage``)
close the module.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

Box = tuple[float, float, float, float]


@dataclass(frozen=True)
class Frame:
    """Camera output: an image and its timestamp (s, from the source, never the wall clock)."""

    index: int
    t: float
    image: np.ndarray


@dataclass(frozen=True)
class Detection:
    """A detector's box. ``weak``: scored under the detector's decision threshold; only a tracker that
    declares ``uses_weak_detections`` gets it (to extend a track it already has), and it is no detection
    in any output or metric."""

    box: Box
    score: float = 1.0
    label: str = "car"
    weak: bool = False


def strong(detections: Iterable[Detection]) -> list[Detection]:
    """``detections`` without the weak ones (those under their detector's decision threshold)."""
    return [d for d in detections if not d.weak]


@dataclass(frozen=True)
class Track:
    """A tracked object: stable id and its box in the current frame."""

    id: int
    box: Box
    score: float = 1.0
    label: str = "car"
    coasting: bool = False   # True when no detection supported it this frame
    age: int = 0             # frames since the track was created


@dataclass(frozen=True)
class HorizonReading:
    """The horizon stage's answer for one frame (:mod:`monorarp.horizon.stages`).

    ``row``: image row (px) of the forward vanishing point that equation 3 uses this frame;
    ``std_px``: its one-sigma uncertainty (px); ``source``: ``"vanishing_point"`` (measured
    this frame), ``"held"`` (an earlier frame's) or ``"calibrated"`` (the calibration's).
    """

    row: float
    std_px: float = 0.0
    source: str = "calibrated"


@dataclass(frozen=True)
class ObjectState:
    """Relative state of one tracked vehicle in the ego frame (m, m/s)."""

    track_id: int
    d_x: float
    d_y: float
    v_x: float
    v_y: float
    # One-sigma uncertainties (m, m/s) of the same quantities where the estimator has them
    # (the Kalman filter's covariance; ``d_y_std`` adds the horizon's and the contact line's
    # uncertainty, see monorarp.state.estimator); None = not estimated (e.g. the paper's differencing).
    # The stated 90 % distance interval is d_y +- 1.645 d_y_std.
    d_x_std: float | None = None
    d_y_std: float | None = None
    v_x_std: float | None = None
    v_y_std: float | None = None
    # Relative longitudinal acceleration (m/s^2) and its one-sigma uncertainty, where the
    # estimator has them (the constant-acceleration Kalman filter); None otherwise.
    a_y: float | None = None
    a_y_std: float | None = None
    # Time (s) since the estimator's filter of this track started (first sighting, or a restart
    # on a jump); None where the estimator keeps no filter.
    age_s: float | None = None
    # Rate of change of the log box width (1/s; closing speed / distance, from the image alone: the
    # looming cue of monorarp.state.expansion) and its one-sigma; None where the estimator has none (or
    # knows it no better than before any measurement).
    expansion_rate: float | None = None
    expansion_rate_std: float | None = None
    # The same rate from registering the vehicle's image patch between frames (1/s; monorarp.state.scale_change,
    # averaged over the last 0.2 s) and its one-sigma; None where the estimator has no image or no
    # registration of this vehicle (too small, occluded, cut, coasting, a new track).
    registered_rate: float | None = None
    registered_rate_std: float | None = None
    # The vehicle's lateral velocity (m/s, ego x) from the same patches' sideways shift, scale and the
    # distance (monorarp.state.scale_change.lateral_displacement, averaged as the rate) and its one-sigma.
    registered_v_x: float | None = None
    registered_v_x_std: float | None = None


@dataclass(frozen=True)
class RiskEstimate:
    """Scene risk score and per-object TTC.

    ``kind`` says what ``risk`` is: ``"inverse_ttc"`` (1/s, the paper's eq. 5: max over
    vehicles of 1/TTC, 0 when none is on a collision course) or ``"probability"``
    (unitless, P(collision or near miss within the horizon), Monte Carlo estimator).
    """

    risk: float
    ttc: dict[int, float | None] = field(default_factory=dict)  # track id -> TTC (s) or None
    kind: str = "inverse_ttc"
    # track id -> one-sigma of its TTC (s), first-order from d_y_std and v_y_std, where both exist
    ttc_std: dict[int, float] = field(default_factory=dict)


@dataclass(frozen=True)
class WarningState:
    """The warning stage's decision for one frame (forward-collision warning, FCW).

    ``active``: a warning episode is on (the driver is alerted). While active,
    ``track_id`` is the object it is for, ``ttc`` that object's in-path TTC by the warning
    stage's own rules (s; not the risk stage's per-object TTC, docs/warning.md; None when it has
    none this frame, e.g. during the hold time), ``episode`` the episode's index in the
    sequence (0-based) and ``onset_t`` its start (s, frame time). ``threat_ids``: tracks
    that pass the in-path and TTC tests this frame (before hysteresis), nearest TTC first.
    """

    active: bool = False
    track_id: int | None = None
    ttc: float | None = None
    episode: int | None = None
    onset_t: float | None = None
    threat_ids: tuple[int, ...] = ()


@dataclass
class FrameResult:
    """Everything the pipeline produced for one frame, plus per-stage time (ms)."""

    index: int
    t: float
    detections: list[Detection]
    tracks: list[Track]
    states: dict[int, ObjectState]
    risk: RiskEstimate
    ego_speed: float | None = None
    timings_ms: dict[str, float] = field(default_factory=dict)
    warning: WarningState = field(default_factory=WarningState)
    horizon: HorizonReading | None = None    # the horizon stage's reading (None: no stage, calibrated)


# ------------------------------------------------------------------------------ stage contracts
# What each pipeline stage must provide (structural: any object with these methods fits; none
# needs to inherit). ``reset()`` (start a new sequence) is optional for every stage except the
# tracker. Images are BGR uint8 (H, W, 3); ``t`` is the frame time (s).

class Detector(Protocol):
    """``detect(image) -> list[Detection]``: the vehicles of one frame. A detector that declares
    ``uses_weak_detections`` also takes ``weak=True`` and then adds its weak detections."""

    def detect(self, image: np.ndarray) -> list[Detection]: ...


class Tracker(Protocol):
    """Detections in, boxes with stable ids out."""

    def update(self, image: np.ndarray, detections: list[Detection], t: float) -> list[Track]: ...

    def reset(self) -> None: ...


class StateEstimator(Protocol):
    """Tracks -> relative state per track id (ego frame, m and m/s); ``horizon`` None = the calibrated one."""

    def update(self, tracks: Sequence[Track], t: float,
               horizon: HorizonReading | None = None) -> dict[int, ObjectState]: ...


class RiskEstimator(Protocol):
    """States -> scene risk. ``ego_speed``: the frame's ego-speed estimate (m/s) or None; an estimator
    that does not need it ignores it (one that does declares ``uses_ego_speed = True``)."""

    def assess(self, states: dict[int, ObjectState], t: float,
               ego_speed: float | None = None) -> RiskEstimate: ...


class EgoSpeedEstimator(Protocol):
    """The ego's speed (m/s) from the frame, or None while it has no valid estimate."""

    def update(self, image: np.ndarray, t: float) -> float | None: ...


class WarningStage(Protocol):
    """The forward-collision warning decision for one frame."""

    def update(self, states: dict[int, ObjectState], risk: RiskEstimate, t: float,
               ego_speed: float | None = None) -> WarningState: ...


class HorizonStage(Protocol):
    """The frame's horizon row for equation 3."""

    def update(self, image: np.ndarray, t: float) -> HorizonReading: ...
