"""Regression check of run metrics against a committed baseline (``monorarp check``).

Each baseline metric has a ``value`` and a slack ``max(tolerance, rel_tolerance * |value|)`` in
the metric's units, judged by its ``direction`` (``lower_is_better``, ``higher_is_better``,
``two_sided``); missing metrics, missing or failed runs are regressions. The baseline format and
every rule: docs/metrics.md (regression check).
"""

from __future__ import annotations

import fnmatch
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from harness.check.metrics import flatten, is_deterministic
from monorarp.core.errors import UserError
from monorarp.app.io import write_json_atomic
from monorarp.core.readers import read_json

VERSION = 1
DIRECTIONS = ("lower_is_better", "higher_is_better", "two_sided")
LOWER, HIGHER, TWO = DIRECTIONS


class CheckInputError(UserError, ValueError):
    """Unreadable or malformed results or baseline (exit 2)."""


@dataclass(frozen=True)
class Rule:
    metric: str                 # fnmatch pattern over dotted metric names
    tolerance: float            # absolute slack, metric units
    direction: str
    rel_tolerance: float = 0.0  # slack as a fraction of |baseline value|

    def to_dict(self) -> dict:
        d = {"metric": self.metric, "tolerance": self.tolerance, "direction": self.direction}
        if self.rel_tolerance:
            d["rel_tolerance"] = self.rel_tolerance
        return d


#: Metrics a new baseline tracks and their default tolerances (absolute; fractions for rates).
DEFAULT_RULES: tuple[Rule, ...] = (
    Rule("frames", 0, TWO),
    Rule("counts.gt_object_frames", 0, TWO, 0.01),    # the simulated world itself changed
    Rule("counts.counted_object_frames", 0, TWO, 0.01),
    Rule("distance.rel_err_median", 0.003, LOWER, 0.1),
    Rule("distance.rel_err_p90", 0.01, LOWER, 0.1),
    Rule("distance.abs_err_median_m", 0.05, LOWER, 0.1),
    Rule("distance.by_range.*.rel_err_median", 0.01, LOWER, 0.1),
    Rule("distance.by_span.*.rel_err_median", 0.005, LOWER, 0.1),
    Rule("lateral.abs_err_median_m", 0.05, LOWER, 0.1),
    Rule("rel_velocity.abs_err_median_mps", 0.25, LOWER, 0.1),
    Rule("ttc.abs_err_median_s", 0.25, LOWER, 0.1),
    Rule("ttc.warning.precision", 0.05, HIGHER),
    Rule("ttc.warning.recall", 0.05, HIGHER),
    Rule("ttc.frame_warning.precision", 0.05, HIGHER),
    Rule("ttc.frame_warning.recall", 0.05, HIGHER),
    Rule("tracking.mota", 0.02, HIGHER),
    Rule("tracking.idf1", 0.02, HIGHER),
    Rule("tracking.id_switches", 1, LOWER),
    Rule("detection.precision", 0.02, HIGHER),
    Rule("detection.recall", 0.02, HIGHER),
    Rule("lane_speed.rel_err_median", 0.01, LOWER, 0.1),
    Rule("lane_speed.abs_err_median_mps", 0.2, LOWER, 0.1),
    Rule("lane_speed.valid_fraction", 0.05, HIGHER),
    Rule("warning.first_warning_ttc_s", 0.3, HIGHER),     # collision-warning timing (scorecard CI subset)
    Rule("warning.false_alarms", 0, LOWER),
    Rule("warning.episodes", 1, TWO),
)


@dataclass(frozen=True)
class RunResult:
    status: str                 # "ok" | "failed" | "missing"
    error: str | None
    metrics: dict[str, Any]     # flattened


@dataclass(frozen=True)
class CheckRow:
    run: str
    metric: str
    baseline: float | None
    now: float | None
    tolerance: float | None     # effective slack
    direction: str | None
    status: str                 # ok | improved | REGRESSED | changed | missing-metric | missing-run | run-failed | new

    @property
    def failed(self) -> bool:
        return self.status not in ("ok", "improved", "new")

    @property
    def delta(self) -> float | None:
        if isinstance(self.now, (int, float)) and isinstance(self.baseline, (int, float)):
            return float(self.now) - float(self.baseline)
        return None


# --------------------------------------------------------------------- input
def checked_exists(path: Path) -> bool:
    try:
        return path.exists()
    except OSError as e:   # e.g. a name too long
        raise CheckInputError(f"{str(path)[:200]}: cannot use this path ({e.strerror or e})") from None


def load_results(path: str | Path) -> dict[str, RunResult]:
    """Runs of a sweep directory (``summary.json``) or of one run directory (``metrics.json``)."""
    path = Path(path)
    if not checked_exists(path):
        raise CheckInputError(f"{path}: no such results directory")
    if path.is_file():
        raise CheckInputError(f"{path}: give a run directory (with metrics.json) or a sweep directory "
                              f"(with summary.json), not a file")
    if (path / "summary.json").is_file():
        data = read_json(path / "summary.json", "sweep summary", CheckInputError)
        runs = data.get("runs") if isinstance(data, dict) else None
        if not isinstance(runs, list) or not all(isinstance(r, dict) and "id" in r for r in runs):
            raise CheckInputError(f"{path / 'summary.json'}: not a sweep summary (no 'runs' list of runs with ids)")
        bad = next((i for i, r in enumerate(runs) if not isinstance(r.get("metrics") or {}, dict)), None)
        if bad is not None:
            raise CheckInputError(f"{path / 'summary.json'}: runs.{bad}.metrics: must be an object {{name: value}}")
        return {str(r["id"]): RunResult(str(r.get("status", "ok")), r.get("error"),
                                        dict(r.get("metrics") or {})) for r in runs}
    if (path / "metrics.json").is_file():
        metrics = read_json(path / "metrics.json", "run metrics", CheckInputError)
        if not isinstance(metrics, dict):
            raise CheckInputError(f"{path / 'metrics.json'}: not a metrics mapping")
        run_id = path.resolve().name
        if (path / "run.json").is_file():
            info = read_json(path / "run.json", "run record", CheckInputError)
            run_id = str(info.get("id", run_id)) if isinstance(info, dict) else run_id
        return {run_id: RunResult("ok", None, flatten(metrics))}
    raise CheckInputError(f"{path}: neither a run directory (metrics.json) nor a sweep directory (summary.json)")


def _number(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def _check_rule_fields(d: Mapping, where: str) -> None:
    if "tolerance" in d and not (_number(d["tolerance"]) and d["tolerance"] >= 0):
        raise CheckInputError(f"{where}: tolerance must be a number >= 0, got {d['tolerance']!r}")
    if "rel_tolerance" in d and not (_number(d["rel_tolerance"]) and d["rel_tolerance"] >= 0):
        raise CheckInputError(f"{where}: rel_tolerance must be a number >= 0, got {d['rel_tolerance']!r}")
    if "direction" in d and d["direction"] not in DIRECTIONS:
        raise CheckInputError(f"{where}: direction must be one of {', '.join(DIRECTIONS)}, got {d['direction']!r}")


def parse_baseline(data: Any, source: str | Path) -> dict:
    """Validate a baseline mapping (see the module docstring); raises :class:`CheckInputError`."""
    if not isinstance(data, dict):
        raise CheckInputError(f"{source}: a baseline must be a JSON object")
    unknown = sorted(set(data) - {"version", "defaults", "runs", "comment"})
    if unknown:
        raise CheckInputError(f"{source}: unknown key(s) {unknown}")
    if data.get("version") != VERSION:
        raise CheckInputError(f"{source}: version: expected {VERSION}, got {data.get('version')!r}")
    defaults = data.get("defaults", [])
    if not isinstance(defaults, list):
        raise CheckInputError(f"{source}: defaults: must be a list of rules")
    for i, d in enumerate(defaults):
        where = f"{source}: defaults.{i}"
        if not isinstance(d, dict) or not isinstance(d.get("metric"), str):
            raise CheckInputError(f"{where}: a rule needs 'metric' (a name pattern)")
        if set(d) - {"metric", "tolerance", "rel_tolerance", "direction"}:
            raise CheckInputError(f"{where}: unknown key(s) {sorted(set(d) - {'metric', 'tolerance', 'rel_tolerance', 'direction'})}")
        if "tolerance" not in d or "direction" not in d:
            raise CheckInputError(f"{where}: a rule needs 'tolerance' and 'direction'")
        _check_rule_fields(d, where)
    runs = data.get("runs")
    if not isinstance(runs, dict):
        raise CheckInputError(f"{source}: runs: must be an object {{run id: {{metric: entry}}}}")
    rules = _rules(data)
    for rid, metrics in runs.items():
        if not isinstance(metrics, dict):
            raise CheckInputError(f"{source}: runs.{rid}: must be an object {{metric: entry}}")
        for name, e in metrics.items():
            where = f"{source}: runs.{rid}.{name}"
            if not isinstance(e, dict) or "value" not in e:
                raise CheckInputError(f"{where}: an entry needs 'value'")
            if set(e) - {"value", "tolerance", "rel_tolerance", "direction"}:
                raise CheckInputError(f"{where}: unknown key(s) {sorted(set(e) - {'value', 'tolerance', 'rel_tolerance', 'direction'})}")
            if e["value"] is not None and not _number(e["value"]):
                raise CheckInputError(f"{where}: value must be a number or null, got {e['value']!r}")
            _check_rule_fields(e, where)
            if ("tolerance" not in e or "direction" not in e) and _match(rules, name) is None:
                raise CheckInputError(f"{where}: no tolerance/direction given and no default rule matches")
    return data


def load_baseline(path: str | Path) -> dict:
    path = Path(path)
    if not checked_exists(path):
        raise CheckInputError(f"{path}: no such baseline file")
    if not path.is_file():
        raise CheckInputError(f"{path}: not a file (a baseline is one JSON file)")
    return parse_baseline(read_json(path, "baseline", CheckInputError), path)


# ------------------------------------------------------------------- compare
def _rules(baseline: Mapping | None) -> list[Rule]:
    own = [Rule(d["metric"], float(d["tolerance"]), d["direction"], float(d.get("rel_tolerance", 0.0)))
           for d in (baseline or {}).get("defaults", [])]
    return own + list(DEFAULT_RULES)


def _match(rules: Sequence[Rule], name: str) -> Rule | None:
    return next((r for r in rules if fnmatch.fnmatchcase(name, r.metric)), None)


def _effective(entry: Mapping, rule: Rule | None) -> tuple[float, float, str]:
    tol = float(entry.get("tolerance", rule.tolerance if rule else 0.0))
    rel = float(entry.get("rel_tolerance", rule.rel_tolerance if rule else 0.0))
    direction = entry.get("direction", rule.direction if rule else TWO)
    return tol, rel, direction


def judge(value: float | None, now: float | None, slack: float, direction: str) -> str:
    """Status of one metric: ok / improved / REGRESSED / changed (null on one side only)."""
    if value is None or now is None:
        return "ok" if value is None and now is None else "changed"
    d = now - value
    worse = {LOWER: d > slack, HIGHER: -d > slack, TWO: abs(d) > slack}[direction]
    if worse:
        return "REGRESSED"
    better = {LOWER: -d > slack, HIGHER: d > slack, TWO: False}[direction]
    return "improved" if better else "ok"


def compare(baseline: Mapping, results: Mapping[str, RunResult]) -> list[CheckRow]:
    """One row per baseline (run, metric), plus rows for missing/failed/new runs."""
    rules = _rules(baseline)
    rows: list[CheckRow] = []
    for rid, metrics in baseline["runs"].items():
        res = results.get(rid)
        if res is None:
            rows.append(CheckRow(rid, "*", None, None, None, None, "missing-run"))
            continue
        if res.status != "ok":
            rows.append(CheckRow(rid, f"* ({res.error or res.status})", None, None, None, None, "run-failed"))
            continue
        for name, entry in metrics.items():
            tol, rel, direction = _effective(entry, _match(rules, name))
            value = entry["value"]
            slack = max(tol, rel * abs(value)) if value is not None else tol
            if name not in res.metrics:
                rows.append(CheckRow(rid, name, value, None, slack, direction, "missing-metric"))
                continue
            now = res.metrics[name]
            now = float(now) if _number(now) else None
            rows.append(CheckRow(rid, name, value, now, slack, direction, judge(value, now, slack, direction)))
    for rid in results:
        if rid not in baseline["runs"]:
            rows.append(CheckRow(rid, "*", None, None, None, None, "new"))
    return rows


# -------------------------------------------------------------------- update
def updated_baseline(old: Mapping | None, results: Mapping[str, RunResult]) -> dict:
    """A baseline of every ok run in ``results``: metrics matching the rules (plus any metric the old
    baseline tracked for that run), current values, tolerances and directions kept from ``old``."""
    rules = _rules(old)
    old_runs = (old or {}).get("runs", {})
    runs: dict[str, dict] = {}
    for rid in sorted(results):
        res = results[rid]
        if res.status != "ok":
            continue
        prev = old_runs.get(rid, {})
        names = [n for n in res.metrics if is_deterministic(n) and _match(rules, n) is not None]
        names += [n for n in prev if n in res.metrics and n not in names]
        entries = {}
        for name in sorted(names, key=lambda n: _order(rules, n)):
            rule = _match(rules, name)
            tol, rel, direction = _effective(prev.get(name, {}), rule)
            v = res.metrics[name]
            e: dict[str, Any] = {"value": float(v) if _number(v) else None, "tolerance": tol}
            if rel:
                e["rel_tolerance"] = rel
            e["direction"] = direction
            entries[name] = e
        runs[rid] = entries
    defaults = list((old or {}).get("defaults") or [r.to_dict() for r in DEFAULT_RULES])
    out: dict[str, Any] = {"version": VERSION}
    if old and "comment" in old:
        out["comment"] = old["comment"]
    out["defaults"] = defaults
    out["runs"] = runs
    return out


def _order(rules: Sequence[Rule], name: str) -> tuple[int, str]:
    idx = next((i for i, r in enumerate(rules) if fnmatch.fnmatchcase(name, r.metric)), len(rules))
    return idx, name


def write_baseline(path: str | Path, data: Mapping) -> None:
    path = Path(path)
    blocker = next((p for p in path.parents if p.exists() or p.is_symlink()), None)
    if blocker is not None and not blocker.is_dir():
        raise CheckInputError(f"{path}: cannot write baseline: {blocker} is not a directory")
    if path.is_dir():
        raise CheckInputError(f"{path}: cannot write baseline: it is a directory (give a file name)")
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        write_json_atomic(path, data, indent=2)
    except OSError as e:
        raise CheckInputError(f"{path}: cannot write baseline ({e.strerror or e})") from None


# -------------------------------------------------------------------- output
def _fmt(v: float | None, signed: bool = False) -> str:
    if v is None:
        return "null"
    return f"{v:+.4g}" if signed else f"{v:.4g}"


def format_table(rows: Sequence[CheckRow]) -> str:
    header = ("run", "metric", "baseline", "now", "delta", "tolerance", "status")
    body = []
    for r in rows:
        tol = "" if r.tolerance is None else ("±" if r.direction == TWO else "") + _fmt(r.tolerance)
        body.append((r.run, r.metric, "" if r.metric.startswith("*") else _fmt(r.baseline),
                     "" if r.metric.startswith("*") else _fmt(r.now),
                     "" if r.delta is None else _fmt(r.delta, signed=True), tol, r.status))
    widths = [max(len(h), *(len(b[i]) for b in body)) if body else len(h) for i, h in enumerate(header)]
    line = lambda cells: "  ".join(c.ljust(w) if i < 2 or i == 6 else c.rjust(w)  # noqa: E731
                                   for i, (c, w) in enumerate(zip(cells, widths))).rstrip()
    return "\n".join([line(header), line(tuple("-" * w for w in widths)), *(line(b) for b in body)])
