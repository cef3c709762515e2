"""Where an export's frames and ground truth come from: a scenario file or a run directory.

* ``SCENARIO.yaml`` — simulated and rendered now (:func:`harness.run.frame_feed.rendered_frames`,
  the frames ``monorarp run`` scores), so the images are the renderer's exact pixels.
* ``RUN_DIR`` — a directory written by ``monorarp run`` or ``monorarp render``: its
  ``camera.json`` and ``ground_truth.jsonl``, and its frames decoded from ``frames.mp4``
  (H.264 at the run's ``--crf``: the pixels are the encoder's, slightly off the
  rendered ones; the labels are exact either way). A run directory without
  ``frames.mp4`` (``monorarp run --no-video``, sweep runs) cannot be exported: the
  error says so; export its scenario file instead.

Everything the export needs is checked by :func:`open_source` before any output exists.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

from harness.run.outputs import CAMERA_NAME, GROUND_TRUTH_NAME, METRICS_NAME, VIDEO_NAME
from harness.world.scenario import Scenario
from harness.world.truth import FrameTruth
from monorarp.app.common_options import check_frames, frames_within
from monorarp.core.camera import CameraModel
from monorarp.core.errors import UserError
from monorarp.core.types import Frame

#: Ground-truth object fields the exports read.
OBJECT_FIELDS = ("id", "box", "visibility", "d_long", "corners_cam", "length", "width")


class ExportInputError(UserError, ValueError):
    """An export source that cannot be read (missing files, wrong frame count)."""


@dataclass
class ExportSource:
    """Frames with their ground truth, the camera that made them, and what they are."""

    name: str                    # sequence name (the scenario's)
    camera: CameraModel
    fps: float
    n_frames: int
    origin: str                  # one line for the summary: where the pixels come from
    frames: Iterator[tuple[Frame, FrameTruth]]


def open_source(path: str | Path, n_frames: int | None = None,
                adjust: Callable[[Scenario], Scenario] | None = None) -> ExportSource:
    """The first ``n_frames`` (default: all) of a scenario file (changed by ``adjust`` when given, e.g. its
    look) or a run directory."""
    path = Path(path)
    check_frames(n_frames, ExportInputError)
    if path.is_dir():
        return _run_dir(path, n_frames)
    if path.suffix.lower() in (".yaml", ".yml"):
        if not path.is_file():
            raise ExportInputError(f"{path}: no such scenario file")
        return _scenario(path, n_frames, adjust)
    if not path.exists():
        raise ExportInputError(f"{path}: no such run directory or scenario file")
    raise ExportInputError(f"{path}: neither a run directory nor a scenario file (.yaml)")


def _scenario(path: Path, n_frames: int | None, adjust: Callable[[Scenario], Scenario] | None = None) -> ExportSource:
    from harness.run.frame_feed import rendered_frames
    from harness.world.scenario import ScenarioError, frames_to_simulate, load_scenario

    scenario = load_scenario(path)
    scenario = scenario if adjust is None else adjust(scenario)
    n = frames_to_simulate(scenario, n_frames, path, "export")
    try:
        frames = rendered_frames(scenario, n)          # sets the simulation up: its errors come here
    except ScenarioError as e:
        msg = str(e).removeprefix(f"scenario {scenario.name!r}: ")
        raise ScenarioError(msg if msg.startswith(str(path)) else f"{path}: {msg}") from None
    return ExportSource(name=scenario.name, camera=scenario.camera.model(), fps=float(scenario.fps), n_frames=n,
                        origin=f"rendered from {path}", frames=frames)


def _read_truth(path: Path) -> list[FrameTruth]:
    truths = []
    try:
        with path.open(encoding="utf-8") as f:
            for k, line in enumerate(f, 1):
                if not line.strip():
                    continue
                try:
                    rec = json.loads(line)
                except json.JSONDecodeError as e:
                    raise ExportInputError(f"{path}: line {k}: not JSON ({e.msg})") from None
                if not isinstance(rec, dict) or not isinstance(rec.get("objects"), list) or "frame" not in rec:
                    raise ExportInputError(f"{path}: line {k}: not a ground-truth frame record")
                for obj in rec["objects"]:
                    missing = [f for f in OBJECT_FIELDS if not isinstance(obj, dict) or f not in obj]
                    if missing:
                        raise ExportInputError(f"{path}: line {k}: an object lacks {', '.join(missing)} "
                                               "(written by an older version? render the scenario again)")
                try:
                    truths.append(FrameTruth.from_json(rec))
                except (KeyError, TypeError, ValueError) as e:
                    raise ExportInputError(f"{path}: line {k}: not a ground-truth frame record "
                                           f"({type(e).__name__}: {e})") from None
    except OSError as e:
        raise ExportInputError(f"{path}: cannot read ({e.strerror or e})") from None
    except UnicodeDecodeError:
        raise ExportInputError(f"{path}: not UTF-8 text") from None
    for k, rec in enumerate(truths):
        if rec.frame != k:
            raise ExportInputError(f"{path}: record {k + 1} is frame {rec.frame}, expected {k}")
    return truths


def _run_fps(run_dir: Path, truths: list[FrameTruth]) -> float:
    metrics = run_dir / METRICS_NAME
    if metrics.is_file():
        try:
            fps = json.loads(metrics.read_text()).get("config", {}).get("fps_scenario")
            if isinstance(fps, (int, float)) and fps > 0:
                return float(fps)
        except (OSError, ValueError, AttributeError):
            pass
    if len(truths) >= 2:
        dt = truths[1].t - truths[0].t
        if dt > 0:
            return 1.0 / dt
    return float("nan")


def _run_name(run_dir: Path) -> str:
    metrics = run_dir / METRICS_NAME
    if metrics.is_file():
        try:
            name = json.loads(metrics.read_text()).get("config", {}).get("scenario")
            if isinstance(name, str) and name:
                return name
        except (OSError, ValueError, AttributeError):
            pass
    return run_dir.resolve().name


def _run_dir(run_dir: Path, n_frames: int | None) -> ExportSource:
    from monorarp.app.video.writer import read_video

    missing = [n for n in (CAMERA_NAME, GROUND_TRUTH_NAME) if not (run_dir / n).is_file()]
    if missing:
        raise ExportInputError(f"{run_dir}: not a run directory (no {' or '.join(missing)}; "
                               "`monorarp run` and `monorarp render` write them)")
    video = run_dir / VIDEO_NAME
    if not video.is_file():
        raise ExportInputError(f"{run_dir}: the run kept no frames ({VIDEO_NAME} is missing: `monorarp run --no-video` "
                               "and sweep runs write none); export its scenario file instead")
    camera = CameraModel.load(run_dir / CAMERA_NAME)
    truths = _read_truth(run_dir / GROUND_TRUTH_NAME)
    if not truths:
        raise ExportInputError(f"{run_dir / GROUND_TRUTH_NAME}: no frames")
    n = frames_within(n_frames, len(truths), "run directory's", f" in {run_dir}", ExportInputError)
    import cv2

    cap = cv2.VideoCapture(str(video))
    n_video = int(cap.get(cv2.CAP_PROP_FRAME_COUNT)) if cap.isOpened() else -1
    cap.release()
    if n_video < 0:
        raise ExportInputError(f"{video}: cannot open video")
    if n_video < n:
        raise ExportInputError(f"{video}: holds {n_video} frames, fewer than the {n} to export")
    fps = _run_fps(run_dir, truths)

    def gen() -> Iterator[tuple[Frame, FrameTruth]]:
        decoded = 0
        for vf, truth in zip(read_video(video, size=(camera.width, camera.height)), truths[:n]):
            decoded += 1
            yield Frame(index=truth.frame, t=truth.t, image=vf.image), truth
        if decoded < n:
            raise ExportInputError(f"{video}: decoded only {decoded} of {n} frames")

    return ExportSource(name=_run_name(run_dir), camera=camera, fps=fps, n_frames=n,
                        origin=f"decoded from {video} (H.264; labels exact)", frames=gen())
