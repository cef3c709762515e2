"""MOTChallenge writer (``--format mot``): one sequence directory ``DIR/<SEQ>/``.

* ``img1/000001.jpg`` .. — the frames (JPEG quality 95, as MOTChallenge ships them),
  numbered from 1 (MOT frame = frame index + 1);
* ``gt/gt.txt`` — ``frame, id, bb_left, bb_top, bb_width, bb_height, conf, class, visibility``,
  one line per vehicle with at least one visible pixel. ``class`` 3 (MOTChallenge's car);
  ``conf`` 1 for the objects the harness scores and 0 for those it ignores (visibility < 0.3
  or farther than 80 m: :func:`harness.scoring.rules.counted_mask`), MOTChallenge's
  "not considered" flag; ``visibility`` the ground truth's;
* ``det/det.txt`` — the chosen detector's boxes, ``frame, -1, bb_left, bb_top, bb_width,
  bb_height, score, -1, -1, -1`` (absent with ``--detector none``);
* ``seqinfo.ini`` — name, imDir, frameRate, seqLength, imWidth, imHeight, imExt.

Boxes: MOTChallenge counts pixels from 1, so ``bb_left = x1 + 1.5`` and ``bb_top = y1 + 1.5``
for a project box ``(x1, y1, x2, y2)`` (pixel centres at integers: a box whose first pixel
column is 0 has ``x1 = -0.5`` and ``bb_left = 1``); ``bb_width = x2 - x1`` = the number of
pixel columns. :func:`mot_to_box` inverts it.

TrackEval's MOTChallenge reader scores pedestrians (class 1) only: to score these car
sequences with it, run it with ``BENCHMARK: MOT15`` or ``DO_PREPROC: False`` (as
``scripts/hota_reference.py`` does); rows with ``conf`` 0 are then left out of the truth.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from pathlib import Path

import cv2
import numpy as np

from harness.world.truth import FrameTruth, ObjectTruth
from monorarp.core.camera import CameraModel

CAR_CLASS = 3
JPEG_QUALITY = 95
IMAGE_EXT = ".jpg"
#: Offset from the project's box coordinates to MOTChallenge's 1-based ones.
MOT_OFFSET = 1.5


def sequence_name(name: str) -> str:
    """A directory-safe sequence name (letters, digits, ``-``, ``_``, ``.``)."""
    safe = re.sub(r"[^A-Za-z0-9._-]+", "_", name).strip("._") or "sequence"
    return safe


def box_to_mot(box: Sequence[float]) -> tuple[float, float, float, float]:
    """Project box ``(x1, y1, x2, y2)`` -> MOTChallenge ``(bb_left, bb_top, bb_width, bb_height)``."""
    x1, y1, x2, y2 = (float(v) for v in box)
    return x1 + MOT_OFFSET, y1 + MOT_OFFSET, x2 - x1, y2 - y1


def mot_to_box(left: float, top: float, width: float, height: float) -> tuple[float, float, float, float]:
    """MOTChallenge ``(bb_left, bb_top, bb_width, bb_height)`` -> project box ``(x1, y1, x2, y2)``."""
    x1, y1 = float(left) - MOT_OFFSET, float(top) - MOT_OFFSET
    return x1, y1, x1 + float(width), y1 + float(height)


def gt_line(frame: int, obj: ObjectTruth, counted: bool) -> str:
    left, top, w, h = box_to_mot(obj.box)
    return f"{frame:d},{obj.id:d},{left:.2f},{top:.2f},{w:.2f},{h:.2f},{int(counted):d},{CAR_CLASS:d},{obj.visibility:.4f}"


def det_line(frame: int, box: Sequence[float], score: float) -> str:
    left, top, w, h = box_to_mot(box)
    return f"{frame:d},-1,{left:.2f},{top:.2f},{w:.2f},{h:.2f},{float(score):.4f},-1,-1,-1"


def seqinfo_text(name: str, fps: float, n_frames: int, camera: CameraModel) -> str:
    fps_text = f"{fps:g}"
    return (f"[Sequence]\nname={name}\nimDir=img1\nframeRate={fps_text}\nseqLength={n_frames:d}\n"
            f"imWidth={camera.width:d}\nimHeight={camera.height:d}\nimExt={IMAGE_EXT}\n")


class MotWriter:
    """Writes one MOTChallenge sequence directory ``root/<name>/``."""

    def __init__(self, root: Path, camera: CameraModel, name: str, fps: float, with_detections: bool = True) -> None:
        from harness.scoring.evaluate import EvalConfig

        self.name = sequence_name(name)
        self.names = (self.name,)
        self.camera, self.fps = camera, fps
        self.seq = Path(root) / self.name
        (self.seq / "img1").mkdir(parents=True)
        (self.seq / "gt").mkdir()
        self._gt = (self.seq / "gt" / "gt.txt").open("w")
        self._det = None
        if with_detections:
            (self.seq / "det").mkdir()
            self._det = (self.seq / "det" / "det.txt").open("w")
        self._eval = EvalConfig()
        self.frames = self.objects = self.detections = 0

    def add(self, index: int, image: np.ndarray, truth: FrameTruth, detections=None) -> None:
        from harness.scoring.rules import counted_mask

        frame = index + 1
        path = self.seq / "img1" / f"{frame:06d}{IMAGE_EXT}"
        if not cv2.imwrite(str(path), image, [cv2.IMWRITE_JPEG_QUALITY, JPEG_QUALITY]):
            raise OSError(f"{path}: cannot write image")
        objs = truth.objects
        for o, c in zip(objs, counted_mask(objs, self._eval)):
            self._gt.write(gt_line(frame, o, bool(c)) + "\n")
        self.objects += len(objs)
        if self._det is not None:
            for d in detections or ():
                self._det.write(det_line(frame, d.box, d.score) + "\n")
                self.detections += 1
        self.frames += 1

    def close(self) -> None:
        self._gt.close()
        if self._det is not None:
            self._det.close()
        (self.seq / "seqinfo.ini").write_text(seqinfo_text(self.name, self.fps, self.frames, self.camera))
