"""Metric names as ``check`` and the sweep summary see them: nested ``metrics.json`` sections flattened
to dotted names, and which of them are deterministic (everything but wall-clock timings)."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

#: Sections of ``metrics.json`` that are settings, not measurements.
SKIPPED_SECTIONS = ("config", "scoring")
#: Metric names (or dotted prefixes) measured on the wall clock.
NONDETERMINISTIC = ("runtime_ms.", "fps", "wall_time_s")


def flatten(metrics: Mapping[str, Any], prefix: str = "", skip: Sequence[str] = SKIPPED_SECTIONS) -> dict[str, Any]:
    """Nested metrics -> ``{dotted.name: number | bool | str | None}`` (lists are skipped)."""
    out: dict[str, Any] = {}
    for k, v in metrics.items():
        if not prefix and k in skip:
            continue
        name = f"{prefix}{k}"
        if isinstance(v, Mapping):
            out.update(flatten(v, f"{name}.", skip))
        elif v is None or isinstance(v, (bool, int, float, str)):
            out[name] = None if isinstance(v, float) and not math.isfinite(v) else v
    return out


def is_deterministic(name: str) -> bool:
    """Whether the metric ``name`` is a pure function of the run (not a wall-clock timing)."""
    return not any(name == p.rstrip(".") or name.startswith(p) for p in NONDETERMINISTIC)


def deterministic_metrics(flat: Mapping[str, Any]) -> dict[str, Any]:
    """``flat`` without wall-clock metrics (``runtime_ms.*``, ``fps``, ``wall_time_s``)."""
    return {k: v for k, v in flat.items() if is_deterministic(k)}
