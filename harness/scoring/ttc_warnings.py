"""TTC warnings and errors (``ttc`` of ``metrics.json``): warning = TTC (s) below the threshold.

Per counted matched object-frame, the estimate's warnings against the truth's and the TTC error
where both have one; per frame (``frame_warning``), the scene warns when any estimated TTC is
below the threshold, the truth when any counted object's is.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from harness.scoring import algo
from harness.scoring.pairing import column, scored_pairs
from harness.scoring.records import ObjectRecord
from harness.scoring.rules import EvalConfig, counted_mask
from harness.world.truth import FrameTruth
from monorarp.core.types import FrameResult


def ttc_metrics(records: Sequence[ObjectRecord], truths: Sequence[FrameTruth], results: Sequence[FrameResult],
                cfg: EvalConfig) -> dict[str, Any]:
    """``ttc.*`` of ``metrics.json``: ``warning``, the errors (s) of pairs where both have a TTC, ``frame_warning``."""
    pairs = scored_pairs(records)
    ttc_est, ttc_gt = column(pairs, "ttc_est"), column(pairs, "ttc_gt")
    ttc: dict[str, Any] = {"warning": algo.warning_classification(ttc_est, ttc_gt, cfg.warning_threshold_s)}
    ttc.update(algo.error_stats(ttc_est, ttc_gt, relative=False, unit="_s"))
    ttc["frame_warning"] = frame_warning_metrics(truths, results, cfg)
    return ttc


def frame_warning_metrics(truths: Sequence[FrameTruth], results: Sequence[FrameResult], cfg: EvalConfig) -> dict:
    """Scene-level warnings: does the frame contain any TTC below the threshold?"""
    thr = cfg.warning_threshold_s
    est = [bool(algo.warnings_from_ttc(list(r.risk.ttc.values()), thr).any()) for r in results]
    gt = []
    for tr in truths:
        objs = [o for o, c in zip(tr.objects, counted_mask(tr.objects, cfg)) if c]
        gt.append(bool(algo.warnings_from_ttc([o.ttc for o in objs], thr).any()))
    est_a, gt_a = np.array(est, dtype=bool), np.array(gt, dtype=bool)
    return algo.precision_recall(int((est_a & gt_a).sum()), int(est_a.sum()), int(gt_a.sum()))
