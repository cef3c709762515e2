"""``summary.json`` and ``summary.csv``: one row per run of the spec, in expansion order.

A row: ``id``, ``scenario``, ``seed``, one ``grid.<field>`` per grid key,
``variant``, ``tracker``, ``detector``, ``status`` (ok/failed/missing), ``error``,
then the run's metrics flattened to dotted names (``distance.rel_err_median``,
``distance.by_range.0-10.rel_err_median``, ``tracking.mota``, ...; the
``config`` and ``scoring`` sections of ``metrics.json`` are left out: they are
settings, not measurements). Missing values are empty CSV cells / JSON null.

Determinism: every metric is a pure function of the run's parameters except
those matched by :data:`harness.check.metrics.NONDETERMINISTIC` (wall-clock timings), which
:func:`harness.check.metrics.deterministic_metrics` drops before comparing executors or worker counts.
"""

from __future__ import annotations

import csv
import io
import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from harness.check.metrics import flatten
from harness.sweep.expand import RunTask, format_value
from harness.sweep.worker import ERROR_JSON, METRICS_JSON, RUN_JSON
from monorarp.app.io import write_atomic, write_json_atomic
from monorarp.core.readers import read_json_or_none

SUMMARY_JSON = "summary.json"
SUMMARY_CSV = "summary.csv"


def collect_rows(tasks: Sequence[RunTask], runs_dir: Path) -> list[dict[str, Any]]:
    """The summary row of each task from what is on disk in ``runs_dir``."""
    rows = []
    for t in tasks:
        d = runs_dir / t.id
        run = read_json_or_none(d / RUN_JSON) or {}
        metrics = read_json_or_none(d / METRICS_JSON)
        err = read_json_or_none(d / ERROR_JSON) or {}
        if metrics is not None and run.get("status", "ok") == "ok":
            status, error = "ok", None
        elif run.get("status") == "failed" or err:
            status, error = "failed", run.get("error") or err.get("error") or "failed"
        else:
            status, error = "missing", "no result on disk"
        rows.append({"id": t.id, "scenario": t.scenario_key, "seed": t.seed,
                     "grid": dict(t.grid), "variant": t.variant,
                     "tracker": t.pipeline["tracker"]["name"], "detector": Path(t.pipeline["detector"]["name"]).name,
                     "status": status, "error": error,
                     "metrics": flatten(metrics) if status == "ok" and isinstance(metrics, Mapping) else {}})
    return rows


def csv_columns(rows: Sequence[Mapping[str, Any]], grid_keys: Sequence[str], headline: Sequence[str] = ()) -> list[str]:
    names = {k for r in rows for k in r["metrics"]}
    first = [m for m in headline if m in names]
    metric_cols = first + sorted(names - set(first))
    return ["id", "scenario", "seed", *(f"grid.{k}" for k in grid_keys), "variant", "tracker", "detector",
            "status", "error", *metric_cols]


def _cell(v: Any) -> str:
    if v is None:
        return ""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        return "" if not math.isfinite(v) else repr(v)
    if isinstance(v, (list, tuple)):
        return format_value(v)
    return str(v)


def to_csv(rows: Sequence[Mapping[str, Any]], grid_keys: Sequence[str], headline: Sequence[str] = ()) -> str:
    cols = csv_columns(rows, grid_keys, headline)
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(cols)
    for r in rows:
        flat = {"id": r["id"], "scenario": r["scenario"], "seed": r["seed"], "variant": r["variant"],
                "tracker": r["tracker"], "detector": r["detector"], "status": r["status"], "error": r["error"],
                **{f"grid.{k}": v for k, v in r["grid"].items()}, **r["metrics"]}
        w.writerow([_cell(flat.get(c)) for c in cols])
    return buf.getvalue()


def write_summary(out_dir: Path, rows: Sequence[Mapping[str, Any]], *, name: str, spec_path: str,
                  grid_keys: Sequence[str], headline: Sequence[str] = ()) -> None:
    """Write ``summary.json`` and ``summary.csv`` (each atomically)."""
    counts = {s: sum(r["status"] == s for r in rows) for s in ("ok", "failed", "missing")}
    write_json_atomic(out_dir / SUMMARY_JSON, {"version": 1, "name": name, "spec": spec_path,
                                               "grid_keys": list(grid_keys), "headline_metrics": list(headline),
                                               "counts": {"runs": len(rows), **counts}, "runs": list(rows)})
    write_atomic(out_dir / SUMMARY_CSV, to_csv(rows, grid_keys, headline))
