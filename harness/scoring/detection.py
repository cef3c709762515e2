"""Detection precision and recall (``detection`` of ``metrics.json``): the detector's raw boxes against
the counted objects at IoU ``min_iou``, with the rules' ignored objects and set-aside boxes left out."""

from __future__ import annotations

from collections.abc import Sequence

from harness.scoring import algo
from harness.scoring.match import split_ignored
from harness.scoring.rules import EvalConfig, counted_mask, out_of_range
from harness.world.truth import FrameTruth
from monorarp.core.boxes import as_boxes
from monorarp.core.camera import CameraModel
from monorarp.core.types import FrameResult


def detection_metrics(truths: Sequence[FrameTruth], results: Sequence[FrameResult], cfg: EvalConfig,
                      camera: CameraModel | None = None) -> dict:
    """Precision, recall, F1 and counts over the run, and the ``min_iou`` they are taken at.

    ``camera`` (the one that rendered the frames) enables the range filter on the detections.
    """
    tp = n_pred = n_true = 0
    for truth, res in zip(truths, results):
        counted = counted_mask(truth.objects, cfg)
        gt_boxes = as_boxes([o.box for o in truth.objects])
        det_boxes = as_boxes([d.box for d in res.detections])
        kept, ignored = split_ignored(gt_boxes, counted, det_boxes, cfg.min_iou, cfg.ignore_cover,
                                      out_of_range(det_boxes, camera, cfg.max_range_m))
        tp += len(kept)
        n_pred += int((~ignored).sum())
        n_true += int(counted.sum())
    detection = algo.precision_recall(tp, n_pred, n_true)
    detection["min_iou"] = cfg.min_iou
    return detection
