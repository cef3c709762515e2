"""Ground-truth records of one frame, and their JSONL form (one line of ``ground_truth.jsonl``).

What each field means (frames, units, how it is computed) is written once, in
:mod:`harness.world.ground_truth`, which makes these records from the simulation. A labelled dataset
(:mod:`harness.kitti_eval`) fills the same records and leaves out what it does not know (None).

:meth:`FrameTruth.to_json` gives the JSON-ready dict, keys in this order: ``frame``, ``t``, ``ego``
(``speed``, ``x``, ``y``, ``heading``, ``lane``, ``crashed``), ``objects`` (``id``, ``name``,
``box``, ``visibility``, ``d_long``, ``d_lat``, ``v_long``, ``v_lat``, ``ttc``, ``lane_rel``,
``corners_cam``, ``length``, ``width``, ``body`` only when set (a fleet's body type), ``crashed``, and
``counted`` only when set; ``s_long``
follows ``d_long`` only on a road with a vertical profile or curves, ``s_lat`` follows ``d_lat`` only
on a curved road), then
``camera`` (a moving camera only). :meth:`FrameTruth.from_json` reads it back; optional fields
absent from the dict are None (``crashed``: False).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any


def _opt(value: Any, kind: type) -> Any:
    return None if value is None else kind(value)


@dataclass(frozen=True)
class ObjectTruth:
    """One vehicle with at least one visible pixel (m, m/s, s, px; :mod:`harness.world.ground_truth`)."""

    id: int
    box: tuple[float, float, float, float]      # tight box of the visible pixels (x1, y1, x2, y2), px
    visibility: float
    d_long: float
    d_lat: float
    v_long: float | None
    v_lat: float | None
    ttc: float | None = None                    # None: no collision within the horizon
    name: str | None = None
    lane_rel: int | None = None
    corners_cam: tuple[tuple[float, float, float], ...] | None = None   # 8 corners, camera frame, m
    length: float | None = None
    width: float | None = None
    crashed: bool = False
    counted: bool | None = None                 # a labelled dataset's own "must be found" flag
    s_long: float | None = None                 # along-road distance, camera's foot point to rear face (profile, curves)
    s_lat: float | None = None                  # along-road lateral offset of the rear face, + right (curves only)
    body: str | None = None                     # body type (harness.world.vehicles.BODY_TYPES); None: by footprint

    def to_json(self) -> dict[str, Any]:
        d = {"id": self.id, "name": self.name, "box": list(self.box), "visibility": self.visibility,
             "d_long": self.d_long}
        if self.s_long is not None:
            d["s_long"] = self.s_long
        d["d_lat"] = self.d_lat
        if self.s_lat is not None:
            d["s_lat"] = self.s_lat
        d |= {"v_long": self.v_long, "v_lat": self.v_lat,
              "ttc": self.ttc, "lane_rel": self.lane_rel,
              "corners_cam": None if self.corners_cam is None else [list(c) for c in self.corners_cam],
              "length": self.length, "width": self.width}
        if self.body is not None:
            d["body"] = self.body
        d["crashed"] = self.crashed
        if self.counted is not None:
            d["counted"] = self.counted
        return d

    @classmethod
    def from_json(cls, d: Mapping[str, Any]) -> ObjectTruth:
        corners = d.get("corners_cam")
        return cls(id=int(d["id"]), box=tuple(float(b) for b in d["box"]), visibility=float(d["visibility"]),
                   d_long=float(d["d_long"]), d_lat=float(d["d_lat"]), v_long=_opt(d.get("v_long"), float),
                   v_lat=_opt(d.get("v_lat"), float), ttc=_opt(d.get("ttc"), float), name=d.get("name"),
                   lane_rel=_opt(d.get("lane_rel"), int),
                   corners_cam=None if corners is None else tuple(tuple(float(v) for v in c) for c in corners),
                   length=_opt(d.get("length"), float), width=_opt(d.get("width"), float),
                   crashed=bool(d.get("crashed", False)), counted=_opt(d.get("counted"), bool),
                   s_long=_opt(d.get("s_long"), float), s_lat=_opt(d.get("s_lat"), float),
                   body=_opt(d.get("body"), str))


@dataclass(frozen=True)
class EgoTruth:
    """The ego vehicle: speed (m/s), road-frame position (m) and heading (rad), lane index, crash flag."""

    speed: float
    x: float | None = None
    y: float | None = None
    heading: float | None = None
    lane: int | None = None
    crashed: bool = False

    def to_json(self) -> dict[str, Any]:
        return {"speed": self.speed, "x": self.x, "y": self.y, "heading": self.heading, "lane": self.lane,
                "crashed": self.crashed}

    @classmethod
    def from_json(cls, d: Mapping[str, Any]) -> EgoTruth:
        return cls(speed=float(d["speed"]), x=_opt(d.get("x"), float), y=_opt(d.get("y"), float),
                   heading=_opt(d.get("heading"), float), lane=_opt(d.get("lane"), int),
                   crashed=bool(d.get("crashed", False)))


@dataclass(frozen=True)
class CameraTruth:
    """The true pose of a moving camera (rad, px): :func:`harness.world.camera_motion.pose_record`."""

    pitch_rad: float
    roll_rad: float
    horizon_row: float
    pitch_offset_rad: float
    horizon_offset_px: float

    def to_json(self) -> dict[str, Any]:
        return {"pitch_rad": self.pitch_rad, "roll_rad": self.roll_rad, "horizon_row": self.horizon_row,
                "pitch_offset_rad": self.pitch_offset_rad, "horizon_offset_px": self.horizon_offset_px}

    @classmethod
    def from_json(cls, d: Mapping[str, Any]) -> CameraTruth:
        return cls(**{k: float(d[k]) for k in ("pitch_rad", "roll_rad", "horizon_row", "pitch_offset_rad",
                                               "horizon_offset_px")})


@dataclass(frozen=True)
class FrameTruth:
    """Everything true about one frame: index, time (s), ego, visible vehicles (sorted by id), camera pose."""

    frame: int
    t: float
    ego: EgoTruth
    objects: tuple[ObjectTruth, ...] = ()
    camera: CameraTruth | None = None           # a moving camera only

    def to_json(self) -> dict[str, Any]:
        d = {"frame": self.frame, "t": self.t, "ego": self.ego.to_json(),
             "objects": [o.to_json() for o in self.objects]}
        if self.camera is not None:
            d["camera"] = self.camera.to_json()
        return d

    @classmethod
    def from_json(cls, d: Mapping[str, Any]) -> FrameTruth:
        cam = d.get("camera")
        return cls(frame=int(d["frame"]), t=float(d["t"]), ego=EgoTruth.from_json(d["ego"]),
                   objects=tuple(ObjectTruth.from_json(o) for o in d["objects"]),
                   camera=None if cam is None else CameraTruth.from_json(cam))

    @property
    def min_ttc(self) -> float | None:
        """The lowest TTC of any object (s), None when none has one."""
        return min((o.ttc for o in self.objects if o.ttc is not None), default=None)
