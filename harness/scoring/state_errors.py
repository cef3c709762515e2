"""Distance, lateral and velocity errors (``distance``, ``lateral``, ``rel_velocity`` of ``metrics.json``).

Over the counted matched object-frames with ``0 <= d_long`` below the last range bin's end (80 m):
the estimate's ``d_y`` / ``d_x`` / ``v_y`` / ``v_x`` (m, m/s) against the truth's ``d_long`` / ``d_lat`` /
``v_long`` / ``v_lat``, by range bin and target span, with the distance intervals' coverage.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from harness.scoring import algo
from harness.scoring.pairing import column, scored_pairs
from harness.scoring.records import ObjectRecord


def state_metrics(records: Sequence[ObjectRecord]) -> dict[str, Any]:
    """``distance``, ``lateral``, ``rel_velocity`` and ``pairs`` (the object-frames scored) of ``metrics.json``."""
    pairs = scored_pairs(records)
    d_gt = column(pairs, "d_long_gt")
    in_range = (d_gt >= 0) & (d_gt < max(hi for _, hi in algo.RANGE_BINS.values()))
    scored = [r for r, ok in zip(pairs, in_range) if ok]
    col = {n: column(scored, n) for n in ("d_long_gt", "d_y_est", "d_lat_gt", "d_x_est", "v_long_gt",
                                          "v_y_est", "v_lat_gt", "v_x_est", "d_y_std")}
    distance = algo.error_stats(col["d_y_est"], col["d_long_gt"], relative=True, unit="_m")
    distance["by_range"] = algo.binned_error_stats(col["d_y_est"], col["d_long_gt"], col["d_long_gt"])
    distance["by_span"] = algo.binned_error_stats(col["d_y_est"], col["d_long_gt"], col["d_long_gt"],
                                                  bins=algo.TARGET_SPANS)
    distance.update(algo.interval_stats(col["d_y_est"], col["d_y_std"], col["d_long_gt"]))
    for name, (lo, hi) in algo.TARGET_SPANS.items():
        sel = (col["d_long_gt"] >= lo) & (col["d_long_gt"] < hi)
        distance["by_span"][name].update(algo.interval_stats(col["d_y_est"][sel], col["d_y_std"][sel],
                                                             col["d_long_gt"][sel]))
    lateral = algo.error_stats(col["d_x_est"], col["d_lat_gt"], relative=False, unit="_m")
    velocity = algo.error_stats(col["v_y_est"], col["v_long_gt"], relative=False, unit="_mps")
    velocity["lateral"] = algo.error_stats(col["v_x_est"], col["v_lat_gt"], relative=False, unit="_mps")
    return {"distance": distance, "lateral": lateral, "rel_velocity": velocity,
            "pairs": {"matched_counted": len(pairs), "in_range": len(scored),
                      "with_state": int(np.isfinite(col["d_y_est"]).sum())}}
