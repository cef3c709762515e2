"""A KITTI dataset's labels as scored truth: :class:`KittiFrameTruth` per frame, read by
:func:`harness.scoring.evaluate.evaluate`, with each label's KITTI fields beside.

``d_long`` / ``d_lat`` (m) from each label's location, size and yaw (:mod:`harness.kitti_eval.geometry`);
on tracking sequences ``v_long`` / ``v_lat`` (m/s) by finite differences over the same track id
(:func:`add_velocities`); no visibility (the ``counted`` flag replaces it), TTC or ego speed.
Which labels count: :func:`is_counted` (rules in :mod:`harness.kitti_eval.evaluate`'s docstring).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from harness.kitti_eval import geometry as geo
from harness.kitti_eval.reader import Sample
from harness.scoring.kitti_difficulty import difficulty_names, passes
from harness.world.truth import EgoTruth, FrameTruth, ObjectTruth
from monorarp.core.camera import CameraModel

VEHICLE_TYPES = ("Car", "Van", "Truck")


def is_counted(sample_kind: str, types: list[str], box: np.ndarray, occluded: np.ndarray,
               truncated: np.ndarray) -> np.ndarray:
    """(N,) does each label count (module docstring)? Range is applied by the scoring."""
    vehicle = np.array([t in VEHICLE_TYPES for t in types], dtype=bool)
    if sample_kind == "tracking":
        h = box[:, 3] - box[:, 1] if len(box) else np.zeros(0)
        return vehicle & (h > 25.0) & (occluded <= 2) & (truncated <= 0)
    return vehicle & passes(box, occluded, truncated, "moderate")


@dataclass(frozen=True)
class KittiObjectTruth(ObjectTruth):
    """A label as scored truth, with its KITTI fields (``label``: the label file and line)."""

    type: str = ""
    truncated: float = 0.0
    occluded: int = 0
    difficulty: str = ""
    label: str = ""


@dataclass(frozen=True)
class KittiFrameTruth(FrameTruth):
    """A frame's labels as scored truth, with the sample's name."""

    sample: str = ""


def truth_record(sample: Sample, kind: str, camera: CameraModel, offset: np.ndarray, frame: int, t: float,
                 id_base: int) -> KittiFrameTruth:
    """The frame's truth: no visibility (the ``counted`` flag replaces it), velocity, TTC or ego speed."""
    lab = sample.labels
    n = len(lab)
    d_long = np.full(n, np.nan)
    d_lat = np.full(n, np.nan)
    real = np.array([t != "DontCare" for t in lab.type], dtype=bool)
    if real.any():
        dl, dx = geo.rear_face_distance(lab.dimensions[real], lab.location[real], lab.rotation_y[real], camera,
                                        offset)
        d_long[real], d_lat[real] = dl, dx
    counted = is_counted(kind, lab.type, lab.box, lab.occluded, lab.truncated) if n else np.zeros(0, bool)
    difficulty = difficulty_names(lab.box, lab.occluded, lab.truncated) if n else []
    objects = []
    for k in range(n):
        tid = int(lab.track_id[k])
        objects.append(KittiObjectTruth(
            id=id_base + tid if tid >= 0 else -(id_base + k + 1), box=tuple(lab.box[k].tolist()),
            visibility=float("nan"), counted=bool(counted[k]), d_long=float(d_long[k]), d_lat=float(d_lat[k]),
            v_long=None, v_lat=None, ttc=None, type=lab.type[k], truncated=float(lab.truncated[k]),
            occluded=int(lab.occluded[k]), difficulty=difficulty[k], label=lab.source[k]))
    return KittiFrameTruth(frame=frame, t=t, ego=EgoTruth(speed=float("nan"), crashed=False),
                           objects=tuple(objects), sample=sample.name)


def add_velocities(truths: list[KittiFrameTruth]) -> list[KittiFrameTruth]:
    """``truths`` with ``v_long``/``v_lat`` (m/s) of tracked labels filled: finite differences of
    ``d_long``/``d_lat`` over the frame times of the same track id in consecutive frames
    (:func:`geometry.finite_difference`)."""
    tracks: dict[int, list[tuple[int, int]]] = {}          # track id -> (frame k, object j)
    for k, tr in enumerate(truths):
        for j, o in enumerate(tr.objects):
            if o.id >= 0 and np.isfinite(o.d_long):
                tracks.setdefault(o.id, []).append((k, j))
    filled: dict[tuple[int, int], dict[str, float | None]] = {}
    for rows in tracks.values():
        f = np.array([truths[k].frame for k, _ in rows])
        t = np.array([truths[k].t for k, _ in rows])
        for key, src in (("v_long", "d_long"), ("v_lat", "d_lat")):
            v = geo.finite_difference(f, t, np.array([getattr(truths[k].objects[j], src) for k, j in rows]))
            for kj, val in zip(rows, v):
                filled.setdefault(kj, {})[key] = float(val) if np.isfinite(val) else None
    return [replace(tr, objects=tuple(replace(o, **filled[(k, j)]) if (k, j) in filled else o
                                      for j, o in enumerate(tr.objects))) for k, tr in enumerate(truths)]
