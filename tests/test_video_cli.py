"""``monorarp video`` / ``calibrate-horizon`` on clips rendered by the harness, and every bad input.

A 320x180 version of ``scenarios/highway_cruise.yaml`` is rendered with
``monorarp render`` (20 frames); ``monorarp video`` runs on its frames.mp4 with
its camera.json. References: the scenario's frame rate and ground truth
(``ground_truth.jsonl``), OpenCV's own decoder, ffmpeg-written variable-frame-rate
files with chosen timestamps, ``cv2.projectPoints`` for the horizon row.
"""

from __future__ import annotations

import json
import math
import shutil
import subprocess
from pathlib import Path

import cv2
import numpy as np
import pytest
import yaml

from monorarp.core.camera import CameraError, CameraModel
from monorarp.app.cli import main
from monorarp.horizon.vanishing import estimate_horizon, vanishing_point
from monorarp.app.video.run import _opencv_gui
from monorarp.app.video.source import VideoSource, VideoSourceError

ROOT = Path(__file__).resolve().parents[1]
W, H, N_FRAMES, FPS = 320, 180, 20, 15.0
TRACK_KEYS = {"id", "box", "coasting", "d_x", "d_y", "v_x", "v_y", "ttc"}
RECORD_KEYS = {"frame", "t", "tracks", "risk", "risk_kind", "ego_speed", "ego_speed_source", "warning"}


def _strict(text: str):
    def bad(name):
        raise ValueError(f"non-standard JSON constant {name}")
    return json.loads(text, parse_constant=bad)


def _scenario(tmp: Path, name: str, **camera) -> Path:
    """highway_cruise.yaml at W x H (hfov kept, so the focal length scales), 3 s long."""
    data = yaml.safe_load((ROOT / "scenarios" / "highway_cruise.yaml").read_text())
    data.update(name=name, duration_s=3.0, fps=FPS)
    data["camera"] = {**(data.get("camera") or {}), "width": W, "height": H, **camera}
    path = tmp / f"{name}.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def _render(tmp: Path, scenario: Path, frames: int) -> Path:
    out = tmp / scenario.stem
    assert main(["render", str(scenario), "--out", str(out), "--frames", str(frames)]) == 0
    return out


def _decode(path: Path) -> list[np.ndarray]:
    cap = cv2.VideoCapture(str(path))
    frames = []
    while True:
        ok, img = cap.read()
        if not ok:
            break
        frames.append(img)
    cap.release()
    return frames


#: The video command's defaults are for real frames (the real-world detector, the size prior); on these
#: rendered frames use what the simulation commands use.
RENDERED = ["--detector", "centernet", "--size-prior", "off"]


@pytest.fixture(scope="module")
def clip(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("video")
    return _render(tmp, _scenario(tmp, "cruise_small"), N_FRAMES)


@pytest.fixture(scope="module")
def run(clip):
    out = clip.parent / "pred"
    assert main(["video", str(clip / "frames.mp4"), "--camera", str(clip / "camera.json"), "--out", str(out),
                 *RENDERED]) == 0
    return out


# ------------------------------------------------------------------------------ outputs
def test_predictions_structure_count_and_container_times(clip, run):
    assert sorted(p.name for p in run.iterdir()) == ["annotated.mp4", "predictions.jsonl", "run.json"]
    recs = [_strict(line) for line in (run / "predictions.jsonl").read_text().splitlines()]
    assert len(recs) == N_FRAMES
    assert [r["frame"] for r in recs] == list(range(N_FRAMES))
    cap = cv2.VideoCapture(str(clip / "frames.mp4"))
    container_fps = cap.get(cv2.CAP_PROP_FPS)
    cap.release()
    assert container_fps == pytest.approx(FPS)
    truth = [_strict(line) for line in (clip / "ground_truth.jsonl").read_text().splitlines()]
    np.testing.assert_allclose([r["t"] for r in recs], np.arange(N_FRAMES) / container_fps, atol=1e-3)
    np.testing.assert_allclose([r["t"] for r in recs], [g["t"] for g in truth], atol=1e-3)
    n_tracks = 0
    for r in recs:
        assert set(r) == RECORD_KEYS
        assert r["risk_kind"] == "inverse_ttc" and r["risk"] >= 0
        ttcs = [t["ttc"] for t in r["tracks"] if t["ttc"] is not None]
        assert r["risk"] == pytest.approx(max((1 / x for x in ttcs), default=0.0))   # equation 5
        assert (r["ego_speed"] is None) == (r["ego_speed_source"] is None)
        for t in r["tracks"]:
            n_tracks += 1
            assert set(t) == TRACK_KEYS
            x1, y1, x2, y2 = t["box"]
            assert x1 < x2 and y1 < y2
    assert n_tracks >= N_FRAMES   # the clip has vehicles ahead in every frame
    # ego speed from the lane markings once it has a window of frames: near the true speed
    est = [(r["ego_speed"], g["ego"]["speed"]) for r, g in zip(recs, truth) if r["ego_speed"] is not None]
    assert len(est) >= N_FRAMES // 2
    assert np.median([abs(e - s) / s for e, s in est]) < 0.05


def _iou(a, b) -> float:
    ix = max(0.0, min(a[2], b[2]) - max(a[0], b[0]))
    iy = max(0.0, min(a[3], b[3]) - max(a[1], b[1]))
    inter = ix * iy
    return inter / ((a[2] - a[0]) * (a[3] - a[1]) + (b[2] - b[0]) * (b[3] - b[1]) - inter)


def _distance_errors(pred_dir: Path, clip: Path) -> list[float]:
    """Relative error of d_y against the true distance of the ground-truth box it overlaps (IoU > 0.5)."""
    recs = [_strict(x) for x in (pred_dir / "predictions.jsonl").read_text().splitlines()]
    truth = [_strict(x) for x in (clip / "ground_truth.jsonl").read_text().splitlines()]
    errs = []
    for r, g in zip(recs, truth):
        objs = [o for o in g["objects"] if o["box"] is not None]
        for t in r["tracks"]:
            if t["d_y"] is None or not objs:
                continue
            best = max(objs, key=lambda o: _iou(t["box"], o["box"]))
            if _iou(t["box"], best["box"]) > 0.5 and best["d_long"] < 50:
                errs.append(abs(t["d_y"] - best["d_long"]) / best["d_long"])
    return errs


def test_distances_follow_the_camera_file(clip, run):
    errs = _distance_errors(run, clip)
    assert len(errs) >= 10 and np.median(errs) < 0.10


def test_camera_file_at_another_resolution_is_scaled(clip, run, tmp_path, capsys):
    cam = CameraModel.load(clip / "camera.json").scaled(2 * W, 2 * H)
    cam.save(tmp_path / "cam640.json")
    out = tmp_path / "scaled"
    rc = main(["video", str(clip / "frames.mp4"), "--camera", str(tmp_path / "cam640.json"), "--out", str(out),
               "--no-video", "--ego-speed", "none", *RENDERED])
    assert rc == 0
    assert "scaled" in capsys.readouterr().err
    assert sorted(p.name for p in out.iterdir()) == ["predictions.jsonl", "run.json"]
    got = _strict((out / "run.json").read_text())["camera"]
    ref = CameraModel.load(clip / "camera.json")
    assert got["fx"] == pytest.approx(ref.fx) and got["horizon_row"] == pytest.approx(ref.horizon_row)
    assert np.median(_distance_errors(out, clip)) < 0.10


def test_annotated_video_decodes(clip, run):
    ann, raw = _decode(run / "annotated.mp4"), _decode(clip / "frames.mp4")
    assert len(ann) == len(raw) == N_FRAMES
    assert ann[0].shape == (H, W, 3)
    diff = [np.abs(a.astype(int) - r.astype(int)).mean() for a, r in zip(ann, raw)]
    assert min(diff) > 1.0   # boxes, header and gauge drawn on every frame


def test_threaded_runner_and_monte_carlo_options(clip, run, tmp_path):
    out = tmp_path / "mc"
    assert main(["video", str(clip / "frames.mp4"), "--camera", str(clip / "camera.json"), "--out", str(out),
                 "--threaded", "--risk", "monte_carlo", "--speed", "25", "--ego-speed", "none",
                 "--frames", "5", "--no-video", *RENDERED]) == 0
    recs = [_strict(x) for x in (out / "predictions.jsonl").read_text().splitlines()]
    assert len(recs) == 5 and any(r["tracks"] for r in recs)   # something to compare
    assert all(r["risk_kind"] == "probability" and 0 <= r["risk"] <= 1 for r in recs)
    assert all(r["ego_speed"] == 25.0 and r["ego_speed_source"] == "given" for r in recs)
    # the threaded runner gives the synchronous run's tracks and states for the same frames
    # (TTC is the risk estimator's: the Monte Carlo one reports its own)
    sync = [_strict(x) for x in (run / "predictions.jsonl").read_text().splitlines()][:5]

    def strip(r):
        return [{k: v for k, v in t.items() if k != "ttc"} for t in r["tracks"]]
    assert [strip(r) for r in recs] == [strip(r) for r in sync]


# ---------------------------------------------------------------------------- timestamps
def test_variable_frame_rate_file_keeps_container_timestamps(tmp_path):
    """Frames shown for chosen durations (ffmpeg concat demuxer): t is each frame's start, not index / fps."""
    import imageio_ffmpeg

    durations = [0.04, 0.2, 0.08, 0.4, 0.12, 0.2, 0.16, 0.08]   # multiples of the demuxer's 1/25 s
    lines = []
    for i, d in enumerate(durations):
        img = np.full((48, 64, 3), 30 * i, np.uint8)
        cv2.imwrite(str(tmp_path / f"{i}.png"), img)
        lines += [f"file '{i}.png'", f"duration {d}"]
    lines.append(f"file '{len(durations) - 1}.png'")
    (tmp_path / "list.txt").write_text("\n".join(lines) + "\n")
    subprocess.run([imageio_ffmpeg.get_ffmpeg_exe(), "-hide_banner", "-loglevel", "error", "-y", "-f", "concat",
                    "-safe", "0", "-i", str(tmp_path / "list.txt"), "-fps_mode", "vfr", "-c:v", "libx264",
                    "-pix_fmt", "yuv420p", "-video_track_timescale", "1000", str(tmp_path / "vfr.mp4")],
                   check=True, timeout=60)
    with VideoSource(tmp_path / "vfr.mp4") as src:
        ts = [f.t for f in src.frames()]
    expected = np.concatenate([[0.0], np.cumsum(durations)])
    np.testing.assert_allclose(ts[: len(expected)], expected[: len(ts)], atol=2e-3)
    assert len(ts) >= len(durations)
    uniform = np.arange(len(ts)) / src.info.fps
    assert np.abs(np.array(ts) - uniform).max() > 0.05   # index / fps would be visibly wrong here


def test_matroska_with_longer_audio_decodes_to_its_end(clip, tmp_path, capsys):
    """Matroska stores no frame count: OpenCV's estimate (duration x rate) counts the 3 s audio track."""
    import imageio_ffmpeg

    mkv = tmp_path / "audio.mkv"
    subprocess.run([imageio_ffmpeg.get_ffmpeg_exe(), "-hide_banner", "-loglevel", "error", "-y",
                    "-i", str(clip / "frames.mp4"), "-f", "lavfi", "-i", "sine=d=3", "-c:v", "copy", "-c:a", "aac",
                    str(mkv)], check=True, timeout=60)
    with VideoSource(mkv) as src:
        assert src.info.frame_count > 30 and not src.info.frame_count_exact   # the estimate, not 20
        assert len(list(src.frames())) == 20
    with VideoSource(clip / "frames.mp4") as src:
        assert src.info.frame_count == 20 and src.info.frame_count_exact
    out = tmp_path / "out"
    assert main(["video", str(mkv), "--camera", str(clip / "camera.json"), "--out", str(out), "--no-video"]) == 0
    assert len((out / "predictions.jsonl").read_text().splitlines()) == 20
    capsys.readouterr()


def test_fallback_time_when_container_gives_none(clip):
    with VideoSource(clip / "frames.mp4") as src:
        assert src._file_time(0, 0.0, -math.inf) == 0.0
        assert src._file_time(3, float("nan"), 0.1) == pytest.approx(3 / FPS)
        assert src._file_time(3, 0.0, 0.1) == pytest.approx(3 / FPS)        # not increasing: index / fps
        assert src._file_time(3, 250.0, 0.1) == pytest.approx(0.25)         # valid: the container's


# ------------------------------------------------------------------------------ horizon
def _horizon_from_projection(cam: CameraModel) -> float:
    """Row where a ground point 10^9 m ahead projects, by cv2.projectPoints (independent of CameraModel)."""
    c, s = math.cos(cam.pitch_rad), math.sin(cam.pitch_rad)
    # camera frame of a camera pitched down by theta: x right, y down, z forward
    R = np.array([[1, 0, 0], [0, 0, -1], [0, 1, 0]], float)
    R = np.array([[1, 0, 0], [0, c, -s], [0, s, c]]) @ R
    rvec, _ = cv2.Rodrigues(R)
    pt = np.array([[[0.0, 1e9, -cam.height_m]]])
    uv, _ = cv2.projectPoints(pt, rvec, np.zeros(3), cam.K, None)
    return float(uv[0, 0, 1])


def test_horizon_row_in_camera_file_gives_the_pitch():
    ref = CameraModel.from_fov(W, H, 70.0, 1.3, pitch_rad=math.radians(3.0))
    row = _horizon_from_projection(ref)
    cam = CameraModel.from_dict({"width": W, "height": H, "hfov_deg": 70.0, "height_m": 1.3, "horizon_row": row})
    assert cam.pitch_rad == pytest.approx(math.radians(3.0), abs=1e-6)
    assert cam.horizon_row == pytest.approx(row, abs=1e-4)
    with pytest.raises(CameraError, match="outside the image"):
        CameraModel.from_dict({"width": W, "height": H, "hfov_deg": 70.0, "height_m": 1.3, "horizon_row": H + 5})


def test_vanishing_point_of_synthetic_segments():
    rng = np.random.default_rng(3)
    vp = np.array([170.3, 77.8])
    segs = []
    for _ in range(12):   # segments on lines through vp, below it, both leanings
        ang = rng.uniform(np.radians(20), np.radians(70)) * rng.choice([-1, 1])
        d = np.array([math.cos(ang) * np.sign(ang), abs(math.sin(ang))])
        a, b = vp + d * rng.uniform(40, 80), vp + d * rng.uniform(90, 140)
        segs.append([*a, *b])
    segs += [[10, 150, 60, 120], [200, 100, 260, 175], [100, 170, 120, 110]]   # outliers
    got = vanishing_point(np.array(segs, float))
    assert got is not None and got.inliers >= 12
    assert (got.u, got.v) == (pytest.approx(vp[0], abs=0.05), pytest.approx(vp[1], abs=0.05))


@pytest.mark.parametrize("pitch_deg", [None, 5.0])
def test_horizon_helper_recovers_rendered_horizon(clip, tmp_path, pitch_deg, capsys):
    if pitch_deg is None:
        rendered = clip
    else:
        scen = _scenario(tmp_path, "pitched", pitch_deg=pitch_deg)
        rendered = _render(tmp_path, scen, 8)
    cam = CameraModel.load(rendered / "camera.json")
    truth_row = json.loads((rendered / "camera.json").read_text())["horizon_row"]
    assert truth_row == pytest.approx(_horizon_from_projection(cam), abs=1e-6)
    est = estimate_horizon(_decode(rendered / "frames.mp4"), cam.fy, cam.cy)
    assert abs(est.row - truth_row) < 3.0
    assert est.frames_used >= est.frames_seen // 2
    # the command prints the same row and the pitch to put in the camera file
    capsys.readouterr()
    assert main(["calibrate-horizon", str(rendered / "frames.mp4"), "--camera", str(rendered / "camera.json")]) == 0
    printed = yaml.safe_load(capsys.readouterr().out)
    assert printed["horizon_row"] == pytest.approx(est.row, abs=0.01)
    assert abs(math.radians(printed["pitch_deg"]) - cam.pitch_rad) < math.atan(3.0 / cam.fy)


def test_horizon_helper_reads_a_distorted_clip_in_its_pinhole_view(tmp_path, capsys):
    """Lane lines curve through a barrel lens; in the lens's virtual pinhole view they are straight again."""
    lens = [-0.22, 0.05, 0.0008, -0.0005, 0.0]
    rendered = _render(tmp_path, _scenario(tmp_path, "lens", hfov_deg=70, distortion=lens), 30)
    truth_row = json.loads((rendered / "camera.json").read_text())["horizon_row"]
    capsys.readouterr()
    assert main(["calibrate-horizon", str(rendered / "frames.mp4"), "--camera", str(rendered / "camera.json")]) == 0
    printed = yaml.safe_load(capsys.readouterr().out)
    cam = CameraModel.load(rendered / "camera.json")
    as_pinhole = estimate_horizon(_decode(rendered / "frames.mp4"), cam.fy, cam.cy)   # the lens ignored
    assert abs(printed["horizon_row"] - truth_row) < 0.25
    assert abs(as_pinhole.row - truth_row) > 2 * abs(printed["horizon_row"] - truth_row)


def test_horizon_helper_on_a_video_at_another_size_speaks_in_the_camera_files_pixels(clip, tmp_path, capsys):
    big = tmp_path / "big.mp4"
    writer = cv2.VideoWriter(str(big), cv2.VideoWriter_fourcc(*"mp4v"), FPS, (2 * W, 2 * H))
    for img in _decode(clip / "frames.mp4"):
        writer.write(cv2.resize(img, (2 * W, 2 * H), interpolation=cv2.INTER_LINEAR))
    writer.release()
    file_row = json.loads((clip / "camera.json").read_text())["horizon_row"]
    capsys.readouterr()
    assert main(["calibrate-horizon", str(big), "--camera", str(clip / "camera.json")]) == 0
    out = capsys.readouterr().out
    row = yaml.safe_load(out)["horizon_row"]
    assert abs(row - file_row) < 3.0                       # the camera file's rows, not the video's (2x)
    last = out.strip().splitlines()[-1]
    assert f"puts the horizon at {file_row:.2f} px" in last
    assert float(last.rsplit("difference ", 1)[1].split()[0]) == pytest.approx(row - file_row, abs=0.011)


# ---------------------------------------------------------------------------- bad input
def _camera_text(**fields) -> str:
    base = {"width": W, "height": H, "hfov_deg": 70.0, "height_m": 1.3, "pitch_deg": 2.0}
    base.update(fields)
    return yaml.safe_dump({k: v for k, v in base.items() if v is not None})


BAD = {
    "missing input": ("{tmp}/nope.mp4", None, [], "no such file"),
    "random bytes": ("{tmp}/random.mp4", None, [], "cannot open as a video"),
    "empty file": ("{tmp}/empty.mp4", None, [], "empty file"),
    "webcam": ("97", None, [], "webcam 97"),
    "camera missing": (None, "{tmp}/nocam.yaml", [], "cannot read camera file"),
    "camera unparsable": (None, "{tmp}/garbled.yaml", [], "cannot parse camera file"),
    "negative focal": (None, "{tmp}/negf.yaml", [], "focal lengths must be positive"),
    "horizon outside": (None, "{tmp}/horizon.yaml", [], "outside the image"),
    "pitch puts horizon outside": (None, "{tmp}/pitch.yaml", [], "outside the image"),
    "unknown detector": (None, None, ["--detector", "nosuch"], "unknown detector 'nosuch'"),
    "unknown tracker": (None, None, ["--tracker", "nosuch"], "unknown tracker 'nosuch'"),
    "missing onnx": (None, None, ["--detector", "{tmp}/absent.onnx"], "model file not found"),
    "truth-only detector": (None, None, ["--detector", "oracle"], "needs the simulation's ground truth"),
    "yolo without its model": (None, None, ["--detector", "yolo"], "detector 'yolo' needs a model file"),
    "truncated video": ("{tmp}/truncated.mp4", None, [], "truncated or corrupt"),
    # camera.json as `monorarp run` writes it, one field edited
    "NaN lateral offset": (None, "{tmp}/nan_lateral.json", [], "lateral_offset_m must be finite, got nan"),
    "infinite forward offset": (None, "{tmp}/inf_forward.json", [], "forward_offset_m must be finite, got inf"),
    "infinite height": (None, "{tmp}/inf_height.json", [], "height_m must be finite, got inf"),
    "width true": (None, "{tmp}/width_true.json", [], "width must be a whole number of pixels, 1..1000000, got True"),
    "fractional width": (None, "{tmp}/width_frac.json", [], "width must be a whole number of pixels, 1..1000000, "
                                                           "got 320.5"),
    "width a word": (None, "{tmp}/width_abc.json", [], "width must be a whole number of pixels, 1..1000000, "
                                                       "got 'abc'"),
    "fx a string": (None, "{tmp}/fx_str.json", [], "fx must be a number, got '457'"),
    "K a string": (None, "{tmp}/k_str.json", [], "K must be a 3x3 matrix (3 rows of 3 numbers), got 'abc'"),
    "K entry a string": (None, "{tmp}/k_entry.json", [], "K[1][2] must be a number, got 'abc'"),
    "cx beside K": (None, "{tmp}/cx_edited.json", [], "cx 10000.0 disagrees with K[0][2] 159.5; give one of them"),
    "cx outside": (None, "{tmp}/cx_outside.yaml", [], "principal point cx=10000.0 px lies outside the image "
                                                      "(-0.5..319.5)"),
    "camera sees no road": (None, "{tmp}/pitched_up.yaml", [], "ego-speed stage 'ground_track' (lane-marking "
                                                               "ego-speed estimator) cannot run:"),
}


def _camera_json(clip: Path, **fields) -> str:
    """The clip's camera.json (K and fx/fy/cx/cy, as `monorarp run` writes it) with ``fields`` replaced;
    NaN / Infinity written as Python's json writes them."""
    data = json.loads((clip / "camera.json").read_text())
    data.update(fields)
    return json.dumps(data)


@pytest.fixture(scope="module")
def bad_files(clip, tmp_path_factory):
    tmp = tmp_path_factory.mktemp("bad")
    (tmp / "random.mp4").write_bytes(np.random.default_rng(0).integers(0, 256, 20000, dtype=np.uint8).tobytes())
    (tmp / "empty.mp4").write_bytes(b"")
    (tmp / "garbled.yaml").write_text("width: [320,\n  height: {\n")
    (tmp / "negf.yaml").write_text(_camera_text(hfov_deg=None, fx=-250.0))
    (tmp / "horizon.yaml").write_text(_camera_text(pitch_deg=None, horizon_row=-12.0))
    (tmp / "pitch.yaml").write_text(_camera_text(pitch_deg=40.0))
    k = json.loads((clip / "camera.json").read_text())["K"]
    for name, fields in {"nan_lateral": dict(lateral_offset_m=math.nan), "inf_forward": dict(forward_offset_m=math.inf),
                         "inf_height": dict(height_m=math.inf), "width_true": dict(width=True),
                         "width_frac": dict(width=W + 0.5), "width_abc": dict(width="abc"), "fx_str": dict(fx="457"),
                         "k_str": dict(K="abc"), "k_entry": dict(K=[k[0], [0.0, k[1][1], "abc"], k[2]]),
                         "cx_edited": dict(cx=10000.0)}.items():
        (tmp / f"{name}.json").write_text(_camera_json(clip, **fields))
    (tmp / "cx_outside.yaml").write_text(_camera_text(hfov_deg=None, fx=250.0, cx=10000))
    (tmp / "pitched_up.yaml").write_text(_camera_text(pitch_deg=-20.0))   # horizon 6 rows above the bottom
    data = (clip / "frames.mp4").read_bytes()
    (tmp / "truncated.mp4").write_bytes(data[: len(data) * 6 // 10])   # moov first (+faststart): opens
    return tmp


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_input_one_line_exit_2_nothing_written(clip, bad_files, case, capsys):
    inp, camera, extra, message = BAD[case]
    inp = (inp or str(clip / "frames.mp4")).format(tmp=bad_files)
    camera = (camera or str(clip / "camera.json")).format(tmp=bad_files)
    out = bad_files / "out" / case.replace(" ", "_")
    rc = main(["video", inp, "--camera", camera, "--out", str(out), *[e.format(tmp=bad_files) for e in extra]])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2
    assert len(err) == 1 and message in err[0] and err[0].startswith("monorarp video: error:")
    assert not out.exists() and not (bad_files / "out").exists()
    assert not [p for p in bad_files.iterdir() if p.name.startswith(".")]   # no temp dirs left


def test_camera_that_sees_no_road_names_file_stage_and_way_out(clip, bad_files, tmp_path, capsys):
    camera = bad_files / "pitched_up.yaml"
    out = tmp_path / "out"
    assert main(["video", str(clip / "frames.mp4"), "--camera", str(camera), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"monorarp video: error: {camera}: ego-speed stage 'ground_track' (lane-marking ego-speed "
                   "estimator) cannot run: no ground rows between 5.0 m and 25.0 m for this camera; "
                   "--ego-speed none runs without it"]
    assert not out.exists()
    assert main(["video", str(clip / "frames.mp4"), "--camera", str(camera), "--out", str(out), "--no-video",
                 "--ego-speed", "none", "--max-frames", "2"]) == 0
    capsys.readouterr()


@pytest.mark.parametrize("fields, message", [
    (dict(lateral_offset_m=math.nan), "lateral_offset_m must be finite"),
    (dict(forward_offset_m=-math.inf), "forward_offset_m must be finite"),
    (dict(height_m=math.inf), "height_m must be finite"),
    (dict(pitch_deg=math.nan), "pitch_deg must be finite"),
    (dict(roll_deg=math.inf), "roll_deg must be finite"),
    (dict(hfov_deg=math.nan), "hfov_deg must be finite"),
    (dict(height_m=10 ** 400), "height_m must be finite"),
    (dict(width=True), "width must be a whole number of pixels"),
    (dict(height=False), "height must be a whole number of pixels"),
    (dict(width=640.5), "width must be a whole number of pixels"),
    (dict(width="640"), "width must be a whole number of pixels"),
    (dict(width=10 ** 400), "width must be a whole number of pixels"),
    (dict(width=0), "width must be a whole number of pixels"),
    (dict(height_m="1.3"), "height_m must be a number, got '1.3'"),
    (dict(height_m=None), "height_m must be a number, got None"),
    (dict(pitch_deg=True), "pitch_deg must be a number, got True"),
    (dict(hfov_deg=None, fx=250.0, cx=-1.0), "principal point cx=-1.0 px lies outside the image"),
    (dict(hfov_deg=None, fx=250.0, cy=H), "principal point cy=180.0 px lies outside the image"),
    (dict(hfov_deg=None, fx=math.inf), "fx must be finite"),
    (dict(hfov_deg=None, K=[[250.0, 0, 159.5], [0, 250.0, 89.5]]), "K must be a 3x3 matrix"),
    (dict(hfov_deg=None, K=[[250.0, 0, 159.5], [0, 250.0, math.nan], [0, 0, 1]]), "K[1][2] must be finite"),
    (dict(hfov_deg=None, K=[[250.0, 0, 159.5], [0, 250.0, 89.5], [0, 0, 1]], fy=251.0), "fy 251.0 disagrees with K"),
    # a typo must not leave its field at the default; an unknown key is refused, even when null
    (dict(pitch_dg=2.0), "unknown key 'pitch_dg' (did you mean 'pitch_deg'?); a camera file holds only width, "
                         "height, K, fx, fy, cx, cy, hfov_deg, height_m, pitch_rad, pitch_deg, horizon_row, "
                         "lateral_offset_m, forward_offset_m, roll_rad, roll_deg"),
    (dict(foo=None, bar=1), "unknown keys 'foo', 'bar'; a camera file holds only width, height, K,"),
    # K: an intrinsic matrix [[fx, 0, cx], [0, fy, cy], [0, 0, 1]]; skew or another last row is not dropped
    (dict(hfov_deg=None, K=[[250.0, 1.0, 159.5], [0, 250.0, 89.5], [0, 0, 1]]),
     "K[0][1] must be 0 (skew is not modelled), got 1.0: K must be an intrinsic matrix [[fx, 0, cx], [0, fy, cy], "
     "[0, 0, 1]]"),
    (dict(hfov_deg=None, K=[[250.0, 0, 159.5], [3.0, 250.0, 89.5], [0, 0, 1]]), "K[1][0] must be 0, got 3.0"),
    (dict(hfov_deg=None, K=[[250.0, 0, 159.5], [0, 250.0, 89.5], [0.1, 0, 1]]), "K[2][0] must be 0, got 0.1"),
    (dict(hfov_deg=None, K=[[250.0, 0, 159.5], [0, 250.0, 89.5], [0, 0, 2]]), "K[2][2] must be 1, got 2.0"),
    (dict(hfov_deg=None, K=[[250.0, 0, 159.5], [0, 250.0, 89.5], [0, 0, 0]]), "K[2][2] must be 1, got 0.0"),
])
def test_camera_file_fields_are_checked_and_named(fields, message):
    """Every numeric field: a finite number (no bool, no string), whole pixels, principal point in the image."""
    d = {"width": W, "height": H, "hfov_deg": 70.0, "height_m": 1.3, **fields}
    with pytest.raises(CameraError) as e:
        CameraModel.from_dict(d, source="cam.yaml")
    assert str(e.value).startswith("cam.yaml: ") and message in str(e.value)


def test_camera_files_written_by_run_still_load(clip):
    cam = CameraModel.load(clip / "camera.json")
    assert set(json.loads((clip / "camera.json").read_text())) | {"roll_rad"} == set(CameraModel.to_dict(
        CameraModel(W, H, 250.0, 250.0, 159.5, 89.5, 1.3, roll_rad=0.1)))          # every key written is read
    rolled = CameraModel(W, H, 250.0, 250.0, 159.5, 89.5, 1.3, pitch_rad=0.02, roll_rad=0.1)
    assert CameraModel.from_dict(rolled.to_dict()) == rolled
    noisy = [[250.0, 1e-9, 159.5], [-1e-9, 250.0, 89.5], [1e-12, 0.0, 1.0 + 1e-10]]    # float noise in K
    assert CameraModel.from_dict({"width": W, "height": H, "K": noisy, "height_m": 1.3}).fx == 250.0
    d = {**json.loads((clip / "camera.json").read_text()), "width": float(W)}   # 320.0: a whole number
    assert CameraModel.from_dict(d) == cam
    assert CameraModel.from_dict({**cam.to_dict(), "cx": cam.cx + 1e-9}) == cam   # K and cx agree
    fx_only = {"width": W, "height": H, "fx": 250.0, "hfov_deg": None, "pitch_deg": None, "height_m": 1.3}
    assert CameraModel.from_dict(fx_only) == CameraModel(W, H, 250.0, 250.0, (W - 1) / 2, (H - 1) / 2, 1.3)
    for cx in (-0.5, W - 0.5):   # principal point on the image's edge: stays there when scaled
        edge = CameraModel(W, H, 250.0, 250.0, cx, (H - 1) / 2, 1.3)
        assert edge.scaled(W // 2, H // 2).cx == (cx + 0.5) / 2 - 0.5 and edge.scaled(W * 2, H * 2).cx == 2 * cx + 0.5


def test_failure_midway_keeps_the_previous_run(clip, run, bad_files, tmp_path, capsys):
    out = tmp_path / "prev"
    shutil.copytree(run, out)
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    rc = main(["video", str(bad_files / "truncated.mp4"), "--camera", str(clip / "camera.json"), "--out", str(out)])
    assert rc == 2 and "decoding failed after frame" in capsys.readouterr().err
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["prev"]


def test_display_without_gui_is_one_clear_line(clip, tmp_path, capsys):
    if _opencv_gui() is not None:
        pytest.skip("this OpenCV build has a GUI backend")
    out = tmp_path / "disp"
    rc = main(["video", str(clip / "frames.mp4"), "--camera", str(clip / "camera.json"), "--out", str(out),
               "--display"])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and "GUI support" in err[0] and not out.exists()


def test_source_errors_are_user_errors(tmp_path):
    with pytest.raises(VideoSourceError, match="no such file"):
        VideoSource(tmp_path / "x.mp4")
    with pytest.raises(VideoSourceError, match="not a file"):
        VideoSource(tmp_path)
