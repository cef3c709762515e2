"""Pure geometry of the KITTI evaluation (no files): the camera from a calibration, and the
rear-face distance and lateral offset of each labelled object.

Frames are :mod:`monorarp.core.camera`'s (camera: x right, y down, z forward; ego: x right, y ahead,
z up, origin at the camera); ``d_long`` / ``d_lat`` (m) as the ground truth defines them. The
mounting read from a calibration and the label geometry: docs/kitti.md.
"""

from __future__ import annotations

import math

import numpy as np

from monorarp.core.camera import CameraError, CameraModel

#: Velodyne axes (x forward, y left, z up) -> ego axes (x right, y ahead, z up) (as in harness.export.geometry).
R_EGO_FROM_VELO = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
#: Tolerance on the matrices of a calibration that holds the mounting (written with 12 significant digits).
MOUNT_TOL = 1e-6
KITTI_RIG_HEIGHT_M = 1.65


def intrinsics(P2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(K, t)`` of ``P2 = K [I | t]`` (K normalised to ``K[2, 2] = 1``); ValueError if P2 is not of that form."""
    P = np.asarray(P2, dtype=float).reshape(3, 4)
    K = P[:, :3]
    scale = abs(K[2, 2])
    if not (scale > 0 and K[0, 0] > 0 and K[1, 1] > 0):
        raise ValueError("P2 is not K [I | t] with positive focal lengths")
    if max(abs(K[1, 0]), abs(K[2, 0]), abs(K[2, 1])) > 1e-9 * max(K[0, 0], 1.0) \
            or abs(K[0, 1]) > 1e-6 * K[0, 0]:
        raise ValueError("P2's left 3x3 block is not an upper-triangular K without skew")
    K = K / K[2, 2]
    t = np.linalg.solve(K, P[:, 3] / P[2, 2])
    return K, t


def mounting_from_calib(calib: dict[str, np.ndarray]) -> dict[str, float] | None:
    """``height_m``, ``pitch_rad``, ``lateral_offset_m``, ``forward_offset_m`` where the calibration holds
    them (a ``monorarp export``'s, module docstring); None otherwise (a real rig's)."""
    R0 = calib.get("R0_rect", np.eye(3))
    tr, imu = calib.get("Tr_velo_to_cam"), calib.get("Tr_imu_to_velo")
    if tr is None or imu is None or np.abs(R0 - np.eye(3)).max() > MOUNT_TOL:
        return None
    if np.abs(tr[:, 3]).max() > MOUNT_TOL or np.abs(imu[:, :3] - np.eye(3)).max() > MOUNT_TOL:
        return None
    r = tr[:, :3] @ R_EGO_FROM_VELO.T                   # R_cam_from_ego
    pitch = math.atan2(-r[2, 2], r[2, 1])
    c, s = math.cos(pitch), math.sin(pitch)
    expected = np.array([[1.0, 0.0, 0.0], [0.0, -s, -c], [0.0, c, -s]])
    if np.abs(r - expected).max() > MOUNT_TOL or not -imu[2, 3] > 0:
        return None
    return {"height_m": float(-imu[2, 3]), "pitch_rad": pitch, "lateral_offset_m": float(imu[1, 3]),
            "forward_offset_m": float(-imu[0, 3])}


def camera_from_calib(calib: dict[str, np.ndarray], width: int, height: int, camera_height_m: float | None = None,
                      horizon_row: float | None = None, where: str = "calibration"
                      ) -> tuple[CameraModel, np.ndarray, dict]:
    """``(camera, t, info)``: the camera of an image of ``width x height`` px, the label-to-camera offset
    ``t`` (m) and where height and pitch came from. Options win over the calibration.

    Raises :class:`~monorarp.core.camera.CameraError` naming ``where`` when no height can be had or the
    result is impossible (e.g. the horizon outside the image), naming ``--horizon-row`` when that row is
    outside the image or gives a pitch beyond +-45 deg.
    """
    try:
        K, t = intrinsics(calib["P2"])
    except ValueError as e:
        raise CameraError(f"{where}: {e}") from None
    mount = mounting_from_calib(calib)
    info = {"mounting_in_calibration": mount is not None}
    kw = dict(mount or {})
    if camera_height_m is not None:
        kw["height_m"], info["height_source"] = float(camera_height_m), "--camera-height"
    elif mount is not None:
        info["height_source"] = "calibration (Tr_imu_to_velo)"
    else:
        raise CameraError(f"{where}: the calibration does not hold the camera's height above the road (its "
                          f"Tr_velo_to_cam/Tr_imu_to_velo are not a monorarp export's); give --camera-height M "
                          f"(KITTI's rig: {KITTI_RIG_HEIGHT_M})")
    if horizon_row is not None:
        row = float(horizon_row)
        if not 0 <= row <= height - 1:      # the option's fault, not the calibration's
            raise CameraError(f"--horizon-row: row {row:g} px lies outside the {width}x{height} image "
                              f"(0..{height - 1})")
        kw["pitch_rad"] = math.atan((K[1, 2] - row) / K[1, 1])
        if not abs(kw["pitch_rad"]) < math.radians(45):
            raise CameraError(f"--horizon-row: row {row:g} px puts the camera's pitch at "
                              f"{math.degrees(kw['pitch_rad']):.1f} deg with {where}'s cy {K[1, 2]:g} and "
                              f"fy {K[1, 1]:g} (at most +-45 deg)")
        info["pitch_source"] = "--horizon-row"
    elif mount is not None:
        info["pitch_source"] = "calibration (Tr_velo_to_cam)"
    else:
        kw["pitch_rad"] = 0.0
        info["pitch_source"] = "level camera (horizon at cy of P2)"
    try:
        cam = CameraModel(int(width), int(height), float(K[0, 0]), float(K[1, 1]), float(K[0, 2]), float(K[1, 2]),
                          **kw)
    except CameraError as e:
        raise CameraError(f"{where}: {e}") from None
    return cam, t, info


def heading_ego(rotation_y: np.ndarray, pitch_rad: float) -> np.ndarray:
    """(N, 2) unit ego-frame (x, y) direction of each label's length axis (module docstring)."""
    ry = np.asarray(rotation_y, dtype=float).reshape(-1)
    f = np.stack([np.cos(ry), -np.sin(ry) / math.cos(pitch_rad)], axis=-1)
    return f / np.linalg.norm(f, axis=-1, keepdims=True)


def footprints_ego(dimensions: np.ndarray, location: np.ndarray, rotation_y: np.ndarray, camera: CameraModel,
                   offset: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """``(corners, centre)``: (N, 4, 2) ego (x, y) footprint corners (m) and (N, 3) ego bottom-face centres.

    ``dimensions`` (N, 3) ``h, w, l``; ``location`` (N, 3) in the label frame; ``offset`` = ``t`` of
    :func:`intrinsics` (label frame -> camera frame).
    """
    dims = np.asarray(dimensions, dtype=float).reshape(-1, 3)
    loc = np.asarray(location, dtype=float).reshape(-1, 3) + (0.0 if offset is None else np.asarray(offset))
    centre = camera.cam_to_ego(loc)
    f = heading_ego(rotation_y, camera.pitch_rad)
    n = np.stack([-f[:, 1], f[:, 0]], axis=-1)
    sl = np.array([1.0, 1.0, -1.0, -1.0])[None, :, None]
    sw = np.array([1.0, -1.0, -1.0, 1.0])[None, :, None]
    corners = (centre[:, None, :2] + sl * (dims[:, None, 2:3] / 2) * f[:, None, :]
               + sw * (dims[:, None, 1:2] / 2) * n[:, None, :])
    return corners, centre


def rear_face_distance(dimensions, location, rotation_y, camera: CameraModel, offset=None
                       ) -> tuple[np.ndarray, np.ndarray]:
    """``(d_long, d_lat)`` (N,) in m: nearest footprint ``y`` and centre ``x`` in the ego frame."""
    corners, centre = footprints_ego(dimensions, location, rotation_y, camera, offset)
    return corners[..., 1].min(axis=1), centre[:, 0]


# ------------------------------------------------------------------------------ velocity
def finite_difference(frames: np.ndarray, t: np.ndarray, x: np.ndarray) -> np.ndarray:
    """(N,) d x / d t of one track's samples (sorted by frame): central differences between consecutive
    frames, one-sided at the ends of a run of consecutive frames, NaN for a run of one frame."""
    f, t, x = (np.asarray(a, dtype=float).reshape(-1) for a in (frames, t, x))
    n = len(f)
    out = np.full(n, np.nan)
    if n < 2:
        return out
    linked = np.diff(f) == 1                       # sample k and k+1 are consecutive frames
    prev_ok = np.r_[False, linked]
    next_ok = np.r_[linked, False]
    lo = np.where(prev_ok, np.arange(n) - 1, np.arange(n))
    hi = np.where(next_ok, np.arange(n) + 1, np.arange(n))
    ok = hi > lo
    with np.errstate(divide="ignore", invalid="ignore"):
        out[ok] = (x[hi[ok]] - x[lo[ok]]) / (t[hi[ok]] - t[lo[ok]])
    return out
