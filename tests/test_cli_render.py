"""``monorarp render`` end to end: the three output files, their schema, determinism, atomicity.

Renders a few frames of ``scenarios/static_distances.yaml`` at 320x180 (the
scenario file with its camera scaled down).
"""

from __future__ import annotations

import json
import math
import shutil
from pathlib import Path

import cv2
import numpy as np
import pytest
import yaml

from monorarp.core.camera import CameraModel
from monorarp.app.cli import main
from monorarp.app.video.writer import read_video
from synthetic import write_scenario

ROOT = Path(__file__).resolve().parents[1]
N_FRAMES = 5
W, H = 320, 180
NAMES = ["camera.json", "frames.mp4", "ground_truth.jsonl"]
OBJECT_KEYS = {"id", "box", "visibility", "d_long", "d_lat", "v_long", "v_lat", "ttc", "corners_cam"}


# Used only while scenarios/static_distances.yaml is not in the tree: the same idea in small.
FALLBACK_STATIC = {
    "name": "static_distances_small", "seed": 0, "duration_s": 2.0, "fps": 15,
    "road": {"lanes": 3}, "traffic": {"vehicles_count": 0},
    "ego": {"lane": 1, "speed_mps": 0.0},
    "vehicles": [
        {"name": "ahead_10", "lane": 0, "distance_m": 10, "behaviour": "stationary"},
        {"name": "left_15", "lane": -1, "distance_m": 15, "behaviour": "stationary"},
        {"name": "right_5", "lane": 1, "distance_m": 5, "behaviour": "stationary"},
        {"name": "ahead_60", "lane": 0, "distance_m": 60, "behaviour": "stationary"},
    ],
}


def _strict_json(text: str):
    def bad(name):
        raise ValueError(f"non-standard JSON constant {name}")
    return json.loads(text, parse_constant=bad)


def _small_scenario(tmp: Path) -> Path:
    """static_distances.yaml with its camera scaled to W x H (focal length scaled alike)."""
    shipped = ROOT / "scenarios" / "static_distances.yaml"
    data = yaml.safe_load(shipped.read_text()) if shipped.exists() else dict(FALLBACK_STATIC)
    cam = dict(data.get("camera") or {})
    scale = W / cam.get("width", 640)
    if cam.get("focal_px") is not None:
        cam["focal_px"] = cam["focal_px"] * scale
    cam.update(width=W, height=H)
    data["camera"] = cam
    return write_scenario(tmp / "small_static.yaml", data)


@pytest.fixture(scope="module")
def renders(tmp_path_factory):
    """The same scenario rendered twice into two directories (A, B)."""
    tmp = tmp_path_factory.mktemp("render")
    scen = _small_scenario(tmp)
    outs = []
    for name in ("A", "B"):
        out = tmp / "runs" / name  # parent "runs" does not exist yet for A
        rc = main(["render", str(scen), "--out", str(out), "--frames", str(N_FRAMES)])
        assert rc == 0
        outs.append(out)
    return scen, outs[0], outs[1]


def test_three_files_and_nothing_else(renders):
    _, a, _ = renders
    assert sorted(p.name for p in a.iterdir()) == NAMES
    assert sorted(p.name for p in a.parent.iterdir()) == ["A", "B"]  # no temp dirs left


def test_camera_json(renders):
    scen, a, _ = renders
    spec = yaml.safe_load(scen.read_text())["camera"]
    d = _strict_json((a / "camera.json").read_text())
    assert {"width", "height", "K", "height_m", "pitch_rad"} <= set(d)
    assert (d["width"], d["height"]) == (W, H)
    K = np.array(d["K"])
    # independent pinhole formula from the scenario's own numbers
    f = spec["focal_px"] if spec.get("focal_px") is not None else (W / 2) / math.tan(math.radians(spec.get("hfov_deg", 70.0)) / 2)
    np.testing.assert_allclose(K, [[f, 0, (W - 1) / 2], [0, f, (H - 1) / 2], [0, 0, 1]], rtol=1e-12)
    assert d["height_m"] == pytest.approx(spec.get("height_m", 1.3))
    assert d["pitch_rad"] == pytest.approx(math.radians(spec.get("pitch_deg", 2.0)))
    cam = CameraModel.load(a / "camera.json")
    np.testing.assert_allclose(cam.K, K)


def _records(path: Path) -> list[dict]:
    return [_strict_json(line) for line in path.read_text().splitlines()]


def test_ground_truth_schema(renders):
    scen, a, _ = renders
    fps = float(yaml.safe_load(scen.read_text()).get("fps", 15.0))
    cam = CameraModel.load(a / "camera.json")
    recs = _records(a / "ground_truth.jsonl")
    assert [r["frame"] for r in recs] == list(range(N_FRAMES))
    n_objects = 0
    for r in recs:
        assert r["t"] == pytest.approx(r["frame"] / fps, abs=1e-12)
        assert isinstance(r["ego"]["speed"], float) and r["ego"]["speed"] >= 0
        for o in r["objects"]:
            n_objects += 1
            assert OBJECT_KEYS <= set(o), OBJECT_KEYS - set(o)
            assert isinstance(o["id"], int) and o["id"] != 0
            x1, y1, x2, y2 = o["box"]
            assert -0.5 <= x1 < x2 <= W - 0.5 and -0.5 <= y1 < y2 <= H - 0.5
            assert 0 < o["visibility"] <= 1
            for k in ("d_long", "d_lat", "v_long", "v_lat"):
                assert isinstance(o[k], float) and math.isfinite(o[k])
            assert o["ttc"] is None or (isinstance(o["ttc"], float) and 0 <= o["ttc"] <= 10)
            corners = np.array(o["corners_cam"], dtype=float)
            assert corners.shape == (8, 3)
            if (corners[:, 2] > 0.5).all():
                # the visible box lies within the projection of the 3-D box (independent projection)
                uv, _ = cv2.projectPoints(corners, np.zeros(3), np.zeros(3), cam.K, None)
                uv = uv.reshape(-1, 2)
                assert x1 >= min(uv[:, 0].min(), W) - 1.0 and x2 <= max(uv[:, 0].max(), 0) + 1.0
                assert y1 >= min(uv[:, 1].min(), H) - 1.0 and y2 <= max(uv[:, 1].max(), 0) + 1.0
    assert n_objects > 0, "static_distances must show vehicles ahead"


def test_video_matches_ground_truth_and_renderer(renders):
    scen, a, _ = renders
    recs = _records(a / "ground_truth.jsonl")
    frames = list(read_video(a / "frames.mp4", size=(W, H)))
    assert len(frames) == len(recs) == N_FRAMES
    np.testing.assert_allclose([f.t for f in frames], [r["t"] for r in recs], atol=1e-3)
    # frame 0 decoded from the mp4 vs. the renderer's own BGR image: lossy but close, same channel order
    from harness.render.renderer import Renderer
    from harness.world.scenario import load_scenario
    from harness.simulation.simulator import simulate

    scenario = load_scenario(scen)
    with Renderer(scenario) as r:
        world = next(iter(simulate(scenario, n_frames=1)))
        img = r.render(world).image
    assert img.shape == frames[0].image.shape == (H, W, 3)
    err = np.abs(img.astype(int) - frames[0].image.astype(int)).mean(axis=(0, 1))
    assert (err < 4.0).all(), err
    swapped = np.abs(img[..., ::-1].astype(int) - frames[0].image.astype(int)).mean(axis=(0, 1))
    assert swapped.sum() > err.sum()


def test_deterministic(renders):
    _, a, b = renders
    assert (a / "ground_truth.jsonl").read_bytes() == (b / "ground_truth.jsonl").read_bytes()
    assert (a / "camera.json").read_bytes() == (b / "camera.json").read_bytes()
    fa = [f.image for f in read_video(a / "frames.mp4")]
    fb = [f.image for f in read_video(b / "frames.mp4")]
    assert len(fa) == len(fb) and all(np.array_equal(x, y) for x, y in zip(fa, fb))
    # the encoder is single-threaded and bit-exact: same frames -> same file
    assert (a / "frames.mp4").read_bytes() == (b / "frames.mp4").read_bytes()


def _snapshot(d: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(d.iterdir())}


def test_failure_mid_run_keeps_previous_run(renders, tmp_path, monkeypatch, capsys):
    scen, a, _ = renders
    out = tmp_path / "out"
    shutil.copytree(a, out)
    before = _snapshot(out)

    import harness.render.renderer as render_pkg

    original = render_pkg.Renderer.render
    calls = {"n": 0}

    def failing(self, world):
        calls["n"] += 1
        if calls["n"] > 2:
            raise RuntimeError("renderer died")
        return original(self, world)

    monkeypatch.setattr(render_pkg.Renderer, "render", failing)
    with pytest.raises(RuntimeError, match="renderer died"):
        main(["render", str(scen), "--out", str(out), "--frames", "4"])
    assert calls["n"] == 3
    assert _snapshot(out) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]  # no .out.tmp-* / .out.old-*

    # a successful run replaces the previous one as a whole
    monkeypatch.setattr(render_pkg.Renderer, "render", original)
    capsys.readouterr()
    assert main(["render", str(scen), "--out", str(out), "--frames", "2"]) == 0
    captured = capsys.readouterr()
    assert "rendered 2 frames" in captured.out and captured.err == ""  # no progress bar off a TTY
    assert sorted(p.name for p in out.iterdir()) == NAMES
    assert len(_records(out / "ground_truth.jsonl")) == 2
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]


def test_refuses_directory_with_foreign_files(renders, tmp_path, capsys):
    scen, _, _ = renders
    out = tmp_path / "mine"
    out.mkdir()
    (out / "notes.txt").write_text("keep me")
    rc = main(["render", str(scen), "--out", str(out), "--frames", "1"])
    err = capsys.readouterr().err
    assert rc == 2 and "notes.txt" in err and len(err.strip().splitlines()) == 1
    assert [p.name for p in out.iterdir()] == ["notes.txt"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["mine"]
