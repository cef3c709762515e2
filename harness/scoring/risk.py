"""Risk scores (``risk`` of ``metrics.json``): AUROC and Brier score of each frame's risk against what
the simulation did next.

Frame j is an *event* when the ego's or a visible vehicle's ``crashed`` flag is set, or a visible
vehicle's true TTC is below ``near_miss_ttc_s`` (s); frame k is labelled positive when an event lies in
frames k .. k + ``risk_horizon_s`` x fps, negative when none does, excluded (nan) when that window
runs past the run's end with no event seen. A risk of ``kind == "probability"`` is its own probability; the paper's 1/TTC (1/s) is mapped
to ``min(1, risk * near_miss_ttc_s)`` for the Brier score. The rules in full: docs/metrics.md.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from harness.scoring import algo
from harness.scoring.rules import EvalConfig
from harness.world.truth import FrameTruth
from monorarp.core.types import FrameResult, RiskEstimate


def risk_event(truth: FrameTruth, near_miss_ttc_s: float) -> bool:
    """Collision (ego's or a visible vehicle's ``crashed`` flag) or near miss (a visible vehicle's TTC < threshold)."""
    if truth.ego.crashed:
        return True
    return any(o.crashed or (o.ttc is not None and o.ttc < near_miss_ttc_s) for o in truth.objects)


def horizon_frames(truths: Sequence[FrameTruth], horizon_s: float) -> int:
    """The label window in frames: ``round(horizon_s / dt)`` with dt the median frame interval."""
    t = np.array([tr.t for tr in truths], dtype=float)
    if t.size < 2:
        return 1 << 30                        # one frame: no window fits, only positives are labelled
    dt = float(np.median(np.diff(t)))
    return int(round(horizon_s / dt)) if dt > 0 else 1 << 30


def risk_labels(truths: Sequence[FrameTruth], cfg: EvalConfig) -> tuple[np.ndarray, np.ndarray]:
    """(events, labels) per frame: bool events and float labels (nan = excluded; see the module docstring)."""
    events = np.array([risk_event(t, cfg.near_miss_ttc_s) for t in truths], dtype=bool)
    return events, algo.horizon_labels(events, horizon_frames(truths, cfg.risk_horizon_s))


def risk_probability(estimates: Sequence[RiskEstimate], near_miss_ttc_s: float) -> np.ndarray:
    """Each risk as a probability: as is for ``kind == "probability"``, else 1/TTC mapped (module docstring)."""
    return np.array([min(max(e.risk, 0.0), 1.0) if e.kind == "probability"
                     else float(algo.inverse_ttc_probability(e.risk, near_miss_ttc_s)) for e in estimates],
                    dtype=float)


def _risk_scores(estimates: Sequence[RiskEstimate], labels: np.ndarray, near_miss_ttc_s: float) -> dict:
    ok = np.isfinite(labels)
    y = labels[ok].astype(bool)
    score = np.array([e.risk for e in estimates], dtype=float)[ok]
    prob = risk_probability(estimates, near_miss_ttc_s)[ok]
    kinds = sorted({e.kind for e in estimates})
    return {"kind": kinds[0] if len(kinds) == 1 else kinds, "auroc": algo.auroc(score, y),
            "brier": algo.brier(prob, y)}


def risk_metrics(truths: Sequence[FrameTruth], results: Sequence[FrameResult], cfg: EvalConfig,
                 baseline: Sequence[RiskEstimate] | None = None) -> dict:
    """``risk.*`` of ``metrics.json``: AUROC and Brier score against the horizon labels.

    ``baseline``: the 1/TTC estimator's output on the same frames, scored alike (``risk.baseline_ttc``).
    """
    events, labels = risk_labels(truths, cfg)
    ok = np.isfinite(labels)
    out: dict[str, Any] = _risk_scores([r.risk for r in results], labels, cfg.near_miss_ttc_s)
    out.update({"horizon_s": cfg.risk_horizon_s, "near_miss_ttc_s": cfg.near_miss_ttc_s,
                "inverse_ttc_probability": f"min(1, risk * {cfg.near_miss_ttc_s:g} s)",
                "frames_scored": int(ok.sum()), "positives": int((labels[ok] == 1).sum()),
                "negatives": int((labels[ok] == 0).sum()), "excluded_past_end": int((~ok).sum()),
                "event_frames": int(events.sum())})
    if baseline is not None:
        if len(baseline) != len(results):
            raise ValueError(f"{len(baseline)} baseline risks for {len(results)} frames")
        out["baseline_ttc"] = _risk_scores(list(baseline), labels, cfg.near_miss_ttc_s)
    return out
