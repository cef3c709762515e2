"""The reference annotation of the real clip (tests/data/solidWhiteRight_gt.txt, notes beside it): its
MOTChallenge layout, its frames, its boxes, and that the benchmark's own reader takes it."""

import importlib.util
from pathlib import Path

from harness.export.mot import CAR_CLASS, mot_to_box

ROOT = Path(__file__).resolve().parents[1]
GT = ROOT / "tests" / "data" / "solidWhiteRight_gt.txt"
NOTES = ROOT / "tests" / "data" / "solidWhiteRight_gt.md"
WIDTH, HEIGHT = 960, 540                           # the clip's frame size (px)
VIDEO_FRAMES = list(range(0, 221, 5))              # 0-based video frames annotated: 0, 5, ..., 220


def rows() -> list[tuple[int, int, tuple[float, float, float, float], float, int]]:
    """(MOT frame, id, project box x1y1x2y2, conf, class) of every line; raises on a malformed one."""
    out = []
    for n, line in enumerate(GT.read_text().splitlines(), 1):
        f = line.split(",")
        assert len(f) == 9, f"line {n}: {len(f)} fields, expected 9"
        left, top, w, h = (float(v) for v in f[2:6])
        assert w > 0 and h > 0, f"line {n}: size {w} x {h}"
        out.append((int(f[0]), int(f[1]), mot_to_box(left, top, w, h), float(f[6]), int(f[7])))
    return out


def test_annotation_covers_every_fifth_frame_once_per_vehicle():
    r = rows()
    assert sorted({frame for frame, *_ in r}) == [k + 1 for k in VIDEO_FRAMES]      # MOT frames are 1-based
    keys = [(frame, oid) for frame, oid, *_ in r]
    assert len(keys) == len(set(keys))
    assert all(oid >= 1 for _, oid in keys)
    assert all(conf == 1 and cls == CAR_CLASS for *_, conf, cls in r)


def test_boxes_lie_inside_the_frame_and_are_at_least_8_px_tall():
    for frame, oid, (x1, y1, x2, y2), *_ in rows():
        assert -0.5 <= x1 < x2 <= WIDTH - 0.5, (frame, oid)
        assert -0.5 <= y1 < y2 <= HEIGHT - 0.5, (frame, oid)
        assert y2 - y1 >= 8.0 and x2 - x1 >= 4.0, (frame, oid)


def test_identities_persist_and_the_target_sized_vehicles_are_there():
    r = rows()
    frames_of: dict[int, set[int]] = {}
    for frame, oid, *_ in r:
        frames_of.setdefault(oid, set()).add(frame)
    # the three cars ahead in the next lanes are in view throughout: one identity each over all 45 frames
    assert sum(len(f) == len(VIDEO_FRAMES) for f in frames_of.values()) >= 3
    tall = [box for _, _, box, *_ in r if box[3] - box[1] >= 20.0]
    assert len(tall) >= 100                       # the target counts vehicles >= 20 px tall


def test_the_benchmarks_reader_takes_it():
    spec = importlib.util.spec_from_file_location("bench_real", ROOT / "benchmarks" / "bench_real.py")
    br = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(br)
    gt = br.read_mot_gt(GT)
    assert list(gt) == VIDEO_FRAMES
    assert sum(len(v) for v in gt.values()) == len(rows())


def test_notes_state_the_clip_licence_and_the_frame_mapping():
    text = NOTES.read_text()
    for needed in ("MIT", "Udacity", "LICENSE-udacity-CarND-LaneLines-P1.txt", "k + 1"):
        assert needed in text, needed
    assert (ROOT / "tests" / "data" / "LICENSE-udacity-CarND-LaneLines-P1.txt").is_file()
