"""State estimator (section IV-C): relative distance and velocity of tracked vehicles.

Tracks -> ``{track id: ObjectState}``: ``d_x`` lateral offset of the vehicle's centre (m, + right),
``d_y`` longitudinal distance to its rear face (m, + ahead), ``v_x``/``v_y`` relative velocity (m/s)
in the ego frame (:mod:`monorarp.core.camera`), from the box geometry of :mod:`monorarp.state.geometry`
and a Kalman filter (or the paper's differencing) over frame timestamps (s). The design and its
measured figures: docs/state_estimation.md.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import replace

import numpy as np

from monorarp.core.camera import CameraError, CameraModel
from monorarp.state.expansion import ExpansionFilter
from monorarp.horizon.ground_profile import contact_ground
from monorarp.core.kalman import kf_predict, kf_update, motion_model
from monorarp.state.scale_change import LoomingRegistration, RateWindow, lateral_displacement
from monorarp.state.geometry import (BORDER_TOL_PX, border_flags, box_distance, contact_line_cut, fragments,
                                     lateral_from_terms, lateral_terms, measure_boxes, near_edge_terms, occluded,
                                     too_narrow)
from monorarp.core.types import HorizonReading, ObjectState, Track


class StateEstimator:
    """Tracks -> ``{track id: ObjectState}`` from box geometry and frame timestamps.

    Parameters:
        camera: the calibrated :class:`CameraModel` (or its dict form).
        velocity: ``"kalman"`` (default) or ``"difference"`` (the paper).
        motion: Kalman motion model, ``"ca"`` (constant acceleration, default) or ``"cv"``.
        process_std: Kalman process noise: jerk std (m/s^3) for ``"ca"``, acceleration std (m/s^2) for ``"cv"``.
        pixel_std: Kalman measurement noise, box-edge std (px).
        max_unmeasured_s: a track whose box has given no distance for longer than this (s; its
            contact line out of view at a side border) is no longer output (one cut by the
            bottom border is: its distance is clamped, see :meth:`_kalman`).
        min_vehicle_width_m, near_border_frac: a box near the side border narrower than this
            width at its distance is taken as cut by the border (:meth:`border_cut_boxes`; 0: never);
            elsewhere it holds a part of a vehicle, whose lateral velocity is then reported with at least
            ``side_cut_lateral_std_mps`` (docs/warning_confirm.md).
        hidden_share: so is a box lying over more than this share of its area behind a nearer vehicle's
            box (one whose bottom edge is lower); None: no such rule.
        pixel_std_per_height: box-edge std per px of box height, added to ``pixel_std`` in
            quadrature: a near vehicle's big box has fuzzier edges (its bottom edge flips between
            the bumper and the tyres' contact by several px), and a frame larger than the
            detector's input has proportionally coarser boxes.
        vehicle_width_m: ``W_r`` of equation 4.
        vehicle_length_m: assumed length (m), used only for the near edge of a box cut by the border.
        contact_offset_m, ground_clearance_m: the contact-line correction (0, 0 = the paper).
        border_tol_px: a box edge this close to the image border (px) is the border's (None: never;
            ``"auto"``, the default: 4 px per 640 px of image width, i.e. 2 px of the detector's
            input, whose boxes are that coarse at any frame size: at 1920x1080, 12 px).
        max_coast_used: consecutive coasting frames after which a track is no longer output.
        side_cut_lateral_std_mps: the lateral-velocity uncertainty (m/s) reported at least, with
            ``ObjectState.v_x_std``, while the box is cut by a side border (the lateral reading is then
            the near-edge model's, biased as the vehicle leaves the view).
        side_band_frac: the same floor while the far edge of a box beside the centre line lies within
            this fraction of the frame width of its side border (0: only when cut). A vehicle leaving
            the view there has a far edge the tracker's box trails (7-14 px at 1920 px in the traces),
            which reads as the vehicle drifting in at 2-3 m/s. Default 0.03 (the sixth tuning round,
            docs/warning_tuning.md: 0.02-0.06 equal on the tuning set).
        forget_s: a track id unseen for this long (s) loses its history.
        edge_std_px: one-sigma (px) of the box's bottom-edge error that persists from frame to frame
            (a detector's and tracker's bias on a vehicle, which the filter, assuming white noise,
            cannot average away); added to ``d_y_std`` through ``d d_y / d row``.
        border_edge_std_px: the same for a box cut by a side border of the image (a partly seen
            vehicle, whose box bottom is far less reliable).
            Defaults 0.9 and 2.7 px: the shipped CenterNet + particle tracker's bottom-edge error
            (90th percentile of |error| / 1.645) over 2193 whole and 146 side-cut object-frames of
            highway_cruise (seeds 3, 4) and dense_traffic (seed 3), 10 s each at 640x360.
        contact_offset_std_m: one-sigma of the contact-line offset (m; rear overhangs of 0.8--1.1 m give
            0.09), added to ``d_y_std`` (not to the filter: it is a per-vehicle bias, not noise).
        horizon_std_px: one-sigma (px) of the calibrated horizon row when no horizon reading is given
            (the pitch the mount lets wander); added to ``d_y_std`` through ``d d_y / d row``.
        grade_std: one-sigma (rise/run) of the road's grade beyond the camera relative to the road
            under the ego (the flat-ground assumption's unknown); added to ``d_y_std`` through
            :meth:`grade_gain`. 0 (default): the ground is taken as exactly flat.
        reinit_sigmas: a measurement this many sigmas of its innovation away from the prediction
            (either axis) restarts the track's filter at the measurement with the wide prior, as a
            new sighting: a jump of that size is the tracker's box moving to another vehicle (or to
            part of one), not motion, and absorbed by the filter it reads as tens of m/s of closing
            speed that a warning would trust (``inf``: never).
        max_inward_offset_m: the most (m) a learnt near-edge offset may move a vehicle towards the
            centre line (:meth:`_inward_clipped`; None: no limit).
        expansion_process_std: process noise (1/s^2) of the per-track expansion-rate filter
            (:mod:`monorarp.state.expansion`), output as ``ObjectState.expansion_rate`` (None where its
            one-sigma exceeds that filter's prior, 1 /s: a rate only predicted since the box stopped
            giving a width), where the distance is unknown or ``expansion_accel_std`` is None.
        expansion_accel_std: relative acceleration one-sigma (m/s^2) that sets that filter's
            process noise from each track's distance (``accel_std / d_y``).
        expansion_pixel_std: one-sigma (px) of each side edge of a box in that filter.
        expansion_constant_speed: that filter predicts a constant closing speed (the rate's own
            growth) instead of a constant rate.
            Defaults 4.5 m/s^2, 1 px, True (the fourth tuning round's filter, default since the fifth:
            docs/warning_tuning.md); ``expansion_accel_std=None, expansion_pixel_std=0.5,
            expansion_constant_speed=False`` is the earlier constant-rate filter, whose sigma was 4x
            too wide at 60-100 m for the looming veto to act there.
        registration: register each vehicle's image patch between consecutive frames
            (:mod:`monorarp.state.scale_change`, given the frame's ``image``) for its scale change, output as
            ``ObjectState.registered_rate`` (1/s): the mean of its rates over the last
            ``registration_window_s`` (0.2 s: 3 frames at 15 fps) and its one-sigma, from
            ``registration_pixel_std`` (px of box width a frame; 0.2 measured on CCRb, CCRs and LVD runs,
            docs/warning_noise.md, Ninth round). The registration in use is the ``registration``
            attribute (None: off); a replay of cached tracks may put a recorded one in its place.
        fusion_sigmas: opt-in (None: off): the registered scale of each frame is also a measurement of the
            range filter (:meth:`_fuse_scale`: the distance ratio between frames, independent of the box's bottom
            edge, which the filter smooths and so lags a braking lead), skipped where it lies beyond this many
            sigmas of the filter's prediction (``motion="ca"`` only). 5 lifts the risk AUROC to 0.9505 but
            doubles the median velocity error and costs distance accuracy near the ego (the per-frame scale reads
            1-2 % slow), so it is off (the twelfth tuning round, docs/scale_fusion.md).
        fusion_pixel_std: the scale's one-sigma (px of box width) in that measurement (None:
            ``registration_pixel_std``).
        registration_top, registration_interpolation: the top fraction of each box left out of its patch
            (0.3), and how the current frame is sampled in the fit (``"linear"``, or ``"cubic"``):
            :func:`monorarp.state.scale_change.register_scale`. 0 and ``"cubic"`` scatter 25-35 % less against the
            true depth ratio, but moved no warning figure, so they are opt-in (docs/scale_fusion.md,
            thirteenth round).
        longitudinal_process_std: the range filter's process noise on the longitudinal axis (m/s^3 for
            ``"ca"``; None: ``process_std``). 9 with the fusion gave 1 false alarm an hour on the benchmark,
            and cost an LVD trial (docs/scale_fusion.md).
        fragment_cover, fragment_width_ratio, fragment_bottom_px: a track box lying over ``fragment_cover`` of
            its area inside another track's box at least ``fragment_width_ratio`` times as wide, their
            bottom edges within ``fragment_bottom_px`` (px at 640 px width; scaled with the image), gets
            no state: both stand on the same ground row, so at the same distance, where two vehicles
            cannot overlap in the image; it is a part of the wider one (a wide vehicle's front or
            rear half read as a car). ``fragment_cover`` None: no such rule.
    """

    uses_camera = True   # the registry passes the run's camera
    uses_image = True    # the pipeline passes each frame's image (``registration``)

    def __init__(self, camera: CameraModel | dict, velocity: str = "kalman", motion: str = "ca",
                 process_std: float = 4.5, pixel_std: float = 0.5, vehicle_width_m: float = 1.8,
                 contact_offset_m: float = 0.95, ground_clearance_m: float = 0.17, max_coast_used: int = 2,
                 init_vel_std: float = 10.0, init_acc_std: float = 5.0, forget_s: float = 1.0,
                 vehicle_length_m: float = 4.5, border_tol_px: float | str | None = "auto",
                 side_cut_lateral_std_mps: float = 2.0, reinit_sigmas: float = 5.0,
                 contact_offset_std_m: float = 0.09, horizon_std_px: float = 0.0, grade_std: float = 0.0,
                 edge_std_px: float = 0.9, border_edge_std_px: float = 2.7,
                 lateral_pixel_std: float | None = None, robust_sigmas: float | None = None,
                 bias_pixel_std: float | None = None, lateral_bias_pixel_std: float | None = None,
                 bias_tau_s: float = 1.0, offset_learn_margin_px: float | None = None,
                 max_inward_offset_m: float | None = 0.3, expansion_process_std: float = 1.0,
                 expansion_accel_std: float | None = 4.5, expansion_constant_speed: bool = True,
                 expansion_pixel_std: float = 1.0,
                 pixel_std_per_height: float = 0.01, max_unmeasured_s: float = 0.5,
                 min_vehicle_width_m: float = 1.4, near_border_frac: float = 0.05,
                 side_band_frac: float = 0.03, registration: bool = True, registration_pixel_std: float = 0.2,
                 registration_window_s: float = 0.2, fragment_cover: float | None = 0.9,
                 fragment_width_ratio: float = 1.5, fragment_bottom_px: float = 3.0,
                 fusion_sigmas: float | None = None, longitudinal_process_std: float | None = None,
                 fusion_pixel_std: float | None = None, registration_top: float = 0.3,
                 registration_interpolation: str = "linear", hidden_share: float | None = 0.5) -> None:
        if velocity not in ("kalman", "difference"):
            raise ValueError(f"velocity must be 'kalman' or 'difference', got {velocity!r}")
        if motion not in ("cv", "ca"):
            raise ValueError(f"motion must be 'cv' or 'ca', got {motion!r}")
        self.camera = camera if isinstance(camera, CameraModel) else CameraModel.from_dict(camera)
        self.velocity, self.motion = velocity, motion
        self.process_std, self.pixel_std = float(process_std), float(pixel_std)
        if longitudinal_process_std is not None and not (np.isfinite(longitudinal_process_std)
                                                         and longitudinal_process_std > 0):
            raise ValueError(f"longitudinal_process_std must be positive or None, got {longitudinal_process_std}")
        self.longitudinal_process_std = self.process_std if longitudinal_process_std is None \
            else float(longitudinal_process_std)
        self.vehicle_width_m = float(vehicle_width_m)
        self.vehicle_length_m = float(vehicle_length_m)
        self.contact_offset_m = float(contact_offset_m)
        self.ground_clearance_m = float(ground_clearance_m)
        if border_tol_px == "auto":
            border_tol_px = BORDER_TOL_PX * self.camera.width / 640.0
        self.border_tol_px = None if border_tol_px is None else float(border_tol_px)
        self.max_coast_used = int(max_coast_used)
        self.side_cut_lateral_std_mps = float(side_cut_lateral_std_mps)
        if offset_learn_margin_px is not None and not (np.isfinite(offset_learn_margin_px) and offset_learn_margin_px >= 0):
            raise ValueError(f"offset_learn_margin_px must be >= 0 or None, got {offset_learn_margin_px}")
        self.offset_learn_margin_px = offset_learn_margin_px
        if max_inward_offset_m is not None and not (np.isfinite(max_inward_offset_m) and max_inward_offset_m >= 0):
            raise ValueError(f"max_inward_offset_m must be >= 0 or None, got {max_inward_offset_m}")
        self.max_inward_offset_m = None if max_inward_offset_m is None else float(max_inward_offset_m)
        self._expansion = ExpansionFilter(pixel_std=expansion_pixel_std, process_std=expansion_process_std,
                                          accel_std=expansion_accel_std,
                                          constant_speed=expansion_constant_speed)
        for name, val in (("registration_pixel_std", registration_pixel_std), ("registration_window_s", registration_window_s)):
            if not (np.isfinite(val) and val > 0):
                raise ValueError(f"{name} must be positive, got {val}")
        try:
            self.registration = LoomingRegistration(pixel_std=registration_pixel_std, top=registration_top,
                                                    interpolation=registration_interpolation) if registration else None
        except ValueError as e:    # its settings are registration_* here
            raise ValueError(f"registration_{e}") from None
        if fusion_sigmas is not None and not (np.isfinite(fusion_sigmas) and fusion_sigmas > 0):
            raise ValueError(f"fusion_sigmas must be positive or None, got {fusion_sigmas}")
        self.fusion_sigmas = None if fusion_sigmas is None else float(fusion_sigmas)
        if fusion_pixel_std is not None and not (np.isfinite(fusion_pixel_std) and fusion_pixel_std > 0):
            raise ValueError(f"fusion_pixel_std must be positive or None, got {fusion_pixel_std}")
        self._fusion_inflation = 1.0 if fusion_pixel_std is None else float(fusion_pixel_std) / float(registration_pixel_std)
        self._rate_window = RateWindow(window_s=registration_window_s)
        self._lateral_window = RateWindow(window_s=registration_window_s, baseline=0.0)
        if fragment_cover is not None and not (np.isfinite(fragment_cover) and 0 < fragment_cover <= 1):
            raise ValueError(f"fragment_cover must be in (0, 1] or None, got {fragment_cover}")
        for name, val in (("fragment_width_ratio", fragment_width_ratio), ("fragment_bottom_px", fragment_bottom_px)):
            if not (np.isfinite(val) and val >= 0):
                raise ValueError(f"{name} must be finite and >= 0, got {val}")
        self.fragment_cover = None if fragment_cover is None else float(fragment_cover)
        self.fragment_width_ratio = float(fragment_width_ratio)
        self.fragment_bottom_px = float(fragment_bottom_px) * self.camera.width / 640.0
        if not reinit_sigmas > 0:
            raise ValueError(f"reinit_sigmas must be > 0, got {reinit_sigmas}")
        if robust_sigmas is not None and not robust_sigmas > 0:
            raise ValueError(f"robust_sigmas must be > 0 or None, got {robust_sigmas}")
        if not bias_tau_s > 0:
            raise ValueError(f"bias_tau_s must be > 0, got {bias_tau_s}")
        self.lateral_pixel_std = self.pixel_std if lateral_pixel_std is None else float(lateral_pixel_std)
        if not (np.isfinite(pixel_std_per_height) and pixel_std_per_height >= 0):
            raise ValueError(f"pixel_std_per_height must be >= 0, got {pixel_std_per_height}")
        self.pixel_std_per_height = float(pixel_std_per_height)
        if not (max_unmeasured_s >= 0):
            raise ValueError(f"max_unmeasured_s must be >= 0, got {max_unmeasured_s}")
        self.max_unmeasured_s = float(max_unmeasured_s)
        for name, val in (("min_vehicle_width_m", min_vehicle_width_m), ("near_border_frac", near_border_frac)):
            if not (np.isfinite(val) and val >= 0):
                raise ValueError(f"{name} must be finite and >= 0, got {val}")
        self.min_vehicle_width_m, self.near_border_frac = float(min_vehicle_width_m), float(near_border_frac)
        if hidden_share is not None and not (np.isfinite(hidden_share) and 0 <= hidden_share < 1):
            raise ValueError(f"hidden_share must be in [0, 1) or None, got {hidden_share}")
        self.hidden_share = None if hidden_share is None else float(hidden_share)
        if not (np.isfinite(side_band_frac) and 0 <= side_band_frac < 0.5):
            raise ValueError(f"side_band_frac must be in [0, 0.5), got {side_band_frac}")
        self.side_band_frac = float(side_band_frac)
        self.robust_sigmas = None if robust_sigmas is None else float(robust_sigmas)
        self.bias_tau_s = float(bias_tau_s)
        if bias_pixel_std is None:
            self._bias_var = None
        else:
            lat = bias_pixel_std if lateral_bias_pixel_std is None else lateral_bias_pixel_std
            self._bias_var = np.array([float(lat), float(bias_pixel_std)]) ** 2   # (x, y) axes, px^2
        self.reinit_sigmas = float(reinit_sigmas)
        for name, val in (("contact_offset_std_m", contact_offset_std_m), ("horizon_std_px", horizon_std_px),
                          ("edge_std_px", edge_std_px), ("border_edge_std_px", border_edge_std_px),
                          ("grade_std", grade_std)):
            if not (np.isfinite(val) and val >= 0):
                raise ValueError(f"{name} must be finite and >= 0, got {val}")
        self.contact_offset_std_m, self.horizon_std_px = float(contact_offset_std_m), float(horizon_std_px)
        self.edge_std_px, self.border_edge_std_px = float(edge_std_px), float(border_edge_std_px)
        self.grade_std = float(grade_std)
        self._extra_px_var = 0.0      # this frame's white horizon noise (px^2), added to the measurement's
        self._profile = None          # this frame's measured road profile (a GroundReading's), None: flat ground
        self._ground_std: np.ndarray | None = None   # per box, the profile's one-sigma added to d_y_std (m)
        n = 2 if motion == "cv" else 3
        self._prior_var = np.array([0.0, init_vel_std ** 2, init_acc_std ** 2][:n])
        self.forget_s = float(forget_s)
        self.reset()

    def reset(self) -> None:
        """Forget every track's history."""
        # per track id: (x, P) of the (x, y) axes [kalman] or the last (d_x, d_y) [difference],
        # the frame time of the last update, and the consecutive coasting count.
        self._state: dict[int, tuple[np.ndarray, np.ndarray] | np.ndarray] = {}
        self._t: dict[int, float] = {}
        self._coast: dict[int, int] = {}
        self._near_offset: dict[int, float] = {}   # per track: far-edge minus near-edge lateral reading (m)
        self._born: dict[int, float] = {}          # per track: frame time its filter (re)started (s)
        self._measured: dict[int, float] = {}      # per track: frame time of its last distance reading (s)
        self._expansion.reset()
        self._rate_window.reset()
        self._lateral_window.reset()
        if self.registration is not None:
            self.registration.reset()

    def measure(self, boxes: np.ndarray) -> np.ndarray:
        """(M, 4) boxes -> (M, 2) ``(d_x, d_y)`` (m) with this estimator's geometry parameters."""
        return measure_boxes(self.camera, boxes, self.vehicle_width_m, self.contact_offset_m,
                             self.ground_clearance_m, self.vehicle_length_m, self.border_tol_px)

    def _terms(self, ids: list[int], boxes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Measured ``d_y`` (M,) and the lateral terms (M, 3) of :func:`lateral_terms`, per-track calibrated.

        While a box beside the centre line is whole, the offset between its far-edge and near-edge
        lateral readings (from the vehicle's true length and width differing from the assumed ones)
        is learnt per track (running mean); once the far edge is cut, the near-edge reading is
        shifted by it, so switching edges makes no jump (which would read as lateral velocity).
        The offset is learnt only from boxes whose sides both lie ``offset_learn_margin_px`` or more
        inside the image (None, the default: ``border_tol_px``). A margin (e.g. 16 px) keeps a detector box
        that stops short of the border while its vehicle enters the view from the side from teaching a
        wrong offset, but also keeps a whole vehicle near the border from teaching the right one
        (tests/test_state.py: a 1.6 m/s lateral-velocity jump), so it is opt-in.
        """
        ground = None
        if self._profile is not None:
            ground, self._ground_std = contact_ground(self.camera, self._profile, boxes[:, 3], self.edge_std_px,
                                                      boxes=boxes, width_m=self.vehicle_width_m,
                                                      length_m=self.vehicle_length_m,
                                                      contact_offset_m=self.contact_offset_m)
        d_y = box_distance(self.camera, boxes, self.contact_offset_m, self.ground_clearance_m, self.border_tol_px,
                           ground)
        terms = lateral_terms(self.camera, boxes, self.vehicle_width_m, self.vehicle_length_m,
                              self.ground_clearance_m, self.border_tol_px)
        near = near_edge_terms(self.camera, boxes, self.vehicle_width_m, self.vehicle_length_m,
                               self.ground_clearance_m)
        flags = border_flags(self.camera, boxes, self.border_tol_px)
        whole = ~flags[:, 0] & ~flags[:, 1] & np.isfinite(near[:, 0]) & np.isfinite(d_y)
        if self.offset_learn_margin_px is not None:
            whole &= ~border_flags(self.camera, boxes, self.offset_learn_margin_px)[:, :2].any(axis=1)
        right, left = boxes[:, 0] > self.camera.cx, boxes[:, 2] < self.camera.cx
        uses_near = (right & flags[:, 1]) | (left & flags[:, 0])
        offset = lateral_from_terms(terms, d_y) - lateral_from_terms(near, d_y)
        for j, i in enumerate(ids):
            if whole[j]:
                old = self._near_offset.get(i)
                self._near_offset[i] = offset[j] if old is None else old + 0.3 * (offset[j] - old)
            elif uses_near[j] and i in self._near_offset:
                terms[j, 2] += self._inward_clipped(self._near_offset[i], right[j])
        gone = contact_line_cut(self.camera, boxes, lateral_from_terms(terms, d_y), d_y, self.vehicle_width_m,
                                self.contact_offset_m, self.border_tol_px)
        return np.where(gone, np.nan, d_y), terms

    def _inward_clipped(self, offset: float, right: bool) -> float:
        """The learnt near-edge offset (m), moving the vehicle towards the centre line by at most
        ``max_inward_offset_m``.

        The near-edge model (assumed length 4.5 m, width 1.8 m) reads a longer or wider vehicle too
        far in, which the offset corrects outwards (a truck: 1 m or more); only a vehicle shorter
        and narrower than any car could need more than ~0.3 m inwards. A larger inward offset was
        learnt from a detector box that stopped short of the border while its vehicle was still
        partly out of view: applied, it put a car in the next lane 2-3 m inside the ego's corridor.
        """
        if self.max_inward_offset_m is None:
            return offset
        return max(offset, -self.max_inward_offset_m) if right else min(offset, self.max_inward_offset_m)

    @property
    def near_limit_m(self) -> float:
        """Distance (m) to a rear face whose contact line lies on the lowest row not taken as the border's.

        A box whose bottom edge is within ``border_tol_px`` of the bottom border is cut: its vehicle
        is nearer than this.
        """
        row = self.camera.height - 0.5 - (self.border_tol_px or 0.0)
        box = np.array([[self.camera.cx - 1.0, row - 1.0, self.camera.cx + 1.0, row]])
        d = box_distance(self.camera, box, self.contact_offset_m, self.ground_clearance_m, None)[0]
        return max(float(d), 0.0)

    def measurement_var(self, z: np.ndarray, box_h: np.ndarray | None = None) -> np.ndarray:
        """(M, 2) variances (m^2) of measured (d_x, d_y): the box edges' pixel noise through equations 3 and 4.

        The pixel noise is ``pixel_std`` and ``pixel_std_per_height`` times the box height
        ``box_h`` (px) in quadrature. ``d d_y / d v = d_y^2 / (h_c F)`` (so the error grows as
        d^2); the lateral error adds the far edge's column error and the share of the distance error.
        """
        d_x, d_y = z[:, 0], np.maximum(z[:, 1], 0.1)
        rel = 0.0 if box_h is None else (self.pixel_std_per_height * np.nan_to_num(box_h, nan=0.0)) ** 2
        px = np.sqrt(self.pixel_std ** 2 + self._extra_px_var + rel)
        lat_px = np.sqrt(self.lateral_pixel_std ** 2 + self._extra_px_var + rel)
        s_y = d_y ** 2 / (self.camera.height_m * self.camera.fy) * px + 0.01
        s_x = d_y / self.camera.fx * lat_px + np.abs(d_x) / d_y * s_y + 0.01
        return np.stack([s_x, s_y], axis=1) ** 2

    def plausible_boxes(self, boxes: np.ndarray) -> np.ndarray:
        """(M, 4) boxes (px) with every row that has a coordinate beyond 10 image sizes set to NaN.

        Such a box is no measurement (a broken detector or tracker): taken at face value, its
        distance (~1e300 m) overflows the filter's covariance. NaN rows are predicted / held.
        """
        limit = 10.0 * max(self.camera.width, self.camera.height)
        bad = ~(np.abs(boxes) <= limit).all(axis=1)
        return np.where(bad[:, None], np.nan, boxes)

    def border_cut_boxes(self, boxes: np.ndarray) -> np.ndarray:
        """(M, 4) boxes (px) with a far edge that stops short of the side border extended to it
        where the box is too narrow to be a whole vehicle.

        Beside the centre line, within ``near_border_frac`` of the frame width from the border on
        its far side, a box narrower than ``min_vehicle_width_m`` at its distance (equation 3)
        cannot hold a whole vehicle: the vehicle runs out of view and the detector's box stops a
        few detector pixels short of the border (at 1920x1080, 20-30 px). Taken at face value its
        far edge puts a next-lane car 2 m inside the ego's lane.
        """
        if self.border_tol_px is None or self.min_vehicle_width_m <= 0 or len(boxes) == 0:
            return boxes
        b = boxes.copy()
        with np.errstate(invalid="ignore"):
            d_y = box_distance(self.camera, b, self.contact_offset_m, self.ground_clearance_m, self.border_tol_px)
            narrow = too_narrow(self.camera, b, d_y, self.min_vehicle_width_m)
            near = self.near_border_frac * self.camera.width
            right = (b[:, 0] > self.camera.cx) & (b[:, 2] >= self.camera.width - 0.5 - near) & narrow
            left = (b[:, 2] < self.camera.cx) & (b[:, 0] <= -0.5 + near) & narrow
        b[right, 2] = np.maximum(b[right, 2], self.camera.width - 0.5)
        b[left, 0] = np.minimum(b[left, 0], -0.5)
        return b

    def horizon_gain(self, d_y: np.ndarray) -> np.ndarray:
        """``|d d_y / d row|`` (m/px): distance change per pixel of horizon-row error.

        The contact line's ground distance ``Y = d_y + contact_offset_m`` seen at depression
        angle ``a`` below the horizon (``Y = h_c cot a``) changes by ``(Y^2 + h_c^2) / h_c`` per
        radian, and one row is ``1 / fy`` rad near the principal point.
        """
        Y = np.asarray(d_y, dtype=float) + self.contact_offset_m
        h = self.camera.height_m
        return (Y * Y + h * h) / (h * self.camera.fy)

    def grade_gain(self, d_y: np.ndarray) -> np.ndarray:
        """``|d d_y / d grade|`` (m per unit rise/run): distance change per unit of road grade.

        A ground that rises with grade ``g`` from the camera's foot point (``z = g y``) meets the ray
        of depression angle ``a`` at ``Y = h_c / (tan a + g)``; the flat reading is ``h_c / tan a``,
        so ``dY/dg = -Y^2 / h_c`` at ``g = 0`` (``Y = d_y + contact_offset_m``, the contact line).
        """
        Y = np.asarray(d_y, dtype=float) + self.contact_offset_m
        return Y * Y / self.camera.height_m

    def distance_std(self, d_y: np.ndarray, filter_std: np.ndarray, horizon_std_px: float,
                     side_cut: np.ndarray | None = None) -> np.ndarray:
        """One-sigma of ``d_y`` (m): the filter's; the horizon row's (``horizon_std_px``) and the box
        bottom edge's persistent error (``edge_std_px``, ``border_edge_std_px`` where ``side_cut``),
        both through :meth:`horizon_gain` (the distance reads their difference); the contact
        line's; the road grade's (``grade_std``, through :meth:`grade_gain`). In quadrature."""
        edge = np.where(side_cut, self.border_edge_std_px, self.edge_std_px) if side_cut is not None \
            else self.edge_std_px
        px = np.hypot(horizon_std_px, edge)
        var = filter_std ** 2 + (self.horizon_gain(d_y) * px) ** 2 + self.contact_offset_std_m ** 2
        if self.grade_std > 0:
            var = var + (self.grade_gain(d_y) * self.grade_std) ** 2
        return np.sqrt(var)

    def update(self, tracks: Sequence[Track], t: float, horizon: HorizonReading | None = None,
               image: np.ndarray | None = None) -> dict[int, ObjectState]:
        """Estimate every usable track's relative state at frame time ``t`` (s); ValueError on a non-finite ``t``.

        ``horizon``: this frame's horizon reading (:mod:`monorarp.horizon.stages`): equation 3 then uses a
        camera pitched to its row (the calibrated one when that row is impossible), the reading's
        ``std_px`` widens ``d_y_std``, and a reading measured this frame (``"vanishing_point"``, white
        noise) also widens the filter's measurement noise; a reading with a measured road profile
        (:class:`monorarp.horizon.ground_profile.GroundReading`) gives the bottom rows' ground distances and their
        uncertainty (:func:`monorarp.horizon.ground_profile.contact_ground`). None: the calibrated horizon with
        ``horizon_std_px``. ``image`` (H x W x 3 RGB or H x W grey): the frame, for ``registration``
        (None: no ``registered_rate``).
        """
        if horizon is None:
            return self._update(tracks, t, self.horizon_std_px, image)
        nominal = self.camera
        try:
            try:
                self.camera = replace(nominal, pitch_rad=math.atan((nominal.cy - float(horizon.row)) / nominal.fy))
            except (CameraError, ValueError):
                self.camera = nominal
            if horizon.source == "vanishing_point":
                self._extra_px_var = float(horizon.std_px) ** 2
            self._profile = getattr(horizon, "profile", None)
            return self._update(tracks, t, float(horizon.std_px), image)
        finally:
            self.camera, self._extra_px_var, self._profile, self._ground_std = nominal, 0.0, None, None

    def _update(self, tracks: Sequence[Track], t: float, horizon_std_px: float,
                image: np.ndarray | None = None) -> dict[int, ObjectState]:
        t = float(t)
        if not np.isfinite(t):
            raise ValueError(f"frame time must be finite, got {t}")
        for tid in [k for k, tk in self._t.items() if t - tk > self.forget_s]:
            self._state.pop(tid), self._t.pop(tid), self._near_offset.pop(tid, None), self._born.pop(tid, None)
            self._measured.pop(tid, None)
        self._coast = {tr.id: self._coast.get(tr.id, 0) + 1 if tr.coasting else 0 for tr in tracks}
        usable = [tr for tr in tracks if self._coast[tr.id] <= self.max_coast_used]
        if usable and self.fragment_cover is not None:
            part = fragments(np.array([tr.box for tr in usable], dtype=float), self.fragment_cover,
                             self.fragment_width_ratio, self.fragment_bottom_px)
            usable = [tr for tr, p in zip(usable, part) if not p]
        if not usable:
            return {}
        ids = [tr.id for tr in usable]
        boxes = self.border_cut_boxes(self.plausible_boxes(np.array([tr.box for tr in usable], dtype=float)))
        d_y, terms = self._terms(ids, boxes)
        coasting = np.array([tr.coasting for tr in usable])
        known = np.array([i in self._state for i in ids])
        # A new track needs both coordinates from its box; a known one is output in any case
        # (the missing coordinates are predicted / held).
        new_ok = np.isfinite(d_y) & np.isfinite(lateral_from_terms(terms, d_y))
        ok = known | new_ok
        if self.velocity == "kalman":
            flags = border_flags(self.camera, boxes, self.border_tol_px)
            cut_bottom, side_cut = flags[:, 2], flags[:, :2].any(axis=1)
            scale = scale_std = None
            if self.registration is not None and image is not None:
                # a box cut by the image's bottom (a vehicle at contact) holds only part of its patch
                scale, scale_std, centre, shift = self.registration.update(image, ids, boxes,
                                                                           ~coasting & ~side_cut & ~cut_bottom)
            fused = (scale, scale_std) if self.fusion_sigmas is not None and scale is not None else None
            out, std, acc = self._kalman(ids, d_y, terms, coasting, known, ok, t, cut_bottom, boxes[:, 3] - boxes[:, 1],
                                         fused)
            restart = np.array([self._born.get(i) == t for i in ids])
            rate, rate_std = self._expansion.update(ids, boxes, ~coasting & ~side_cut, t, restart, out[:, 1])
            # A rate known no better than the filter's prior is none: one only predicted since the box
            # stopped giving a width (cut by a side border, coasting) grows without bound at a constant
            # closing speed (to 1e25 /s within 5 s of a car beside the ego).
            known_rate = rate_std <= self._expansion.init_rate_std
            rate, rate_std = np.where(known_rate, rate, np.nan), np.where(known_rate, rate_std, np.nan)
            reg = reg_std = lat = lat_std = np.full(len(ids), np.nan)
            if scale is not None:
                reg, reg_std = self._rate_window.update(ids, scale, scale_std, t)
                depth = out[:, 1] * scale                   # the earlier frame's distance
                d_x = lateral_displacement(centre, shift, scale, depth, self.camera.fx, self.camera.cx)
                # the shift known to registration_pixel_std px of the registered (reduced) frame
                d_x_std = depth / self.camera.fx * self.registration.pixel_std * self.registration.reduction(image.shape[1])
                lat, lat_std = self._lateral_window.update(ids, d_x, d_x_std, t)
            # A box cut by a side border gives its lateral position from the near-edge model (an
            # assumed length): biased, not noisy, which the filter's covariance cannot know. Say so. So
            # does a box that shows a part of a vehicle only: too narrow for a whole one at its distance (a
            # dark car against a dark truck, read 0.9 m wide at 8.6 m), or mostly behind a nearer vehicle's box.
            biased = side_cut | too_narrow(self.camera, boxes, out[:, 1], self.min_vehicle_width_m)
            if self.hidden_share is not None:
                biased |= occluded(boxes, self.hidden_share)
            if self.side_band_frac > 0:
                band = border_flags(self.camera, boxes, self.side_band_frac * self.camera.width)
                biased |= (band[:, 1] & (boxes[:, 0] > self.camera.cx)) | (band[:, 0] & (boxes[:, 2] < self.camera.cx))
            std[biased, 2] = np.maximum(std[biased, 2], self.side_cut_lateral_std_mps)
            std[:, 1] = self.distance_std(out[:, 1], std[:, 1], horizon_std_px, side_cut)
            if self._ground_std is not None:
                std[:, 1] = np.hypot(std[:, 1], self._ground_std)
            # A distance only predicted for longer than max_unmeasured_s (the box gives none: its
            # contact line is out of view at a side border) is no estimate any more: constant
            # velocity carries it through the ego. A box cut by the bottom border stays (clamped).
            for i, has in zip(ids, np.isfinite(d_y) & ~coasting):
                if has:
                    self._measured[i] = t
            stale = np.array([t - self._measured.get(i, t) > self.max_unmeasured_s + 1e-9 for i in ids])
            ok = ok & ~(stale & ~cut_bottom)
            return {tid: ObjectState(tid, *map(float, row), *map(float, sd), *(None, None) if ac is None else map(float, ac),
                                     age_s=float(t - self._born[tid]), expansion_rate=_finite_or_none(er),
                                     expansion_rate_std=_finite_or_none(er_std), registered_rate=_finite_or_none(rr),
                                     registered_rate_std=_finite_or_none(rr_std), registered_v_x=_finite_or_none(lv),
                                     registered_v_x_std=_finite_or_none(lv_std))
                    for tid, row, sd, ac, good, er, er_std, rr, rr_std, lv, lv_std
                    in zip(ids, out, std, acc if acc is not None else [None] * len(ids), ok, rate, rate_std, reg, reg_std,
                           lat, lat_std)
                    if good}
        out = self._difference(ids, d_y, terms, known, ok, t)
        return {tid: ObjectState(tid, *map(float, row)) for tid, row, good in zip(ids, out, ok) if good}

    def _difference(self, ids, d_y, terms, known, ok, t) -> np.ndarray:
        """The paper: v = (d_k - d_{k-1}) / (t_k - t_{k-1}); 0 at initialisation.

        A coordinate the box does not give is held at its last value (velocity 0 on that axis).
        """
        prev = np.array([self._state[i] if k else (np.nan, np.nan) for i, k in zip(ids, known)]).reshape(-1, 2)
        y = np.where(np.isfinite(d_y), d_y, prev[:, 1])
        x = lateral_from_terms(terms, y)
        x = np.where(np.isfinite(x), x, prev[:, 0])
        z = np.stack([x, y], axis=1)
        dt = np.array([t - self._t[i] if k else 0.0 for i, k in zip(ids, known)])
        with np.errstate(divide="ignore", invalid="ignore"):
            v = np.where((dt > 0)[:, None] & known[:, None], (z - prev) / dt[:, None], 0.0)
        for i, zi, good in zip(ids, z, ok):
            if good:
                self._state[i], self._t[i] = zi, t
        return np.concatenate([z, v], axis=1)

    def _kalman(self, ids, d_y, terms, coasting, known, ok, t, cut_bottom=None, box_h=None,
                scale: tuple[np.ndarray, np.ndarray] | None = None) -> np.ndarray:
        """Kalman filter per track and axis, vectorised over both (arrays of shape (M, 2, n)).

        Returns the (M, 4) states ``(d_x, d_y, v_x, v_y)``, their (M, 4) one-sigma
        uncertainties from the filter's covariance (m, m/s), and with the ``"ca"`` model the
        (M, 2) longitudinal acceleration and its one-sigma uncertainty (m/s^2; else None).

        With ``bias_pixel_std`` the state of each axis ends with the box edge's slowly varying
        error ``b`` (px), a first-order Gauss-Markov process (time constant ``bias_tau_s``); the
        measurement is ``z = p + J b + w`` with ``J`` the metres per pixel of that edge
        (``d_y / F`` for a column, ``d_y^2 / (h_c F)`` for the bottom row) and ``w`` the white part
        (``pixel_std``). An edge drifting for a fraction of a second then reads as either motion or
        bias, and the velocity's covariance says so.

        A box cut by the image's bottom border gives no distance, but bounds it: the vehicle's
        rear is nearer than the ground seen at the bottom row (:meth:`near_limit_m`) and not
        behind the camera. The predicted distance is clamped into ``[0, near_limit]`` there
        (velocity and acceleration along y zeroed at 0), so a vehicle that stays that close
        (e.g. after a crash) is not extrapolated through the ego.

        ``scale``: this frame's registered ``(scale, scale_std)`` per track, fused after the boxes
        (:meth:`_fuse_scale`); None: not fused.
        """
        m, n = len(ids), len(self._prior_var)
        nb = 0 if self._bias_var is None else 1
        N = n + nb
        x, P = np.zeros((m, 2, N)), np.zeros((m, 2, N, N))
        for j, (i, k) in enumerate(zip(ids, known)):
            if k:
                x[j], P[j] = self._state[i]
        dt = np.array([t - self._t[i] if k else 0.0 for i, k in zip(ids, known)])
        Fm, Qm = motion_model(self.motion, np.repeat(dt[:, None], 2, axis=1), 1.0)
        Qm = Qm * (np.array([self.process_std, self.longitudinal_process_std]) ** 2)[None, :, None, None]
        F, Q = np.zeros((m, 2, N, N)), np.zeros((m, 2, N, N))
        F[..., :n, :n], Q[..., :n, :n] = Fm, Qm
        if nb:
            phi = np.exp(-dt / self.bias_tau_s)[:, None]
            F[..., n, n] = phi
            Q[..., n, n] = self._bias_var * (1.0 - phi ** 2)
        x, P = kf_predict(x, P, F, Q)
        # Measurements; the lateral one uses the predicted distance where the box gives none.
        y_ref = np.where(np.isfinite(d_y), d_y, x[:, 1, 0])
        z = np.stack([lateral_from_terms(terms, y_ref), d_y], axis=1)
        has = np.isfinite(z)
        zf = np.where(has, z, x[:, :, 0])
        r = self.measurement_var(np.nan_to_num(zf, nan=1.0), box_h)
        h = np.zeros((m, 2, N))
        h[..., 0] = 1.0
        if nb:
            d = np.maximum(np.nan_to_num(zf[:, 1], nan=1.0), 0.1)
            h[..., n] = np.stack([d / self.camera.fx, d * d / (self.camera.height_m * self.camera.fy)], axis=1)
        hx = np.einsum("...i,...i->...", h, x)
        S = np.einsum("...i,...ij,...j->...", h, P, h) + r
        # A jump far beyond the innovation's spread: another vehicle's box, restart (class docstring).
        nis = np.where(has, (zf - hx) ** 2 / S, 0.0)
        fresh = ~known | (known & ~coasting & (nis > self.reinit_sigmas ** 2).any(axis=1))
        for j in np.flatnonzero(fresh & ok):
            self._born[ids[j]] = t
            # first sighting: at the measurement, at rest (the paper's v = 0), wide prior; p = z - J b
            x[j] = 0.0
            x[j, :, 0] = zf[j]
            P[j] = np.diag(np.r_[self._prior_var, [0.0] * nb])[None] + 0.0
            P[j, :, 0, 0] = r[j]
            if nb:
                P[j, :, n, n] = self._bias_var
                P[j, :, 0, 0] += h[j, :, n] ** 2 * self._bias_var
                P[j, :, 0, n] = P[j, :, n, 0] = -h[j, :, n] * self._bias_var
        if self.robust_sigmas is not None:
            # Huber: an innovation beyond robust_sigmas counts as if its spread were that large
            c2 = self.robust_sigmas ** 2
            r = np.where(~fresh[:, None] & (nis > c2), r + S * (nis / c2 - 1.0), r)
        upd = (~fresh & ~coasting)[:, None] & has
        xu, Pu = kf_update(x, P, np.nan_to_num(zf), r, h)
        x, P = np.where(upd[..., None], xu, x), np.where(upd[..., None, None], Pu, P)
        if scale is not None and n == 3 and not nb:
            x, P = self._fuse_scale(x, P, scale[0], scale[1], dt, ~fresh & ~coasting & known)
        if cut_bottom is not None:
            blind = cut_bottom & known & ~np.isfinite(d_y)
            x[blind, 1, 0] = np.minimum(x[blind, 1, 0], self.near_limit_m)
            behind = blind & (x[:, 1, 0] < 0.0)
            x[behind, 1, 0] = 0.0
            x[behind, 1, 1:n] = 0.0
        for j, i in enumerate(ids):
            if ok[j]:
                self._state[i], self._t[i] = (x[j], P[j]), t
        std = np.sqrt(np.maximum(np.concatenate([P[:, :, 0, 0], P[:, :, 1, 1]], axis=1), 0.0))
        acc = None if n < 3 else np.stack([x[:, 1, 2], np.sqrt(np.maximum(P[:, 1, 2, 2], 0.0))], axis=1)
        return np.concatenate([x[:, :, 0], x[:, :, 1]], axis=1), std, acc

    def _fuse_scale(self, x: np.ndarray, P: np.ndarray, scale: np.ndarray, scale_std: np.ndarray, dt: np.ndarray,
                    usable: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The longitudinal filters (``x[:, 1]``, state ``(d, v, a)``) updated with each vehicle's registered
        scale ``s = d_prev / d`` since the previous frame (:mod:`monorarp.state.scale_change`), one-sigma ``scale_std``.

        Over the frame interval ``dt`` the distance changed by ``d_prev - d = -(v dt - a dt^2 / 2)``, so
        ``0 = (s - 1) d + v dt - a dt^2 / 2 + e d`` with ``e`` the scale's error: a linear measurement
        ``h = (s - 1, dt, -dt^2 / 2)`` of value 0 and variance ``(d scale_std)^2``. It is skipped where its
        innovation exceeds ``fusion_sigmas`` of its spread (a patch that holds another vehicle, or a car
        whose yaw changes its image).
        """
        good = usable & np.isfinite(scale) & np.isfinite(scale_std) & (dt > 0)
        if not good.any():
            return x, P
        xy, Py = x[:, 1], P[:, 1]
        h = np.stack([np.nan_to_num(scale - 1.0), dt, -dt * dt / 2.0], axis=1)
        r = (np.maximum(xy[:, 0], 0.1) * np.nan_to_num(scale_std, nan=1.0) * self._fusion_inflation) ** 2
        innov = -np.einsum("mi,mi->m", h, xy)
        S = np.einsum("mi,mij,mj->m", h, Py, h) + r
        good &= innov ** 2 <= self.fusion_sigmas ** 2 * S
        xu, Pu = kf_update(xy, Py, np.zeros(len(xy)), r, h)
        x, P = x.copy(), P.copy()
        x[good, 1], P[good, 1] = xu[good], Pu[good]
        return x, P


def _finite_or_none(v: float) -> float | None:
    return float(v) if np.isfinite(v) else None
