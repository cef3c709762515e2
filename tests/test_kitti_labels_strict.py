"""Messy real datasets: every KITTI label and calibration field checked against the devkit's definitions,
``--lenient`` for datasets known to be dirty, camera files that do not fit the video, ``--out`` that is
the current directory, and refusals that name the true reason (a directory, a broken or looping link)."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import pytest

from harness.kitti_eval.reader import KittiInputError, open_dataset, parse_calib, parse_tracking_labels
from monorarp.app import cli
from monorarp.app.common_options import out_dir
from monorarp.app.video.run import camera_for
from monorarp.app.video.source import VideoInfo
from monorarp.core.camera import CameraError, CameraModel
from monorarp.core.errors import UserError
from monorarp.core.readers import path_problem, read_text
from test_kitti_eval import HAND_LABELS, W, H, kitti_rig_calib, write_object_dataset

GOOD = HAND_LABELS[0][0]     # Car 0.00 0 -1.60 180 40 240 100 1.50 1.60 4.00 0.50 1.65 20.00 -1.5708
DONTCARE = HAND_LABELS[3][0]


def _car(**kw: str) -> str:
    """The good Car line with some fields replaced (KITTI's field names)."""
    names = ("type", "truncated", "occluded", "alpha", "x1", "y1", "x2", "y2", "h", "w", "l", "x", "y", "z",
             "rotation_y")
    parts = dict(zip(names, GOOD.split()))
    parts.update(kw)
    return " ".join(parts[n] for n in names)


def _eval(ds: Path, out: Path, *extra: str) -> int:
    return cli.main(["eval", "kitti", str(ds), "--detector", "labels", "--camera-height", "1.65",
                     "--out", str(out), *extra])


def _refused(capsys, ds: Path, out: Path, needle: str, *extra: str) -> str:
    rc = _eval(ds, out, *extra)
    err = capsys.readouterr().err.strip()
    assert rc == 2, err
    assert len(err.splitlines()) == 1 and "Traceback" not in err, err
    assert needle in err, err
    assert not out.exists()
    return err


# --------------------------------------------------------------------------- label fields
BAD_LINES = {   # line -> the words the refusal must hold (file and line are checked as well)
    "box outside the image": (_car(x1="5000", y1="4000", x2="5100", y2="4050"), "field x1"),
    "box at negative coordinates": (_car(x1="-50", y1="-40", x2="-10", y2="-5"), "field x1"),
    "box beyond the right edge": (_car(x2=f"{W + 1.5:.2f}"), "field x2"),
    "zero-area box": (_car(x2="180.00"), "zero area"),
    "inverted box": (_car(y2="30.00"), "y2 < y1"),
    "zero length on a Car": (_car(l="0.00"), "field l"),
    "negative height": (_car(h="-2.00"), "field h"),
    "the DontCare sentinel on a Car": (_car(h="-1", w="-1", l="-1"), "field h"),
    "behind the camera": (_car(z="-5.00"), "field z"),
    "at the camera": (_car(z="0.00"), "field z"),
    "unknown type": (_car(type="Spaceship"), "field type"),
    "wrong case": (_car(type="car"), "did you mean 'Car'"),
    "truncated 5": (_car(truncated="5.0"), "field truncated"),
    "negative truncation": (_car(truncated="-0.5"), "field truncated"),
    "occluded 9": (_car(occluded="9"), "field occluded"),
    "fractional occlusion": (_car(occluded="1.5"), "field occluded"),
    "alpha beyond pi": (_car(alpha="4.00"), "field alpha"),
    "rotation_y beyond pi": (_car(rotation_y="-3.50"), "field rotation_y"),
    "DontCare box outside": (DONTCARE.replace("10.00 10.00 50.00 30.00", "900 10 950 30"), "field x1"),
}


@pytest.mark.parametrize("case", sorted(BAD_LINES))
def test_bad_label_field_refused_naming_file_line_field(case, tmp_path, capsys):
    line, needle = BAD_LINES[case]
    ds = write_object_dataset(tmp_path / "ds")
    (ds / "label_2" / "000001.txt").write_text(f"{GOOD}\n{line}\n")
    err = _refused(capsys, ds, tmp_path / "out", needle)
    assert "label_2/000001.txt: line 2:" in err, err


@pytest.mark.parametrize("line", [
    _car(x1="0.00", y1="0.00", x2=f"{W - 1:.2f}", y2=f"{H - 1:.2f}"),    # clipped to the image, as KITTI does
    _car(x1="-0.50", x2=f"{W - 0.5:.2f}", y2=f"{H:.2f}"),                  # within the pixel of tolerance
    _car(x1="200.00", x2="200.50"),                                        # KITTI has half-pixel-wide boxes
    _car(truncated="1.00", occluded="3", alpha="-3.14", rotation_y="3.14"),
    _car(type="Person_sitting"), _car(type="Misc"), _car(type="Tram"),
    DONTCARE,
])
def test_what_the_devkit_allows_is_accepted(line, tmp_path):
    ds = write_object_dataset(tmp_path / "ds", labels=[line])
    assert len(open_dataset(ds).sequences[0].samples[0].labels) == 1


def test_tracking_labels_same_track_twice_in_a_frame(tmp_path):
    body = GOOD.split(maxsplit=1)[1]
    ok = tmp_path / "ok.txt"
    ok.write_text(f"0 3 Car {body}\n0 -1 {DONTCARE}\n0 -1 {DONTCARE}\n1 3 Car {body}\n")
    assert len(parse_tracking_labels(ok, (W, H))[0]) == 3      # DontCare's -1 may repeat
    bad = tmp_path / "bad.txt"
    bad.write_text(f"0 3 Car {body}\n0 3 Van {body}\n")
    with pytest.raises(KittiInputError, match=r"bad.txt: line 2: field track_id: 3 is given twice in frame 0 "
                                              r"\(first at line 1\)"):
        parse_tracking_labels(bad, (W, H))
    skipped: list[str] = []                                        # --lenient: the second line left out
    assert len(parse_tracking_labels(bad, (W, H), skipped)[0]) == 1
    assert skipped == ["bad.txt:2: field track_id: 3 is given twice in frame 0 (first at line 1)"]
    level = tmp_path / "level.txt"                                 # tracking: truncation is a level 0/1/2
    level.write_text(f"0 3 Car 0.5 {body.split(maxsplit=1)[1]}\n")
    with pytest.raises(KittiInputError, match="line 1: field truncated"):
        parse_tracking_labels(level, (W, H))


def test_calibration_fields_checked(tmp_path):
    good = kitti_rig_calib()
    p = tmp_path / "c.txt"
    p.write_text(good)
    parse_calib(p)
    lines = good.splitlines()
    r0 = next(k for k, x in enumerate(lines) if x.startswith("R0_rect"))
    p2 = next(k for k, x in enumerate(lines) if x.startswith("P2"))
    bad_r0 = lines.copy()
    bad_r0[r0] = "R0_rect: 2 0 0 0 1 0 0 0 1"
    bad_p2 = lines.copy()
    bad_p2[p2] = "P2: -700 0 199.5 0 0 700 74.5 0 0 0 1 0"
    for text, needle in ((bad_r0, f"line {r0 + 1}: R0_rect is not a rotation"),
                         (bad_p2, f"line {p2 + 1}: P2 ")):
        p.write_text("\n".join(text) + "\n")
        with pytest.raises(KittiInputError, match=needle):
            parse_calib(p)


# --------------------------------------------------------------------------- --lenient
def test_lenient_skips_counts_and_lists_bad_lines(tmp_path, capsys):
    ds = write_object_dataset(tmp_path / "ds")
    (ds / "label_2" / "000001.txt").write_text(f"{GOOD}\n{_car(type='car')}\n{_car(z='-5')}\n{GOOD} 1\n")
    _refused(capsys, ds, tmp_path / "strict", "000001.txt: line 2: field type")
    out = tmp_path / "lenient"
    assert _eval(ds, out, "--lenient") == 0, capsys.readouterr().err
    metrics = json.loads((out / "metrics.json").read_text())
    skipped = metrics["dataset"]["skipped_lines"]
    assert skipped["count"] == 3
    assert [s.split(": ")[0] for s in skipped["lines"]] == ["000001.txt:2", "000001.txt:3", "000001.txt:4"]
    assert "field type" in skipped["lines"][0] and "field z" in skipped["lines"][1]
    assert metrics["dataset"]["labels"] == len(HAND_LABELS) + 1
    assert "skipped 3 bad label lines" in capsys.readouterr().out


def test_lenient_does_not_excuse_a_broken_dataset(tmp_path, capsys):
    ds = write_object_dataset(tmp_path / "ds")
    (ds / "calib" / "000001.txt").unlink()
    _refused(capsys, ds, tmp_path / "out", "calib/000001.txt: missing", "--lenient")


# --------------------------------------------------------------------------- true reasons
def _break(path: Path, how: str) -> None:
    """Replace ``path`` by a directory, a dangling symbolic link or a symbolic link loop."""
    path.unlink()
    if how == "directory":
        path.mkdir()
    elif how == "dangling":
        path.symlink_to(path.with_name("nowhere.txt"))
    else:
        path.symlink_to(path.name)                                   # a link to itself


REASONS = {"directory": "is a directory", "dangling": "broken symbolic link", "loop": "symbolic link loop"}


@pytest.mark.parametrize("how", sorted(REASONS))
@pytest.mark.parametrize("part", ["label_2/000001.txt", "calib/000001.txt", "image_2/000001.png"])
def test_unreadable_part_named_with_its_true_reason(part, how, tmp_path, capsys):
    ds = write_object_dataset(tmp_path / "ds")
    _break(ds / part, how)
    err = _refused(capsys, ds, tmp_path / "out", f"{part}: {REASONS[how]}")
    assert "missing" not in err and "not a KITTI image name" not in err, err


def test_dataset_path_that_is_a_file(tmp_path, capsys):
    f = tmp_path / "ds"
    f.write_text("x")
    _refused(capsys, f, tmp_path / "out", "ds: not a directory")
    _refused(capsys, tmp_path / "nosuch", tmp_path / "out", "nosuch: no such dataset directory")


def test_path_problem_names_each_reason(tmp_path):
    (tmp_path / "f").write_text("x")
    (tmp_path / "d").mkdir()
    (tmp_path / "dangling").symlink_to(tmp_path / "nowhere")
    (tmp_path / "loop").symlink_to("loop")
    assert path_problem(tmp_path / "f") is None and path_problem(tmp_path / "d", "directory") is None
    assert path_problem(tmp_path / "d") == "is a directory"
    assert path_problem(tmp_path / "f", "directory") == "not a directory"
    assert path_problem(tmp_path / "none") == "no such file"
    assert path_problem(tmp_path / "f" / "x") == "not a directory: f"
    assert path_problem(tmp_path / "dangling").startswith("broken symbolic link")
    assert path_problem(tmp_path / "loop") == "symbolic link loop"
    for name, reason in (("d", "is a directory"), ("dangling", "broken symbolic link"), ("loop", "symbolic link loop")):
        with pytest.raises(UserError, match=reason):
            read_text(tmp_path / name, "camera file")


# --------------------------------------------------------------------------- cameras
def _camera(w: int, h: int) -> CameraModel:
    return CameraModel.from_fov(w, h, 60.0, 1.3, 0.0)


def _info(w: int, h: int) -> VideoInfo:
    return VideoInfo(name="clip.mp4", width=w, height=h, fps=25.0, frame_count=2, is_webcam=False)


def test_camera_of_another_shape_than_the_video_is_refused():
    with pytest.raises(CameraError) as e:
        camera_for(_camera(640, 480), _info(960, 540), log=None)
    msg = str(e.value)
    assert "960x540" in msg and "640x480" in msg and "calibrate-horizon" in msg, msg
    assert "monorarp calibrate " not in msg            # no such command


@pytest.mark.parametrize("cam, video", [((1920, 1080), (960, 540)), ((1242, 375), (621, 188)),
                                        ((1280, 720), (854, 480)), ((960, 540), (960, 540))])
def test_camera_resized_with_the_video_is_accepted(cam, video):
    got, scaled = camera_for(_camera(*cam), _info(*video), log=None)
    assert (got.width, got.height) == video and scaled == (cam != video)


def test_tiny_camera_file_refused_for_its_size(tmp_path):
    p = tmp_path / "tiny.yaml"
    p.write_text("width: 64\nheight: 36\nhfov_deg: 60\nheight_m: 1.3\nhorizon_row: 304\n")
    with pytest.raises(CameraError, match=r"64x36.*too small") as e:
        CameraModel.load(p)
    assert "horizon" not in str(e.value)


# --------------------------------------------------------------------------- --out
def test_out_must_not_be_the_current_directory_or_above(tmp_path, monkeypatch):
    work = tmp_path / "a" / "b"
    work.mkdir(parents=True)
    monkeypatch.chdir(work)
    for text in ("", ".", "./", str(work), "..", str(tmp_path), "/", "../b"):
        with pytest.raises(argparse.ArgumentTypeError, match="must name a directory"):
            out_dir(text)
    assert out_dir("out") == Path("out") and out_dir("../c") == Path("../c")


def test_out_dot_refused_by_eval_nothing_written(tmp_path, capsys, monkeypatch):
    ds = write_object_dataset(tmp_path / "ds")
    work = tmp_path / "empty"
    work.mkdir()
    monkeypatch.chdir(work)
    assert _eval(ds, Path(".")) == 2
    assert "--out" in capsys.readouterr().err
    assert not list(work.iterdir())

