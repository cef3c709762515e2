"""Scoring of a KITTI run: the run scoring (:func:`harness.scoring.evaluate.evaluate`), KITTI's Car AP
(:mod:`harness.scoring.kitti_ap`) and the dataset's facts -> ``metrics.json``; the per-object records with
each label's KITTI columns -> ``per_object.csv``."""

from __future__ import annotations

import csv
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from harness.kitti_eval.reader import Dataset
from harness.kitti_eval.truth import KittiFrameTruth
from harness.scoring import kitti_ap
from harness.scoring.evaluate import EvalConfig, evaluate
from harness.scoring.records import COLUMNS, ObjectRecord, cell
from monorarp.core.types import FrameResult

KITTI_COLUMNS = ("sample", "type", "truncated", "occluded", "difficulty", "label")


def ap_inputs(truths: list[KittiFrameTruth], results: list[FrameResult]) -> tuple[list, list]:
    """Per-image :class:`~harness.scoring.kitti_ap.ImageTruth` / ``ImageDetections`` of the detector's output."""
    tr, de = [], []
    for truth, res in zip(truths, results):
        objs = truth.objects
        tr.append(kitti_ap.ImageTruth(types=[o.type for o in objs],
                                      boxes=np.array([o.box for o in objs], dtype=float).reshape(-1, 4),
                                      occluded=np.array([o.occluded for o in objs], dtype=int),
                                      truncated=np.array([o.truncated for o in objs], dtype=float)))
        de.append(kitti_ap.ImageDetections(boxes=np.array([d.box for d in res.detections], dtype=float).reshape(-1, 4),
                                           scores=np.array([d.score for d in res.detections], dtype=float),
                                           labels=[d.label for d in res.detections]))
    return tr, de


def bootstrap(tr: list, de: list, resamples: int = 400, seed: int = 0) -> dict:
    """Moderate Car AP_R40 at IoU 0.5 and 0.7 over image resamples (:func:`kitti_ap.bootstrap_ap_r40`): the
    95 % percentile interval and the resamples themselves (to compare two sets' APs, resample both)."""
    out: dict = {"unit": "image", "resamples": resamples, "seed": seed}
    for thr in (0.5, 0.7):
        b = kitti_ap.bootstrap_ap_r40(tr, de, "Car", "moderate", thr, resamples, seed)
        ok = b[np.isfinite(b)]
        out[f"moderate_iou_{thr:g}"] = {
            "interval_95": [round(float(v), 4) for v in np.percentile(ok, [2.5, 97.5])] if len(ok) else None,
            "samples": [None if not np.isfinite(v) else round(float(v), 4) for v in b]}
    return out


def score(ds: Dataset, truths: list[KittiFrameTruth], results: list[FrameResult], facts: dict,
          wall_s: float) -> tuple[dict, list[dict]]:
    """``(metrics, per-object rows)`` of a run (:func:`harness.kitti_eval.run.run_dataset`'s truths, results and
    facts); ``wall_s``: the evaluation's wall time so far (s)."""
    cfg = EvalConfig()
    run_info = {"dataset": str(ds.root), "kind": ds.kind, "components": facts["components"],
                "fps_sequence": facts["fps"] if ds.kind == "tracking" else None,
                "detector_score_threshold": facts.get("score_threshold")}
    metrics, records = evaluate(truths, results, cfg, wall_time_s=facts["pipeline_s"], run_info=run_info,
                                tracking=ds.kind == "tracking")
    tr, de = ap_inputs(truths, results)
    metrics["kitti_ap"] = kitti_ap.kitti_ap(tr, de, "Car")
    metrics["kitti_ap"]["bootstrap"] = bootstrap(tr, de)
    metrics["dataset"] = {
        "root": str(ds.root), "kind": ds.kind, "frames": len(truths),
        "sequences": len({t.sample.split("/")[0] for t in truths}) if ds.kind == "tracking" else None,
        "labels": sum(len(t.objects) for t in truths),
        "counted_rule": ("Car/Van/Truck, box height > 25 px, occluded <= 1, truncated <= 0.30, d_long <= 80 m"
                         if ds.kind == "object" else
                         "Car/Van/Truck, box height > 25 px, occluded <= 2, truncation level 0, d_long <= 80 m"),
        "distance_truth": "nearest ego-y of the label's footprint (location, w, l, rotation_y; heading "
                          "(cos ry, -sin ry / cos pitch)); lateral: ego-x of the bottom-face centre",
        "skipped_lines": {"count": len(ds.skipped), "lines": list(ds.skipped)},
        "camera": facts["camera"], "camera_model": facts.get("camera_model"),
        "frames_per_s_total": len(truths) / wall_s if wall_s > 0 else None,
        "frames_per_s_pipeline": metrics["fps"]}
    rows = per_object_rows(truths, records)
    return metrics, rows


def per_object_rows(truths: list[KittiFrameTruth], records: Sequence[ObjectRecord]) -> list[dict]:
    """The run's per-object records with the KITTI columns of each label beside them."""
    by_key = {(t.frame, o.id): o for t in truths for o in t.objects}
    samples = {t.frame: t.sample for t in truths}
    rows = []
    for r in records:
        d = {c: getattr(r, c) for c in COLUMNS}
        o = by_key.get((r.frame, r.gt_id)) if r.gt_id is not None else None
        d.update({"sample": samples.get(r.frame, ""), "type": o.type if o else "",
                  "truncated": o.truncated if o else None, "occluded": o.occluded if o else None,
                  "difficulty": o.difficulty if o else "", "label": o.label if o else ""})
        rows.append(d)
    return rows


def write_rows(rows: list[dict], path: Path) -> None:
    """``per_object.csv``: the run's columns, then :data:`KITTI_COLUMNS` (empty cell = missing / NaN)."""
    cols = list(COLUMNS) + list(KITTI_COLUMNS)
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(cols)
        for r in rows:
            w.writerow([cell(r.get(c)) for c in cols])
