"""Camera motion: the seeded pose model, the scenario block's validation, and the renderer's
moved camera checked against cv2.projectPoints and the sky/road boundary with the true pose."""

from __future__ import annotations

import math
from dataclasses import replace

import cv2
import numpy as np
import pytest

from harness.world.camera_motion import CameraMotion, CameraMotionModel
from harness.world.ground_truth import frame_truth
from harness.world.geometry import vehicle_pose_world
from harness.render.meshes import vehicle_trimesh
from harness.render.renderer import Renderer
from harness.render.shading import SKY_RGB
from harness.world.scenario import ScenarioError, parse_scenario
from harness.world.state import VehicleState, WorldState
from monorarp.core.camera import CameraModel

NOMINAL = CameraModel.from_fov(640, 360, 70.0, 1.3, math.radians(2.0))


def _model(seed=3, **block):
    return CameraMotionModel(CameraMotion.model_validate(block), NOMINAL, 15.0, seed)


def _poses(model, n, speeds=None):
    speeds = np.full(n, 25.0) if speeds is None else speeds
    return np.array([model.pose_deg(k, s) for k, s in enumerate(speeds)])


VIB = {"vibration": {"pitch_amplitude_deg": 0.5, "roll_amplitude_deg": 0.3, "band_hz": [1.0, 3.0]}}


def test_same_seed_same_poses_other_seed_others():
    a, b = _poses(_model(**VIB), 60), _poses(_model(**VIB), 60)
    assert np.array_equal(a, b)
    assert not np.allclose(a, _poses(_model(seed=4, **VIB), 60))
    assert np.array_equal(_poses(_model(**VIB), 20), a[:20])          # a prefix does not change


def test_vibration_bounded_and_in_band():
    model = _model(**VIB)
    t = np.arange(15 * 120) / 15.0
    vib = model.vibration_deg(t)
    assert np.abs(vib[:, 0]).max() <= 0.5 + 1e-12 and np.abs(vib[:, 1]).max() <= 0.3 + 1e-12
    assert np.abs(vib[:, 0]).max() > 0.35                                  # it does reach near its peak
    spec = np.abs(np.fft.rfft(vib[:, 0]))
    freqs = np.fft.rfftfreq(len(t), 1 / 15.0)
    top = freqs[np.argsort(spec)[-2:]]
    assert ((top >= 0.99) & (top <= 3.01)).all()
    # RMS of a sum of 2 equal sinusoids of peak-sum A: A / 2
    assert np.sqrt((vib[:, 0] ** 2).mean()) == pytest.approx(0.25, rel=0.05)


def test_mount_error_constant_and_suspension_pitches_down_when_braking():
    still = _poses(_model(mount={"pitch_deg": 0.4, "roll_deg": -0.2}), 10)
    assert np.allclose(still, [0.4, -0.2])
    k = 0.1
    speeds = np.concatenate([np.full(5, 25.0), 25.0 - 6.0 * np.arange(1, 76) / 15.0])   # brake at 6 m/s^2
    p = _poses(_model(suspension={"pitch_deg_per_mps2": k, "natural_hz": 1.5, "damping_ratio": 0.7}), 80, speeds)
    assert np.allclose(p[:5, 0], 0.0) and p[5, 0] > 0
    assert p[10, 0] > 0.2                                                  # nose (and camera) down
    assert p[-1, 0] == pytest.approx(k * 6.0, abs=0.01)                    # settles at the static pitch
    assert p[:, 0].max() < 2 * k * 6.0


def test_frames_must_come_in_order():
    m = _model(**VIB)
    m.pose_deg(0, 25.0)
    with pytest.raises(ValueError, match="in order"):
        m.pose_deg(2, 25.0)


def _scenario_dict(pitch_deg=3.0, **motion):
    return {"name": "m", "seed": 5, "camera": {"width": 320, "height": 180, "hfov_deg": 70, "height_m": 1.4,
                                             "pitch_deg": pitch_deg}, "camera_motion": motion}


@pytest.mark.parametrize("motion, field", [
    # vertical half-FOV 21.5 deg at 320x180, 70 deg HFOV: the horizon leaves the image beyond it
    ({"pitch_deg": 15.0, "vibration": {"pitch_amplitude_deg": 7.0}}, "camera_motion.vibration.pitch_amplitude_deg"),
    ({"pitch_deg": -15.0, "mount": {"pitch_deg": -7.0}}, "camera_motion.mount.pitch_deg"),
    ({"pitch_deg": 15.0, "suspension": {"pitch_deg_per_mps2": 0.3}}, "camera_motion.suspension.pitch_deg_per_mps2"),
    ({"vibration": {"pitch_amplitude_deg": 0.5, "band_hz": [1.0, 9.0]}}, "camera_motion.vibration.band_hz"),
    ({"vibration": {"band_hz": [3.0, 1.0]}}, "band_hz"),
    ({"vibration": {"pitch_amplitude_deg": -0.5}}, "camera_motion.vibration.pitch_amplitude_deg"),
    ({"suspension": {"natural_hz": 0}}, "camera_motion.suspension.natural_hz"),
    ({"wobble": 1}, "camera_motion.wobble"),
])
def test_impossible_motion_rejected_naming_the_field(motion, field):
    with pytest.raises(ScenarioError) as e:
        parse_scenario(_scenario_dict(**motion), "s.yaml")
    msg = str(e.value)
    assert "\n" not in msg
    assert field in msg and msg.startswith("s.yaml")


def test_motion_within_the_image_accepted():
    s = parse_scenario(_scenario_dict(pitch_deg=15.0, vibration={"pitch_amplitude_deg": 6.0}))
    assert s.camera_motion.vibration.pitch_amplitude_deg == 6.0


def test_no_block_is_the_still_camera():
    s = parse_scenario({"name": "m"})
    assert s.camera_motion is None


# ------------------------------------------------------------------ rendering
LANE_W = 3.7
EGO = VehicleState(0, 100.0, LANE_W, 0.0, 25.0, 25.0, 0.0, 1, 5.0, 2.0)
CARS = (VehicleState(1, 118.0, LANE_W, 0.0, 20.0, 20.0, 0.0, 1, 4.6, 1.9),
        VehicleState(2, 125.0, 0.0, 0.02, 22.0, 22.0, 0.4, 0, 4.4, 1.8))


def _moving_scenario():
    d = _scenario_dict(mount={"pitch_deg": 0.8, "roll_deg": 1.5},
                       vibration={"pitch_amplitude_deg": 1.0, "roll_amplitude_deg": 1.0, "band_hz": [1.0, 3.0]})
    d["road"] = {"lanes": 3, "lane_width_m": LANE_W}
    return parse_scenario(d)


@pytest.fixture(scope="module")
def moved_frames():
    s = _moving_scenario()
    out = []
    with Renderer(s) as r:
        for k in range(4):
            w = WorldState(k, k / s.fps, EGO, CARS if k % 2 else ())
            f = r.render(w)
            out.append((w, f, frame_truth(w, r.camera, f), r.camera))
    return out


def test_truth_carries_the_true_pose(moved_frames):
    poses = []
    for w, f, truth, nominal in moved_frames:
        cam = truth.camera
        assert cam.pitch_rad == pytest.approx(f.camera.pitch_rad)
        assert cam.pitch_offset_rad == pytest.approx(f.camera.pitch_rad - nominal.pitch_rad)
        assert cam.horizon_offset_px == pytest.approx(cam.horizon_row - nominal.horizon_row)
        poses.append((cam.pitch_rad, cam.roll_rad))
    assert len(set(poses)) == len(poses)                           # it moves from frame to frame
    assert abs(poses[0][1]) > math.radians(0.4)


def _rotation_independent(pitch: float, roll: float) -> np.ndarray:
    """Ego (x right, y ahead, z up) -> OpenCV camera, built from cv2.Rodrigues axis-angle rotations."""
    level = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])
    # Camera axes turned down by `pitch` (z towards y), then about the optical axis by `roll` (x towards y,
    # the right side dips): point coordinates change by Rx(pitch), then by Rz(-roll).
    r_pitch, _ = cv2.Rodrigues(np.array([pitch, 0.0, 0.0]))
    r_roll, _ = cv2.Rodrigues(np.array([0.0, 0.0, -roll]))
    return r_roll @ r_pitch @ level


def _filled(uv: np.ndarray, faces: np.ndarray, shape) -> np.ndarray:
    """Pixels whose centre (integer coordinates) lies inside any projected triangle (the rasteriser's rule)."""
    mask = np.zeros(shape, bool)
    for tri in uv[faces]:
        (x0, y0), (x1, y1), (x2, y2) = tri
        area = (x1 - x0) * (y2 - y0) - (x2 - x0) * (y1 - y0)
        if abs(area) < 1e-12:
            continue
        c0, r0 = max(math.ceil(tri[:, 0].min()), 0), max(math.ceil(tri[:, 1].min()), 0)
        c1, r1 = min(math.floor(tri[:, 0].max()), shape[1] - 1), min(math.floor(tri[:, 1].max()), shape[0] - 1)
        if c1 < c0 or r1 < r0:
            continue
        yy, xx = np.mgrid[r0:r1 + 1, c0:c1 + 1].astype(float)
        w0 = ((x1 - xx) * (y2 - yy) - (x2 - xx) * (y1 - yy)) / area
        w1 = ((x2 - xx) * (y0 - yy) - (x0 - xx) * (y2 - yy)) / area
        inside = (w0 >= 0) & (w1 >= 0) & (1 - w0 - w1 >= 0)
        mask[r0:r1 + 1, c0:c1 + 1] |= inside
    return mask


def test_silhouettes_where_cv2_projects_with_the_true_pose(moved_frames):
    """Each vehicle's id-pass silhouette against its mesh projected by cv2.projectPoints with the
    true pose (rotation built from cv2.Rodrigues): extremes within a pixel (slanted edges under roll
    leave the extreme vertex's own pixel uncovered), IoU of the filled triangles >= 0.95; the
    nominal pose does not fit."""
    checked = 0
    for w, f, truth, nominal in moved_frames:
        if not w.vehicles:
            continue
        R = _rotation_independent(truth.camera.pitch_rad, truth.camera.roll_rad)
        rvec, _ = cv2.Rodrigues(R)
        rvec_nominal, _ = cv2.Rodrigues(_rotation_independent(nominal.pitch_rad, 0.0))
        for v in w.vehicles:
            tm = vehicle_trimesh(v.length, v.width, (0, 0, 0))
            pose = vehicle_pose_world(v)
            pw = tm.vertices @ pose[:3, :3].T + pose[:3, 3]
            cam_x, cam_y = EGO.x + nominal.forward_offset_m, EGO.y
            p_ego = np.stack([-pw[:, 1] - cam_y, pw[:, 0] - cam_x, pw[:, 2] - nominal.height_m], axis=1)
            uv = cv2.projectPoints(p_ego.reshape(-1, 1, 3), rvec, np.zeros(3), nominal.K, None)[0].reshape(-1, 2)
            rows, cols = np.nonzero(f.id_mask == v.id)
            for lo, got in ((uv[:, 0].min(), cols.min()), (uv[:, 1].min(), rows.min())):
                assert math.ceil(lo) <= got <= math.ceil(lo) + 1, (v.id, lo, got)
            for hi, got in ((uv[:, 0].max(), cols.max()), (uv[:, 1].max(), rows.max())):
                assert math.floor(hi) - 1 <= got <= math.floor(hi), (v.id, hi, got)
            rendered = f.id_mask == v.id
            ious = []
            for rv in (rvec, rvec_nominal):
                uv_k = cv2.projectPoints(p_ego.reshape(-1, 1, 3), rv, np.zeros(3), nominal.K, None)[0].reshape(-1, 2)
                filled = _filled(uv_k, tm.faces, rendered.shape)
                ious.append((filled & rendered).sum() / (filled | rendered).sum())
            assert ious[0] >= 0.95 and ious[1] < 0.9, (v.id, ious)
            # the truth's 3-D box corners are in the true camera frame
            corners = np.asarray(next(o for o in truth.objects if o.id == v.id).corners_cam)
            assert np.allclose(f.camera.project_cam(corners),
                               cv2.projectPoints(f.camera.cam_to_ego(corners).reshape(-1, 1, 3), rvec,
                                                 np.zeros(3), nominal.K, None)[0].reshape(-1, 2), atol=1e-4)
            checked += 1
    assert checked >= 4


def test_rendered_horizon_is_the_true_tilted_one(moved_frames):
    """Sky/road boundary per column = the true horizon line (through the forward vanishing point,
    slope -tan(roll) in the image), not the nominal row."""
    sky = np.round(np.array(SKY_RGB[::-1]) * 255)
    for w, f, truth, nominal in moved_frames:
        if w.vehicles:
            continue
        cam = f.camera
        R = _rotation_independent(cam.pitch_rad, cam.roll_rad)
        vp = nominal.K @ R @ np.array([0.0, 1.0, 0.0])
        u0, v0 = vp[:2] / vp[2]
        assert v0 == pytest.approx(truth.camera.horizon_row, abs=1e-6)
        off_nominal = []
        for col in (40, 160, 280):
            is_sky = np.abs(f.image[:, col].astype(int) - sky).max(axis=1) <= 2
            boundary = np.argmin(is_sky) - 0.5                     # first non-sky row's upper edge
            expect = v0 - (col - u0) * math.tan(cam.roll_rad) * nominal.fy / nominal.fx
            assert boundary == pytest.approx(expect, abs=1.5), col
            off_nominal.append(abs(boundary - nominal.horizon_row))
        assert max(off_nominal) > 2.5                                # the nominal horizon does not fit


def test_camera_roll_in_files_and_horizon_row():
    cam = CameraModel.from_dict({"width": 640, "height": 360, "hfov_deg": 70, "height_m": 1.3,
                                 "pitch_deg": 2.0, "roll_deg": 1.5})
    assert cam.roll_rad == pytest.approx(math.radians(1.5))
    assert CameraModel.from_dict(cam.to_dict()) == cam
    assert "roll_rad" not in NOMINAL.to_dict()
    vp = cam.K @ cam.R_cam_from_ego @ np.array([0.0, 1.0, 0.0])          # forward vanishing point
    assert vp[1] / vp[2] == pytest.approx(cam.horizon_row, abs=1e-9)
    with pytest.raises(Exception, match="roll"):
        replace(NOMINAL, roll_rad=math.radians(40))
