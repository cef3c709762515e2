"""Human names and units of metric keys for report tables and plots (docs/metrics.md has the definitions).

:func:`metric_label` gives ``"distance error 5–40 m, median %"`` for
``distance.by_span.5-40.rel_err_median``; :func:`display_value` scales a value to the label's unit
(relative errors are fractions in ``metrics.json`` and percent in every report table and plot).
"""

from __future__ import annotations

import math
import re
from typing import Any

#: key -> (name, unit); unit "%" means the stored value is a fraction shown as a percent.
LABELS: dict[str, tuple[str, str]] = {
    "frames": ("frames", ""),
    "fps": ("frames per second", ""),
    "distance.rel_err_median": ("distance error, median", "%"),
    "distance.rel_err_p90": ("distance error, p90", "%"),
    "distance.abs_err_median_m": ("distance error, median", "m"),
    "lateral.abs_err_median_m": ("lateral error, median", "m"),
    "rel_velocity.abs_err_median_mps": ("closing-speed error, median", "m/s"),
    "ttc.abs_err_median_s": ("TTC error, median", "s"),
    "ttc.warning.precision": ("TTC-warning precision", ""),
    "ttc.warning.recall": ("TTC-warning recall", ""),
    "ttc.frame_warning.precision": ("per-frame TTC-warning precision", ""),
    "ttc.frame_warning.recall": ("per-frame TTC-warning recall", ""),
    "tracking.mota": ("MOTA", ""),
    "tracking.idf1": ("IDF1", ""),
    "tracking.id_switches": ("ID switches", ""),
    "tracking.false_positives": ("false positives", ""),
    "tracking.misses": ("misses", ""),
    "detection.precision": ("detection precision", ""),
    "detection.recall": ("detection recall", ""),
    "lane_speed.rel_err_median": ("ego-speed error, median", "%"),
    "lane_speed.abs_err_median_mps": ("ego-speed error, median", "m/s"),
    "lane_speed.valid_fraction": ("ego speed valid", "%"),
    "warning.first_warning_ttc_s": ("true TTC at first warning", "s"),
    "warning.episodes": ("warning episodes", ""),
    "warning.false_alarms": ("false alarms", ""),
    "runtime_ms.total": ("pipeline time per frame", "ms"),
}
_BIN = re.compile(r"^distance\.by_(range|span)\.(\d+)-(\d+)\.(rel_err_median|abs_err_median_m|count)$")
_SUFFIXES = (("rel_err", "%"), ("_mps2", "m/s²"), ("_mps", "m/s"), ("_ms", "ms"), ("_m", "m"), ("_s", "s"))


def metric_unit(key: str) -> str:
    """The unit a metric is shown in ("%" for relative errors and fractions named so; "" for counts and scores)."""
    return _label(key)[1]


def _label(key: str) -> tuple[str, str]:
    if key in LABELS:
        return LABELS[key]
    m = _BIN.match(key)
    if m:
        what = {"rel_err_median": ("distance error {}–{} m, median", "%"),
                "abs_err_median_m": ("distance error {}–{} m, median", "m"),
                "count": ("object-frames {}–{} m", "")}[m.group(4)]
        return what[0].format(m.group(2), m.group(3)), what[1]
    if key.startswith("runtime_ms."):
        return f"{key.split('.', 1)[1].replace('.', ' ')} time", "ms"
    for suffix, unit in _SUFFIXES:
        if key.endswith(suffix) or f"{suffix}_" in key:
            return key.replace("_", " "), unit
    return key, ""


def metric_label(key: str) -> str:
    """``"name unit"`` of a metric key for a table header or an axis; unknown keys keep their name."""
    name, unit = _label(key)
    return f"{name} {unit}".strip()


def display_value(key: str, value: Any) -> Any:
    """``value`` in the label's unit: a relative error or fraction shown in % is multiplied by 100."""
    if metric_unit(key) == "%" and isinstance(value, (int, float)) and not isinstance(value, bool) \
            and math.isfinite(value):
        return 100.0 * value
    return value
