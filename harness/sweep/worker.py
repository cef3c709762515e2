"""One sweep run, isolated: whatever happens, ``runs/<id>/`` appears complete or not at all.

Success: the files of :func:`harness.run.runner.run_scenario` (``metrics.json``,
``per_object.csv``, ``camera.json``, ``ground_truth.jsonl``, ``annotated.mp4``
when videos are on) plus ``run.json`` (``{"id", "status": "ok", "error": null,
"params", "wall_time_s"}``). Failure: ``run.json`` with ``"status": "failed"``
and the one-line error, plus ``error.json`` (error and traceback).

This module imports nothing heavy at import time: executors pickle references
to its functions into fresh worker processes.
"""

from __future__ import annotations

import errno
import os
import re
import shutil
import tempfile
import time
import traceback
from dataclasses import dataclass
from pathlib import Path

from harness.sweep import faults
from harness.sweep.expand import RunTask

RUN_JSON = "run.json"
ERROR_JSON = "error.json"
METRICS_JSON = "metrics.json"

_detections = None    # this process's DetectionMemo (harness.run.detection_memo), made by the first run


def detection_memo():
    """This process's :class:`~harness.run.detection_memo.DetectionMemo`: runs that feed the same detector the
    same frames (the variants of one scenario instance) compute its detections once."""
    global _detections
    if _detections is None:
        from harness.run.detection_memo import DetectionMemo

        _detections = DetectionMemo()
    return _detections


@dataclass(frozen=True)
class RunOutcome:
    id: str
    status: str            # "ok" | "failed" | "skipped" (resume)
    error: str | None = None
    wall_time_s: float = 0.0


def owned_names() -> tuple[str, ...]:
    from harness.run.outputs import OUTPUT_NAMES

    return (*OUTPUT_NAMES, RUN_JSON, ERROR_JSON)


def _one_line(e: BaseException) -> str:
    return " ".join(f"{type(e).__name__}: {e}".split())


def describe_error(e: BaseException) -> str:
    """One line for a run's error; a full disk is named as such, with the file being written."""
    if isinstance(e, OSError) and e.errno in (errno.ENOSPC, errno.EDQUOT):
        name = Path(str(e.filename)).name if e.filename else ""
        name = re.sub(r"^\.(.+)\.[^.]+\.tmp$", r"\1", name)      # temp file of an atomic write -> its target
        return f"no space left on device{f' while writing {name}' if name else ''} ({_one_line(e)})"
    return _one_line(e)


def run_into(task: RunTask, out: Path) -> RunOutcome:
    """Run ``task`` writing its files into the existing empty directory ``out``; never raises for run errors."""
    os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
    from monorarp.app.io import write_json_atomic

    t0 = time.perf_counter()
    error, tb = task.error, None
    if error is None:
        try:
            import harness.run.runner as hrun
            from harness.world.scenario import parse_scenario
            from harness.scoring.evaluate import EvalConfig

            scenario = parse_scenario(task.scenario, task.scenario_file)
            n = scenario.n_frames if task.frames is None else min(task.frames, scenario.n_frames)
            extra = {}
            if task.cache_dir is not None:
                from harness.run.frame_cache import FrameCache

                extra["cache"] = FrameCache(task.cache_dir, task.cache_max_bytes)
            with faults.writing(task.id):
                hrun.run_scenario(scenario, task.pipeline, n_frames=n, out_dir=out, annotate=task.annotate,
                                  write_frames=False,
                                  eval_config=EvalConfig(warning_threshold_s=task.warning_threshold_s),
                                  detections=detection_memo(), **extra)
            if not (out / METRICS_JSON).is_file():
                raise RuntimeError("the run finished without writing metrics.json")
            faults.before_commit(task.id)
        except Exception as e:  # noqa: BLE001 - recorded; the sweep goes on
            error, tb = describe_error(e), traceback.format_exc()
    wall = time.perf_counter() - t0
    if error is not None:
        for p in out.iterdir():      # nothing half-done stays next to error.json
            shutil.rmtree(p) if p.is_dir() else p.unlink()
        write_json_atomic(out / ERROR_JSON, {"id": task.id, "error": error, "traceback": tb})
    status = "ok" if error is None else "failed"
    write_json_atomic(out / RUN_JSON, {"id": task.id, "status": status, "error": error,
                                       "params": task.params(), "wall_time_s": wall})
    return RunOutcome(task.id, status, error, wall)


def execute(task: RunTask, runs_dir: str) -> RunOutcome:
    """Run ``task`` into ``runs_dir/<id>/`` atomically (local executors: the driver's filesystem)."""
    from monorarp.app.io import atomic_output_dir

    with atomic_output_dir(Path(runs_dir) / task.id, owned_names=owned_names()) as tmp:
        outcome = run_into(task, tmp)
    return outcome


def execute_detached(task: RunTask) -> tuple[RunOutcome, dict[str, bytes]]:
    """Run ``task`` in a private temporary directory and return its files' bytes (remote executors:
    the worker may be on another machine, the driver writes the files)."""
    with tempfile.TemporaryDirectory(prefix=f"monorarp-{task.id[:40]}-") as d:
        out = Path(d) / "run"
        out.mkdir()
        outcome = run_into(task, out)
        files = {p.name: p.read_bytes() for p in sorted(out.iterdir()) if p.is_file()}
    return outcome, files


def write_run_files(runs_dir: str | Path, run_id: str, files: dict[str, bytes]) -> None:
    """Write a detached run's files as ``runs_dir/<run_id>/``, atomically."""
    from monorarp.app.io import atomic_output_dir

    allowed = set(owned_names())
    with atomic_output_dir(Path(runs_dir) / run_id, owned_names=owned_names()) as tmp:
        for name, data in files.items():
            if name not in allowed or "/" in name:
                raise ValueError(f"run {run_id}: unexpected file {name!r} from a worker")
            (tmp / name).write_bytes(data)


def failed_outcome_files(task: RunTask, error: str) -> dict[str, bytes]:
    """``run.json``/``error.json`` bytes for a run whose worker died before it could write them."""
    from monorarp.app.io import dumps

    return {RUN_JSON: (dumps({"id": task.id, "status": "failed", "error": error, "params": task.params(),
                              "wall_time_s": None}, indent=2) + "\n").encode(),
            ERROR_JSON: (dumps({"id": task.id, "error": error, "traceback": None}, indent=2) + "\n").encode()}
