"""Figures of the road-curvature sweep: distance error by span (whole run and with the camera on the
arc), tracking, detection, lane-marking ego speed, warnings, and how often another lane's car stands
in the straight-ahead corridor of the warning stage.

Run the sweep first, then print its table (one row per radius, direction and variant; seeds pooled:
distance errors by object-frame from each run's ``per_object.csv`` with the metrics' selection,
counted, matched object-frames with a state and ``0 <= d_long < 80``; the other figures are the
runs' ``metrics.json`` means, episode counts summed)::

    monorarp sweep scenarios/conditions/curves.yaml --out /tmp/curves
    python benchmarks/bench_curves.py /tmp/curves

"On the arc": the camera has driven past the entry clothoid and not past the arc's end
(``start_m + transition_m .. + length_m`` ahead of its t = 0 position, road ``x``). "In the straight
corridor": a truth object in another lane (``lane_rel != 0``) 0..80 m ahead whose centre is within
1.8 m of the ego's straight-ahead line (``|d_lat| < 1.8``: its 1.8 m width overlaps the 1.8 m wide
corridor of the ``fcw`` warning stage), share of all other-lane object-frames 0..80 m ahead.
"""

from __future__ import annotations

import json
import sys
from collections import defaultdict
from pathlib import Path

import numpy as np

from harness.scoring.records import read_csv

CORRIDOR_M = 1.8


def _run(run: Path) -> dict:
    """Distance rows (d_long, d_y, on-arc flag), corridor counts and headline metrics of one run."""
    params = json.loads((run / "run.json").read_text())["params"]
    seg = params["scenario"]["road"]["curves"][0]
    arc = (seg["start_m"] + seg["transition_m"], seg["start_m"] + seg["transition_m"] + seg["length_m"])
    ego_x, inside, other = {}, 0, 0
    with open(run / "ground_truth.jsonl") as f:
        for line in f:
            rec = json.loads(line)
            ego_x[rec["frame"]] = rec["ego"]["x"]
            for o in rec["objects"]:
                if o["lane_rel"] != 0 and 0 <= o["d_long"] < 80:
                    other += 1
                    inside += abs(o["d_lat"]) < CORRIDOR_M
    x0 = ego_x[0]
    rows = [(r.d_long_gt, r.d_y_est, arc[0] <= ego_x[r.frame] - x0 <= arc[1])
            for r in read_csv(run / "per_object.csv")
            if r.matched and r.counted and np.isfinite(r.d_y_est) and 0 <= r.d_long_gt < 80]
    m = json.loads((run / "metrics.json").read_text())
    return {"rows": np.array(rows, dtype=float).reshape(-1, 3), "inside": inside, "other": other,
            "mota": m["tracking"]["mota"], "idf1": m["tracking"]["idf1"], "recall": m["detection"]["recall"],
            "lane": m["lane_speed"]["rel_err_median"], "episodes": m["warning"]["episodes"],
            "false_alarms": m["warning"]["false_alarms"], "conflict": m["warning"]["conflict_frames"]}


def _median_rel(rows: np.ndarray, sel: np.ndarray) -> str:
    return "-" if not sel.any() else f"{np.median(np.abs(rows[sel, 1] - rows[sel, 0]) / rows[sel, 0]):.3f}"


def _mean(values, fmt: str) -> str:
    """Mean of the values that are not None (a short run can have no lane-speed estimate), or "-"."""
    v = [x for x in values if x is not None]
    return "-" if not v else format(float(np.mean(v)), fmt)


def main(sweep: str) -> int:
    groups: dict[tuple, list[dict]] = defaultdict(list)
    for run_json in sorted(Path(sweep, "runs").glob("*/run.json")):
        params = json.loads(run_json.read_text())["params"]
        seg = params["scenario"]["road"]["curves"][0]
        groups[(-seg["radius_m"], seg["direction"], params["variant"])].append(_run(run_json.parent))
    print("| radius (m) | direction | variant | rel. error 5-40 m | 40-80 m | on the arc: 5-40 m | 40-80 m "
          "| MOTA | IDF1 | recall | lane speed rel. error | warning episodes (false) | truth conflict frames "
          "| other-lane cars in the straight corridor |")
    print("|" + "---|" * 14)
    for (neg_r, direction, variant), runs in sorted(groups.items(), key=lambda kv: (kv[0][0], kv[0][1], kv[0][2])):
        rows = np.concatenate([r["rows"] for r in runs])
        d, on_arc = rows[:, 0], rows[:, 2] > 0
        near, far = (d >= 5) & (d < 40), (d >= 40) & (d < 80)
        inside, other = sum(r["inside"] for r in runs), sum(r["other"] for r in runs)
        print(f"| {-neg_r:g} | {direction} | {variant} | {_median_rel(rows, near)} | {_median_rel(rows, far)} "
              f"| {_median_rel(rows, near & on_arc)} | {_median_rel(rows, far & on_arc)} "
              f"| {_mean([r['mota'] for r in runs], '.3f')} | {_mean([r['idf1'] for r in runs], '.3f')} "
              f"| {_mean([r['recall'] for r in runs], '.3f')} | {_mean([r['lane'] for r in runs], '.4f')} "
              f"| {sum(r['episodes'] for r in runs)} ({sum(r['false_alarms'] for r in runs)}) "
              f"| {sum(r['conflict'] for r in runs)} | {inside} / {other} ({inside / max(other, 1):.1%}) |")
    return 0


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit("usage: python benchmarks/bench_curves.py SWEEP_DIR")
    sys.exit(main(sys.argv[1]))
