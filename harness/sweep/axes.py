"""Report section: every headline metric against the value of each grid axis.

For an axis, the runs are grouped by (variant, axis value) and a metric's mean over
the group's finished runs is plotted (so with several axes each point averages over
the others). Numeric axes are drawn on a numeric x axis (logarithmic when its positive values span
a factor of 100 or more, e.g. a curve radius from 300 m to 100 km); an axis with any
non-numeric value (e.g. ``conditions.time_of_day``, or ``null`` = effect off) is
drawn as categories in the spec's order.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

from harness.sweep.expand import format_value
from harness.sweep.labels import display_value, metric_label

MAX_METRICS = 8


def _num(v: Any) -> float | None:
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        return None
    return float(v)


def _log_scale(values: Sequence[float]) -> bool:
    """Whether a numeric axis reads better logarithmic: all values positive, spanning >= 100x."""
    return bool(values) and min(values) > 0 and max(values) >= 100 * min(values)


def axis_table(rows: Sequence[Mapping], key: str, metric: str) -> dict[str, list[tuple[Any, float | None]]]:
    """{variant: [(axis value, mean of ``metric`` over ok runs with that value, in the unit of its label:
    relative errors in %)]} in first-seen value order."""
    values: list[Any] = []
    for r in rows:
        v = r["grid"].get(key)
        if v not in values:
            values.append(v)
    out: dict[str, list[tuple[Any, float | None]]] = {}
    for variant in dict.fromkeys(r["variant"] for r in rows):
        pts = []
        for v in values:
            xs = [_num(r["metrics"].get(metric)) for r in rows
                  if r["variant"] == variant and r["status"] == "ok" and r["grid"].get(key) == v]
            xs = [x for x in xs if x is not None]
            pts.append((v, display_value(metric, sum(xs) / len(xs)) if xs else None))
        out[variant] = pts
    return out


def axis_section(rows: Sequence[Mapping], grid_keys: Sequence[str], headline: Sequence[str]) -> str:
    """HTML (heading, note, one figure per axis) or "" when the sweep has no grid."""
    from harness.sweep.html import png

    if not grid_keys or not rows:
        return ""
    import matplotlib.pyplot as plt

    metrics = list(headline)[:MAX_METRICS]
    heading = "<h2>Metrics against each grid axis</h2>"
    if not metrics or not any(r["status"] == "ok" for r in rows):
        return heading + "<p class='note'>No finished run: nothing to plot.</p>"
    parts = [heading + "<p class='note'>Mean over the finished runs with that axis value (and every value of "
             "the other axes), per variant.</p>"]
    for key in grid_keys:
        ncol = min(3, len(metrics))
        nrow = math.ceil(len(metrics) / ncol)
        fig, axs = plt.subplots(nrow, ncol, figsize=(4.2 * ncol, 3.0 * nrow), squeeze=False)
        for ax, metric in zip(axs.ravel(), metrics):
            table = axis_table(rows, key, metric)
            any_values = next(iter(table.values()), [])
            numeric = all(_num(v) is not None for v, _ in any_values)
            for variant, pts in table.items():
                xs = [float(v) if numeric else i for i, (v, _) in enumerate(pts)]
                ys = [float("nan") if y is None else y for _, y in pts]
                ax.plot(xs, ys, marker="o", label=variant)
            if numeric and _log_scale([float(v) for v, _ in any_values]):
                ax.set_xscale("log")
            if numeric and len(any_values) <= 12:
                ax.set_xticks([float(v) for v, _ in any_values], [format_value(v) for v, _ in any_values])
                ax.minorticks_off()
            if not numeric:
                ax.set_xticks(range(len(any_values)), [format_value(v) for v, _ in any_values], rotation=30)
            if not any(y is not None for pts in table.values() for _, y in pts):
                ax.text(0.5, 0.5, "no value in any finished run", ha="center", va="center",
                        transform=ax.transAxes, fontsize=8, color="0.4")
                ax.set_xticks([])
                ax.set_yticks([])
            ax.set_title(metric_label(metric), fontsize=9)
            ax.set_xlabel(key, fontsize=8)
            ax.grid(alpha=0.3)
        for ax in axs.ravel()[len(metrics):]:
            ax.set_visible(False)
        if len(table) > 1:
            axs.ravel()[0].legend(fontsize=7)
        fig.tight_layout()
        parts.append(png(fig))
    return "\n".join(parts)
