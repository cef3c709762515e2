"""Tracking metrics (``tracking`` of ``metrics.json``): CLEAR MOT and identity metrics (motmetrics,
:mod:`harness.scoring.mot`), HOTA (:mod:`harness.scoring.hota`) and, with a camera, the MOT metrics of
each range bin alone. Counted objects and set-aside tracks as the rules say (docs/metrics.md).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from harness.scoring import algo
from harness.scoring.mot import MotScorer
from harness.scoring.rules import EvalConfig, counted_mask, ground_range, out_of_range
from harness.world.truth import FrameTruth, ObjectTruth
from monorarp.core.boxes import as_boxes
from monorarp.core.camera import CameraModel
from monorarp.core.types import FrameResult

NAN = float("nan")
#: Keys of ``metrics["tracking"]`` (all null when tracking is not scored).
TRACKING_KEYS = ("mota", "motp", "idf1", "idp", "idr", "id_switches", "false_positives", "misses", "objects",
                 "unique_objects", "fragmentations", "mostly_tracked", "partially_tracked", "mostly_lost",
                 "precision", "recall", "hota", "deta", "assa", "loca", "hota_by_alpha", "by_range")
#: What each range bin of ``tracking.by_range`` is given (motmetrics names).
BIN_METRICS = ("mota", "idf1", "idr", "num_switches", "num_false_positives", "num_misses", "num_objects")


def tracking_metrics(truths: Sequence[FrameTruth], results: Sequence[FrameResult], cfg: EvalConfig,
                     camera: CameraModel | None = None, tracking: bool = True) -> dict:
    """``tracking.*``: motmetrics' CLEAR MOT and identity metrics, HOTA and ``by_range``.

    ``tracking=False`` (independent images, e.g. a KITTI object dataset): every value is null.
    ``by_range`` (with a camera): the CLEAR MOT and identity metrics of each range bin alone
    (:func:`range_bins_of`); null without a camera, which places unmatched tracks.
    """
    if not tracking:
        return dict.fromkeys(TRACKING_KEYS)
    mot = MotScorer(cfg.min_iou)
    bins = {name: MotScorer(cfg.min_iou, hota=False) for name in algo.RANGE_BINS} if camera is not None else {}
    for truth, res in zip(truths, results):
        objs = truth.objects
        counted = counted_mask(objs, cfg)
        gt_boxes = as_boxes([o.box for o in objs])
        gt_ids, tr_ids = [o.id for o in objs], [t.id for t in res.tracks]
        tr_boxes = as_boxes([t.box for t in res.tracks])
        split = mot.update(gt_ids, gt_boxes, counted, tr_ids, tr_boxes, frame=truth.frame,
                           ignore_cover=cfg.ignore_cover, track_out_of_range=out_of_range(tr_boxes, camera, cfg.max_range_m))
        if bins:
            gt_bin, tr_bin = range_bins_of(objs, counted, tr_boxes, camera, split)
            for name, scorer in bins.items():
                g, e = gt_bin == name, tr_bin == name
                scorer.add([i for i, k in zip(gt_ids, g) if k], gt_boxes[g], [i for i, k in zip(tr_ids, e) if k],
                           tr_boxes[e], frame=truth.frame)
    m = _finite(mot.compute())
    out = {"mota": m["mota"], "motp": m["motp"], "idf1": m["idf1"], "idp": m["idp"], "idr": m["idr"],
           **_counts(m),
           "unique_objects": int(m["num_unique_objects"]), "fragmentations": int(m["num_fragmentations"]),
           "mostly_tracked": int(m["mostly_tracked"]), "partially_tracked": int(m["partially_tracked"]),
           "mostly_lost": int(m["mostly_lost"]), "precision": m["precision"], "recall": m["recall"]}
    h = mot.hota_result()
    nothing = not (h.tp + h.fn + h.fp).any()     # no counted object and no track: null, as MOTA (TrackEval says 0)
    out.update({k: NAN if nothing else v for k, v in h.summary().items() if k in ("hota", "deta", "assa", "loca")})
    out["hota_by_alpha"] = h.to_dict()      # per-threshold statistics: sequences combine exactly (hota.combine)
    out["by_range"] = {name: {"mota": b["mota"], "idf1": b["idf1"], "idr": b["idr"], **_counts(b)}
                       for name, b in ((n, _finite(s.compute(BIN_METRICS))) for n, s in bins.items())} \
        if bins else None
    return out


def range_bins_of(objects: Sequence[ObjectTruth], counted: np.ndarray, tr_boxes: np.ndarray, camera: CameraModel,
                  split: tuple[list[tuple[int, int, float]], np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """The range bin (:data:`algo.RANGE_BINS` label, None: no bin) of each object and each track of a frame.

    A counted object is in the bin of its true ``d_long``. A track matched (IoU >= ``min_iou``) to a
    counted object is in that object's bin; any other track the whole-run scoring keeps is in the bin
    of its own claim, the ground range of its bottom edge (nuScenes' per-distance convention:
    a false positive is a vehicle claimed at that range). Tracks the whole run sets aside are in no bin.
    ``split``: the whole run's (matches, set-aside mask) of the frame (:meth:`MotScorer.update`).
    So each counted object, miss and false positive of the run falls in one bin.
    """
    gt_bin = algo.bin_labels([o.d_long for o in objects])
    gt_bin[~np.asarray(counted, dtype=bool)] = None
    tr_bin = algo.bin_labels(ground_range(tr_boxes, camera))
    kept, set_aside = split
    for g, e, _ in kept:
        tr_bin[e] = gt_bin[g]
    tr_bin[set_aside] = None
    return gt_bin, tr_bin


def _finite(m: Mapping[str, float]) -> dict[str, float]:
    """Undefined ratios (e.g. MOTA with no counted object is -inf in motmetrics) become nan -> null."""
    return {k: (v if np.isfinite(v) else NAN) for k, v in m.items()}


def _counts(m: Mapping[str, float]) -> dict[str, int]:
    return {"id_switches": int(m["num_switches"]), "false_positives": int(m["num_false_positives"]),
            "misses": int(m["num_misses"]), "objects": int(m["num_objects"])}
