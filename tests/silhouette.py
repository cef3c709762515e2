"""Shared check of the road-geometry tests: a rendered vehicle's id-pass silhouette against cv2.projectPoints."""

from __future__ import annotations

import math

import cv2
import numpy as np


def rot_ego_to_cv(pitch: float) -> np.ndarray:
    """Rotation from the ego frame (x right, y ahead, z up) to OpenCV's camera frame, pitched down by ``pitch``."""
    level = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])
    r_pitch, _ = cv2.Rodrigues(np.array([pitch, 0.0, 0.0]))
    return r_pitch @ level


def assert_silhouette(camera, world_vertices: np.ndarray, cam_w: np.ndarray, r_ego: np.ndarray, frame,
                      truth_object) -> np.ndarray:
    """Project the vehicle's world-frame mesh vertices (W: X ahead, Y left, Z up) through the camera at
    ``cam_w`` on the ego body ``r_ego`` with cv2.projectPoints; assert the id mask's extremes (vehicle
    id 1) lie within a pixel of them and the truth box is the silhouette's. Returns the vertices in
    the ego frame (m)."""
    body = (world_vertices - cam_w) @ r_ego                       # ego body: X ahead, Y left, Z up
    p_ego = np.stack([-body[:, 1], body[:, 0], body[:, 2]], axis=1)
    rvec, _ = cv2.Rodrigues(rot_ego_to_cv(camera.pitch_rad))
    uv = cv2.projectPoints(p_ego.reshape(-1, 1, 3), rvec, np.zeros(3), camera.K, None)[0].reshape(-1, 2)
    rows, cols = np.nonzero(frame.id_mask == 1)
    assert rows.size > 50
    for lo, got in ((uv[:, 0].min(), cols.min()), (uv[:, 1].min(), rows.min())):
        assert math.ceil(lo) <= got <= math.ceil(lo) + 1, (lo, got)
    for hi, got in ((uv[:, 0].max(), cols.max()), (uv[:, 1].max(), rows.max())):
        assert math.floor(hi) - 1 <= got <= math.floor(hi), (hi, got)
    assert truth_object.box == (cols.min() - 0.5, rows.min() - 0.5, cols.max() + 0.5, rows.max() + 0.5)
    return p_ego
