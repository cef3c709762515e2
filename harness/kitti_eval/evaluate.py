"""``monorarp eval kitti``: a KITTI dataset -> detector (or the labels) -> state estimator (and tracker
on sequences) -> the run scoring of :mod:`harness.scoring.evaluate` + KITTI AP, written atomically.
The steps: :mod:`~harness.kitti_eval.truth` (labels -> truth), :mod:`~harness.kitti_eval.run` (the
pipeline over the frames), :mod:`~harness.kitti_eval.score` (metrics and per-object rows).

Frames: an object dataset's images are independent (each is its own one-frame sequence: every
stage is reset before it, and each detection is its own track, so no tracker runs); a tracking
sequence's frames run in order through the tracker, at ``t = frame / fps`` (KITTI: 10 Hz).

Truth per frame (:class:`~harness.kitti_eval.truth.KittiFrameTruth`, the :class:`~harness.world.truth.FrameTruth` that
:func:`harness.scoring.evaluate.evaluate` reads, plus the label's KITTI fields): each label's box,
``d_long``/``d_lat`` from its location, size and yaw (:mod:`harness.kitti_eval.geometry`); on
tracking sequences ``v_long``/``v_lat`` = finite differences of those over the frame times of the
same track id (central, one-sided at a track's ends); no TTC or ego speed (null in ``metrics.json``).

A label **counts** (must be found; a track matching it is scored for distance) when its type is
``Car``, ``Van`` or ``Truck`` and it passes KITTI's *moderate* filter (object datasets: box height
> 25 px, occlusion <= 1, truncation <= 0.30) or KITTI tracking's (box height > 25 px, occlusion
<= 2, truncation level 0), and lies within 80 m; every other label (other types, ``DontCare``,
harder vehicles) is *ignored*: neither missed nor, when a detection or track matches it, a false
positive (the run scoring's rule).

Outputs in ``OUT``: ``metrics.json`` (the run keys, ``tracking`` null for object datasets, plus
``kitti_ap`` from :mod:`harness.scoring.kitti_ap` and ``dataset``) and ``per_object.csv`` (the run's
columns plus ``sample``, ``type``, ``truncated``, ``occluded``, ``difficulty``, ``label``).
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import numpy as np

from harness.kitti_eval.options import LABELS_DETECTOR, KittiEvalOptions
from harness.kitti_eval.reader import Dataset
from harness.kitti_eval.run import run_dataset
from harness.kitti_eval.score import score, write_rows
from harness.scoring.evaluate import write_metrics
from monorarp.app.io import atomic_output_dir

__all__ = ["LABELS_DETECTOR", "KittiEvalOptions", "dataset_summary", "evaluate_kitti"]

METRICS_NAME = "metrics.json"
PER_OBJECT_NAME = "per_object.csv"
OUTPUT_NAMES = (METRICS_NAME, PER_OBJECT_NAME)


def evaluate_kitti(ds: Dataset, opts: KittiEvalOptions, out: str | Path) -> dict:
    """Run, score and write ``OUT/metrics.json`` and ``OUT/per_object.csv`` (all or nothing); returns metrics."""
    start = time.perf_counter()
    with atomic_output_dir(out, owned_names=OUTPUT_NAMES) as tmp:
        truths, results, facts = run_dataset(ds, opts)
        metrics, rows = score(ds, truths, results, facts, time.perf_counter() - start)
        write_metrics(metrics, tmp / METRICS_NAME)
        write_rows(rows, tmp / PER_OBJECT_NAME)
    return metrics


def dataset_summary(metrics: dict) -> str:
    """A few lines for the terminal."""
    ap = metrics["kitti_ap"]
    d, lat, det = metrics["distance"], metrics["lateral"], metrics["detection"]

    def num(v: Any, fmt: str = "{:.3f}") -> str:
        return "-" if v is None or (isinstance(v, float) and not np.isfinite(v)) else fmt.format(v)

    lines = [f"{metrics['dataset']['kind']} dataset, {metrics['frames']} frames, "
             f"{metrics['dataset']['labels']} labels; detector {metrics['config']['components']['detector']}",
             f"distance |d_y - d_long| median {num(d['abs_err_median_m'])} m, rel. median "
             f"{num(d['rel_err_median'])} ({d['count']} pairs); lateral median {num(lat['abs_err_median_m'])} m",
             f"detection @IoU 0.5: precision {num(det['precision'])}, recall {num(det['recall'])}"]
    for thr in ("0.7", "0.5"):
        a = ap[f"iou_{thr}"]
        lines.append(f"Car AP_R40 @IoU {thr}: easy {num(a['easy']['ap_r40'])}, moderate "
                     f"{num(a['moderate']['ap_r40'])}, hard {num(a['hard']['ap_r40'])}")
    t = metrics.get("tracking") or {}
    if t.get("mota") is not None:
        lines.append(f"tracking: MOTA {num(t['mota'])}, IDF1 {num(t['idf1'])}, HOTA {num(t.get('hota'))}")
    lines.append(f"{num(metrics['dataset']['frames_per_s_total'], '{:.1f}')} frames/s overall, "
                 f"{num(metrics['fps'], '{:.1f}')} frames/s in the pipeline")
    return "\n".join(lines)
