"""State estimator (section IV-C): relative distance and velocity of tracked vehicles.

Tracks -> ``{track id: ObjectState}``: ``d_x`` lateral offset of the vehicle's centre (m, + right),
``d_y`` longitudinal distance to its rear face (m, + ahead), ``v_x``/``v_y`` relative velocity (m/s)
in the ego frame (:mod:`monorarp.core.camera`). :class:`StateEstimator` composes the box measurements
(:mod:`monorarp.state.measurement`, on the geometry of :mod:`monorarp.state.geometry` and, given a road
profile, :mod:`monorarp.state.ground_contact`), the noise models (:mod:`monorarp.state.noise`), the
per-track velocity filters over frame timestamps (s; :mod:`monorarp.state.filters`) and the looming
cues (:mod:`monorarp.state.expansion`, :mod:`monorarp.state.scale_change`); its settings are a
:class:`~monorarp.state.config.StateConfig`. The design and its measured figures: docs/state_estimation.md.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import replace
from typing import Any

import numpy as np

from monorarp.core.camera import CameraError, CameraModel
from monorarp.core.types import HorizonReading, ObjectState, Track
from monorarp.state.config import StateConfig, state_config
from monorarp.state.expansion import ExpansionFilter
from monorarp.state.filters import DifferenceTracks, KalmanTracks
from monorarp.state.geometry import border_flags, fragments, lateral_from_terms, measure_boxes, occluded, too_narrow
from monorarp.state.ground_contact import contact_ground
from monorarp.state.kind import TrackKinds
from monorarp.state.measurement import (NearEdgeOffsets, border_cut_boxes, border_tolerance, distance_std, grade_gain,
                                        horizon_gain, near_limit_m, plausible_boxes)
from monorarp.state.pinhole_view import pinhole_view
from monorarp.state.noise import MeasurementNoise, ProcessNoise, bias_variance, prior_variance
from monorarp.state.scale_change import LoomingRegistration, RateWindow, lateral_displacement
from monorarp.state.size_prior import SIZE_PRIORS, fuse, ground_fit, height_distance, priors_of, width_distance


class StateEstimator:
    """Tracks -> ``{track id: ObjectState}`` from box geometry and frame timestamps.

    ``StateEstimator(camera, config=None, **overrides)``: ``camera`` the calibrated :class:`CameraModel`
    (or its dict form); ``config`` a :class:`~monorarp.state.config.StateConfig` (None: the defaults),
    with ``overrides`` (its field names, e.g. ``velocity="difference"``) validated in; a bad one raises
    :class:`~monorarp.state.config.StateConfigError`, one line naming it. ``config`` is the result.

    Per frame: boxes beyond 10 image sizes are no measurement, a track coasting for more than
    ``max_coast_used`` frames or a fragment of another track's vehicle gets no state, and a box too narrow
    for a whole vehicle beside a side border is taken as cut by it; the boxes give ``d_y`` and the lateral
    terms (per-track near-edge offsets, the road profile's ground where given), the filters the states.
    With ``velocity="kalman"``: a distance only predicted for longer than ``max_unmeasured_s`` (its
    contact line out of view at a side border) is no longer output, one cut by the bottom border is
    (clamped, :meth:`monorarp.state.filters.KalmanTracks.update`); the reported ``d_y_std`` adds the errors
    the filter cannot see (:meth:`distance_std`), ``v_x_std`` is at least ``side_cut_lateral_std_mps``
    where the lateral reading is biased (a side-cut box, a part of a vehicle, a far edge in the side band);
    ``expansion_rate`` comes from the box width's filter (None where known no better than its prior) and
    ``registered_rate`` / ``registered_v_x`` from registering each vehicle's patch between frames (given
    the frame's ``image``). The registration in use is the ``registration`` attribute (None: off); a
    replay of cached tracks may put a recorded one in its place. With ``size_prior`` each track's kind is voted
    from its labels over time (``kind_memory_s``, :mod:`monorarp.state.kind`); a change of kind re-expresses its
    filter instead of restarting it (:meth:`_kind_fused`).
    """

    uses_camera = True   # the registry passes the run's camera
    uses_image = True    # the pipeline passes each frame's image (``registration``)

    def __init__(self, camera: CameraModel | dict | None = None, config: StateConfig | None = None,
                 **overrides: Any) -> None:
        self.config = c = state_config(config, overrides)
        self.camera = camera if isinstance(camera, CameraModel) else CameraModel.from_dict(camera)
        self.border_tol_px = border_tolerance(c.border_tol_px, self.camera.width)
        self.fragment_bottom_px = c.fragment_bottom_px * self.camera.width / 640.0   # px of this image
        self.hidden_side_px = None if c.hidden_side_px is None else c.hidden_side_px * self.camera.width / 640.0
        self._near_edge = NearEdgeOffsets(c.offset_learn_margin_px, c.max_inward_offset_m)
        self._expansion = ExpansionFilter(pixel_std=c.expansion_pixel_std, process_std=c.expansion_process_std,
                                          accel_std=c.expansion_accel_std,
                                          constant_speed=c.expansion_constant_speed)
        self.registration = LoomingRegistration(pixel_std=c.registration_pixel_std, top=c.registration_top,
                                                interpolation=c.registration_interpolation) \
            if c.registration else None
        self._rate_window = RateWindow(window_s=c.registration_window_s)
        self._lateral_window = RateWindow(window_s=c.registration_window_s, baseline=0.0)
        self._filter: KalmanTracks | DifferenceTracks
        if c.velocity == "kalman":
            y_std = c.process_std if c.longitudinal_process_std is None else c.longitudinal_process_std
            process = ProcessNoise(c.motion, (c.process_std, y_std),
                                   bias_variance(c.bias_pixel_std, c.lateral_bias_pixel_std), c.bias_tau_s)
            inflation = 1.0 if c.fusion_pixel_std is None else c.fusion_pixel_std / c.registration_pixel_std
            self._filter = KalmanTracks(process, prior_variance(c.motion, c.init_vel_std, c.init_acc_std),
                                        c.reinit_sigmas, c.robust_sigmas, c.fusion_sigmas, inflation)
        else:
            self._filter = DifferenceTracks()
        self._extra_px_var = 0.0      # this frame's white horizon noise (px^2), added to the measurement's
        self._profile = None          # this frame's measured road profile (a GroundReading's), None: flat ground
        self._ground_std: np.ndarray | None = None   # per box, the profile's one-sigma added to d_y_std (m)
        self._prior_std: np.ndarray | None = None    # per box, the size-prior fusion's one-sigma (m; NaN: none)
        self._kinds = TrackKinds(c.kind_memory_s, c.kind_switch_share) \
            if c.size_prior and c.kind_memory_s is not None else None     # per track, its kind for the size prior
        self.reset()

    def reset(self) -> None:
        """Forget every track's history."""
        self._filter.reset()                       # per track: the filter's state and last update time
        self._coast: dict[int, int] = {}           # per track: consecutive coasting frames
        self._measured: dict[int, float] = {}      # per track: frame time of its last distance reading (s)
        self._near_edge.reset()
        if self._kinds is not None:
            self._kinds.reset()
        self._expansion.reset()
        self._rate_window.reset()
        self._lateral_window.reset()
        if self.registration is not None:
            self.registration.reset()

    # ------------------------------------------------------------------ the measurements, configured
    def measure(self, boxes: np.ndarray) -> np.ndarray:
        """(M, 4) boxes -> (M, 2) ``(d_x, d_y)`` (m) with this estimator's geometry parameters."""
        c = self.config
        return measure_boxes(self.camera, boxes, c.vehicle_width_m, c.contact_offset_m, c.ground_clearance_m,
                             c.vehicle_length_m, self.border_tol_px)

    @property
    def near_limit_m(self) -> float:
        """Distance (m) to a rear face whose contact line lies on the lowest row not taken as the border's
        (:func:`monorarp.state.measurement.near_limit_m`)."""
        return near_limit_m(self.camera, self.border_tol_px, self.config.contact_offset_m,
                            self.config.ground_clearance_m)

    def plausible_boxes(self, boxes: np.ndarray) -> np.ndarray:
        """(M, 4) boxes with the rows beyond 10 image sizes NaN (:func:`monorarp.state.measurement.plausible_boxes`)."""
        return plausible_boxes(self.camera, boxes)

    def border_cut_boxes(self, boxes: np.ndarray) -> np.ndarray:
        """(M, 4) boxes with the far edge of one too narrow for a vehicle near a side border extended to it
        (:func:`monorarp.state.measurement.border_cut_boxes`)."""
        c = self.config
        return border_cut_boxes(self.camera, boxes, self.border_tol_px, c.min_vehicle_width_m, c.near_border_frac,
                                c.contact_offset_m, c.ground_clearance_m)

    def horizon_gain(self, d_y: np.ndarray) -> np.ndarray:
        """``|d d_y / d row|`` (m/px) (:func:`monorarp.state.measurement.horizon_gain`)."""
        return horizon_gain(self.camera, d_y, self.config.contact_offset_m)

    def grade_gain(self, d_y: np.ndarray) -> np.ndarray:
        """``|d d_y / d grade|`` (m per unit rise/run) (:func:`monorarp.state.measurement.grade_gain`)."""
        return grade_gain(self.camera, d_y, self.config.contact_offset_m)

    def distance_std(self, d_y: np.ndarray, filter_std: np.ndarray, horizon_std_px: float,
                     side_cut: np.ndarray | None = None) -> np.ndarray:
        """One-sigma of ``d_y`` (m): the filter's and, in quadrature, the errors it cannot see
        (:func:`monorarp.state.measurement.distance_std`)."""
        c = self.config
        return distance_std(self.camera, d_y, filter_std, horizon_std_px, side_cut, c.edge_std_px,
                            c.border_edge_std_px, c.contact_offset_std_m, c.grade_std, c.contact_offset_m)

    def size_fused(self, labels: Sequence[str], boxes: np.ndarray, d_y: np.ndarray,
                   horizon_std_px: float) -> tuple[np.ndarray, np.ndarray, dict[str, np.ndarray]]:
        """The ground plane's ``d_y`` (M,) of ``boxes`` fused with their size prior's
        (:mod:`monorarp.state.size_prior`): ``(fused d_y, its one-sigma, the parts)``; the parts (``ground``,
        ``height``, ``width``, each with a ``_std``) are each reading and its one-sigma (m; NaN where it takes no
        part), ``ground`` on the frame's fitted ground plane with ``size_prior_ground_fit``. A box whose ground
        distance is NaN, or whose kind has no prior, keeps the flat ground plane's ``d_y`` (one-sigma NaN)."""
        c = self.config
        cam, tol = self.camera, self.border_tol_px
        prior = priors_of(labels, SIZE_PRIORS if c.size_priors is None else c.size_priors)
        flags = border_flags(cam, boxes, tol)
        side_cut = flags[:, :2].any(axis=1)
        g_std = distance_std(cam, d_y, np.zeros(len(d_y)), horizon_std_px, side_cut, c.edge_std_px,
                             c.border_edge_std_px, c.contact_offset_std_m, math.hypot(c.grade_std, c.ground_pitch_std),
                             c.contact_offset_m)
        if self._ground_std is not None:
            g_std = np.hypot(g_std, self._ground_std)
        hidden = occluded(boxes, c.size_prior_hidden_share) if c.size_prior_hidden_share is not None \
            else np.zeros(len(boxes), bool)
        top_cut = boxes[:, 1] <= -0.5 + (tol or 0.0)
        h, h_std = height_distance(cam, boxes, prior[:, 0], prior[:, 1], c.size_prior_edge_std_px, c.contact_offset_m)
        # a box cut by a side border may not reach the roof (a bonnet or boot is lower): no height there
        h = np.where(hidden | top_cut | flags[:, 2] | side_cut, np.nan, h)
        ground = d_y
        if c.size_prior_ground_fit and self._profile is None:
            ground, g_std = self._fitted_ground(boxes, d_y, h, h_std)
        w = w_std = np.full(len(d_y), np.nan)
        if c.size_prior_width:
            w, w_std = width_distance(cam, boxes, prior[:, 2], prior[:, 3], prior[:, 4], prior[:, 5],
                                      c.size_prior_edge_std_px)
            w = np.where(hidden | side_cut, np.nan, w)
        fused, std = fuse([ground, h, w], [g_std, h_std, w_std])
        has = np.isfinite(d_y) & np.isfinite(prior[:, 0])
        parts = {"ground": ground, "ground_std": g_std, "height": h, "height_std": h_std, "width": w, "width_std": w_std}
        return np.where(has, fused, d_y), np.where(has, std, np.nan), parts

    def track_kind(self, track_id: int) -> str | None:
        """The kind (lower case) the size prior uses for a track; None: no such track, or no per-track kind
        (``size_prior`` off or ``kind_memory_s`` None: each box's label)."""
        return None if self._kinds is None else self._kinds.kind.get(track_id)

    def _kind_fused(self, usable: Sequence[Track], boxes: np.ndarray, d_y: np.ndarray, terms: np.ndarray,
                    horizon_std_px: float, t: float) -> tuple[np.ndarray, np.ndarray, dict[str, np.ndarray]]:
        """:meth:`size_fused` with each track's kind (:class:`~monorarp.state.kind.TrackKinds`,
        voted at frame time ``t``, s) instead of its box's label. A track whose kind changes keeps its filter,
        re-expressed under the new kind (:meth:`~monorarp.state.filters.KalmanTracks.rescale`, by the ratio of the
        two kinds' fused distances of this box); where either is NaN (no distance this frame) the change waits."""
        kinds, ids = self._kinds, [tr.id for tr in usable]
        proposed = kinds.update(ids, [tr.label for tr in usable], [tr.score for tr in usable],
                                [not tr.coasting for tr in usable], t)
        current = [kinds.kind[i] for i in ids]
        fused, std, parts = self.size_fused(current, boxes, d_y, horizon_std_px)
        switch = np.array([p != q for p, q in zip(proposed, current)])
        if not switch.any():
            return fused, std, parts
        known = self._filter.known(ids)
        new, new_std, new_parts = self.size_fused([p if w else q for p, q, w in zip(proposed, current, switch)],
                                                  boxes, d_y, horizon_std_px)
        go = switch & (~known | (np.isfinite(fused) & np.isfinite(new) & (fused > 0) & (new > 0)))
        if not (go == switch).all():
            new, new_std, new_parts = self.size_fused([p if w else q for p, q, w in zip(proposed, current, go)],
                                                      boxes, d_y, horizon_std_px)
        shift = np.nan_to_num(terms[:, 0] * (new - fused))
        for j in np.flatnonzero(go):
            ratio = float(new[j] / fused[j]) if known[j] else 1.0
            if not (math.isfinite(ratio) and ratio > 0):        # (the other kinds moved the ground fit)
                new[j], new_std[j] = fused[j], std[j]
                continue
            kinds.commit(ids[j], proposed[j])
            if known[j]:
                self._filter.rescale(ids[j], ratio, float(shift[j]))
        return new, new_std, new_parts

    def _fitted_ground(self, boxes: np.ndarray, d_y: np.ndarray, h: np.ndarray, h_std: np.ndarray
                       ) -> tuple[np.ndarray, np.ndarray]:
        """Each box's ground distance (m) and its one-sigma on the frame's ground plane fitted to the other
        vehicles' size distances ``h`` +- ``h_std`` (:func:`monorarp.state.size_prior.ground_fit`); NaN where
        ``d_y`` is (no ground reading) or the box's bottom is not below the fitted horizon."""
        c, cam = self.config, self.camera
        off, edge = c.contact_offset_m, c.edge_std_px / cam.fy          # rad per px of bottom edge
        v = (boxes[:, 3] - (cam.cy - cam.fy * math.tan(cam.pitch_rad))) / cam.fy
        with np.errstate(invalid="ignore", divide="ignore"):
            x = 1.0 / (h + off)
            v_std = np.sqrt((cam.height_m * h_std * x * x) ** 2 + edge ** 2 + (c.ground_roughness_m * x) ** 2)
            theta, cov = ground_fit(v, np.where(x > 0, x, np.nan), v_std, cam.height_m, c.camera_height_std_m,
                                    c.ground_pitch_std)
            den = v - theta[:, 1]
            y = np.where(den > 0, theta[:, 0] / den, np.nan)
            jac = np.stack([1.0 / den, theta[:, 0] / den ** 2], axis=1)
            var = np.einsum("mi,mij,mj->m", jac, cov, jac) + (jac[:, 1] * edge) ** 2 \
                + (c.ground_roughness_m / den) ** 2 + c.contact_offset_std_m ** 2
        good = np.isfinite(d_y) & np.isfinite(y)
        return np.where(good, y - off, np.nan), np.where(good, np.sqrt(var), np.nan)

    def _noise(self) -> MeasurementNoise:
        """This frame's measurement noise model (its camera, its horizon's white noise)."""
        c = self.config
        lateral = c.pixel_std if c.lateral_pixel_std is None else c.lateral_pixel_std
        return MeasurementNoise(self.camera, c.pixel_std, lateral, c.pixel_std_per_height, self._extra_px_var)

    def _terms(self, ids: list[int], boxes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Measured ``d_y`` (M,) and the lateral terms (M, 3), per-track calibrated
        (:meth:`monorarp.state.measurement.NearEdgeOffsets.readings`), on this frame's road profile if any."""
        c = self.config
        ground = None
        if self._profile is not None:
            ground, self._ground_std = contact_ground(self.camera, self._profile, boxes[:, 3], c.edge_std_px,
                                                      boxes=boxes, width_m=c.vehicle_width_m,
                                                      length_m=c.vehicle_length_m,
                                                      contact_offset_m=c.contact_offset_m)
        return self._near_edge.readings(self.camera, ids, boxes, ground, c.vehicle_width_m, c.vehicle_length_m,
                                        c.contact_offset_m, c.ground_clearance_m, self.border_tol_px,
                                        self.hidden_side_px)

    # ------------------------------------------------------------------ the stage
    def update(self, tracks: Sequence[Track], t: float, horizon: HorizonReading | None = None,
               image: np.ndarray | None = None) -> dict[int, ObjectState]:
        """Estimate every usable track's relative state at frame time ``t`` (s); ValueError on a non-finite ``t``.

        ``horizon``: this frame's horizon reading (:mod:`monorarp.horizon.stages`): equation 3 then uses a
        camera pitched to its row (the calibrated one when that row is impossible), the reading's
        ``std_px`` widens ``d_y_std``, and a reading measured this frame (``"vanishing_point"``, white
        noise) also widens the filter's measurement noise; a reading with a measured road profile
        (:class:`monorarp.core.ground_profile.GroundReading`) gives the bottom rows' ground distances and their
        uncertainty (:func:`monorarp.state.ground_contact.contact_ground`). None: the calibrated horizon with
        ``horizon_std_px``. ``image`` (H x W x 3 RGB or H x W grey): the frame, for ``registration``
        (None: no ``registered_rate``).
        """
        if horizon is None:
            return self._update(tracks, t, self.config.horizon_std_px, image)
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
            self._prior_std = None

    def _update(self, tracks: Sequence[Track], t: float, horizon_std_px: float,
                image: np.ndarray | None = None) -> dict[int, ObjectState]:
        if self.camera.distorted:     # lens distortion: the geometry in the ideal pinhole canvas
            return self._pinhole_update(tracks, t, horizon_std_px, image)
        c = self.config
        t = float(t)
        if not np.isfinite(t):
            raise ValueError(f"frame time must be finite, got {t}")
        for tid in self._filter.unseen(t, c.forget_s):
            self._filter.forget(tid)
            self._near_edge.forget(tid)
            self._measured.pop(tid, None)
            if self._kinds is not None:
                self._kinds.forget(tid)
        self._coast = {tr.id: self._coast.get(tr.id, 0) + 1 if tr.coasting else 0 for tr in tracks}
        usable = [tr for tr in tracks if self._coast[tr.id] <= c.max_coast_used]
        if usable and c.fragment_cover is not None:
            part = fragments(np.array([tr.box for tr in usable], dtype=float), c.fragment_cover,
                             c.fragment_width_ratio, self.fragment_bottom_px)
            usable = [tr for tr, p in zip(usable, part) if not p]
        if not usable:
            return {}
        ids = [tr.id for tr in usable]
        boxes = self.border_cut_boxes(self.plausible_boxes(np.array([tr.box for tr in usable], dtype=float)))
        d_y, terms = self._terms(ids, boxes)
        self._prior_std = None
        if c.size_prior:
            d_y, self._prior_std, _ = self._kind_fused(usable, boxes, d_y, terms, horizon_std_px, t) \
                if self._kinds is not None else self.size_fused([tr.label for tr in usable], boxes, d_y, horizon_std_px)
        coasting = np.array([tr.coasting for tr in usable])
        known = self._filter.known(ids)
        # A new track needs both coordinates from its box; a known one is output in any case
        # (the missing coordinates are predicted / held).
        new_ok = np.isfinite(d_y) & np.isfinite(lateral_from_terms(terms, d_y))
        ok = known | new_ok
        if isinstance(self._filter, KalmanTracks):
            return self._kalman_states(self._filter, ids, boxes, d_y, terms, coasting, known, ok, t, horizon_std_px,
                                       image)
        out = self._filter.update(ids, d_y, terms, known, ok, t)
        return {tid: ObjectState(tid, *map(float, row)) for tid, row, good in zip(ids, out, ok) if good}

    def _pinhole_update(self, tracks: Sequence[Track], t: float, horizon_std_px: float,
                        image: np.ndarray | None) -> dict[int, ObjectState]:
        """:meth:`_update` for a distorted camera: the tracks' boxes and the image in its virtual pinhole camera
        (:mod:`monorarp.state.pinhole_view`). A measured road profile (rows of the distorted image) is not used."""
        real, profile = self.camera, self._profile
        view = pinhole_view(real, self.border_tol_px)
        boxes = view.boxes(np.array([tr.box for tr in tracks], dtype=float).reshape(-1, 4))
        ideal = [replace(tr, box=tuple(float(x) for x in b)) for tr, b in zip(tracks, boxes)]
        self.camera, self._profile = view.virtual(real), None
        try:
            return self._update(ideal, t, horizon_std_px, None if image is None else view.image(image))
        finally:
            self.camera, self._profile = real, profile

    def _kalman_states(self, kf: KalmanTracks, ids: list[int], boxes: np.ndarray, d_y: np.ndarray,
                       terms: np.ndarray, coasting: np.ndarray, known: np.ndarray, ok: np.ndarray, t: float,
                       horizon_std_px: float, image: np.ndarray | None) -> dict[int, ObjectState]:
        """The Kalman filters' states, their uncertainties and the looming cues of the usable tracks."""
        c = self.config
        flags = border_flags(self.camera, boxes, self.border_tol_px)
        cut_bottom, side_cut = flags[:, 2], flags[:, :2].any(axis=1)
        scale = scale_std = None
        if self.registration is not None and image is not None:
            # a box cut by the image's bottom (a vehicle at contact) holds only part of its patch
            scale, scale_std, centre, shift = self.registration.update(image, ids, boxes,
                                                                       ~coasting & ~side_cut & ~cut_bottom)
        fused = (scale, scale_std) if c.fusion_sigmas is not None and scale is not None else None
        out, std, acc = kf.update(ids, d_y, terms, coasting, known, ok, t, self.camera, self._noise(),
                                  self.near_limit_m, cut_bottom, boxes[:, 3] - boxes[:, 1], fused)
        restart = np.array([kf.born.get(i) == t for i in ids])
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
        biased = side_cut | too_narrow(self.camera, boxes, out[:, 1], c.min_vehicle_width_m)
        if c.hidden_share is not None:
            biased |= occluded(boxes, c.hidden_share)
        if c.side_band_frac > 0:
            band = border_flags(self.camera, boxes, c.side_band_frac * self.camera.width)
            biased |= (band[:, 1] & (boxes[:, 0] > self.camera.cx)) | (band[:, 0] & (boxes[:, 2] < self.camera.cx))
        std[biased, 2] = np.maximum(std[biased, 2], c.side_cut_lateral_std_mps)
        filter_std = std[:, 1].copy()
        std[:, 1] = self.distance_std(out[:, 1], std[:, 1], horizon_std_px, side_cut)
        if self._ground_std is not None:
            std[:, 1] = np.hypot(std[:, 1], self._ground_std)
        if self._prior_std is not None:      # the fusion's one-sigma holds the errors the filter cannot see
            fused = np.isfinite(self._prior_std)
            std[fused, 1] = np.hypot(filter_std[fused], self._prior_std[fused])
        # A distance only predicted for longer than max_unmeasured_s (the box gives none: its
        # contact line is out of view at a side border) is no estimate any more: constant
        # velocity carries it through the ego. A box cut by the bottom border stays (clamped).
        for i, has in zip(ids, np.isfinite(d_y) & ~coasting):
            if has:
                self._measured[i] = t
        stale = np.array([t - self._measured.get(i, t) > c.max_unmeasured_s + 1e-9 for i in ids])
        # A filter (re)started on a box that gives no distance (cut by the bottom border from its first
        # sighting, or after a jump to another vehicle) knows none: its 0 m start is no estimate.
        unmeasured = np.array([self._measured.get(i, -np.inf) < kf.born.get(i, t) for i in ids], dtype=bool)
        ok = ok & ~(stale & ~cut_bottom) & ~unmeasured
        return {tid: ObjectState(tid, *map(float, row), *map(float, sd), *(None, None) if ac is None else map(float, ac),
                                 age_s=float(t - kf.born[tid]), expansion_rate=_finite_or_none(er),
                                 expansion_rate_std=_finite_or_none(er_std), registered_rate=_finite_or_none(rr),
                                 registered_rate_std=_finite_or_none(rr_std), registered_v_x=_finite_or_none(lv),
                                 registered_v_x_std=_finite_or_none(lv_std))
                for tid, row, sd, ac, good, er, er_std, rr, rr_std, lv, lv_std
                in zip(ids, out, std, acc if acc is not None else [None] * len(ids), ok, rate, rate_std, reg, reg_std,
                       lat, lat_std)
                if good}


def _finite_or_none(v: float) -> float | None:
    return float(v) if np.isfinite(v) else None
