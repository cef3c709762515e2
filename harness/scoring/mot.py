"""CLEAR MOT and identity metrics (py-motmetrics) from per-frame boxes.

Counting rule: each frame's ground-truth objects are split into *counted*
ones (by default visibility >= 0.3 and within the evaluation range; see
:class:`harness.scoring.rules.EvalConfig`) and *ignored* ones. Tracks are
first matched (Hungarian, IoU >= 0.5) against all objects; tracks matched to
an ignored object are removed from that frame (MOTChallenge's distractor
rule), and so are, optionally, tracks near no counted object that cover most
of an ignored object's visible box or lie beyond the evaluation range
(:func:`harness.scoring.match.split_ignored`). Ignored objects are not given
to the accumulator: they are neither misses nor false positives. Everything left goes to
``motmetrics.MOTAccumulator`` with distance 1 - IoU (NaN below IoU 0.5),
which does its own CLEAR-MOT matching with identity continuity.
``motp`` is therefore the mean (1 - IoU) of matched pairs (lower is better).

The distance matrix is computed here: motmetrics 1.4's ``distances.iou_matrix``
calls ``np.asfarray``, removed in numpy 2.

HOTA (:mod:`harness.scoring.hota`, motmetrics has none) sees the same frames: the
counted objects and the tracks left after the ignore rule, with their full IoU
matrix as the similarity (HOTA applies its own thresholds, 0.05 .. 0.95).
"""

from __future__ import annotations

from collections.abc import Sequence

import motmetrics as mm
import numpy as np

from harness.scoring.hota import HotaAccumulator, HotaResult
from harness.scoring.match import MIN_IOU, split_ignored
from monorarp.core.boxes import as_boxes, iou_matrix

METRICS = ("num_frames", "mota", "motp", "idf1", "idp", "idr", "num_switches", "num_false_positives",
           "num_misses", "num_objects", "num_matches", "num_fragmentations", "mostly_tracked",
           "partially_tracked", "mostly_lost", "num_unique_objects", "precision", "recall")


class MotScorer:
    """Feeds frames into a ``MOTAccumulator``; :meth:`compute` returns the metrics."""

    def __init__(self, min_iou: float = MIN_IOU, hota: bool = True) -> None:
        """``hota=False``: CLEAR MOT and identity metrics only (:meth:`hota_result` is unavailable)."""
        self.min_iou = min_iou
        self.acc = mm.MOTAccumulator(auto_id=False)
        self.hota = HotaAccumulator() if hota else None
        self._frame = 0

    def update(self, gt_ids: Sequence[int], gt_boxes, counted: Sequence[bool],
               track_ids: Sequence[int], track_boxes, frame: int | None = None,
               ignore_cover: float | None = None,
               track_out_of_range: Sequence[bool] | None = None) -> tuple[list[tuple[int, int, float]], np.ndarray]:
        """One frame: GT ids/boxes with their counted mask, track ids/boxes.

        ``ignore_cover``/``track_out_of_range``: see :func:`harness.scoring.match.split_ignored`.
        Returns that split: (Hungarian matches with counted objects, mask of the tracks set aside).
        """
        gt_boxes, track_boxes = as_boxes(gt_boxes), as_boxes(track_boxes)
        counted = np.asarray(counted, dtype=bool).reshape(-1)
        split = split_ignored(gt_boxes, counted, track_boxes, self.min_iou, ignore_cover, track_out_of_range)
        keep = ~split[1]
        self.add([i for i, c in zip(gt_ids, counted) if c], gt_boxes[counted],
                 [i for i, k in zip(track_ids, keep) if k], track_boxes[keep], frame)
        return split

    def add(self, gt_ids: Sequence[int], gt_boxes, track_ids: Sequence[int], track_boxes,
            frame: int | None = None) -> None:
        """One frame whose objects all count and whose tracks are all scored (no ignore rule)."""
        g_ids, h_ids = [int(i) for i in gt_ids], [int(i) for i in track_ids]
        iou = iou_matrix(as_boxes(gt_boxes), as_boxes(track_boxes))
        dist = np.where(iou >= self.min_iou, 1.0 - iou, np.nan)
        fid = self._frame if frame is None else int(frame)
        self.acc.update(g_ids, h_ids, dist, frameid=fid)
        if self.hota is not None:
            self.hota.update(g_ids, h_ids, iou)
        self._frame = fid + 1

    def compute(self, metrics: Sequence[str] = METRICS) -> dict[str, float]:
        """``metrics`` (default :data:`METRICS`) as plain floats (nan when undefined, e.g. MOTA with no objects)."""
        mh = mm.metrics.create()
        df = mh.compute(self.acc, metrics=list(metrics), name="run")
        return {k: float(df.loc["run", k]) for k in metrics}

    def hota_result(self) -> HotaResult:
        """HOTA of the frames fed so far (:func:`harness.scoring.hota.hota`)."""
        if self.hota is None:
            raise ValueError("this scorer was made with hota=False")
        return self.hota.compute()
