"""``per_frame.csv``: one row per frame of ego speed (m/s), risk and its label, warning and the truth's
crash flag and lowest TTC (s)."""

from __future__ import annotations

import csv
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from harness.scoring.records import as_float, cell
from harness.scoring.risk import risk_labels, risk_probability
from harness.scoring.rules import EvalConfig
from harness.world.truth import FrameTruth
from monorarp.core.types import FrameResult, RiskEstimate

NAN = float("nan")
FRAME_COLUMNS = ("frame", "t", "ego_speed_est", "ego_speed_gt", "risk", "risk_kind", "risk_probability",
                 "baseline_ttc_risk", "fcw_ttc_risk", "manoeuvre_ttc_risk", "risk_event", "risk_label",
                 "warning_active", "warning_track", "warning_ttc", "ego_crashed", "true_min_ttc")


def frame_rows(truths: Sequence[FrameTruth], results: Sequence[FrameResult], cfg: EvalConfig,
               baseline: Sequence[RiskEstimate] | None = None, fcw_risk: Sequence[float] | None = None,
               manoeuvre_risk: Sequence[float] | None = None) -> list[dict]:
    """One row per frame (``per_frame.csv``): ego speed estimate/truth (m/s), risk, its label (nan = excluded),
    the warning decision (active, track, its TTC) and the truth's crash flag and lowest TTC (s)."""
    events, labels = risk_labels(truths, cfg)
    prob = risk_probability([r.risk for r in results], cfg.near_miss_ttc_s)
    rows = []
    for k, (tr, res) in enumerate(zip(truths, results)):
        rows.append({"frame": res.index, "t": res.t,
                     "ego_speed_est": NAN if res.ego_speed is None else float(res.ego_speed),
                     "ego_speed_gt": tr.ego.speed, "risk": float(res.risk.risk),
                     "risk_kind": res.risk.kind, "risk_probability": float(prob[k]),
                     "baseline_ttc_risk": NAN if baseline is None else float(baseline[k].risk),
                     "fcw_ttc_risk": NAN if fcw_risk is None else float(fcw_risk[k]),
                     "manoeuvre_ttc_risk": NAN if manoeuvre_risk is None else float(manoeuvre_risk[k]),
                     "risk_event": bool(events[k]), "risk_label": labels[k],
                     "warning_active": bool(res.warning.active), "warning_track": res.warning.track_id,
                     "warning_ttc": as_float(res.warning.ttc), "ego_crashed": tr.ego.crashed,
                     "true_min_ttc": as_float(tr.min_ttc)})
    return rows


def write_frame_csv(rows: Sequence[Mapping], path: str | Path) -> None:
    """Write :func:`frame_rows` as CSV (empty cell = missing / NaN / excluded)."""
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(FRAME_COLUMNS)
        for r in rows:
            w.writerow([cell(int(r[c]) if c == "risk_label" and np.isfinite(r[c]) else r[c])
                        for c in FRAME_COLUMNS])
