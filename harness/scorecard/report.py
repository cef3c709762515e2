"""The scorecard's HTML section and its console table (from the ``scorecard.json`` mapping)."""

from __future__ import annotations

import html
from collections.abc import Mapping

import numpy as np

from harness.sweep.html import CSS, fmt, png, table

CSS_EXTRA = "tr.pass td{background:#e6f4ea}tr.fail td{background:#fde8e8}"


def _ttcs(t: Mapping) -> str:
    return " ".join("–" if v is None else f"{v:.2f}" for v in t["ttc_at_first_warning_s"])


def _params(t: Mapping) -> str:
    return ", ".join(f"{k} {v:g}" if isinstance(v, (int, float)) else f"{k} {v}" for k, v in t["params"].items())


def tests_rows(card: Mapping) -> tuple[list[str], list[list], list[str]]:
    header = ["suite", "test", "parameters", "ego km/h", "target km/h", "required TTC s", "passed trials",
              "true TTC at first warning (per trial) s", "verdict"]
    rows, classes = [], []
    for t in card["tests"]:
        rows.append([t["suite"], t["test"], _params(t), round(t["ego_speed_mps"] * 3.6, 1),
                     round(t["target_speed_mps"] * 3.6, 1), t["required_ttc_s"],
                     f"{t['trials_passed']}/{t['trials']} (need {t['min_trials_passed']})", _ttcs(t),
                     "PASS" if t["passed"] else "FAIL"])
        classes.append("pass" if t["passed"] else "fail")
    return header, rows, classes


def _warmup_note(fa: Mapping) -> str:
    """``", traffic warmed up 4 s"`` when the nominal runs' worlds ran before frame 0 (``traffic.warmup_s``)."""
    w = [v for v in fa.get("warmup_s") or [] if v]
    if not w:
        return ""
    return ", traffic warmed up " + " / ".join(f"{v:g}" for v in fa["warmup_s"]) + " s"


def _braking_note(fa: Mapping) -> str:
    """``" (N of them: ...)"`` for the false alarms whose vehicle truly braked hard enough (docs/metrics.md)."""
    n = fa.get("braking")
    if not n:
        return ""
    return (f" ({n} of them for a vehicle truly braking so hard that, had it kept braking, its TTC fell under "
            f"the threshold)")


def console_table(card: Mapping) -> str:
    """Plain-text scorecard for the terminal."""
    header, rows, _ = tests_rows(card)
    keep = [0, 1, 2, 3, 5, 6, 7, 8]
    cells = [[str(header[i]) for i in keep]] + [[fmt(r[i]) if not isinstance(r[i], str) else r[i] for i in keep]
                                                for r in rows]
    widths = [min(60, max(len(c[i]) for c in cells)) for i in range(len(keep))]
    lines = ["  ".join(c[i][:60].ljust(widths[i]) for i in range(len(keep))) for c in cells]
    fa = card["false_alarms"]
    if fa["runs"]:
        lines.append(f"false alarms: {fa['episodes']} in {fa['hours']:.2f} h / {fa['km']:.1f} km of nominal "
                     f"traffic ({fa['runs']} runs{_warmup_note(fa)}) = {fmt(fa['per_hour'])} per hour{_braking_note(fa)}")
        for e in fa["list"][:20]:
            lines.append(f"  {e['run']} t={e['t_s']:.2f}s: {e['why']}")
    if card.get("risk"):
        for h, per in card["risk"].items():
            lines.append(f"risk @ {h}: " + "; ".join(f"{name} AUROC {fmt(v['auroc'])} AP {fmt(v['ap'])} "
                                                     f"({v['positives']}/{v['frames']} positive frames)"
                                                     for name, v in per.items()))
    for k, v in card["summary"].items():
        lines.append(f"{k}: {fmt(v) if not isinstance(v, dict) else v}")
    if card["failed_runs"]:
        lines.append(f"{len(card['failed_runs'])} runs failed: " + "; ".join(f"{f['id']}: {f['error']}"
                                                                           for f in card["failed_runs"][:5]))
    return "\n".join(lines)


def timing_plot(card: Mapping) -> str:
    """True TTC at first warning against ego speed, one marker per trial and protocol, required TTC as lines."""
    import matplotlib.pyplot as plt

    tests = [t for t in card["tests"] if t["required_ttc_s"] is not None]
    if not tests:
        return ""
    fig, ax = plt.subplots(figsize=(8, 4.5))
    names = sorted({t["test"] for t in tests})
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for k, name in enumerate(names):
        xs, ys, miss = [], [], []
        for t in (t for t in tests if t["test"] == name):
            for v in t["ttc_at_first_warning_s"]:
                (xs.append(t["ego_speed_mps"] * 3.6), ys.append(v)) if v is not None else \
                    miss.append(t["ego_speed_mps"] * 3.6)
            req = t["required_ttc_s"]
            ax.hlines(req, t["ego_speed_mps"] * 3.6 - 3, t["ego_speed_mps"] * 3.6 + 3, colors=colours[k % 10],
                      linestyles="--", linewidth=1)
        c = colours[k % 10]
        ax.scatter(xs, ys, s=18, color=c, label=name, alpha=0.8)
        if miss:
            ax.scatter(miss, [0.0] * len(miss), marker="x", color=c, s=30)
    ax.set_xlabel("ego speed (km/h)")
    ax.set_ylabel("true TTC at first warning (s)")
    ax.set_title("Warning timing (dashes: required TTC; x at 0: no warning or a premature one)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, ncol=3)
    return png(fig)


def roc_plot(card: Mapping, curves: Mapping[str, tuple[np.ndarray, np.ndarray]] | None) -> str:
    import matplotlib.pyplot as plt

    if not curves:
        return ""
    fig, ax = plt.subplots(figsize=(4.5, 4.5))
    for name, (fpr, tpr) in curves.items():
        ax.plot(fpr, tpr, label=name)
    ax.plot([0, 1], [0, 1], color="#999", linewidth=0.8, linestyle=":")
    ax.set_xlabel("false positive rate")
    ax.set_ylabel("true positive rate")
    ax.set_title("Risk ROC, 2 s horizon (pooled)")
    ax.legend(fontsize=8)
    return png(fig)


def render_scorecard(card: Mapping, roc_curves: Mapping | None = None, standalone: bool = True) -> str:
    """The scorecard section (a whole page when ``standalone``)."""
    import matplotlib

    matplotlib.use("Agg", force=True)
    e = html.escape
    cfg = card["config"]
    parts = [f"<h2>Collision-warning scorecard</h2><p class='note'>detector <code>{e(cfg['detector'])}</code>, "
             f"tracker <code>{e(cfg['tracker'])}</code>, suites {e(', '.join(cfg['suites']))}. A conflict trial "
             f"passes when its first warning comes at a true TTC at or above the required one; a pass-by trial "
             f"when no warning comes.</p>"]
    summ = card["summary"]
    if summ:
        parts.append(table(["figure", "value"], [[k, v if not isinstance(v, dict) else
                                                    ", ".join(f"{a} {b}" for a, b in v.items())]
                                                   for k, v in summ.items()], left=2))
    if card["tests"]:
        header, rows, classes = tests_rows(card)
        parts.append(table(header, rows, left=3, row_classes=classes))
        parts.append(timing_plot(card))
    fa = card["false_alarms"]
    if fa["runs"]:
        parts.append(f"<h3>False alarms in nominal traffic</h3><p><b>{fa['episodes']}</b> warning episodes without "
                     f"a conflict in {fa['hours']:.2f} h ({fa['km']:.1f} km, {fa['runs']} runs"
                     f"{html.escape(_warmup_note(fa))}): "
                     f"<b>{fmt(fa['per_hour'])}</b> per hour{html.escape(_braking_note(fa))}.</p>")
        if fa["list"]:
            parts.append(table(["run", "t (s)", "track", "vehicle", "braking held: true TTC (s)", "why"],
                                [[x["run"], x["t_s"], x["track_id"], x["gt_id"], x.get("true_braking_ttc_s"), x["why"]]
                                 for x in fa["list"]], left=6))
    if card.get("risk"):
        rows = [[h, name, v["auroc"], v["ap"], v["positives"], v["frames"], v["runs"]]
                for h, per in card["risk"].items() for name, v in per.items()]
        parts.append("<h3>Risk over the scenario family</h3>" +
                     table(["horizon", "estimator", "AUROC", "AP", "positive frames", "frames", "runs"], rows, left=2))
        parts.append(roc_plot(card, roc_curves))
    if card["failed_runs"]:
        parts.append("<h3>Failed runs</h3>" + table(["run", "error"], [[f["id"], f["error"]]
                                                                        for f in card["failed_runs"]], left=2))
    body = "\n".join(p for p in parts if p)
    if not standalone:
        return body
    return (f"<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'><title>monorarp scorecard</title>"
            f"<style>{CSS}{CSS_EXTRA}</style></head><body><h1>monorarp scorecard</h1>\n{body}\n</body></html>\n")
