"""Reading a KITTI object or tracking dataset from disk (text formats of KITTI's devkits).

Layouts (``DIR`` or ``DIR/training``):

* **object**: ``image_2/NNNNNN.png``, ``label_2/NNNNNN.txt`` (15 fields a line:
  ``type truncated occluded alpha x1 y1 x2 y2 h w l x y z rotation_y``), ``calib/NNNNNN.txt``;
* **tracking**: ``image_02/SSSS/NNNNNN.png``, ``label_02/SSSS.txt`` (17 fields a line: ``frame
  track_id`` then the 15 above), ``calib/SSSS.txt``.

Calibration files hold ``key: 12 numbers`` (or ``key 12 numbers``, KITTI tracking's spelling):
``P2`` is required; ``R0_rect``/``R_rect``, ``Tr_velo_to_cam``/``Tr_velo_cam`` and
``Tr_imu_to_velo``/``Tr_imu_velo`` are read when present. Every problem raises
:class:`KittiInputError` naming the file (and line, and field): a missing, misnamed or unreadable part
(with its true reason, :func:`~monorarp.core.readers.path_problem`), a label line with the wrong number
of fields, a field that is not a number or outside KITTI's definition (:func:`check_object`), a track id
given twice in one frame, a calibration without ``P2`` or whose matrices are not of KITTI's form.
``lenient=True`` skips bad label *lines* instead (listed in :attr:`Dataset.skipped`); a bad file is
refused either way. Everything here is read before any output exists; images are decoded as they are
scored (their sizes, from the file headers, are read here to check the boxes).
"""

from __future__ import annotations

import math
import re
import struct
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from harness.kitti_eval import geometry as geo
from monorarp.core.errors import UserError
from monorarp.core.readers import MAX_JSON_BYTES, path_problem, read_text

IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg")
OBJECT_DIRS = ("image_2", "label_2", "calib")
TRACKING_DIRS = ("image_02", "label_02", "calib")
#: KITTI's aliases of calibration keys -> the object benchmark's names.
CALIB_ALIASES = {"R_rect": "R0_rect", "Tr_velo_cam": "Tr_velo_to_cam", "Tr_imu_velo": "Tr_imu_to_velo"}
CALIB_SHAPES = {"P0": (3, 4), "P1": (3, 4), "P2": (3, 4), "P3": (3, 4), "R0_rect": (3, 3),
                "Tr_velo_to_cam": (3, 4), "Tr_imu_to_velo": (3, 4), "Tr_cam_to_road": (3, 4)}
N_OBJECT_FIELDS = 15
N_TRACKING_FIELDS = 17
#: KITTI's object types (the devkit's readme), spelled as the devkit spells them (case matters).
KITTI_TYPES = ("Car", "Van", "Truck", "Pedestrian", "Person_sitting", "Cyclist", "Tram", "Misc", "DontCare")
#: Pixels a box may reach beyond the image's pixel centres 0..W-1 / 0..H-1 (KITTI clips boxes to the image).
BOX_TOL_PX = 1.0
#: Radians an angle may exceed [-pi, pi] by (labels are printed rounded: 3.1416 for pi).
ANGLE_TOL = 1e-3
#: Largest deviation of a calibration's rotation from orthonormal (KITTI prints 7 significant digits).
ROTATION_TOL = 1e-3
#: DontCare's values of the fields it has none for (KITTI writes them so).
DONTCARE_SENTINELS = {"truncated": -1.0, "occluded": -1.0, "alpha": -10.0, "h": -1.0, "w": -1.0, "l": -1.0,
                      "x": -1000.0, "y": -1000.0, "z": -1000.0, "rotation_y": -10.0}


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
    skipped: list[str] = field(default_factory=list)   # lenient: "FILE:LINE: reason" of each skipped line

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
        problem = _matrix_problem(key, out[key])
        if problem:
            raise KittiInputError(f"{path}: line {k}: {m.group(1)} {problem}")
    if "P2" not in out:
        raise KittiInputError(f"{path}: no P2 (the left colour camera's 3x4 projection matrix)")
    return out


def _matrix_problem(key: str, m: np.ndarray) -> str | None:
    """What keeps calibration matrix ``key`` from KITTI's form (None if nothing): projections ``K [I | t]``
    with positive focal lengths, rotations (``R0_rect``, the rotation part of ``Tr_*``) orthonormal."""
    if key.startswith("P"):
        try:
            geo.intrinsics(m)
        except ValueError as e:
            return f"is not a projection matrix ({e})"
        return None
    if key in ("R0_rect", "Tr_velo_to_cam", "Tr_imu_to_velo"):
        r = m[:, :3]
        if np.abs(r @ r.T - np.eye(3)).max() > ROTATION_TOL or np.linalg.det(r) < 0:
            return "is not a rotation" + ("" if key == "R0_rect" else " in its left 3x3 block") + \
                f" (R R^T differs from I by {np.abs(r @ r.T - np.eye(3)).max():.3g}, det {np.linalg.det(r):.3g})"
    return None


_FIELD_NAMES = ("type", "truncated", "occluded", "alpha", "x1", "y1", "x2", "y2", "h", "w", "l", "x", "y", "z",
                "rotation_y")


def _parse_object_fields(parts: list[str], where: str, size: tuple[int, int] | None = None,
                         tracking: bool = False) -> tuple:
    try:
        nums = [float(v) for v in parts[1:]]
    except ValueError:
        bad = next(i for i, v in enumerate(parts[1:], 1) if not _is_float(v))
        raise KittiInputError(f"{where}: field {_FIELD_NAMES[bad]} = {parts[bad]!r} is not a number") from None
    if not np.isfinite(nums).all():
        bad = next(i for i, v in enumerate(nums, 1) if not math.isfinite(v))
        raise KittiInputError(f"{where}: field {_FIELD_NAMES[bad]} = {parts[bad]} is not finite")
    problem = check_object(parts[0], nums, size, tracking)
    if problem:
        raise KittiInputError(f"{where}: {problem}")
    return parts[0], nums


def check_object(typ: str, nums: list[float], size: tuple[int, int] | None, tracking: bool = False) -> str | None:
    """What in one label is outside KITTI's definitions (the devkit's readme), as ``"field NAME = V: why"``,
    or None. ``nums``: the 14 numbers after the type; ``size``: the image's (width, height) px, None to
    skip the box-in-image check. DontCare may hold its sentinels (``-1``, ``-10``, ``-1000``) instead."""
    if typ not in KITTI_TYPES:
        close = [t for t in KITTI_TYPES if t.lower() == typ.lower()]
        hint = f" (did you mean {close[0]!r}? KITTI's types are case-sensitive)" if close else \
            f" (KITTI's types: {', '.join(KITTI_TYPES)})"
        return f"field type = {typ!r} is not a KITTI type{hint}"
    dc = typ == "DontCare"
    v = dict(zip(_FIELD_NAMES[1:], nums))

    def bad(name: str, why: str) -> str:
        return f"field {name} = {v[name]:g} {why}"

    def sentinel(name: str) -> bool:
        return dc and v[name] == DONTCARE_SENTINELS[name]

    if not sentinel("truncated"):
        if tracking and v["truncated"] not in (0.0, 1.0, 2.0):
            return bad("truncated", "is not a KITTI tracking truncation level (0, 1, 2)")
        if not tracking and not 0.0 <= v["truncated"] <= 1.0:
            return bad("truncated", "is outside 0..1 (the share of the object outside the image)")
    if not sentinel("occluded") and v["occluded"] not in (0.0, 1.0, 2.0, 3.0):
        return bad("occluded", "is not a KITTI occlusion state (0, 1, 2, 3)")
    for name in ("alpha", "rotation_y"):
        if not sentinel(name) and not abs(v[name]) <= math.pi + ANGLE_TOL:
            return bad(name, "is outside -pi..pi (rad)")
    x1, y1, x2, y2 = nums[3:7]
    if not (x2 >= x1 and y2 >= y1):
        return f"box {x1:g} {y1:g} {x2:g} {y2:g} has x2 < x1 or y2 < y1"
    if x2 == x1 or y2 == y1:
        return f"box {x1:g} {y1:g} {x2:g} {y2:g} has zero area"
    if size is not None:
        w, h = size
        for name, lim in (("x1", w), ("y1", h), ("x2", w), ("y2", h)):
            if not -BOX_TOL_PX <= v[name] <= lim - 1 + BOX_TOL_PX:
                axis = name[0]
                return bad(name, f"lies outside the {w}x{h} image ({axis} 0..{lim - 1} px, "
                                 f"{BOX_TOL_PX:g} px of tolerance; KITTI clips boxes to the image)")
    for name in ("h", "w", "l"):
        if not sentinel(name) and not v[name] > 0:
            return bad(name, "is not a positive size (m)" + ("" if dc else "; only DontCare has none (-1)"))
    if not sentinel("z") and not v["z"] > 0:
        return bad("z", "puts the object behind or at the camera (z must be > 0 m)")
    return None


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


def _label_lines(path: Path, n_fields: int, kind: str, skipped: list[str] | None):
    """(line number, fields, ``"FILE: line N"``) of each non-blank line; KittiInputError on a wrong field count.
    With ``skipped`` (lenient) such a line is recorded there as ``"FILE:N: reason"`` (:func:`_skip`) and left out."""
    for k, line in enumerate(_read_lines(path, f"KITTI {kind} label file"), 1):
        parts = line.split()
        if not parts:
            continue
        where = f"{path}: line {k}"
        if len(parts) != n_fields:
            err = KittiInputError(f"{where}: {len(parts)} fields, a KITTI {kind} label has {n_fields}")
            if skipped is None:
                raise err
            _skip(skipped, path, k, err)
            continue
        yield k, parts, where


def _skip(skipped: list[str], path: Path, k: int, err: KittiInputError) -> None:
    skipped.append(f"{path.name}:{k}: {str(err).removeprefix(f'{path}: line {k}: ')}")


def parse_object_labels(path: Path, size: tuple[int, int] | None = None,
                        skipped: list[str] | None = None) -> Labels:
    """A ``label_2`` file (15 fields a line; a 16th, a detection score, is refused: this reads truth), each line
    checked (:func:`check_object`; ``size``: the image's (width, height) px). ``skipped``: lenient (above)."""
    rows = []
    for k, parts, where in _label_lines(path, N_OBJECT_FIELDS, "object", skipped):
        try:
            typ, nums = _parse_object_fields(parts, where, size)
        except KittiInputError as e:
            if skipped is None:
                raise
            _skip(skipped, path, k, e)
            continue
        rows.append((typ, nums, len(rows), f"{path.name}:{k}"))
    return _labels(rows)


def parse_tracking_labels(path: Path, size: tuple[int, int] | None = None,
                          skipped: list[str] | None = None) -> dict[int, Labels]:
    """A ``label_02`` file (17 fields a line) -> labels per frame index; each line checked as in
    :func:`parse_object_labels` (truncation: KITTI tracking's levels 0, 1, 2), and no track id twice in a
    frame (DontCare's -1 excepted)."""
    per_frame: dict[int, list] = {}
    first: dict[tuple[int, int], int] = {}
    for k, parts, where in _label_lines(path, N_TRACKING_FIELDS, "tracking", skipped):
        try:
            frame, tid, typ, nums = _tracking_line(parts, where, size, first, k)
        except KittiInputError as e:
            if skipped is None:
                raise
            _skip(skipped, path, k, e)
            continue
        first.setdefault((frame, tid), k)
        per_frame.setdefault(frame, []).append((typ, nums, tid, f"{path.name}:{k}"))
    return {f: _labels(rows) for f, rows in per_frame.items()}


def _tracking_line(parts: list[str], where: str, size: tuple[int, int] | None, first: dict, k: int) -> tuple:
    try:
        frame, tid = int(parts[0]), int(parts[1])
    except ValueError:
        raise KittiInputError(f"{where}: frame and track_id must be integers, got {parts[0]!r} {parts[1]!r}") \
            from None
    if frame < 0:
        raise KittiInputError(f"{where}: field frame: negative frame {frame}")
    typ, nums = _parse_object_fields(parts[2:], where, size, tracking=True)
    if tid < -1 or (tid == -1 and typ != "DontCare"):
        raise KittiInputError(f"{where}: field track_id = {tid}: a {typ} needs a track id >= 0 "
                              "(only DontCare has none, -1)")
    if tid >= 0 and (frame, tid) in first:
        raise KittiInputError(f"{where}: field track_id: {tid} is given twice in frame {frame} "
                              f"(first at line {first[(frame, tid)]})")
    return frame, tid, typ, nums


# ---------------------------------------------------------------------------- layouts
def _images(folder: Path, root: Path) -> dict[int, Path]:
    out: dict[int, Path] = {}
    for p in sorted(folder.iterdir()):
        if p.name.startswith("."):
            continue
        if not (re.fullmatch(r"\d{6}", p.stem) and p.suffix.lower() in IMAGE_SUFFIXES):
            raise KittiInputError(f"{p}: not a KITTI image name (6 digits, .png): misnamed file in {folder.name}/")
        problem = path_problem(p)
        if problem:
            raise KittiInputError(f"{p}: {problem} (an image of the dataset)")
        if int(p.stem) in out:
            raise KittiInputError(f"{p}: a second image for frame {p.stem}")
        out[int(p.stem)] = p
    return out


def _image_size(p: Path) -> tuple[int, int]:
    """(width, height) px of image ``p``: from a PNG's IHDR header (not decoded), else decoded by OpenCV."""
    try:
        with open(p, "rb") as f:
            head = f.read(24)
        if head[:8] == b"\x89PNG\r\n\x1a\n" and head[12:16] == b"IHDR":
            w, h = struct.unpack(">II", head[16:24])
            if w > 0 and h > 0:
                return int(w), int(h)
        import cv2

        img = cv2.imread(str(p), cv2.IMREAD_UNCHANGED)
        if img is None:
            raise ValueError("not a readable image")
        return int(img.shape[1]), int(img.shape[0])
    except (OSError, ValueError) as e:
        raise KittiInputError(f"{p}: cannot read image ({path_problem(p) or type(e).__name__})") from None


def _check_principal_point(image: Path, size: tuple[int, int], calib: dict[str, np.ndarray], calib_path: Path) -> None:
    """KittiInputError when P2's principal point lies outside the image: an image of another size than the
    calibration (checked before the label boxes, which would lie outside it too)."""
    K, _ = geo.intrinsics(calib["P2"])                      # parse_calib checked its form
    w, h = size
    if not (0 <= K[0, 2] <= w - 1 and 0 <= K[1, 2] <= h - 1):
        raise KittiInputError(f"{image}: {w}x{h} image, but the principal point of {calib_path} ({K[0, 2]:.1f}, "
                              f"{K[1, 2]:.1f}) lies outside it: image of another size than the calibration")


def _check_part(p: Path, owner: str) -> None:
    """KittiInputError naming why label or calibration file ``p`` (``owner`` needs it) cannot be read."""
    problem = path_problem(p)
    if problem == "no such file":
        raise KittiInputError(f"{p}: missing ({owner} has none)")
    if problem:
        raise KittiInputError(f"{p}: {problem} ({owner} needs it)")


def _missing_dirs(root: Path, names: tuple[str, ...]) -> list[str]:
    for n in names:
        problem = path_problem(root / n, "directory")
        if problem and problem != "no such directory":
            raise KittiInputError(f"{root / n}: {problem}")
    return [n for n in names if not (root / n).is_dir()]


def open_dataset(path: str | Path, lenient: bool = False) -> Dataset:
    """Read and check every label and calibration file of the dataset at ``path`` (KittiInputError on any
    problem; ``lenient``: bad label lines are skipped and listed in :attr:`Dataset.skipped` instead)."""
    root = Path(path)
    problem = path_problem(root, "directory")
    if problem == "no such directory":
        raise KittiInputError(f"{root}: no such dataset directory")
    if problem:
        raise KittiInputError(f"{root}: {problem} (a KITTI dataset is a directory)")
    if not (root / "image_2").exists() and not (root / "image_02").exists() and (root / "training").is_dir():
        root = root / "training"
    obj_missing, trk_missing = _missing_dirs(root, OBJECT_DIRS), _missing_dirs(root, TRACKING_DIRS)
    if (root / "image_2").is_dir() or (root / "label_2").is_dir():
        if obj_missing:
            raise KittiInputError(f"{root}: KITTI object dataset lacks {', '.join(d + '/' for d in obj_missing)}")
        return _object_dataset(root, [] if lenient else None)
    if (root / "image_02").is_dir() or (root / "label_02").is_dir():
        if trk_missing:
            raise KittiInputError(f"{root}: KITTI tracking dataset lacks {', '.join(d + '/' for d in trk_missing)}")
        return _tracking_dataset(root, [] if lenient else None)
    raise KittiInputError(f"{root}: not a KITTI dataset (object: image_2/, label_2/, calib/; "
                          "tracking: image_02/, label_02/, calib/)")


def _object_dataset(root: Path, skipped: list[str] | None) -> Dataset:
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
            _check_part(p, f"image_2/{image.name}")
        calib, size = parse_calib(calib_path), _image_size(image)
        _check_principal_point(image, size, calib, calib_path)
        labels = parse_object_labels(label_path, size, skipped)
        sample = Sample(name=stem, frame=idx, image=image, labels=labels, calib=calib, calib_path=calib_path)
        sequences.append(Sequence(name=stem, samples=[sample]))
    return Dataset(root=root, kind="object", sequences=sequences, skipped=skipped or [])


def _tracking_dataset(root: Path, skipped: list[str] | None) -> Dataset:
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
            _check_part(p, f"sequence image_02/{d.name}/")
        images = _images(d, root)
        if not images:
            raise KittiInputError(f"{d}: no images")
        first_image = images[min(images)]
        calib, size = parse_calib(calib_path), _image_size(first_image)
        _check_principal_point(first_image, size, calib, calib_path)
        labels = parse_tracking_labels(label_path, size, skipped)
        extra = sorted(set(labels) - set(images))
        if extra:
            raise KittiInputError(f"{label_path}: labels for frame {extra[0]}, which has no image in "
                                  f"image_02/{d.name}/")
        frames = sorted(images)
        if frames != list(range(frames[0], frames[0] + len(frames))):
            gap = next(f for a, f in zip(range(frames[0], frames[0] + len(frames)), frames) if a != f)
            raise KittiInputError(f"{d}: frames are not consecutive (image {gap:06d} follows a gap)")
        samples = [Sample(name=f"{d.name}/{f:06d}", frame=f, image=images[f], labels=labels.get(f, _labels([])),
                          calib=calib, calib_path=calib_path) for f in frames]
        sequences.append(Sequence(name=d.name, samples=samples))
    return Dataset(root=root, kind="tracking", sequences=sequences, skipped=skipped or [])
