"""Light, weather and lens conditions (harness/render/effects.py): default path untouched,
fog against Koschmieder's closed form on a flat target at a known range, lamps, motion blur,
JPEG, determinism, bad input (one line, exit 2)."""

from __future__ import annotations

import math
from pathlib import Path

import cv2
import numpy as np
import pytest

from harness.render import effects
from harness.render.meshes import vehicle_color
from harness.render.renderer import Renderer
from harness.world.scenario import ScenarioError, load_scenario, parse_scenario
from harness.world.state import VehicleState, WorldState
from monorarp.app.cli import main

LANE_W = 4.0
W, H = 320, 180


def _scenario(conditions=None, **extra):
    d = {"name": "c", "seed": 5, "road": {"lanes": 3, "lane_width_m": LANE_W},
         "camera": {"width": W, "height": H, "hfov_deg": 70, "height_m": 1.3, "pitch_deg": 2.0,
                    "forward_offset_m": 0.5}, **extra}
    if conditions is not None:
        d["conditions"] = conditions
    return parse_scenario(d)


EGO = VehicleState(0, 100.0, LANE_W, 0.0, 25.0, 25.0, 0.0, 1, 5.0, 2.0)
CARS = (VehicleState(1, 118.0, LANE_W, 0.0, 25.0, 25.0, 0.0, 1, 4.6, 1.9),
        VehicleState(2, 125.0, 0.0, 0.0, 22.0, 22.0, 0.0, 0, 4.4, 1.8),
        VehicleState(3, 150.0, 2 * LANE_W, 0.0, 22.0, 22.0, 0.0, 2, 12.0, 2.5))


def _world(vehicles=CARS, frame=3, ego=EGO):
    return WorldState(frame, frame / 15, ego, tuple(vehicles))


def _render(conditions, world=None, **extra):
    with Renderer(_scenario(conditions, **extra)) as r:
        return r.render(world or _world())


# ------------------------------------------------------------------ default path
@pytest.mark.parametrize("neutral", [{}, {"time_of_day": "day", "rain": 0.0, "headlights": False}])
def test_no_or_neutral_conditions_render_identical_frames(neutral):
    ref = _render(None)
    f = _render(neutral)
    assert f.image.tobytes() == ref.image.tobytes()
    assert f.id_mask.tobytes() == ref.id_mask.tobytes()


def test_every_effect_deterministic_and_truth_unchanged():
    allc = {"time_of_day": "dusk", "fog_visibility_m": 80.0, "rain": 0.7, "exposure_s": 0.02,
            "readout_s": 0.02, "jpeg_quality": 50}
    ref = _render(None)
    a, b = _render(allc), _render(allc)
    assert a.image.tobytes() == b.image.tobytes()
    assert a.image.tobytes() != ref.image.tobytes()
    assert a.id_mask.tobytes() == ref.id_mask.tobytes()          # fog/darkness never hide a vehicle from the truth
    assert a.full_pixels == ref.full_pixels
    c = _render(allc, world=_world(frame=4))                       # rain streaks are seeded per frame
    assert not np.array_equal(c.image, a.image)


# ------------------------------------------------------------------ fog = Koschmieder
def _dark_truck_id() -> int:
    """A vehicle id whose paint is dark (strong contrast against the fog) in palette 0."""
    return next(i for i in range(1, 200) if sum(vehicle_color(0, i)) < 200)


@pytest.mark.parametrize("d_rear", [15.0, 30.0, 60.0])
def test_fog_contrast_follows_koschmieder_on_flat_target(d_rear):
    """Rear face of a truck straight ahead at camera-to-face distance ``d_rear``: linear contrast
    against the airlight falls as exp(-3.912 r / V), r the range along the pixel's ray, found
    from the camera model (not from the depth buffer) by intersecting the ray with the face's plane."""
    sc = _scenario()
    cam = sc.camera.model()
    length = 12.0
    x = EGO.x + sc.camera.forward_offset_m + d_rear + length / 2
    truck = VehicleState(_dark_truck_id(), x, EGO.y, 0.0, 0.0, 0.0, 0.0, 1, length, 2.5)
    world = _world((truck,))
    # centre of the cargo box's rear face (z 1.1..3.6 m above the ground), projected with cv2
    p_ego = np.array([[0.0, d_rear, -cam.height_m + 2.3]])
    uv, _ = cv2.projectPoints(cam.ego_to_cam(p_ego).reshape(-1, 1, 3), np.zeros(3), np.zeros(3), cam.K, None)
    u, v = np.rint(uv.reshape(2)).astype(int)
    ray_cam = np.linalg.inv(cam.K) @ np.array([u, v, 1.0])
    ray_ego = cam.R_cam_from_ego.T @ (ray_cam / np.linalg.norm(ray_cam))
    rng = d_rear / ray_ego[1]
    clear = _render(None, world)
    i0 = effects.to_linear(clear.image[v, u]).astype(float)
    assert clear.id_mask[v, u] == truck.id
    airlight = np.asarray(effects.FOG_RGB[::-1]) ** effects.GAMMA
    ch = int(np.argmax(np.abs(i0 - airlight)))
    assert abs(i0[ch] - airlight[ch]) > 0.3
    for vis in (50.0, 100.0, 300.0):
        fog = _render({"fog_visibility_m": vis}, world)
        i = effects.to_linear(fog.image[v, u]).astype(float)
        t_meas = (i[ch] - airlight[ch]) / (i0[ch] - airlight[ch])
        t_true = math.exp(-3.912 * rng / vis)
        assert abs(t_meas - t_true) < 0.015, (vis, t_meas, t_true)


def test_fog_sky_is_airlight_and_visibility_only_reduces_contrast():
    sky_px = (5, W // 2)
    near = _render({"fog_visibility_m": 400.0})
    far = _render({"fog_visibility_m": 60.0})
    want = np.rint(255 * np.asarray(effects.FOG_RGB[::-1])).astype(int)
    assert np.abs(far.image[sky_px].astype(int) - want).max() <= 1
    clear = _render(None)
    # the road at the bottom of the image: its contrast to the airlight shrinks as V drops
    a = np.asarray(effects.FOG_RGB[::-1]) ** effects.GAMMA
    dev = [np.abs(effects.to_linear(f.image[-5:, :]) - a).mean() for f in (clear, near, far)]
    assert dev[0] > dev[1] > dev[2]


# ------------------------------------------------------------------ light
def test_night_headlights_light_the_road_ahead_and_tail_lamps_glow():
    on = _render({"time_of_day": "night"}, world=_world(()))
    off = _render({"time_of_day": "night", "headlights": False}, world=_world(()))
    cam = _scenario().camera.model()
    uv, _ = cv2.projectPoints(cam.ego_to_cam(np.array([[0.0, 15.0, -cam.height_m]])).reshape(-1, 1, 3),
                              np.zeros(3), np.zeros(3), cam.K, None)
    u, v = np.rint(uv.reshape(2)).astype(int)
    assert on.image[v, u].astype(int).sum() > off.image[v, u].astype(int).sum() + 30
    assert np.array_equal(on.image[:20], off.image[:20])            # the sky is not lit
    lamps = _render({"time_of_day": "night"})
    red = (lamps.image[..., 2] > 200) & (lamps.image[..., 1] < 120)
    assert red.any() and (lamps.id_mask[red] >= 0).all()             # lit tail lamps sit on vehicles


def test_dusk_and_night_darker_than_day():
    means = [_render(c).image.mean() for c in (None, {"time_of_day": "dusk"}, {"time_of_day": "night"})]
    assert means[0] > means[1] > means[2]


# ------------------------------------------------------------------ lens
def test_motion_blur_leaves_a_vehicle_at_ego_speed_sharp_and_smears_the_road():
    sharp = _render(None)
    blur = _render({"exposure_s": 0.03})
    same_speed = sharp.id_mask == 1                                  # CARS[0] moves at the ego's speed
    inner = cv2.erode(same_speed.astype(np.uint8), np.ones((5, 5), np.uint8)).astype(bool)
    assert inner.sum() > 50
    assert np.abs(blur.image[inner].astype(int) - sharp.image[inner].astype(int)).max() <= 1
    cam = _scenario().camera.model()
    road = (sharp.id_mask < 0) & (np.arange(H)[:, None] > cam.horizon_row + 5)
    diff = np.abs(blur.image[road].astype(int) - sharp.image[road].astype(int)).max(axis=1)
    assert diff.max() > 20 and (diff > 2).mean() > 0.02             # marking edges smeared along the flow
    parked = _render({"exposure_s": 0.03}, world=_world(
        tuple(VehicleState(c.id, c.x, c.y, 0, 0, 0, 0, c.lane, c.length, c.width) for c in CARS),
        ego=VehicleState(0, 100.0, LANE_W, 0.0, 0.0, 0.0, 0.0, 1, 5.0, 2.0)))
    still = _render(None, world=_world(
        tuple(VehicleState(c.id, c.x, c.y, 0, 0, 0, 0, c.lane, c.length, c.width) for c in CARS),
        ego=VehicleState(0, 100.0, LANE_W, 0.0, 0.0, 0.0, 0.0, 1, 5.0, 2.0)))
    assert np.abs(parked.image.astype(int) - still.image.astype(int)).max() <= 1   # nothing moves: no blur


def test_jpeg_is_cv2_round_trip_of_the_frame():
    plain = _render({"rain": 0.5})
    jpg = _render({"rain": 0.5, "jpeg_quality": 30})
    ok, buf = cv2.imencode(".jpg", plain.image, [cv2.IMWRITE_JPEG_QUALITY, 30])
    assert np.array_equal(jpg.image, cv2.imdecode(buf, cv2.IMREAD_COLOR))


# ------------------------------------------------------------------ bad input
BAD = [
    ("negative_visibility", "name: x\nconditions:\n  fog_visibility_m: -50\n", ["conditions.fog_visibility_m", "greater than 0"]),
    ("zero_visibility", "name: x\nconditions: {fog_visibility_m: 0}\n", ["conditions.fog_visibility_m"]),
    ("rain_above_one", "name: x\nconditions: {rain: 1.5}\n", ["conditions.rain", "less than or equal to 1"]),
    ("time_of_day", "name: x\nconditions: {time_of_day: midnight}\n", ["conditions.time_of_day", "night"]),
    ("negative_exposure", "name: x\nconditions: {exposure_s: -0.01}\n", ["conditions.exposure_s"]),
    ("jpeg_quality", "name: x\nconditions: {jpeg_quality: 0}\n", ["conditions.jpeg_quality"]),
    ("unknown_key", "name: x\nconditions: {snow: 1}\n", ["conditions.snow", "Extra inputs"]),
]


@pytest.mark.parametrize("case_id,text,needles", BAD, ids=[b[0] for b in BAD])
def test_impossible_conditions_one_line_exit_2(tmp_path, capsys, case_id, text, needles):
    path = tmp_path / f"{case_id}.yaml"
    path.write_text(text)
    out = tmp_path / "out"
    rc = main(["render", str(path), "--out", str(out)])
    err = capsys.readouterr().err
    assert rc == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err
    for needle in needles:
        assert needle in lines[0], (needle, lines[0])
    assert not out.exists()
    with pytest.raises(ScenarioError):
        load_scenario(path)


def test_shipped_light_weather_sweep_expands():
    from harness.sweep.expand import load_and_expand

    exp = load_and_expand(Path(__file__).resolve().parent.parent / "scenarios/conditions/light_weather.yaml")
    assert len(exp.tasks) == 128 and all(t.error is None for t in exp.tasks)
    tods = {t.scenario["conditions"]["time_of_day"] for t in exp.tasks}
    assert tods == {"day", "low_sun", "dusk", "night"}


def test_linear_depth_inverts_the_opengl_projection():
    n, f = 0.05, 6000.0
    z = np.array([0.5, 3.0, 40.0, 100.0, 400.0], dtype=np.float64)
    # window depth of a point at z under glFrustum-style projection (closed form)
    d = (f + n - 2 * f * n / z) / (f - n) * 0.5 + 0.5
    got = effects.linear_depth(np.append(d, 1.0).astype(np.float32), n, f)
    assert np.allclose(got[:-1], z, rtol=2e-3) and got[-1] == 0.0


def test_axis_table_means_per_value_and_variant():
    from harness.sweep.axes import axis_section, axis_table

    rows = [{"id": str(i), "variant": var, "status": "ok", "grid": {"conditions.fog_visibility_m": fog, "x": x},
             "metrics": {"detection.recall": rec}}
            for i, (var, fog, x, rec) in enumerate([("a", None, 1, 1.0), ("a", None, 2, 0.8), ("a", 100.0, 1, 0.4),
                                                    ("a", 100.0, 2, 0.2), ("b", None, 1, 0.5), ("b", 100.0, 1, None)])]
    t = axis_table(rows, "conditions.fog_visibility_m", "detection.recall")
    assert t["a"] == [(None, pytest.approx(0.9)), (100.0, pytest.approx(0.3))]
    assert t["b"] == [(None, 0.5), (100.0, None)]
    html = axis_section(rows, ["conditions.fog_visibility_m", "x"], ["detection.recall"])
    assert html.count("<img") == 2
    html = axis_section(rows, ["x"], ["detection.recall", "ttc.warning.precision"])   # null in every run: a note
    assert html.count("<img") == 1
    failed = [{**r, "status": "failed", "metrics": {}} for r in rows]
    html = axis_section(failed, ["x"], ["detection.recall"])
    assert "No finished run" in html and "<img" not in html
