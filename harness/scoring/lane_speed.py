"""Ego (lane) speed (``lane_speed`` of ``metrics.json``): ``FrameResult.ego_speed`` (m/s, None = no
estimate) against the truth's ``ego.speed``, over the frames with an estimate; ``valid_fraction`` =
those frames / all frames (null when the run has no ego-speed stage)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from harness.scoring import algo
from harness.world.truth import FrameTruth
from monorarp.core.types import FrameResult

NAN = float("nan")


def lane_speed_metrics(truths: Sequence[FrameTruth], results: Sequence[FrameResult], method: str | None) -> dict:
    """Ego-speed estimate (m/s) against the truth's ``ego.speed``; ``method``: the stage's name (None: none)."""
    est = np.array([NAN if r.ego_speed is None else float(r.ego_speed) for r in results], dtype=float)
    gt = np.array([t.ego.speed for t in truths], dtype=float)
    out: dict[str, Any] = {"method": method}
    out.update(algo.error_stats(est, gt, relative=True, unit="_mps"))
    n_valid = int(np.isfinite(est).sum())
    out["valid_fraction"] = algo.ratio(n_valid, len(results)) if method is not None else NAN
    out["frames_with_estimate"] = n_valid
    return out
