"""KITTI object and KITTI tracking writers (text formats of KITTI's devkits; maths in
:mod:`harness.export.geometry`, which also says how the pitched camera is represented).

``--format kitti``: ``image_2/``, ``label_2/``, ``calib/`` per frame; ``--format kitti-tracking``:
one sequence ``0000`` (``image_02/``, ``label_02/``, ``calib/``, a seqmap). Boxes in the
project's pixel convention, sizes and positions in m. Files and fields: docs/formats.md
(``monorarp export``).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

import cv2
import numpy as np

from harness.export import geometry as geo
from harness.world.truth import FrameTruth, ObjectTruth
from monorarp.core.camera import CameraModel

SEQUENCE = "0000"
SEQMAP_NAME = "evaluate_tracking.seqmap.training"
OBJECT_DIRS = ("image_2", "label_2", "calib")
TRACKING_DIRS = ("image_02", "label_02", "calib")


#: KITTI's fields of a ``DontCare`` region (its devkit's convention): only the 2-D box is meaningful.
DONTCARE = {"type": "DontCare", "truncated": -1.0, "truncated_level": -1, "occluded": -1, "alpha": -10.0,
            "dimensions": [-1.0, -1.0, -1.0], "location": [-1000.0, -1000.0, -1000.0], "rotation_y": -10.0}


# ------------------------------------------------------------------------------ text
def label_fields(objects: Sequence[ObjectTruth], camera: CameraModel) -> list[dict]:
    """The KITTI fields of each ground-truth object (dicts in object order; numbers unrounded). A vehicle
    whose ground-face centre is not in front of the camera (z <= 0: a long truck alongside, seen only by its
    front) has no KITTI 3-D label (KITTI's locations are in front of the camera): it is written as a
    ``DontCare`` region of its 2-D box, so a detection on it is neither a hit nor a false alarm."""
    if not objects:
        return []
    corners = np.array([o.corners_cam for o in objects], dtype=float)
    box = geo.kitti_box(corners)
    extent = geo.projected_extent(corners, camera)
    trunc = geo.truncation(extent, camera.width, camera.height)
    occ = geo.occlusion([o.visibility for o in objects], trunc)
    occ_level = geo.levels(occ, geo.OCCLUSION_LEVELS)
    trunc_level = geo.levels(trunc, geo.TRUNCATION_LEVELS)
    out = []
    for k, o in enumerate(objects):
        if not box["location"][k][2] > 0:
            out.append({"id": o.id, **DONTCARE, "box": [float(b) for b in o.box]})
            continue
        out.append({"id": o.id, "type": geo.kitti_type(o.length, o.width, o.body),
                    "truncated": float(trunc[k]), "truncated_level": int(trunc_level[k]),
                    "occluded": int(occ_level[k]), "alpha": float(box["alpha"][k]),
                    "box": [float(b) for b in geo.kitti_2d_box(extent[k], o.box, camera.width, camera.height)],
                    "dimensions": [float(box["h"][k]), float(box["w"][k]), float(box["l"][k])],
                    "location": [float(v) for v in box["location"][k]],
                    "rotation_y": float(box["rotation_y"][k])})
    return out


def _common(f: Mapping) -> str:
    x1, y1, x2, y2 = f["box"]
    h, w, l = f["dimensions"]
    x, y, z = f["location"]
    return (f"{f['alpha']:.4f} {x1:.2f} {y1:.2f} {x2:.2f} {y2:.2f} {h:.4f} {w:.4f} {l:.4f} "
            f"{x:.4f} {y:.4f} {z:.4f} {f['rotation_y']:.4f}")


def object_line(f: Mapping) -> str:
    """One ``label_2`` line (15 fields)."""
    return f"{f['type']} {f['truncated']:.2f} {f['occluded']:d} {_common(f)}"


def tracking_line(frame: int, f: Mapping) -> str:
    """One ``label_02`` line (17 fields: frame, track id, then the object fields)."""
    return f"{frame:d} {f['id']:d} {f['type']} {f['truncated_level']:d} {f['occluded']:d} {_common(f)}"


def _numbers(m: np.ndarray) -> str:
    return " ".join(f"{v:.12e}" for v in np.asarray(m, dtype=float).ravel())


def calib_text(camera: CameraModel, tracking: bool = False) -> str:
    """The ``calib`` file: KITTI object spelling, or KITTI tracking's (``R_rect``, ``Tr_velo_cam``, ``Tr_imu_velo``)."""
    c = geo.calibration(camera)
    lines = [f"{k}: {_numbers(c[k])}" for k in ("P0", "P1", "P2", "P3")]
    if tracking:
        lines += [f"R_rect {_numbers(c['R0_rect'])}", f"Tr_velo_cam {_numbers(c['Tr_velo_to_cam'])}",
                  f"Tr_imu_velo {_numbers(c['Tr_imu_to_velo'])}"]
    else:
        lines += [f"{k}: {_numbers(c[k])}" for k in ("R0_rect", "Tr_velo_to_cam", "Tr_imu_to_velo")]
    return "\n".join(lines) + "\n"


def _write_png(path: Path, image: np.ndarray) -> None:
    if not cv2.imwrite(str(path), image):
        raise OSError(f"{path}: cannot write image")


# --------------------------------------------------------------------------- writers
class KittiObjectWriter:
    """Writes one KITTI object sample (image, labels, calibration) per frame."""

    names = OBJECT_DIRS

    def __init__(self, root: Path, camera: CameraModel, name: str = "", fps: float = 0.0) -> None:
        self.root, self.camera = Path(root), camera
        for d in OBJECT_DIRS:
            (self.root / d).mkdir()
        self._calib = calib_text(camera)
        self.frames = self.objects = 0

    def add(self, index: int, image: np.ndarray, truth: FrameTruth, detections=None) -> None:
        stem = f"{index:06d}"
        _write_png(self.root / "image_2" / f"{stem}.png", image)
        fields = label_fields(truth.objects, self.camera)
        (self.root / "label_2" / f"{stem}.txt").write_text("".join(object_line(f) + "\n" for f in fields))
        (self.root / "calib" / f"{stem}.txt").write_text(self._calib)
        self.frames += 1
        self.objects += len(fields)

    def close(self) -> None:
        pass


class KittiTrackingWriter:
    """Writes one KITTI tracking sequence (``0000``): images per frame, one label file, one calibration."""

    names = (*TRACKING_DIRS, SEQMAP_NAME)

    def __init__(self, root: Path, camera: CameraModel, name: str = "", fps: float = 0.0) -> None:
        self.root, self.camera = Path(root), camera
        (self.root / "image_02" / SEQUENCE).mkdir(parents=True)
        (self.root / "label_02").mkdir()
        (self.root / "calib").mkdir()
        self._labels = (self.root / "label_02" / f"{SEQUENCE}.txt").open("w")
        self.frames = self.objects = 0
        self._last = -1

    def add(self, index: int, image: np.ndarray, truth: FrameTruth, detections=None) -> None:
        _write_png(self.root / "image_02" / SEQUENCE / f"{index:06d}.png", image)
        for f in label_fields(truth.objects, self.camera):
            self._labels.write(tracking_line(index, f) + "\n")
            self.objects += 1
        self.frames += 1
        self._last = index

    def close(self) -> None:
        self._labels.close()
        (self.root / "calib" / f"{SEQUENCE}.txt").write_text(calib_text(self.camera, tracking=True))
        (self.root / SEQMAP_NAME).write_text(f"{SEQUENCE} empty 000000 {self._last + 1:06d}\n")
