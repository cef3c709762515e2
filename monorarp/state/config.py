"""The state estimator's settings: :class:`StateConfig` (units: m, m/s, px, s).

Every setting of :class:`monorarp.state.estimator.StateEstimator` with its default, its valid range
(a field constraint) and a one-line description; the model they tune: docs/state_estimation.md.
:func:`state_config` builds one from keyword overrides (the registry's ``kwargs``, YAML ``state_kwargs``,
``--velocity``) and refuses a bad value with one line naming the field.

How the defaults were chosen:

* ``edge_std_px`` 0.9 and ``border_edge_std_px`` 2.7: the shipped CenterNet + particle tracker's
  bottom-edge error (90th percentile of |error| / 1.645) over 2193 whole and 146 side-cut object-frames
  of highway_cruise (seeds 3, 4) and dense_traffic (seed 3), 10 s each at 640x360. Such an error
  persists from frame to frame (a per-vehicle bias the filter, assuming white noise, cannot average
  away), so it widens ``d_y_std`` instead of the filter's noise; so does ``contact_offset_std_m``
  (rear overhangs of 0.8--1.1 m give 0.09).
* ``pixel_std_per_height``: a near vehicle's big box has fuzzier edges (its bottom edge flips between
  the bumper and the tyres' contact by several px), and a frame larger than the detector's input has
  proportionally coarser boxes.
* ``border_tol_px`` ``"auto"``: 4 px per 640 px of image width, i.e. 2 px of the detector's input, whose
  boxes are that coarse at any frame size (at 1920x1080, 12 px).
* ``side_band_frac`` 0.03: a vehicle leaving the view has a far edge the tracker's box trails (7-14 px
  at 1920 px in the traces), which reads as the vehicle drifting in at 2-3 m/s; the sixth tuning round
  (docs/warning_tuning.md: 0.02-0.06 equal on the tuning set).
* ``reinit_sigmas`` 5: a jump that large is the tracker's box moving to another vehicle (or to part of
  one), not motion; absorbed by the filter it reads as tens of m/s of closing speed.
* ``max_inward_offset_m`` 0.3: only a vehicle shorter and narrower than any car could need more; a
  larger inward offset was learnt from a detector box that stopped short of the border while its
  vehicle was still partly out of view, and put a car in the next lane 2-3 m inside the ego's corridor.
* ``expansion_accel_std`` 4.5 m/s^2, ``expansion_pixel_std`` 1 px, ``expansion_constant_speed``: the
  fourth tuning round's filter, default since the fifth (docs/warning_tuning.md);
  ``expansion_accel_std=None, expansion_pixel_std=0.5, expansion_constant_speed=False`` is the earlier
  constant-rate filter, whose sigma was 4x too wide at 60-100 m for the looming veto to act there.
* ``registration_pixel_std`` 0.2 px: measured on CCRb, CCRs and LVD runs (docs/warning_noise.md, Ninth
  round); ``registration_window_s`` 0.2 s is 3 frames at 15 fps.
* ``fusion_sigmas`` None (off): 5 lifts the risk AUROC to 0.9505 but doubles the median velocity error
  and costs distance accuracy near the ego (the per-frame scale reads 1-2 % slow; the twelfth tuning
  round, docs/scale_fusion.md). ``longitudinal_process_std`` 9 with the fusion gave 1 false alarm an
  hour on the benchmark and cost an LVD trial.
* ``registration_top`` 0 and ``registration_interpolation`` ``"cubic"`` scatter 25-35 % less against
  the true depth ratio but moved no warning figure, so they are opt-in (docs/scale_fusion.md,
  thirteenth round).
* ``size_prior`` off: on rendered frames the ground is flat and the camera level, so the ground plane alone is
  exact; on real roads it reads 10 % near (docs/state_estimation.md). The real-frame commands turn it on.
* ``kind_memory_s`` None (opt-in, e.g. 1 s with ``kind_switch_share`` 0.75): yolox flips a real SUV between car,
  truck and bus from frame to frame (docs/state_estimation.md); a per-track kind halves the filter restarts and
  warns 1.0 s earlier on a braking lead, but lets a longer-lived filter read a box top's drift as closing: 2 false
  episodes on the stress clip with no warning due, so it is not on by default.
* ``offset_learn_margin_px`` None: a margin (e.g. 16 px) keeps a detector box that stops short of the
  border while its vehicle enters the view from teaching a wrong near-edge offset, but also keeps a
  whole vehicle near the border from teaching the right one (tests/test_state.py: a 1.6 m/s
  lateral-velocity jump), so it is opt-in.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field

from monorarp.core.errors import UserError
from monorarp.core.settings import with_overrides


class StateConfigError(UserError, ValueError):
    """A bad state-estimator setting (unknown name, wrong type, out of range); its message is one line naming it."""


class StateConfig(BaseModel):
    """Settings of the geometric state estimator (module docstring for how the defaults were chosen).

    Every number must be finite unless its description allows ``inf``; a field typed ``... | None``
    turns its rule off (or falls back to another field) with None.
    """

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False, frozen=True)

    # Filter
    velocity: Literal["kalman", "difference"] = Field("kalman", description=(
        "relative velocity from a Kalman filter per track, or the paper's frame differencing"))
    motion: Literal["ca", "cv"] = Field("ca", description=(
        "Kalman motion model: constant acceleration or constant velocity"))
    process_std: float = Field(4.5, description=(
        "Kalman process noise: jerk std (m/s^3) for 'ca', acceleration std (m/s^2) for 'cv'"))
    longitudinal_process_std: float | None = Field(None, gt=0, description=(
        "the same on the longitudinal axis (m/s^3 for 'ca'); None: process_std"))
    pixel_std: float = Field(0.5, description="Kalman measurement noise: box-edge std (px)")
    pixel_std_per_height: float = Field(0.01, ge=0, description=(
        "box-edge std per px of box height (px/px), added to pixel_std in quadrature"))
    lateral_pixel_std: float | None = Field(None, description=(
        "box-edge std (px) of the lateral measurement; None: pixel_std"))
    init_vel_std: float = Field(10.0, description="prior velocity std (m/s) of a new track's filter")
    init_acc_std: float = Field(5.0, description="prior acceleration std (m/s^2) of a new track's filter ('ca')")
    reinit_sigmas: float = Field(5.0, gt=0, allow_inf_nan=True, description=(
        "a measurement this many innovation sigmas off restarts the track's filter there (inf: never)"))
    robust_sigmas: float | None = Field(None, gt=0, allow_inf_nan=True, description=(
        "Huber: an innovation beyond this many sigmas counts as if its spread were that large; None: off"))
    bias_pixel_std: float | None = Field(None, description=(
        "std (px) of the box edge's slowly varying error, estimated as a filter state; None: none"))
    lateral_bias_pixel_std: float | None = Field(None, description=(
        "the same on the lateral axis (px); None: bias_pixel_std"))
    bias_tau_s: float = Field(1.0, gt=0, allow_inf_nan=True, description=(
        "time constant (s) of that error, a first-order Gauss-Markov process"))

    # Track bookkeeping
    max_coast_used: int = Field(2, description="consecutive coasting frames after which a track is no longer output")
    forget_s: float = Field(1.0, description="a track id unseen for this long (s) loses its history")
    max_unmeasured_s: float = Field(0.5, ge=0, allow_inf_nan=True, description=(
        "a track whose box gave no distance for longer (s; contact line out of view) is no longer output"))

    # Vehicle model and boxes (ego frame of monorarp.core.camera)
    vehicle_width_m: float = Field(1.8, description="assumed vehicle width W_r (m) of equation 4")
    vehicle_length_m: float = Field(4.5, description=(
        "assumed vehicle length (m), used only for the near edge of a box cut by a side border"))
    contact_offset_m: float = Field(0.95, description=(
        "rear face to the tyres' contact line (m): the contact-line correction (0: the paper)"))
    ground_clearance_m: float = Field(0.17, description=(
        "height (m) of the vehicle's underside at its rear face (0: the paper)"))
    border_tol_px: float | Literal["auto"] | None = Field("auto", description=(
        "a box edge this close (px) to the image border is the border's; 'auto': 4 px per 640 px wide; None: never"))
    min_vehicle_width_m: float = Field(1.4, ge=0, description=(
        "a box narrower than this (m) at its distance shows a part of a vehicle (0: never)"))
    near_border_frac: float = Field(0.05, ge=0, description=(
        "such a box within this fraction of the frame width of its far side border is cut by it"))
    offset_learn_margin_px: float | None = Field(None, ge=0, description=(
        "the near-edge offset is learnt only from boxes this far (px) inside the side borders; None: border_tol_px"))
    max_inward_offset_m: float | None = Field(0.3, ge=0, description=(
        "most (m) a learnt near-edge offset may move a vehicle towards the centre line; None: no limit"))
    fragment_cover: float | None = Field(0.9, gt=0, le=1, description=(
        "a box with this share of its area inside a wider track box on its ground row gets no state; None: off"))
    fragment_width_ratio: float = Field(1.5, ge=0, description="... that box at least this many times as wide")
    fragment_bottom_px: float = Field(3.0, ge=0, description=(
        "... their bottom edges within this (px at 640 px width; scaled with the image)"))
    hidden_side_px: float | None = Field(2.0, ge=0, description=(
        "a box side within this (px at 640 px width; scaled with the image) of a nearer vehicle's box reaching "
        "across it is that vehicle's edge: the lateral reading takes the other side, as at a border; None: off"))
    hidden_share: float | None = Field(0.5, ge=0, lt=1, description=(
        "a box over more than this share of its area behind a nearer vehicle's box shows a part of it; None: off"))

    # Reported uncertainty
    side_cut_lateral_std_mps: float = Field(2.0, description=(
        "lateral-velocity one-sigma (m/s) reported at least for a box cut by a side border or showing a part"))
    side_band_frac: float = Field(0.03, ge=0, lt=0.5, description=(
        "the same while a side box's far edge lies within this fraction of the frame width of its border"))
    edge_std_px: float = Field(0.9, ge=0, description=(
        "one-sigma (px) of the bottom edge's persistent error, added to d_y_std"))
    border_edge_std_px: float = Field(2.7, ge=0, description="the same (px) for a box cut by a side border")
    contact_offset_std_m: float = Field(0.09, ge=0, description="one-sigma (m) of contact_offset_m, added to d_y_std")
    horizon_std_px: float = Field(0.0, ge=0, description=(
        "one-sigma (px) of the calibrated horizon row where no horizon reading is given, added to d_y_std"))
    grade_std: float = Field(0.0, ge=0, description=(
        "one-sigma (rise/run) of the road's grade ahead relative to the ego's, added to d_y_std (0: flat)"))

    # Size prior (monorarp.state.size_prior): the distance from the box's height / width given the vehicle's kind
    size_prior: bool = Field(False, description=(
        "fuse each box's distance from its kind's height and width with the ground plane's (inverse variance)"))
    size_priors: dict[str, tuple[float, float, float, float, float, float]] | None = Field(None, description=(
        "kind -> (height, its std, width, its std, length, its std) m; None: monorarp.state.size_prior.SIZE_PRIORS"))
    size_prior_width: bool = Field(False, description=(
        "the size prior also uses the box width (whole boxes only; on KITTI it reads 13 % off and hurts the fusion)"))
    size_prior_edge_std_px: float = Field(1.0, gt=0, description=(
        "one-sigma (px) of each box edge in the size prior's distances"))
    ground_pitch_std: float = Field(0.01, ge=0, description=(
        "one-sigma (rad, or rise/run) of the camera's pitch and the road's grade under the vehicle, in the "
        "ground plane's one-sigma the size prior is fused with"))
    size_prior_ground_fit: bool = Field(True, description=(
        "the size prior's ground plane is fitted per frame to the other vehicles' sizes and bottom rows"))
    camera_height_std_m: float = Field(0.1, gt=0, description=(
        "prior one-sigma (m) of the camera's height over the ground under the vehicles, in that fit"))
    ground_roughness_m: float = Field(0.15, ge=0, description=(
        "one-sigma (m) of the ground under each vehicle about the fitted plane"))
    size_prior_hidden_share: float | None = Field(None, ge=0, lt=1, description=(
        "a box over more than this share of its area behind a nearer vehicle's box takes no size prior; None: any"))
    kind_memory_s: float | None = Field(None, gt=0, description=(
        "time constant (s) of the decayed score-weighted label votes giving each track's kind; None: each box's label"))
    kind_switch_share: float = Field(0.75, gt=0.5, le=1, description=(
        "a track's kind changes only to a label holding this share of its votes (hysteresis)"))

    # Looming: expansion rate of the box width (monorarp.state.expansion)
    expansion_process_std: float = Field(1.0, gt=0, description=(
        "process noise (1/s^2) of the expansion-rate filter where no distance or expansion_accel_std is given"))
    expansion_accel_std: float | None = Field(4.5, gt=0, description=(
        "relative acceleration one-sigma (m/s^2) setting that noise as accel_std / d_y; None: expansion_process_std"))
    expansion_pixel_std: float = Field(1.0, gt=0, description="one-sigma (px) of each side edge in that filter")
    expansion_constant_speed: bool = Field(True, description=(
        "that filter predicts a constant closing speed instead of a constant rate"))

    # Looming: registration of the vehicle's image patch (monorarp.state.scale_change)
    registration: bool = Field(True, description=(
        "register each vehicle's patch between frames for registered_rate (needs the frame's image)"))
    registration_pixel_std: float = Field(0.2, gt=0, description=(
        "one-sigma of the registered scale (px of box width a frame)"))
    registration_window_s: float = Field(0.2, gt=0, description="window (s) the registered rates are averaged over")
    registration_top: float = Field(0.3, ge=0, lt=1, description="top fraction of each box left out of its patch")
    registration_interpolation: Literal["linear", "cubic"] = Field("linear", description=(
        "how the current frame is sampled in the fit"))
    fusion_sigmas: float | None = Field(None, gt=0, description=(
        "fuse the registered scale into the range filter, gated at this many sigmas ('ca' only); None: off"))
    fusion_pixel_std: float | None = Field(None, gt=0, description=(
        "the scale's one-sigma (px of box width) in that fusion; None: registration_pixel_std"))


#: The state settings of the commands whose frames are real (``video``, ``eval kitti`` on real data): the size prior,
#: and the box bottom taken at the rear face (a real box's vertical extent lies there: docs/state_estimation.md).
REAL_FRAMES_STATE: dict[str, Any] = {"size_prior": True, "contact_offset_m": 0.0}


def state_config(base: StateConfig | None = None, overrides: Mapping[str, Any] | None = None) -> StateConfig:
    """``base`` (default: the defaults) with ``overrides`` validated in; :class:`StateConfigError` if bad."""
    return with_overrides(StateConfig, base, overrides, "state", StateConfigError)
