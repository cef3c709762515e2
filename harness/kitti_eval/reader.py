"""Reading a KITTI object or tracking dataset from disk (text formats of KITTI's devkits).

Layouts (``DIR`` or ``DIR/training``):

* **object**: ``image_2/NNNNNN.png``, ``label_2/NNNNNN.txt`` (15 fields a line:
  ``type truncated occluded alpha x1 y1 x2 y2 h w l x y z rotation_y``), ``calib/NNNNNN.txt``;
* **tracking**: ``image_02/SSSS/NNNNNN.png``, ``label_02/SSSS.txt`` (17 fields a line: ``frame
  track_id`` then the 15 above), ``calib/SSSS.txt``.

Calibration files hold ``key: 12 numbers`` (or ``key 12 numbers``, KITTI tracking's spelling):
``P2`` is required; ``R0_rect``/``R_rect``, ``Tr_velo_to_cam``/``Tr_velo_cam`` and
``Tr_imu_to_velo``/``Tr_imu_velo`` are read when present. Every problem raises
:class:`KittiInputError` naming the file (and line): a missing or misnamed part, a label
line with the wrong number of fields or a field that is not a number, a calibration without
``P2``. Everything here is read before any output exists; images are checked as they are read.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from monorarp.core.errors import UserError
from monorarp.core.readers import MAX_JSON_BYTES, read_text

IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg")
OBJECT_DIRS = ("image_2", "label_2", "calib")
TRACKING_DIRS = ("image_02", "label_02", "calib")
#: KITTI's aliases of calibration keys -> the object benchmark's names.
CALIB_ALIASES = {"R_rect": "R0_rect", "Tr_velo_cam": "Tr_velo_to_cam", "Tr_imu_velo": "Tr_imu_to_velo"}
CALIB_SHAPES = {"P0": (3, 4), "P1": (3, 4), "P2": (3, 4), "P3": (3, 4), "R0_rect": (3, 3),
                "Tr_velo_to_cam": (3, 4), "Tr_imu_to_velo": (3, 4), "Tr_cam_to_road": (3, 4)}
N_OBJECT_FIELDS = 15
N_TRACKING_FIELDS = 17


class KittiInputError(UserError, ValueError):
    """A KITTI dataset that cannot be read (the message names the file and line)."""


@dataclass
class Labels:
    """The label lines of one image (arrays of equal length; units: px, m, rad)."""

    type: list[str]
    truncated: np.ndarray      # (N,) share 0..1 (object) or level 0/1/2 (tracking)
    occluded: np.ndarray       # (N,) int 0..3
    alpha: np.ndarray
    box: np.ndarray            # (N, 4) x1 y1 x2 y2 (px)
    dimensions: np.ndarray     # (N, 3) h w l (m)
    location: np.ndarray       # (N, 3) x y z of the bottom-face centre in the label (rectified camera) frame (m)
    rotation_y: np.ndarray     # (N,) rad
    track_id: np.ndarray       # (N,) int (object datasets: the line index)
    source: list[str] = field(default_factory=list)   # "file:line" of each object

    def __len__(self) -> int:
        return len(self.type)


@dataclass
class Sample:
    """One image with its labels and calibration."""

    name: str                  # e.g. "000123" or "0003/000017"
    frame: int                 # frame index within its sequence (object datasets: the sample number)
    image: Path
    labels: Labels
    calib: dict[str, np.ndarray]
    calib_path: Path


@dataclass
class Sequence:
    """Samples played in order (a KITTI tracking sequence, or one object sample by itself)."""

    name: str
    samples: list[Sample]


@dataclass
class Dataset:
    root: Path
    kind: str                  # "object" or "tracking"
    sequences: list[Sequence]

    @property
    def n_frames(self) -> int:
        return sum(len(s.samples) for s in self.sequences)


# ---------------------------------------------------------------------------- text formats
def _read_lines(path: Path, what: str) -> list[str]:
    return read_text(path, what, KittiInputError, MAX_JSON_BYTES).splitlines()


def parse_calib(path: Path) -> dict[str, np.ndarray]:
    """The matrices of a calibration file (names as in KITTI object's ``calib``); ``P2`` is required."""
    out: dict[str, np.ndarray] = {}
    for k, line in enumerate(_read_lines(path, "KITTI calibration file"), 1):
        if not line.strip():
            continue
        m = re.match(r"\s*([A-Za-z0-9_]+)\s*:?\s*(.*)$", line)
        if not m:
            raise KittiInputError(f"{path}: line {k}: not a 'key: numbers' line")
        key, rest = CALIB_ALIASES.get(m.group(1), m.group(1)), m.group(2).split()
        try:
            values = np.array([float(v) for v in rest], dtype=float)
        except ValueError:
            raise KittiInputError(f"{path}: line {k}: {m.group(1)} holds a value that is not a number") from None
        shape = CALIB_SHAPES.get(key)
        if shape is None:
            continue                            # other keys (e.g. S_02, D_02 of the raw data) are not used
        if values.size != shape[0] * shape[1]:
            raise KittiInputError(f"{path}: line {k}: {m.group(1)} has {values.size} numbers, expected "
                                  f"{shape[0] * shape[1]}")
        if not np.isfinite(values).all():
            raise KittiInputError(f"{path}: line {k}: {m.group(1)} holds a non-finite number")
        out[key] = values.reshape(shape)
    if "P2" not in out:
        raise KittiInputError(f"{path}: no P2 (the left colour camera's 3x4 projection matrix)")
    return out


_FIELD_NAMES = ("type", "truncated", "occluded", "alpha", "x1", "y1", "x2", "y2", "h", "w", "l", "x", "y", "z",
                "rotation_y")


def _parse_object_fields(parts: list[str], where: str) -> tuple:
    try:
        nums = [float(v) for v in parts[1:]]
    except ValueError:
        bad = next(i for i, v in enumerate(parts[1:], 1) if not _is_float(v))
        raise KittiInputError(f"{where}: field {_FIELD_NAMES[bad]} = {parts[bad]!r} is not a number") from None
    if not np.isfinite(nums).all():
        raise KittiInputError(f"{where}: a field is not finite")
    x1, y1, x2, y2 = nums[3:7]
    if parts[0] != "DontCare" and not (x2 >= x1 and y2 >= y1):
        raise KittiInputError(f"{where}: box {x1:g} {y1:g} {x2:g} {y2:g} has x2 < x1 or y2 < y1")
    return parts[0], nums


def _is_float(v: str) -> bool:
    try:
        float(v)
        return True
    except ValueError:
        return False


def _labels(rows: list[tuple[str, list[float], int, str]]) -> Labels:
    nums = np.array([r[1] for r in rows], dtype=float).reshape(-1, 14)
    return Labels(type=[r[0] for r in rows], truncated=nums[:, 0], occluded=nums[:, 1].astype(int),
                  alpha=nums[:, 2], box=nums[:, 3:7], dimensions=nums[:, 7:10], location=nums[:, 10:13],
                  rotation_y=nums[:, 13], track_id=np.array([r[2] for r in rows], dtype=int),
                  source=[r[3] for r in rows])


def _label_lines(path: Path, n_fields: int, kind: str):
    """(line number, fields, ``"FILE: line N"``) of each non-blank line; KittiInputError on a wrong field count."""
    for k, line in enumerate(_read_lines(path, f"KITTI {kind} label file"), 1):
        parts = line.split()
        if not parts:
            continue
        where = f"{path}: line {k}"
        if len(parts) != n_fields:
            raise KittiInputError(f"{where}: {len(parts)} fields, a KITTI {kind} label has {n_fields}")
        yield k, parts, where


def parse_object_labels(path: Path) -> Labels:
    """A ``label_2`` file (15 fields a line; a 16th, a detection score, is refused: this reads truth)."""
    rows = []
    for k, parts, where in _label_lines(path, N_OBJECT_FIELDS, "object"):
        typ, nums = _parse_object_fields(parts, where)
        rows.append((typ, nums, len(rows), f"{path.name}:{k}"))
    return _labels(rows)


def parse_tracking_labels(path: Path) -> dict[int, Labels]:
    """A ``label_02`` file (17 fields a line) -> labels per frame index."""
    per_frame: dict[int, list] = {}
    for k, parts, where in _label_lines(path, N_TRACKING_FIELDS, "tracking"):
        try:
            frame, tid = int(parts[0]), int(parts[1])
        except ValueError:
            raise KittiInputError(f"{where}: frame and track_id must be integers, got {parts[0]!r} {parts[1]!r}") \
                from None
        if frame < 0:
            raise KittiInputError(f"{where}: negative frame {frame}")
        typ, nums = _parse_object_fields(parts[2:], where)
        per_frame.setdefault(frame, []).append((typ, nums, tid, f"{path.name}:{k}"))
    return {f: _labels(rows) for f, rows in per_frame.items()}


# ---------------------------------------------------------------------------- layouts
def _images(folder: Path, root: Path) -> dict[int, Path]:
    out: dict[int, Path] = {}
    for p in sorted(folder.iterdir()):
        if p.name.startswith("."):
            continue
        if not (p.is_file() and re.fullmatch(r"\d{6}", p.stem) and p.suffix.lower() in IMAGE_SUFFIXES):
            raise KittiInputError(f"{p}: not a KITTI image name (6 digits, .png): misnamed file in {folder.name}/")
        if int(p.stem) in out:
            raise KittiInputError(f"{p}: a second image for frame {p.stem}")
        out[int(p.stem)] = p
    return out


def _missing_dirs(root: Path, names: tuple[str, ...]) -> list[str]:
    return [n for n in names if not (root / n).is_dir()]


def open_dataset(path: str | Path) -> Dataset:
    """Read every label and calibration file of the dataset at ``path`` (KittiInputError on any problem)."""
    root = Path(path)
    if not root.is_dir():
        raise KittiInputError(f"{root}: no such dataset directory")
    if not (root / "image_2").exists() and not (root / "image_02").exists() and (root / "training").is_dir():
        root = root / "training"
    obj_missing, trk_missing = _missing_dirs(root, OBJECT_DIRS), _missing_dirs(root, TRACKING_DIRS)
    if (root / "image_2").is_dir() or (root / "label_2").is_dir():
        if obj_missing:
            raise KittiInputError(f"{root}: KITTI object dataset lacks {', '.join(d + '/' for d in obj_missing)}")
        return _object_dataset(root)
    if (root / "image_02").is_dir() or (root / "label_02").is_dir():
        if trk_missing:
            raise KittiInputError(f"{root}: KITTI tracking dataset lacks {', '.join(d + '/' for d in trk_missing)}")
        return _tracking_dataset(root)
    raise KittiInputError(f"{root}: not a KITTI dataset (object: image_2/, label_2/, calib/; "
                          "tracking: image_02/, label_02/, calib/)")


def _object_dataset(root: Path) -> Dataset:
    images = _images(root / "image_2", root)
    if not images:
        raise KittiInputError(f"{root / 'image_2'}: no images")
    for folder in ("label_2", "calib"):
        for p in sorted((root / folder).iterdir()):
            if p.name.startswith("."):
                continue
            if not (re.fullmatch(r"\d{6}", p.stem) and p.suffix == ".txt"):
                raise KittiInputError(f"{p}: not a KITTI {folder} file name (6 digits, .txt)")
            if int(p.stem) not in images:
                raise KittiInputError(f"{p}: no image image_2/{p.stem}.png for it")
    sequences = []
    for idx, image in images.items():
        stem = f"{idx:06d}"
        label_path, calib_path = root / "label_2" / f"{stem}.txt", root / "calib" / f"{stem}.txt"
        for p in (label_path, calib_path):
            if not p.is_file():
                raise KittiInputError(f"{p}: missing (image_2/{image.name} has none)")
        sample = Sample(name=stem, frame=idx, image=image, labels=parse_object_labels(label_path),
                        calib=parse_calib(calib_path), calib_path=calib_path)
        sequences.append(Sequence(name=stem, samples=[sample]))
    return Dataset(root=root, kind="object", sequences=sequences)


def _tracking_dataset(root: Path) -> Dataset:
    seq_dirs = sorted(p for p in (root / "image_02").iterdir() if not p.name.startswith("."))
    if not seq_dirs:
        raise KittiInputError(f"{root / 'image_02'}: no sequences")
    names = set()
    for p in seq_dirs:
        if not (p.is_dir() and re.fullmatch(r"\d{4}", p.name)):
            raise KittiInputError(f"{p}: not a KITTI tracking sequence folder (4 digits)")
        names.add(p.name)
    for folder in ("label_02", "calib"):
        for p in sorted((root / folder).iterdir()):
            if p.name.startswith("."):
                continue
            if not (re.fullmatch(r"\d{4}", p.stem) and p.suffix == ".txt"):
                raise KittiInputError(f"{p}: not a KITTI tracking {folder} file name (4 digits, .txt)")
            if p.stem not in names:
                raise KittiInputError(f"{p}: no image sequence image_02/{p.stem}/ for it")
    sequences = []
    for d in seq_dirs:
        label_path, calib_path = root / "label_02" / f"{d.name}.txt", root / "calib" / f"{d.name}.txt"
        for p in (label_path, calib_path):
            if not p.is_file():
                raise KittiInputError(f"{p}: missing (sequence image_02/{d.name}/ has none)")
        images = _images(d, root)
        if not images:
            raise KittiInputError(f"{d}: no images")
        labels = parse_tracking_labels(label_path)
        extra = sorted(set(labels) - set(images))
        if extra:
            raise KittiInputError(f"{label_path}: labels for frame {extra[0]}, which has no image in "
                                  f"image_02/{d.name}/")
        frames = sorted(images)
        if frames != list(range(frames[0], frames[0] + len(frames))):
            gap = next(f for a, f in zip(range(frames[0], frames[0] + len(frames)), frames) if a != f)
            raise KittiInputError(f"{d}: frames are not consecutive (image {gap:06d} follows a gap)")
        calib = parse_calib(calib_path)
        samples = [Sample(name=f"{d.name}/{f:06d}", frame=f, image=images[f], labels=labels.get(f, _labels([])),
                          calib=calib, calib_path=calib_path) for f in frames]
        sequences.append(Sequence(name=d.name, samples=samples))
    return Dataset(root=root, kind="tracking", sequences=sequences)
