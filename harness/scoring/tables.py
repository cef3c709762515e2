"""Printable tables from a ``metrics.json`` dict: the paper's Table II and a run summary."""

from __future__ import annotations

from collections.abc import Mapping

from harness.scoring.algo import RANGE_BINS

#: The paper's Table II (ms per frame; FPS), FasterRCNN on a GTX 1070 at 1080p.
PAPER_TABLE_II = {"detector": 120.7, "tracker": 3.2, "state": 0.3, "risk": 0.4, "fps": 5.5629}
_ROWS = (("Object Detector", "detector"), ("Tracker", "tracker"), ("State Estimator", "state"),
         ("Risk Estimator", "risk"))
_EXTRA_ROWS = (("Ego Speed", "ego_speed"),)   # not in the paper's table


def _num(v, fmt: str = "{:.2f}") -> str:
    return "-" if v is None or v != v else fmt.format(v)


def _pct(v) -> str:
    return _num(None if v is None else 100 * v, "{:.2f}%")


def table_ii(metrics: Mapping, paper: bool = True) -> str:
    """Table II: mean wall-clock ms per frame of each component, the stage total and FPS."""
    rt = metrics.get("runtime_ms", {})
    head = f"{'Component':<18}{'Time per Frame (ms)':>21}" + (f"{'paper (ms)':>12}" if paper else "")
    lines = ["TABLE II: Overall Runtime of Risk Prediction System", head, "-" * len(head)]
    for label, key in _ROWS:
        lines.append(f"{label:<18}{_num(rt.get(key), '{:.3f}'):>21}" + (f"{PAPER_TABLE_II[key]:>12.1f}" if paper else ""))
    for label, key in _EXTRA_ROWS:
        if rt.get(key):
            lines.append(f"{label:<18}{_num(rt.get(key), '{:.3f}'):>21}" + (f"{'-':>12}" if paper else ""))
    lines.append(f"{'Total (stages)':<18}{_num(rt.get('total'), '{:.3f}'):>21}" + (f"{'':>12}" if paper else ""))
    lines.append(f"{'Total (FPS)':<18}{_num(metrics.get('fps'), '{:.2f}'):>21}"
                 + (f"{PAPER_TABLE_II['fps']:>12.2f}" if paper else ""))
    return "\n".join(lines)


def summary_table(metrics: Mapping) -> str:
    """Human-readable summary of a run's metrics (distance by range, tracking, detection, TTC, runtime)."""
    d, lat, vel = metrics["distance"], metrics["lateral"], metrics["rel_velocity"]
    cfg = metrics.get("config", {})
    out = [f"run: {cfg.get('scenario', '?')} (seed {cfg.get('seed', '?')}), {metrics['frames']} frames; "
           f"components: {', '.join(f'{k}={v}' for k, v in cfg.get('components', {}).items())}", ""]
    out.append(f"{'distance (d_y vs d_long)':<26}{'rel. median':>12}{'rel. p90':>10}{'abs. median':>13}{'count':>8}")
    for name in RANGE_BINS:
        b = d["by_range"][name]
        out.append(f"{'  ' + name + ' m':<26}{_pct(b['rel_err_median']):>12}{_pct(b['rel_err_p90']):>10}"
                   f"{_num(b['abs_err_median_m'], '{:.3f} m'):>13}{b['count']:>8}")
    out.append(f"{'  all (0-80 m)':<26}{_pct(d['rel_err_median']):>12}{_pct(d['rel_err_p90']):>10}"
               f"{_num(d['abs_err_median_m'], '{:.3f} m'):>13}{d['count']:>8}")
    out.append(f"lateral |d_x - d_lat| median {_num(lat['abs_err_median_m'], '{:.3f}')} m (p90 "
               f"{_num(lat['abs_err_p90_m'], '{:.3f}')}); rel. velocity |v_y - v_long| median "
               f"{_num(vel['abs_err_median_mps'], '{:.3f}')} m/s (p90 {_num(vel['abs_err_p90_mps'], '{:.3f}')})")
    w = metrics["ttc"]["warning"]
    out.append(f"TTC warnings (< {w['threshold_s']:g} s): precision {_num(w['precision'], '{:.3f}')}, recall "
               f"{_num(w['recall'], '{:.3f}')} (tp {w['tp']}, fp {w['fp']}, fn {w['fn']})")
    ls = metrics.get("lane_speed")
    if ls and ls.get("method"):
        out.append(f"lane speed ({ls['method']}): rel. error median {_pct(ls['rel_err_median'])}, abs. median "
                   f"{_num(ls['abs_err_median_mps'], '{:.3f}')} m/s, valid {_pct(ls['valid_fraction'])} of frames")
    rk = metrics.get("risk")
    if rk:
        line = (f"risk ({rk['kind']}, {rk['horizon_s']:g} s horizon): AUROC {_num(rk['auroc'], '{:.3f}')}, Brier "
                f"{_num(rk['brier'], '{:.3f}')} over {rk['frames_scored']} frames ({rk['positives']} positive, "
                f"{rk['excluded_past_end']} excluded past the end)")
        if rk.get("baseline_ttc"):
            b = rk["baseline_ttc"]
            line += f"; 1/TTC baseline AUROC {_num(b['auroc'], '{:.3f}')}, Brier {_num(b['brier'], '{:.3f}')}"
        out.append(line)
    t, det = metrics["tracking"], metrics["detection"]
    hota = f", HOTA {_num(t['hota'], '{:.3f}')} (DetA {_num(t['deta'], '{:.3f}')}, AssA {_num(t['assa'], '{:.3f}')})" \
        if "hota" in t else ""
    out.append(f"tracking: MOTA {_num(t['mota'], '{:.3f}')}, IDF1 {_num(t['idf1'], '{:.3f}')}{hota}, id switches "
               f"{t['id_switches']}, FP {t['false_positives']}, misses {t['misses']} of {t['objects']}")
    if t.get("by_range"):
        out.append("  by range, MOTA/IDF1 (objects): " + "; ".join(
            f"{name} m {_num(b['mota'], '{:.3f}')}/{_num(b['idf1'], '{:.3f}')} ({b['objects']})"
            for name, b in t["by_range"].items()))
    out.append(f"detection @IoU {det['min_iou']:g}: precision {_num(det['precision'], '{:.3f}')}, recall "
               f"{_num(det['recall'], '{:.3f}')}")
    out += ["", table_ii(metrics)]
    return "\n".join(out)
