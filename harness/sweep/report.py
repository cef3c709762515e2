"""``report.html``: one self-contained page (inline CSS, plots as base64 PNG from matplotlib's Agg
backend, no scripts, no external resources) that opens in a browser with no network.

Sections: overview (with ``checks``: the regression verdict against a baseline and its failing
checks, :func:`verdict_section`) and failed runs; every run with its headline metrics (named with
units, :mod:`harness.sweep.labels`; a zero TTC-warning precision or recall and a failing check highlighted);
distance error against range per variant (pooled over runs from each run's
``per_object.csv``: counted, matched object-frames with a state, 0-80 m);
TTC over time against truth for the risky cases (scenario/seed/grid whose
ground truth has a TTC below the warning threshold; the object with the lowest
true TTC, every variant's estimate for it); tracker comparison; runtime breakdown.
"""

from __future__ import annotations

import html
import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from harness.sweep.html import CSS, fmt, png, table
from harness.sweep.labels import display_value, metric_label
from monorarp.warning.thresholds import TTC_CUE_THRESHOLD_S

DEFAULT_HEADLINE = ("distance.rel_err_median", "distance.abs_err_median_m", "rel_velocity.abs_err_median_mps",
                    "tracking.mota", "tracking.idf1", "tracking.id_switches", "ttc.warning.precision",
                    "ttc.warning.recall", "runtime_ms.total", "fps")
RANGE_EDGES = np.arange(0.0, 80.0 + 1e-9, 5.0)
REPORT_BINS = {"0-10": (0, 10), "10-20": (10, 20), "20-40": (20, 40), "40-80": (40, 80)}
STAGES = ("detector", "ego_speed", "tracker", "state", "risk", "warning")
MAX_TTC_PLOTS = 8
CSV_COLUMNS = ["t", "gt_id", "track_id", "counted", "matched", "d_long_gt", "d_y_est", "ttc_gt", "ttc_est"]

def _mean(values: Sequence[Any]) -> float | None:
    x = [float(v) for v in values if isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)]
    return float(np.mean(x)) if x else None


def _sum(values: Sequence[Any]) -> int | None:
    x = [int(v) for v in values if isinstance(v, (int, float)) and not isinstance(v, bool)]
    return int(sum(x)) if x else None


def _variants(rows: Sequence[Mapping]) -> list[str]:
    return list(dict.fromkeys(r["variant"] for r in rows))


def load_per_object(run_dir: Path):
    """The columns of ``per_object.csv`` the report uses (a pandas DataFrame), or None."""
    import pandas as pd

    path = run_dir / "per_object.csv"
    if not path.is_file():
        return None
    try:
        df = pd.read_csv(path, usecols=lambda c: c in CSV_COLUMNS)
    except (OSError, ValueError):
        return None
    for c in df.columns:          # an empty or partly empty file gives object columns
        if c in ("counted", "matched"):
            df[c] = pd.to_numeric(df[c], errors="coerce").fillna(0).astype(bool)
        else:
            df[c] = pd.to_numeric(df[c], errors="coerce").astype(float)
    return df


def _range_pairs(df) -> tuple[np.ndarray, np.ndarray]:
    """(true distance, estimated distance) of counted matched object-frames with a state, 0 <= d < 80 m."""
    if df is None or not {"counted", "matched", "d_long_gt", "d_y_est"} <= set(df.columns):
        return np.empty(0), np.empty(0)
    sel = df["counted"] & df["matched"] & np.isfinite(df["d_y_est"]) & (df["d_long_gt"] >= 0) & (df["d_long_gt"] < 80)
    return df.loc[sel, "d_long_gt"].to_numpy(float), df.loc[sel, "d_y_est"].to_numpy(float)


# ----------------------------------------------------------------- sections
def distance_section(rows: Sequence[Mapping], frames: Mapping[str, Any]) -> str:
    import matplotlib.pyplot as plt

    pooled: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    for v in _variants(rows):
        parts = [_range_pairs(frames.get(r["id"])) for r in rows if r["variant"] == v and r["status"] == "ok"]
        gt = np.concatenate([p[0] for p in parts]) if parts else np.empty(0)
        est = np.concatenate([p[1] for p in parts]) if parts else np.empty(0)
        pooled[v] = (gt, est)
    if not any(g.size for g, _ in pooled.values()):
        return "<h2>Distance error against range</h2><p class='note'>No scored object-frames.</p>"
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(11, 3.8))
    centres = (RANGE_EDGES[:-1] + RANGE_EDGES[1:]) / 2
    table_rows = []
    for v, (gt, est) in pooled.items():
        rel = np.abs(est - gt) / np.maximum(gt, 1e-9) * 100
        ab = np.abs(est - gt)
        idx = np.digitize(gt, RANGE_EDGES) - 1
        med_rel = [np.median(rel[idx == i]) if np.any(idx == i) else np.nan for i in range(len(centres))]
        med_abs = [np.median(ab[idx == i]) if np.any(idx == i) else np.nan for i in range(len(centres))]
        ax1.plot(centres, med_rel, marker="o", ms=3, label=v)
        ax2.plot(centres, med_abs, marker="o", ms=3, label=v)
        row: list[Any] = [v]
        for lo, hi in REPORT_BINS.values():
            m = (gt >= lo) & (gt < hi)
            row += [float(np.median(rel[m])) if m.any() else None, int(m.sum())]
        row.append(float(np.median(rel)) if rel.size else None)
        table_rows.append(row)
    ax1.set(xlabel="true longitudinal distance d_long (m)", ylabel="median |d_y - d_long| / d_long (%)",
            title="relative distance error (5 m bins)")
    ax2.set(xlabel="true longitudinal distance d_long (m)", ylabel="median |d_y - d_long| (m)",
            title="absolute distance error (5 m bins)")
    for ax in (ax1, ax2):
        ax.grid(alpha=0.3)
        ax.set_xlim(0, 80)
        ax.set_ylim(bottom=0)
    ax1.legend(fontsize=8)
    header = ["variant"] + [h for b in REPORT_BINS for h in (f"{b} m rel. median %", "n")] + ["all rel. median %"]
    return ("<h2>Distance error against range</h2><p class='note'>Pooled over every finished run of each variant: "
            "counted, matched object-frames with a state estimate, 0 ≤ d_long &lt; 80 m.</p>"
            + png(fig) + table(header, table_rows))


def _cases(rows: Sequence[Mapping]) -> dict[tuple, list[Mapping]]:
    out: dict[tuple, list[Mapping]] = {}
    for r in rows:
        key = (r["scenario"], r["seed"], tuple(r["grid"].items()))
        out.setdefault(key, []).append(r)
    return out


def ttc_section(rows: Sequence[Mapping], frames: Mapping[str, Any], threshold_s: float) -> str:
    import matplotlib.pyplot as plt

    plots, n_risky = [], 0
    for (scenario, seed, grid), runs in _cases(rows).items():
        truth_df = next((frames[r["id"]] for r in runs if frames.get(r["id"]) is not None), None)
        if truth_df is None or "ttc_gt" not in truth_df:
            continue
        gt_rows = truth_df[truth_df["counted"] & truth_df["gt_id"].notna() & np.isfinite(truth_df["ttc_gt"])]
        if gt_rows.empty or not (gt_rows["ttc_gt"] < threshold_s).any():
            continue
        n_risky += 1
        if len(plots) >= MAX_TTC_PLOTS:
            continue
        obj = gt_rows.loc[gt_rows["ttc_gt"].idxmin(), "gt_id"]
        fig, ax = plt.subplots(figsize=(6.2, 3.3))
        truth = truth_df[truth_df["gt_id"] == obj].sort_values("t")
        ax.plot(truth["t"], truth["ttc_gt"], color="black", lw=2, label="truth")
        for r in runs:
            df = frames.get(r["id"])
            if df is None:
                continue
            est = df[(df["gt_id"] == obj) & df["matched"]].sort_values("t")
            ax.plot(est["t"], est["ttc_est"], marker=".", ms=3, lw=1, label=r["variant"])
        ax.axhline(threshold_s, color="red", ls="--", lw=1, label=f"warning {threshold_s:g} s")
        ax.set(xlabel="t (s)", ylabel="TTC (s)", ylim=(0, 10),
               title=f"{scenario} seed {seed} {' '.join(f'{k}={v}' for k, v in grid)} (object {int(obj)})")
        ax.title.set_fontsize(9)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
        plots.append(png(fig))
    head = "<h2>TTC over time against truth (risky cases)</h2>"
    if not n_risky:
        return head + f"<p class='note'>No case has a true TTC below {threshold_s:g} s.</p>"
    more = f" Showing the first {MAX_TTC_PLOTS} of {n_risky}." if n_risky > MAX_TTC_PLOTS else ""
    return (head + f"<p class='note'>Cases whose ground truth has a TTC below {threshold_s:g} s; the object with the "
            f"lowest true TTC; estimates while a track is matched to it (gaps: no TTC or no match).{more}</p>"
            + "".join(plots))


def _zero_score(metric: str, value: Any) -> bool:
    """A warning precision or recall of exactly 0: the warning never fired for a real threat (or never rightly)."""
    return metric.endswith(("warning.recall", "warning.precision")) and isinstance(value, (int, float)) \
        and not isinstance(value, bool) and value == 0


def tracker_section(rows: Sequence[Mapping]) -> str:
    metrics = ["tracking.mota", "tracking.idf1", "tracking.id_switches", "tracking.false_positives", "tracking.misses",
               "distance.rel_err_median", "ttc.warning.precision", "ttc.warning.recall", "runtime_ms.tracker",
               "runtime_ms.total", "fps"]
    summed = {"tracking.id_switches", "tracking.false_positives", "tracking.misses"}
    header = ["variant", "tracker", "detector", "runs ok", *(metric_label(m) for m in metrics)]
    out, marks, titles = [], [], []
    for v in _variants(rows):
        rs = [r for r in rows if r["variant"] == v]
        ok = [r["metrics"] for r in rs if r["status"] == "ok"]
        vals = [(_sum if m in summed else _mean)([x.get(m) for x in ok]) for m in metrics]
        out.append([v, rs[0]["tracker"], rs[0]["detector"], f"{len(ok)}/{len(rs)}",
                    *(display_value(m, x) for m, x in zip(metrics, vals))])
        marks.append([""] * 4 + ["hl" if _zero_score(m, x) else "" for m, x in zip(metrics, vals)])
        titles.append([""] * 4 + ["0: no real threat warned in time" if _zero_score(m, x) else ""
                                  for m, x in zip(metrics, vals)])
    return ("<h2>Tracker comparison</h2><p class='note'>Per variant: means over finished runs (ID switches, false "
            "positives and misses summed); identical frames and detections for every variant of a case. "
            "Highlighted: a TTC-warning precision or recall of 0.</p>"
            + table(header, out, left=3, cell_classes=marks, cell_titles=titles))


def _stages_run(rows: Sequence[Mapping], runs_dir: Path | None) -> dict[str, set[str]]:
    """Per variant, the stages its pipeline has (``run.json``'s ``params.pipeline``; a stage set to null is not
    run); a variant without a readable record: every stage with a non-zero time."""
    from monorarp.core.readers import read_json_or_none

    out: dict[str, set[str]] = {}
    for v in _variants(rows):
        ok = [r for r in rows if r["variant"] == v and r["status"] == "ok"]
        run = read_json_or_none(runs_dir / ok[0]["id"] / "run.json") if ok and runs_dir is not None else None
        pipe = (run or {}).get("params", {}).get("pipeline") if isinstance(run, Mapping) else None
        if isinstance(pipe, Mapping):
            out[v] = {s for s in STAGES if pipe.get(s) is not None or s in ("detector", "tracker")}
        else:
            out[v] = {s for s in STAGES if any(r["metrics"].get(f"runtime_ms.{s}") for r in ok)}
    return out


def runtime_section(rows: Sequence[Mapping], runs_dir: Path | None = None) -> str:
    import matplotlib.pyplot as plt

    variants = _variants(rows)
    ran = _stages_run(rows, runs_dir)
    means = {v: {s: (_mean([r["metrics"].get(f"runtime_ms.{s}") for r in rows
                            if r["variant"] == v and r["status"] == "ok"]) if s in ran[v] else None)
                 for s in STAGES}
             for v in variants}
    totals = {v: _mean([r["metrics"].get("runtime_ms.total") for r in rows if r["variant"] == v and r["status"] == "ok"])
              for v in variants}
    if not any(totals.values()):
        return "<h2>Runtime breakdown</h2><p class='note'>No timings.</p>"
    shown = [s for s in STAGES if any(s in ran[v] for v in variants)] or list(STAGES)
    fig, ax = plt.subplots(figsize=(8, 0.6 + 0.45 * len(variants)))
    left = np.zeros(len(variants))
    for s in shown:
        vals = np.array([means[v][s] or 0.0 for v in variants])
        ax.barh(variants, vals, left=left, label=s)
        left += vals
    ax.set(xlabel="mean time per frame (ms)", title="pipeline runtime per stage")
    ax.invert_yaxis()
    ax.legend(fontsize=7, ncol=len(shown), loc="upper center", bbox_to_anchor=(0.5, -0.25 - 0.6 / len(variants)))
    ax.grid(alpha=0.3, axis="x")
    stage_table = table(["variant", *(f"{s} ms" for s in STAGES), "total ms", "fps"],
                         [[v, *(means[v][s] for s in STAGES), totals[v],
                           _mean([r["metrics"].get("fps") for r in rows if r["variant"] == v and r["status"] == "ok"])]
                          for v in variants])
    absent = [s for s in STAGES if s not in shown]
    note = f" “–”: a stage the sweep's pipeline does not run ({', '.join(absent)})." if absent else ""
    return ("<h2>Runtime breakdown</h2><p class='note'>Mean per-frame time of each stage (wall clock on the machine "
            f"that ran it; not part of any determinism or regression check).{note}</p>" + png(fig) + stage_table)


def verdict_section(checks: Sequence[Any], baseline_path: str) -> str:
    """The regression verdict against ``baseline_path`` (``monorarp check``'s rows) and its failing checks."""
    e = html.escape
    fails = [c for c in checks if c.failed]
    checked = sum(c.status != "new" for c in checks)
    new = sum(c.status == "new" for c in checks)
    improved = sum(c.status == "improved" for c in checks)
    extra = "".join([f"; {improved} improved beyond tolerance" if improved else "",
                     f"; {new} run(s) not in the baseline (not checked)" if new else ""])
    if not fails:
        return (f"<div class='verdict pass'><b>Regression check: OK</b> — all {checked} checks within tolerance of "
                f"<code>{e(baseline_path)}</code>{e(extra)}.</div>")
    rows = []
    for c in fails:
        scale = (lambda x: display_value(c.metric, x)) if c.metric != "*" else (lambda x: x)
        delta = None if c.delta is None else scale(c.delta)
        rows.append([c.run, metric_label(c.metric) if not c.metric.startswith("*") else c.metric, c.status,
                     scale(c.baseline), scale(c.now), delta, None if c.tolerance is None else scale(c.tolerance),
                     (c.direction or "").replace("_", " ")])
    return (f"<div class='verdict fail'><b>REGRESSION: {len(fails)} of {checked} checks failed</b> against "
            f"<code>{e(baseline_path)}</code>{e(extra)}.</div>"
            + table(["run", "metric", "status", "baseline", "now", "change", "tolerance", "direction"], rows, left=3))


def runs_section(rows: Sequence[Mapping], grid_keys: Sequence[str], headline: Sequence[str],
                 checks: Sequence[Any] = ()) -> str:
    failing = {(c.run, c.metric): c for c in checks if c.failed}
    header = ["id", "scenario", "seed", *grid_keys, "variant", "status", *(metric_label(m) for m in headline)]
    fixed = 5 + len(grid_keys)
    body, marks, titles = [], [], []
    for r in rows:
        vals = [r["metrics"].get(m) for m in headline]
        body.append([r["id"], r["scenario"], r["seed"], *(r["grid"].get(k) for k in grid_keys), r["variant"],
                     r["status"], *(display_value(m, v) for m, v in zip(headline, vals))])
        mk, tt = [""] * fixed, [""] * fixed
        for m, v in zip(headline, vals):
            c = failing.get((r["id"], m))
            if c is not None:
                mk.append("hl")
                tt.append(f"{c.status} against the baseline ({fmt(display_value(m, c.baseline))})")
            elif _zero_score(m, v):
                mk.append("hl")
                tt.append("0: no real threat warned in time")
            else:
                mk.append("")
                tt.append("")
        marks.append(mk)
        titles.append(tt)
    classes = ["failed" if r["status"] != "ok" else "" for r in rows]
    note = ("<p class='note'>Relative errors in %. Highlighted: a TTC-warning precision or recall of 0"
            + (", and every value failing the regression check" if checks else "") + ".</p>")
    return "<h2>Runs</h2>" + note + table(header, body, left=2, row_classes=classes, cell_classes=marks,
                                          cell_titles=titles)


def render_report(rows: Sequence[Mapping], runs_dir: Path, *, name: str, spec_path: str, grid_keys: Sequence[str],
                  headline: Sequence[str] = (), threshold_s: float = TTC_CUE_THRESHOLD_S,
                  checks: Sequence[Any] | None = None, baseline_path: str | None = None) -> str:
    """The whole HTML page as a string; ``checks`` (:func:`harness.check.baseline.compare`'s rows against
    ``baseline_path``): the regression verdict at the top."""
    import matplotlib

    matplotlib.use("Agg", force=True)
    headline = list(headline) or list(DEFAULT_HEADLINE)
    frames = {r["id"]: load_per_object(runs_dir / r["id"]) for r in rows if r["status"] == "ok"}
    n_ok = sum(r["status"] == "ok" for r in rows)
    failed = [r for r in rows if r["status"] != "ok"]
    e = html.escape
    status = (f"<span class='ok'>all {n_ok} runs finished</span>" if not failed else
              f"<span class='bad'>{len(failed)} of {len(rows)} runs failed</span>")
    parts = [f"<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'><title>{e(name)} — monorarp sweep</title>"
             f"<style>{CSS}</style></head><body>",
             f"<h1>Sweep {e(name)}</h1><p>spec <code>{e(spec_path)}</code> — {len(rows)} runs — {status}.</p>"]
    if checks is not None:
        parts.append(verdict_section(checks, baseline_path or "baseline"))
    if failed:
        parts.append("<h2>Failed runs</h2>" + table(["id", "status", "error"],
                                                      [[r["id"], r["status"], r["error"]] for r in failed], left=3))
    from harness.sweep.axes import axis_section

    parts += [runs_section(rows, grid_keys, headline, checks or ()), axis_section(rows, grid_keys, headline),
              distance_section(rows, frames),
              ttc_section(rows, frames, threshold_s), tracker_section(rows), runtime_section(rows, runs_dir),
              "</body></html>\n"]
    return "\n".join(parts)
