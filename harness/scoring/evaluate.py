"""Scoring orchestration: per-frame truths + pipeline FrameResults -> records and ``metrics.json``.

Tracks are matched to counted ground-truth objects per frame (Hungarian on IoU,
:mod:`~harness.scoring.pairing`), then each metric family scores the run: distance, lateral and
velocity errors (m, m/s; :mod:`~harness.scoring.state_errors`), TTC warnings
(:mod:`~harness.scoring.ttc_warnings`), tracking (:mod:`~harness.scoring.tracking`), detection
(:mod:`~harness.scoring.detection`), lane speed (:mod:`~harness.scoring.lane_speed`), risk
(:mod:`~harness.scoring.risk`), warning episodes (:mod:`~harness.scoring.warnings`), runtime
(:mod:`~harness.scoring.runtime`) and the horizon (:mod:`~harness.scoring.horizon`), all under the
rules of :class:`~harness.scoring.rules.EvalConfig` (:mod:`~harness.scoring.rules`). The rules in
full: docs/metrics.md.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import asdict
from pathlib import Path

from harness.scoring.detection import detection_metrics
from harness.scoring.horizon import horizon_metrics
from harness.scoring.lane_speed import lane_speed_metrics
from harness.scoring.pairing import frame_records
from harness.scoring.records import ObjectRecord
from harness.scoring.risk import risk_metrics
from harness.scoring.rules import EvalConfig
from harness.scoring.runtime import runtime_metrics
from harness.scoring.state_errors import state_metrics
from harness.scoring.tracking import tracking_metrics
from harness.scoring.ttc_warnings import ttc_metrics
from harness.scoring.warnings import warning_metrics
from harness.world.truth import FrameTruth
from monorarp.app.io import write_json_atomic
from monorarp.core.camera import CameraModel
from monorarp.core.types import FrameResult, RiskEstimate

__all__ = ["EvalConfig", "evaluate", "write_metrics"]

NAN = float("nan")


def evaluate(truths: Sequence[FrameTruth], results: Sequence[FrameResult], cfg: EvalConfig = EvalConfig(),
             wall_time_s: float | None = None, run_info: Mapping | None = None,
             camera: CameraModel | None = None, baseline_risk: Sequence[RiskEstimate] | None = None,
             ego_speed_method: str | None = None, fcw_threshold_s: float | None = None,
             tracking: bool = True) -> tuple[dict, list[ObjectRecord]]:
    """Score a run. ``truths[i]`` and ``results[i]`` must describe the same frame.

    ``camera`` (the one that rendered the frames) enables the range filter on predictions.
    ``baseline_risk``: the 1/TTC estimator's output on the same frames (``risk.baseline_ttc``).
    ``ego_speed_method``: name of the ego-speed stage (None: the run has none).
    ``fcw_threshold_s``: the warning stage's TTC threshold, which defines a truth conflict
    for ``warning.*`` (:mod:`harness.scoring.warnings`); None: ``cfg.warning_threshold_s``.
    ``tracking=False``: the frames are independent images, ``tracking.*`` is all null.

    Returns ``(metrics, records)``; ``metrics`` is JSON-ready after :func:`monorarp.app.io.to_jsonable`.
    """
    if len(truths) != len(results):
        raise ValueError(f"{len(truths)} truths but {len(results)} results")
    for tr, res in zip(truths, results):
        if tr.frame != res.index:
            raise ValueError(f"truth frame {tr.frame} paired with result frame {res.index}")
    records = [r for tr, res in zip(truths, results) for r in frame_records(tr, res, cfg, camera)]
    sm = state_metrics(records)
    runtime, fps = runtime_metrics(results, wall_time_s)
    metrics = {
        "frames": len(results),
        **{k: sm[k] for k in ("distance", "lateral", "rel_velocity")},
        "ttc": ttc_metrics(records, truths, results, cfg),
        "tracking": tracking_metrics(truths, results, cfg, camera, tracking),
        "detection": detection_metrics(truths, results, cfg, camera),
        "lane_speed": lane_speed_metrics(truths, results, ego_speed_method),
        "risk": risk_metrics(truths, results, cfg, baseline_risk),
        "warning": warning_metrics(truths, results, fcw_threshold_s or cfg.warning_threshold_s, cfg.min_iou),
        "runtime_ms": runtime,
        "fps": fps,
        "wall_time_s": NAN if wall_time_s is None else float(wall_time_s),
        "counts": {"gt_object_frames": sum(len(t.objects) for t in truths),
                   "counted_object_frames": int(sum(r.counted for r in records if r.gt_id is not None)),
                   "track_frames": sum(len(r.tracks) for r in results),
                   "detections": sum(len(r.detections) for r in results), **sm["pairs"]},
        "scoring": {**asdict(cfg), "range_filter_on_predictions": camera is not None},
        "config": dict(run_info or {}),
    }
    horizon = horizon_metrics(truths, results, camera)
    if horizon is not None:
        metrics["horizon"] = horizon
    return metrics, records


def write_metrics(metrics: Mapping, path: str | Path) -> None:
    """Strict JSON (NaN -> null), written atomically."""
    write_json_atomic(path, metrics, indent=2)
