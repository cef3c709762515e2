"""The scorecard's HTML section and its console table (from the ``scorecard.json`` mapping)."""

from __future__ import annotations

import html
from collections.abc import Mapping

import numpy as np

from harness.sweep.html import CSS, fmt, png, table

CSS_EXTRA = "tr.pass td{background:#e6f4ea}tr.fail td{background:#fde8e8}"


def _ttcs(t: Mapping) -> str:
    return " ".join("–" if v is None else f"{v:.2f}" for v in t["ttc_at_first_warning_s"])


def _margins(t: Mapping) -> str:
    """Per trial: true TTC at first warning minus the required TTC (s); "–" for no timed warning or no requirement."""
    req = t["required_ttc_s"]
    if req is None:
        return "–"
    return " ".join("–" if v is None else f"{v - req:+.2f}" for v in t["ttc_at_first_warning_s"])


#: A protocol parameter's name and how its value reads (protocols.conflict_scenario's ``shown``).
PARAM_TEXT = {
    "offset": lambda v: "offset 0 %" if v == 0 else f"offset {100 * v:+.0f} %",   # of the target's width
    "gap_m": lambda v: f"gap {v:g} m",
    "decel_mps2": lambda v: f"decel {v:g} m/s²",
}
_SUFFIX_UNITS = (("_mps2", " m/s²"), ("_mps", " m/s"), ("_kmh", " km/h"), ("_m", " m"), ("_s", " s"))


def param_text(key: str, value) -> str:
    """``gap_m``, 30 -> ``gap 30 m``; a key without a known unit keeps its name."""
    if key in PARAM_TEXT and isinstance(value, (int, float)):
        return PARAM_TEXT[key](value)
    for suffix, unit in _SUFFIX_UNITS:
        if key.endswith(suffix) and isinstance(value, (int, float)):
            return f"{key[:-len(suffix)]} {value:g}{unit}"
    return f"{key} {value:g}" if isinstance(value, (int, float)) and not isinstance(value, bool) else f"{key} {value}"


def _params(t: Mapping) -> str:
    return ", ".join(param_text(k, v) for k, v in t["params"].items())


PARAM_NOTE = "offset: the target's lateral offset, % of its width; gap: the start distance; decel: the lead's braking"


def tests_rows(card: Mapping) -> tuple[list[str], list[list], list[str]]:
    header = ["suite", "test", "parameters", "ego km/h", "target km/h", "required TTC s", "passed trials",
              "true TTC at first warning s (per trial)", "margin s (per trial)", "verdict"]
    rows, classes = [], []
    for t in card["tests"]:
        rows.append([t["suite"], t["test"], _params(t), round(t["ego_speed_mps"] * 3.6, 1),
                     round(t["target_speed_mps"] * 3.6, 1), t["required_ttc_s"],
                     f"{t['trials_passed']}/{t['trials']} (need {t['min_trials_passed']})", _ttcs(t), _margins(t),
                     "PASS" if t["passed"] else "FAIL"])
        classes.append("pass" if t["passed"] else "fail")
    return header, rows, classes


def _pct(v: float) -> str:
    return f"{100 * v:.1f} %"


def summary_lines(summary: Mapping) -> list[tuple[str, str]]:
    """The headline figures as (label, text), no Python reprs: ``("test points passed", "ci 5/5")``."""
    out = []
    if "nhtsa_passed" in summary:
        out.append(("NHTSA test points passed", str(summary["nhtsa_passed"])))
    if "nhtsa_trials_passed" in summary:
        out.append(("NHTSA trials passed", str(summary["nhtsa_trials_passed"])))
    if summary.get("ncap_above_30kmh_ttc_ge_2s") is not None:
        ci = summary.get("ncap_above_30kmh_ttc_ge_2s_ci95")
        text = _pct(summary["ncap_above_30kmh_ttc_ge_2s"]) + f" of {summary.get('ncap_above_30kmh_runs')} runs"
        if ci:
            text += f" (95 % interval {_pct(ci[0])} – {_pct(ci[1])})"
        out.append(("Euro NCAP runs above 30 km/h warned at TTC ≥ 2.0 s", text))
    tp = summary.get("tests_passed")
    if isinstance(tp, Mapping) and tp:
        out.append(("test points passed", ", ".join(f"{k} {v}" for k, v in tp.items())))
    known = {"nhtsa_passed", "nhtsa_trials_passed", "ncap_above_30kmh_ttc_ge_2s", "ncap_above_30kmh_runs",
             "ncap_above_30kmh_ttc_ge_2s_ci95", "tests_passed"}
    out += [(k.replace("_", " "), fmt(v)) for k, v in summary.items()
            if k not in known and not isinstance(v, (dict, list))]
    return out


def _hours(h: float) -> str:
    return f"{h:.3g} h" + (f" ({h * 3600:.0f} s)" if h < 0.1 else "")


def false_alarm_rate(fa: Mapping) -> str:
    """``0 per hour (95 % interval 0 – 369); target ≤ 1 per hour: <verdict>``."""
    ci = fa.get("per_hour_ci95")
    text = f"{fmt(fa['per_hour'])} per hour"
    if ci and ci[1] is not None:
        text += f" (95 % interval {ci[0]:.3g} – {ci[1]:.3g})"
    target = fa.get("target_per_hour")
    if target is not None:
        text += f"; target ≤ {target:g} per hour: {fa.get('verdict')}"
        if str(fa.get("verdict", "")).startswith("exposure") and fa.get("hours_needed"):
            text += f" (needs {fa['hours_needed']:.2f} h without a false alarm)"
    return text


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
    keep = [0, 1, 2, 3, 5, 6, 7, 8, 9]
    cells = [[str(header[i]) for i in keep]] + [[fmt(r[i]) if not isinstance(r[i], str) else r[i] for i in keep]
                                                for r in rows]
    widths = [min(60, max(len(c[i]) for c in cells)) for i in range(len(keep))]
    lines = ["  ".join(c[i][:60].ljust(widths[i]) for i in range(len(keep))).rstrip() for c in cells]
    if rows:
        lines.append(f"({PARAM_NOTE}; margin: true TTC at first warning minus the required TTC)")
    fa = card["false_alarms"]
    if fa["runs"]:
        lines.append(f"false alarms: {fa['episodes']} in {_hours(fa['hours'])} / {fa['km']:.1f} km of nominal "
                     f"traffic ({fa['runs']} runs{_warmup_note(fa)}) = {false_alarm_rate(fa)}{_braking_note(fa)}")
        for e in fa["list"][:20]:
            lines.append(f"  {e['run']} t={e['t_s']:.2f}s: {e['why']}")
    if card.get("risk"):
        for h, per in card["risk"].items():
            lines.append(f"risk @ {h}: " + "; ".join(f"{name} AUROC {fmt(v['auroc'])} AP {fmt(v['ap'])} "
                                                     f"({v['positives']}/{v['frames']} positive frames)"
                                                     for name, v in per.items()))
    for label, text in summary_lines(card["summary"]):
        lines.append(f"{label}: {text}")
    if card["failed_runs"]:
        lines.append(f"{len(card['failed_runs'])} runs failed: " + "; ".join(f"{f['id']}: {f['error']}"
                                                                           for f in card["failed_runs"][:5]))
    return "\n".join(lines)


def timing_plot(card: Mapping) -> str:
    """True TTC at first warning against ego speed, one marker per trial and protocol, required TTC as lines.

    Tests at the same ego speed are set side by side (a few km/h apart); a trial without a timed
    warning is an x below the axis's 0, inside the plot."""
    import matplotlib.pyplot as plt
    from matplotlib.lines import Line2D

    tests = [t for t in card["tests"] if t["required_ttc_s"] is not None]
    if not tests:
        return ""
    fig, ax = plt.subplots(figsize=(8, 4.5))
    names = sorted({t["test"] for t in tests})
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    step = 1.6                                        # km/h between tests drawn at the same speed
    top, any_miss = 0.0, False
    for k, name in enumerate(names):
        dx = (k - (len(names) - 1) / 2) * step
        xs, ys, miss = [], [], []
        c = colours[k % 10]
        for t in (t for t in tests if t["test"] == name):
            x = t["ego_speed_mps"] * 3.6 + dx
            for v in t["ttc_at_first_warning_s"]:
                (xs.append(x), ys.append(v)) if v is not None else miss.append(x)
            req = t["required_ttc_s"]
            top = max(top, req)
            ax.hlines(req, x - step / 2, x + step / 2, colors=c, linestyles="--", linewidth=1.5)
        top = max([top, *ys])
        ax.scatter(xs, ys, s=18, color=c, label=name, alpha=0.8)
        if miss:
            any_miss = True
            ax.scatter(miss, [-0.25] * len(miss), marker="x", color=c, s=30)
    ax.set_ylim(-0.5, top * 1.1 + 0.2)
    ax.axhline(0, color="0.6", linewidth=0.8)
    ax.set_xlabel("ego speed (km/h)")
    ax.set_ylabel("true TTC at first warning (s)")
    ax.set_title("Warning timing per trial against the required TTC")
    ax.grid(alpha=0.3)
    handles, labels = ax.get_legend_handles_labels()
    handles.append(Line2D([], [], color="0.3", linestyle="--"))
    labels.append("required TTC")
    if any_miss:
        handles.append(Line2D([], [], color="0.3", marker="x", linestyle=""))
        labels.append("no timed warning")
    ax.legend(handles, labels, fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0))
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
    fa = card["false_alarms"]
    rows = summary_lines(card["summary"])
    if fa["runs"]:
        rows.insert(0, ("false alarms per hour of nominal traffic", false_alarm_rate(fa)))
    if rows:
        parts.append(table(["figure", "value"], rows, left=2))
    if card["tests"]:
        header, rows, classes = tests_rows(card)
        parts.append(table(header, rows, left=3, row_classes=classes))
        parts.append(f"<p class='note'>{e(PARAM_NOTE)}; margin: true TTC at first warning minus the required "
                     f"TTC (negative: too late).</p>")
        parts.append(timing_plot(card))
    if fa["runs"]:
        verdict = str(fa.get("verdict", ""))
        cls = "ok" if verdict == "PASS" else "bad"
        parts.append(f"<h3>False alarms in nominal traffic</h3><p><b>{fa['episodes']}</b> warning episodes without "
                     f"a conflict in {e(_hours(fa['hours']))} of driving, {fa['km']:.1f} km, {fa['runs']} runs"
                     f"{html.escape(_warmup_note(fa))}: <b>{e(false_alarm_rate(fa).split('; ')[0])}</b>"
                     f"{html.escape(_braking_note(fa))}; target ≤ {fa.get('target_per_hour', 1):g} per hour: "
                     f"<span class='{cls}'>{e(verdict)}</span>.</p><p class='note'>The interval is the exact "
                     f"(Garwood) Poisson one; PASS needs its upper end at or below the target, which even with no "
                     f"false alarm takes {fa.get('hours_needed') or 0:.2f} h of driving.</p>")
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
