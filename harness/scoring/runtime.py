"""Runtime (``runtime_ms`` and ``fps`` of ``metrics.json``): mean and p90 ms per frame of each stage."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from monorarp.core.types import FrameResult

NAN = float("nan")
#: The pipeline's stages, in the order ``runtime_ms`` lists them (other timings follow, sorted).
STAGES = ("detector", "ego_speed", "tracker", "state", "risk", "warning", "total")


def runtime_metrics(results: Sequence[FrameResult], wall_time_s: float | None) -> tuple[dict, float]:
    """Mean (and p90) per-frame time of each stage (ms) and frames per second of wall time."""
    keys = list(STAGES) + sorted({k for r in results for k in r.timings_ms} - set(STAGES))
    rt: dict[str, Any] = {}
    p90: dict[str, float] = {}
    for k in keys:
        x = np.array([r.timings_ms[k] for r in results if k in r.timings_ms], dtype=float)
        rt[k] = float(x.mean()) if x.size else NAN
        p90[k] = float(np.percentile(x, 90)) if x.size else NAN
    rt["p90"] = p90
    fps = len(results) / wall_time_s if wall_time_s and wall_time_s > 0 else NAN
    return rt, fps
