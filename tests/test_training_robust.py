"""The appearance-randomised detector: its style sampler and post-process, its ONNX start, the shipped file."""

from __future__ import annotations

import dataclasses

import cv2
import numpy as np
import pytest

from monorarp.pipeline.detectors import load_detector
from monorarp.detection.centernet import DEFAULT_MODEL, ROBUST_MODEL, RobustCenterNetDetector
from rendered_frame import first_frame
from training import appearance
from training.appearance import Style

# ------------------------------------------------------------------ style sampler


def test_training_draws_never_fall_in_the_heldout_family():
    rng = np.random.default_rng(0)
    train = [appearance.sample_training(rng) for _ in range(20000)]
    assert not any(appearance.is_heldout(s) for s in train)
    # each held-out mark lies outside what training draws reach, with a margin
    assert max(s.gamma for s in train) < appearance.HELDOUT_GAMMA_MIN - 0.05
    assert max(s.grade_mix for s in train) == 0.0
    assert max(s.body_sat[1] for s in train) < appearance.HELDOUT_BODY_SAT_MIN - 0.2
    assert max(appearance._tint(s.ground_gain) for s in train) < appearance.HELDOUT_TINT_MIN - 0.03
    assert max(appearance._tint(s.sky_gain) for s in train) < appearance.HELDOUT_TINT_MIN - 0.03


def test_heldout_draws_carry_every_mark():
    rng = np.random.default_rng(1)
    for s in (appearance.sample_heldout(rng) for _ in range(2000)):
        assert s.gamma >= appearance.HELDOUT_GAMMA_MIN and s.grade_mix >= appearance.HELDOUT_GRADE_MIN
        assert s.body_sat[0] >= appearance.HELDOUT_BODY_SAT_MIN
        assert min(appearance._tint(s.ground_gain), appearance._tint(s.sky_gain)) >= appearance.HELDOUT_TINT_MIN


def test_sampling_is_seeded():
    a = [appearance.sample_training(np.random.default_rng([3, k])) for k in range(5)]
    b = [appearance.sample_training(np.random.default_rng([3, k])) for k in range(5)]
    assert a == b and len({s.seed for s in a}) == 5


# ------------------------------------------------------------------ post-process

H, W, HORIZON = 90, 160, 40.0


def scene() -> tuple[np.ndarray, np.ndarray]:
    """A synthetic frame: sky above the horizon, grey road below, two painted 'vehicles' (ids 0, 3)."""
    rng = np.random.default_rng(5)
    img = np.empty((H, W, 3), np.uint8)
    img[:40] = (230, 190, 160)                    # BGR sky
    img[40:] = (100, 105, 110)                    # road
    img = np.clip(img + rng.integers(-8, 9, img.shape), 0, 255).astype(np.uint8)
    ids = np.full((H, W), -1, np.int32)
    ids[30:60, 20:60] = 0
    img[30:60, 20:60] = (40, 40, 170)             # red car
    ids[35:55, 100:130] = 3
    img[35:55, 100:130] = (150, 90, 30)           # blue car
    return img, ids


KNOBS = {   # knob -> (value, region it may change: "all", "veh", "sky", "ground")
    "gamma": (1.3, "all"), "contrast": (1.2, "all"), "saturation": (0.6, "all"),
    "white_balance": ((1.1, 1.0, 0.9), "all"), "grade_mix": (0.4, "all"), "vignette": (0.3, "all"),
    "body_hue_deg": (60.0, "veh"), "body_sat": ((0.4, 0.5), "veh"), "body_val": ((0.6, 0.7), "veh"),
    "ground_gain": ((1.1, 0.9, 1.0), "ground"), "ground_texture": (0.15, "ground"), "sky_gain": ((0.9, 1.1, 1.0), "sky"),
}


def test_neutral_style_leaves_the_frame_unchanged():
    img, ids = scene()
    assert np.array_equal(appearance.apply(Style(seed=1), img, ids, HORIZON), img)


@pytest.mark.parametrize("knob", KNOBS)
def test_each_knob_changes_its_region_only_and_is_deterministic(knob):
    img, ids = scene()
    value, region = KNOBS[knob]
    style = dataclasses.replace(Style(seed=7), **{knob: value})
    out = appearance.apply(style, img, ids, HORIZON)
    assert np.array_equal(out, appearance.apply(style, img, ids, HORIZON))
    changed = np.abs(out.astype(int) - img.astype(int)).max(axis=2) > 2
    veh = ids >= 0
    sky = ~veh & (np.arange(H)[:, None] < HORIZON)
    where = {"all": np.ones_like(veh), "veh": veh, "sky": sky, "ground": ~veh & ~sky}[region]
    assert changed[where].mean() > 0.3, f"{knob} changed {changed[where].mean():.2f} of its region"
    assert not changed[~where].any(), f"{knob} changed pixels outside its region"


def test_body_paint_differs_per_vehicle_and_per_seed():
    img, ids = scene()
    style = Style(seed=7, body_hue_deg=90.0)
    a = appearance.apply(style, img, ids, HORIZON)
    b = appearance.apply(dataclasses.replace(style, seed=8), img, ids, HORIZON)
    assert not np.array_equal(a[ids == 0], b[ids == 0])
    # each vehicle gets its own hue rotation: the two cars' rotations (circular, degrees) differ
    def hue(im: np.ndarray, v: int) -> float:
        return float(np.median(cv2.cvtColor(im.astype(np.float32) / 255, cv2.COLOR_BGR2HSV)[ids == v][:, 0]))

    turn = [(hue(a, v) - hue(img, v) + 180.0) % 360.0 - 180.0 for v in (0, 3)]
    assert abs(turn[0] - turn[1]) > 2.0 and max(map(abs, turn)) > 2.0


# ------------------------------------------------------------------ weights read back from ONNX


def test_onnx_weights_read_back_compute_the_same_outputs():
    torch = pytest.importorskip("torch")
    ort = pytest.importorskip("onnxruntime")
    from training.model import ExportWrapper
    from training.onnx_init import net_from_onnx

    net = ExportWrapper(net_from_onnx(DEFAULT_MODEL)).eval()
    x = np.random.default_rng(0).random((1, 3, 192, 320), dtype=np.float32)
    sess = ort.InferenceSession(str(DEFAULT_MODEL), providers=["CPUExecutionProvider"])
    o_hm, o_lt = sess.run(["heatmap", "ltrb"], {"image": x})
    with torch.no_grad():
        t_hm, t_lt = (t.numpy() for t in net(torch.from_numpy(x)))
    assert np.abs(t_hm - o_hm).max() < 1e-4 and np.abs(t_lt - o_lt).max() < 1e-2
    assert np.abs(o_lt).max() > 10          # not a trivially zero graph


# ------------------------------------------------------------------ the shipped alternative model


def test_robust_model_is_small_registered_and_finds_a_rendered_vehicle():
    from monorarp.core.boxes import iou

    assert ROBUST_MODEL.stat().st_size <= 10_000_000
    scen, image, truth = first_frame({
        "name": "robust_check", "seed": 3, "duration_s": 1.0, "fps": 15.0, "road": {"lanes": 3},
        "ego": {"lane": 1, "speed_mps": 25.0}, "traffic": {"vehicles_count": 1, "density": 0.2},
        "vehicles": [{"name": "lead", "lane": 0, "distance_m": 15.0, "speed_mps": 25.0, "behaviour": "constant_speed"}],
        "camera": {"width": 640, "height": 360, "hfov_deg": 70, "height_m": 1.4, "pitch_deg": 1.0},
        "conditions": {"time_of_day": "dusk", "fog_visibility_m": 150.0}})
    det = load_detector("centernet_robust", camera=scen.camera.model())
    assert isinstance(det, RobustCenterNetDetector) and det.path == ROBUST_MODEL
    lead = min((o for o in truth.objects if abs(o.d_lat) < 1.0), key=lambda o: o.d_long)
    assert 13.0 < lead.d_long < 17.0
    boxes = np.array([d.box for d in det.detect(image)], float).reshape(-1, 4)
    assert len(boxes) and iou(boxes, np.array(lead.box, float)[None]).max() >= 0.7
