"""The one pinhole camera model shared by the renderer and the state estimator.

Frames (all right-handed, SI units):

* **Ego frame** (the paper's, used for every pipeline output): origin at the
  camera's optical centre, ``x`` lateral (positive to the right), ``y``
  longitudinal (positive ahead, along the ego vehicle's heading), ``z`` up.
  The flat ground plane is ``z = -height_m``.
* **Camera frame** (OpenCV): ``x`` right, ``y`` down, ``z`` along the optical
  axis. The camera is pitched down by ``pitch_rad`` about its ``x`` axis and has
  no yaw relative to the ego vehicle (roll: ``roll_rad``, below).
* **Pixels** (OpenCV): ``u`` right, ``v`` down, pixel centres at integer
  coordinates. *Ideal* pixels are the pinhole projection ``u = fx X / Z + cx``; a camera with lens
  distortion (``distortion``: OpenCV's ``k1, k2, p1, p2, k3``, :mod:`monorarp.core.distortion`; default
  all 0, a pure pinhole) sees them at the *distorted* pixels :meth:`CameraModel.distort_pixels` gives.
  :meth:`CameraModel.project_cam` gives image (distorted) pixels and
  :meth:`CameraModel.ground_point_from_pixel` takes them; everything else here (``K``, ``horizon_row``)
  is the pinhole part. :attr:`CameraModel.pinhole` is the camera without its distortion.

Roll (``roll_rad``, default 0): the camera turned about its optical axis after the
pitch, positive clockwise as seen from behind the camera (its right side dips;
the scene turns counter-clockwise in the image). A calibration normally has no
roll; the harness uses it for the *true* per-frame pose of a moving camera
(:mod:`harness.world.camera_motion`).

Mounting: the camera sits ``height_m`` above the ground, ``forward_offset_m``
ahead of the ego vehicle's centre and ``lateral_offset_m`` to its right.
"""

from __future__ import annotations

import json
import math
import numbers
from dataclasses import asdict, dataclass, replace
from pathlib import Path

import numpy as np

from monorarp.core import distortion as _lens
from monorarp.core.errors import UserError


class CameraError(UserError, ValueError):
    """An impossible or unreadable camera calibration."""


MAX_PIXELS = 1_000_000   # a camera file's width / height at most (a bound far above any camera's)
#: A camera file's smallest width x height (px): below it a car at 20 m is a few pixels, no detector finds it.
MIN_FILE_SIZE = (160, 90)
_FINITE = ("fx", "fy", "cx", "cy", "height_m", "pitch_rad", "lateral_offset_m", "forward_offset_m", "roll_rad")
# the numeric fields of a camera file; every one given is checked, also when another field takes precedence
_FILE_NUMBERS = ("fx", "fy", "cx", "cy", "hfov_deg", "height_m", "pitch_rad", "pitch_deg", "horizon_row",
                 "lateral_offset_m", "forward_offset_m", "roll_rad", "roll_deg")
#: every key a camera file may hold: the documented ones (docs/formats.md) and all that :meth:`CameraModel.to_dict`
#: writes (``camera.json``: K beside fx/fy/cx/cy, the derived horizon_row, roll_rad when not 0); others are refused
FILE_KEYS = ("width", "height", "K", *_FILE_NUMBERS, "distortion")
#: largest deviation of K's fixed entries (``[[fx, 0, cx], [0, fy, cy], [0, 0, 1]]``) taken as float noise
_K_TOL = 1e-9


def _show(value: object) -> str:
    """``repr(value)``, shortened to fit an error line."""
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def _number(value: object, name: str) -> float:
    """``value`` as a finite float; :class:`CameraError` naming ``name`` for a bool, a string, NaN, inf, ..."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real):
        raise CameraError(f"{name} must be a number, got {_show(value)}")
    try:
        x = float(value)
    except OverflowError:   # an integer beyond float range
        x = math.inf
    if not math.isfinite(x):
        raise CameraError(f"{name} must be finite, got {_show(value)}")
    return x


def _pixels(value: object, name: str) -> int:
    """``value`` as a whole number of pixels, 1..MAX_PIXELS (640 or 640.0; not 640.5, true or "640")."""
    whole = isinstance(value, numbers.Integral) and not isinstance(value, bool) or (
        isinstance(value, (float, np.floating)) and math.isfinite(value) and float(value).is_integer())
    if not (whole and 0 < value <= MAX_PIXELS):
        raise CameraError(f"{name} must be a whole number of pixels, 1..{MAX_PIXELS}, got {_show(value)}")
    return int(value)


def _matrix3(value: object, name: str) -> np.ndarray:
    """``value`` (3 rows of 3 numbers) as a 3x3 float array; :class:`CameraError` naming the bad entry."""
    rows = value.tolist() if isinstance(value, np.ndarray) else value
    if not (isinstance(rows, (list, tuple)) and len(rows) == 3
            and all(isinstance(r, (list, tuple)) and len(r) == 3 for r in rows)):
        raise CameraError(f"{name} must be a 3x3 matrix (3 rows of 3 numbers), got {_show(value)}")
    return np.array([[_number(v, f"{name}[{i}][{j}]") for j, v in enumerate(r)] for i, r in enumerate(rows)])


def _intrinsic_matrix(K: np.ndarray) -> None:
    """:class:`CameraError` naming the first entry that keeps ``K`` from being ``[[fx, 0, cx], [0, fy, cy],
    [0, 0, 1]]`` (no skew: the model has none, and dropping it would move every projection)."""
    scale = max(abs(K[0, 0]), abs(K[1, 1]), 1.0)      # the zeros beside fx/fy are in pixels
    for (i, j), want, tol in (((0, 1), 0.0, _K_TOL * scale), ((1, 0), 0.0, _K_TOL * scale),
                              ((2, 0), 0.0, _K_TOL), ((2, 1), 0.0, _K_TOL), ((2, 2), 1.0, _K_TOL)):
        if not abs(K[i, j] - want) <= tol:
            what = " (skew is not modelled)" if (i, j) == (0, 1) else ""
            raise CameraError(f"K[{i}][{j}] must be {want:g}{what}, got {float(K[i, j])!r}: K must be an "
                              "intrinsic matrix [[fx, 0, cx], [0, fy, cy], [0, 0, 1]]")


def _distortion_list(value: object) -> tuple[float, ...]:
    """A camera file's ``distortion`` (4 or 5 numbers) as a tuple of floats; :class:`CameraError` otherwise."""
    items = value.tolist() if isinstance(value, np.ndarray) else value
    if not (isinstance(items, (list, tuple)) and len(items) in (4, 5)):
        raise CameraError(f"distortion must be a list [k1, k2, p1, p2, k3] (or [k1, k2, p1, p2]), got {_show(value)}")
    return tuple(_number(x, f"distortion[{i}]") for i, x in enumerate(items))


def _unknown_keys(d: dict) -> str | None:
    """The problem with keys of ``d`` a camera file may not hold (a typo such as ``pitch_dg`` would
    otherwise leave its field at the default unnoticed), or None."""
    import difflib

    unknown = [k for k in d if k not in FILE_KEYS]
    if not unknown:
        return None
    names = ", ".join(_show(k) for k in unknown[:5]) + (f" and {len(unknown) - 5} more" if len(unknown) > 5 else "")
    hint = ""
    if len(unknown) == 1 and isinstance(unknown[0], str):
        close = difflib.get_close_matches(unknown[0], FILE_KEYS, n=1)
        hint = f" (did you mean {close[0]!r}?)" if close else ""
    return (f"unknown key{'s' if len(unknown) > 1 else ''} {names}{hint}; a camera file holds only "
            f"{', '.join(FILE_KEYS)}")


def _check_file_size(d: dict, path: Path) -> None:
    """:class:`CameraError` for a camera file whose width x height is below :data:`MIN_FILE_SIZE` (checked
    first: its other fields, e.g. a horizon row outside so small an image, are not the problem)."""
    try:
        w, h = _pixels(d.get("width"), "width"), _pixels(d.get("height"), "height")
    except CameraError:
        return                                # from_dict names the bad or missing field
    if w < MIN_FILE_SIZE[0] or h < MIN_FILE_SIZE[1]:
        raise CameraError(f"{path}: the camera file's image, {w}x{h} px, is too small (at least "
                          f"{MIN_FILE_SIZE[0]}x{MIN_FILE_SIZE[1]}: a car 20 m ahead would be a few pixels); give "
                          "the width and height of the video's frames")


@dataclass(frozen=True)
class CameraModel:
    """Intrinsics (pixels) and mounting (metres, radians) of a forward dashcam."""

    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float
    height_m: float
    pitch_rad: float = 0.0
    lateral_offset_m: float = 0.0
    forward_offset_m: float = 0.0
    roll_rad: float = 0.0
    #: OpenCV lens distortion ``(k1, k2, p1, p2, k3)``; all 0: a pure pinhole (:mod:`monorarp.core.distortion`)
    distortion: tuple[float, float, float, float, float] = _lens.ZERO

    def __post_init__(self) -> None:
        if self.distortion is not _lens.ZERO:
            try:
                object.__setattr__(self, "distortion", _lens.coefficients(self.distortion))
            except (TypeError, ValueError) as e:
                raise CameraError(f"distortion: {e}") from None
        problems = [f"{name} must be finite, got {getattr(self, name)}" for name in _FINITE
                    if not math.isfinite(getattr(self, name))]
        problems += [f"distortion must be finite, got {list(self.distortion)}"] \
            if not all(math.isfinite(x) for x in self.distortion) else []
        if problems:    # NaN or inf would pass (or confuse) the range checks below
            raise CameraError("; ".join(problems))
        if self.width <= 0 or self.height <= 0:
            problems.append(f"resolution must be positive, got {self.width}x{self.height}")
        if not (self.fx > 0 and self.fy > 0):
            problems.append(f"focal lengths must be positive, got fx={self.fx}, fy={self.fy}")
        for name, size in (("cx", self.width), ("cy", self.height)):   # the image spans -0.5..size-0.5 px
            if not -0.5 <= getattr(self, name) <= size - 0.5:
                problems.append(f"principal point {name}={getattr(self, name)} px lies outside the image "
                                f"(-0.5..{size - 0.5})")
        if not self.height_m > 0:
            problems.append(f"mounting height must be positive, got {self.height_m} m")
        if not abs(self.pitch_rad) < math.radians(45):
            problems.append(f"pitch must be within +-45 deg, got {math.degrees(self.pitch_rad):.1f} deg")
        if not abs(self.roll_rad) < math.radians(30):
            problems.append(f"roll must be within +-30 deg, got {math.degrees(self.roll_rad):.1f} deg")
        if not problems and not (0 <= self.horizon_row <= self.height - 1):
            problems.append(
                f"horizon row {self.horizon_row:.1f} px lies outside the image (0..{self.height - 1}); "
                "check pitch and cy"
            )
        if not problems and self.distorted:
            why = _lens.check(self.width, self.height, self.fx, self.fy, self.cx, self.cy, self.distortion)
            if why:
                problems.append(why)
        if problems:
            raise CameraError("; ".join(problems))

    # ----------------------------------------------------------------- builders
    @classmethod
    def from_fov(
        cls,
        width: int,
        height: int,
        hfov_deg: float,
        height_m: float,
        pitch_rad: float = 0.0,
        lateral_offset_m: float = 0.0,
        forward_offset_m: float = 0.0,
        roll_rad: float = 0.0,
        distortion: tuple[float, ...] = _lens.ZERO,
    ) -> "CameraModel":
        """Square pixels, principal point at the image centre, horizontal FOV in degrees (of the pinhole part)."""
        if not 1.0 < hfov_deg < 179.0:
            raise CameraError(f"horizontal FOV must be in (1, 179) deg, got {hfov_deg}")
        f = (width / 2.0) / math.tan(math.radians(hfov_deg) / 2.0)
        return cls(width, height, f, f, (width - 1) / 2.0, (height - 1) / 2.0,
                   height_m, pitch_rad, lateral_offset_m, forward_offset_m, roll_rad, distortion)

    def scaled(self, width: int, height: int) -> "CameraModel":
        """The same camera at another resolution (intrinsics scaled, mounting kept)."""
        sx, sy = width / self.width, height / self.height
        return replace(self, width=width, height=height, fx=self.fx * sx, fy=self.fy * sy,
                       cx=(self.cx + 0.5) * sx - 0.5, cy=(self.cy + 0.5) * sy - 0.5)

    # ------------------------------------------------------------- derived values
    @property
    def K(self) -> np.ndarray:
        """3x3 intrinsic matrix, OpenCV convention."""
        return np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])

    @property
    def distorted(self) -> bool:
        """True when the camera has lens distortion (any coefficient non-zero)."""
        return any(self.distortion)

    @property
    def pinhole(self) -> "CameraModel":
        """This camera without its lens distortion (itself when it has none)."""
        return replace(self, distortion=_lens.ZERO) if self.distorted else self

    @property
    def horizon_row(self) -> float:
        """Image row (px) of the horizon: where points at infinity on the ground plane project.

        With roll the horizon is a tilted line; this is the row of its forward vanishing point
        (where lines parallel to the direction of travel meet), ``cy - fy cos(roll) tan(pitch)``.
        """
        return self.cy - self.fy * math.cos(self.roll_rad) * math.tan(self.pitch_rad)

    @property
    def R_cam_from_ego(self) -> np.ndarray:
        """Rotation taking ego-frame vectors (x right, y ahead, z up) to the camera frame."""
        c, s = math.cos(self.pitch_rad), math.sin(self.pitch_rad)
        # level camera: x_c = x, y_c = -z, z_c = y; then pitch down by theta about x_c.
        level = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])
        pitch = np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])
        if self.roll_rad == 0.0:
            return pitch @ level
        cr, sr = math.cos(self.roll_rad), math.sin(self.roll_rad)
        roll = np.array([[cr, sr, 0.0], [-sr, cr, 0.0], [0.0, 0.0, 1.0]])   # about the optical axis
        return roll @ pitch @ level

    # ---------------------------------------------------------------- transforms
    def ego_to_cam(self, points_ego: np.ndarray) -> np.ndarray:
        """(..., 3) ego-frame points (m) -> (..., 3) camera-frame points (m)."""
        return np.asarray(points_ego, dtype=float) @ self.R_cam_from_ego.T

    def cam_to_ego(self, points_cam: np.ndarray) -> np.ndarray:
        """(..., 3) camera-frame points (m) -> (..., 3) ego-frame points (m)."""
        return np.asarray(points_cam, dtype=float) @ self.R_cam_from_ego

    def project_cam(self, points_cam: np.ndarray) -> np.ndarray:
        """(..., 3) camera-frame points with z > 0 -> (..., 2) pixels (u, v), distorted by the lens if any."""
        p = np.asarray(points_cam, dtype=float)
        z = p[..., 2]
        uv = np.stack([self.fx * p[..., 0] / z + self.cx, self.fy * p[..., 1] / z + self.cy], axis=-1)
        return self.distort_pixels(uv) if self.distorted else uv

    def distort_pixels(self, uv: np.ndarray) -> np.ndarray:
        """(..., 2) ideal (pinhole) pixels -> (..., 2) pixels of the distorted image (``cv2.projectPoints``)."""
        return self._through_lens(uv, _lens.distort)

    def undistort_pixels(self, uv: np.ndarray) -> np.ndarray:
        """(..., 2) pixels of the distorted image -> (..., 2) ideal pixels (``cv2.undistortPoints`` with ``P = K``)."""
        return self._through_lens(uv, _lens.undistort)

    def _through_lens(self, uv: np.ndarray, mapping) -> np.ndarray:
        """``mapping`` (normalised coordinates, coefficients -> normalised coordinates) applied to pixels."""
        uv = np.asarray(uv, dtype=float)
        if not self.distorted:
            return uv.copy()
        xy = np.stack([(uv[..., 0] - self.cx) / self.fx, (uv[..., 1] - self.cy) / self.fy], axis=-1)
        m = mapping(xy, self.distortion)
        return np.stack([m[..., 0] * self.fx + self.cx, m[..., 1] * self.fy + self.cy], axis=-1)

    def project_ego(self, points_ego: np.ndarray) -> np.ndarray:
        """(..., 3) ego-frame points -> (..., 2) pixels."""
        return self.project_cam(self.ego_to_cam(points_ego))

    def ground_point_from_pixel(self, u: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Intersect the rays through pixels (u, v) with the ground plane.

        Returns (..., 3) ego-frame points; rows at or above the horizon give NaN. Pixels of a
        distorted camera are undistorted first.
        """
        u = np.asarray(u, dtype=float)
        v = np.asarray(v, dtype=float)
        if self.distorted:
            u, v = np.moveaxis(self.undistort_pixels(np.stack(np.broadcast_arrays(u, v), axis=-1)), -1, 0)
        rays_cam = np.stack([(u - self.cx) / self.fx, (v - self.cy) / self.fy, np.ones_like(u)], axis=-1)
        rays_ego = self.cam_to_ego(rays_cam)
        down = -rays_ego[..., 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            scale = np.where(down > 1e-12, self.height_m / down, np.nan)
        return rays_ego * scale[..., None]

    # ----------------------------------------------------------------- file I/O
    def to_dict(self) -> dict:
        """The ``camera.json`` layout: width, height, K, height_m, pitch_rad and the rest."""
        d = asdict(self)
        if d["roll_rad"] == 0.0:      # a calibration has no roll: keep camera.json as it was
            del d["roll_rad"]
        if self.distorted:            # likewise a pinhole's has no distortion key
            d["distortion"] = list(self.distortion)
        else:
            del d["distortion"]
        d["K"] = self.K.tolist()
        d["horizon_row"] = self.horizon_row
        return d

    @classmethod
    def from_dict(cls, d: dict, source: str = "camera") -> "CameraModel":
        """Build from ``camera.json``-style dict (``K`` or fx/fy/cx/cy) or a YAML camera file.

        Accepted keys: width, height; either K (3x3) or fx, fy, cx, cy, or hfov_deg;
        height_m; pitch_rad or pitch_deg, or horizon_row (px; pitch = atan((cy - horizon_row) / fy));
        lateral_offset_m; forward_offset_m; roll_rad or roll_deg (default 0); distortion (OpenCV's
        ``[k1, k2, p1, p2, k3]`` or ``[k1, k2, p1, p2]``, default none). When both a pitch and ``horizon_row`` are given
        (as in ``camera.json``) they must agree within 1 px, and fx/fy/cx/cy given with K must equal K's.
        Every numeric field must be a finite number (not a bool or a string; width and height whole pixels);
        an optional field that is null counts as not given. ``K`` must be ``[[fx, 0, cx], [0, fy, cy], [0, 0, 1]]``.
        Any other key (:data:`FILE_KEYS`) is refused.
        """
        if not isinstance(d, dict):
            raise CameraError(f"{source}: must be a mapping, got {_show(d)}")
        problem = _unknown_keys(d)
        if problem:
            raise CameraError(f"{source}: {problem}")
        d = {k: v for k, v in d.items() if v is not None or k in ("width", "height", "height_m")}   # null: not given
        try:
            cam = cls._from_dict_intrinsics(d, source)
            if "horizon_row" in d:
                row = _number(d["horizon_row"], "horizon_row")
                if "pitch_rad" not in d and "pitch_deg" not in d:
                    if not 0 <= row <= cam.height - 1:
                        raise CameraError(f"horizon_row {row:.1f} px lies outside the image (0..{cam.height - 1})")
                    return replace(cam, pitch_rad=math.atan((cam.cy - row) / cam.fy))
                if abs(row - cam.horizon_row) > 1.0:
                    raise CameraError(f"horizon_row {row:.1f} px disagrees with the pitch, which puts the horizon "
                                      f"at {cam.horizon_row:.1f} px; give one of them")
            return cam
        except KeyError as e:
            raise CameraError(f"{source}: missing field {e.args[0]!r}") from None
        except CameraError as e:
            msg = str(e)
            raise CameraError(msg if msg.startswith(source) else f"{source}: {msg}") from None
        except (TypeError, ValueError, OverflowError) as e:   # OverflowError: int(inf)
            raise CameraError(f"{source}: {e}") from None

    @classmethod
    def _from_dict_intrinsics(cls, d: dict, source: str) -> "CameraModel":
        """:meth:`from_dict` without ``horizon_row`` (pitch 0 when no pitch field is given); its errors
        are given their one-line form by :meth:`from_dict`."""
        width, height = _pixels(d["width"], "width"), _pixels(d["height"], "height")
        n = {k: _number(d[k], k) for k in _FILE_NUMBERS if k in d}
        K = _matrix3(d["K"], "K") if "K" in d else None
        if K is not None:
            _intrinsic_matrix(K)
        pitch = n["pitch_rad"] if "pitch_rad" in n else math.radians(n.get("pitch_deg", 0.0))
        roll = n["roll_rad"] if "roll_rad" in n else math.radians(n.get("roll_deg", 0.0))
        mount = dict(height_m=n["height_m"], pitch_rad=pitch,
                     lateral_offset_m=n.get("lateral_offset_m", 0.0),
                     forward_offset_m=n.get("forward_offset_m", 0.0), roll_rad=roll)
        if "distortion" in d:
            mount["distortion"] = _distortion_list(d["distortion"])
        if K is not None:
            for name, (i, j) in (("fx", (0, 0)), ("fy", (1, 1)), ("cx", (0, 2)), ("cy", (1, 2))):
                # camera.json holds both: an edit to one of them alone must not pass unnoticed
                if name in n and not math.isclose(n[name], K[i, j], rel_tol=1e-9, abs_tol=1e-6):
                    raise CameraError(f"{name} {n[name]} disagrees with K[{i}][{j}] {K[i, j]}; give one of them")
            return cls(width, height, K[0, 0], K[1, 1], K[0, 2], K[1, 2], **mount)
        if "fx" in n:
            return cls(width, height, n["fx"], n.get("fy", n["fx"]),
                       n.get("cx", (width - 1) / 2), n.get("cy", (height - 1) / 2), **mount)
        if "hfov_deg" in n:
            return cls.from_fov(width, height, n["hfov_deg"], **mount)
        raise CameraError(f"{source}: needs K, fx/fy/cx/cy or hfov_deg")

    def save(self, path: str | Path) -> None:
        Path(path).write_text(json.dumps(self.to_dict(), indent=2))

    @classmethod
    def load(cls, path: str | Path) -> "CameraModel":
        """Read a camera from JSON (``camera.json``) or YAML."""
        from monorarp.core.readers import parse_json, parse_yaml, read_text

        path = Path(path)
        text = read_text(path, "camera file", CameraError)
        if path.suffix.lower() not in (".yaml", ".yml"):
            data = parse_json(text, path, "camera file", CameraError)
        else:
            try:
                data = parse_yaml(text, path, CameraError)
            except CameraError as e:
                raise CameraError(f"{path}: cannot parse camera file ({str(e).removeprefix(f'{path}: ')})") from None
        if not isinstance(data, dict):
            raise CameraError(f"{path}: camera file must hold a mapping")
        _check_file_size(data, path)
        return cls.from_dict(data, source=str(path))
