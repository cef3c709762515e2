"""Figures of the road-grade sweep: distance error by span and beyond the grade change, and the
stated 90 % distance interval's coverage and mean / median width.

Run the sweep first, then print its table (one row per variant and grade, seeds pooled by
object-frame from each run's ``per_object.csv``; the same selection as ``metrics.json``: counted,
matched object-frames with a state and ``0 <= d_long < 80``)::

    monorarp sweep scenarios/conditions/grade.yaml --out /tmp/grade
    python benchmarks/bench_grade.py /tmp/grade

Any other sweep works too (a level road: no "beyond" rows, grade printed as 0), e.g. the
``lane_width`` horizon stage against the plain pipeline on highway_cruise (docs/road_profile.md).

"Beyond the change": the object's rear face lies past the end of the first vertical curve
(``start_m + transition_m`` ahead of the camera at t = 0, less the distance the camera has driven),
i.e. the vehicle stands on the new grade. Errors are ``|d_y - d_long|`` (the metrics' distance,
see docs/road_profile.md); relative errors divide by ``d_long``; ``bias`` is the median of
``(d_y - d_long) / d_long``.
"""

from __future__ import annotations

import json
from collections import defaultdict
from pathlib import Path

import numpy as np

from harness.scoring.algo import Z90
from harness.scoring.records import read_csv


def _rows(run: Path) -> np.ndarray:
    """(N, 4) d_long, d_y_est, d_y_std, beyond-the-change flag of the scored object-frames of one run."""
    params = json.loads((run / "run.json").read_text())["params"]
    profile = params["scenario"]["road"].get("profile") or []
    end_ahead = profile[0]["start_m"] + profile[0]["transition_m"] if profile else np.inf   # from the camera at t = 0
    ego_x = {}
    with open(run / "ground_truth.jsonl") as f:
        for line in f:
            rec = json.loads(line)
            ego_x[rec["frame"]] = rec["ego"]["x"]
    x0 = ego_x[0]
    out = [(r.d_long_gt, r.d_y_est, r.d_y_std, r.d_long_gt > end_ahead - (ego_x[r.frame] - x0))
           for r in read_csv(run / "per_object.csv")
           if r.matched and r.counted and np.isfinite(r.d_y_est) and 0 <= r.d_long_gt < 80]
    return np.array(out, dtype=float).reshape(-1, 4)


def _stats(d, est, std, sel) -> tuple:
    """Count, median / p90 |rel. error|, median rel. bias, median abs. error (m), 90 % coverage,
    mean and median interval width (m) of the selected object-frames."""
    if not sel.any():
        return (0,) + (np.nan,) * 7
    rel = (est[sel] - d[sel]) / d[sel]
    ok = np.isfinite(std[sel])
    err, s = np.abs(est[sel] - d[sel])[ok], std[sel][ok]
    return (int(sel.sum()), float(np.median(np.abs(rel))), float(np.percentile(np.abs(rel), 90)),
            float(np.median(rel)), float(np.median(np.abs(est[sel] - d[sel]))),
            float(np.mean(err <= Z90 * s)) if ok.any() else np.nan,
            float(np.mean(2 * Z90 * s)) if ok.any() else np.nan,
            float(np.median(2 * Z90 * s)) if ok.any() else np.nan)


def main(sweep: str) -> int:
    pooled: dict[tuple[str, float], list[np.ndarray]] = defaultdict(list)
    for run in sorted(Path(sweep, "runs").iterdir()):
        if not (run / "per_object.csv").exists():
            continue
        params = json.loads((run / "run.json").read_text())["params"]
        grade = float(params.get("grid", {}).get("road.profile.0.grade", 0.0))
        pooled[(params["variant"], grade)].append(_rows(run))
    print("| variant | grade | span | object-frames | median rel. error | p90 rel. error | median rel. bias | "
          "median abs. error (m) | 90 % coverage | mean width (m) | median width (m) |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for variant, grade in sorted(pooled):
        d, est, std, beyond = np.concatenate(pooled[(variant, grade)]).T
        for name, sel in (("5-40 m", (d >= 5) & (d < 40)), ("40-80 m", (d >= 40) & (d < 80)),
                          ("beyond the change", beyond > 0), ("all 0-80 m", np.ones(len(d), bool))):
            n, rel, p90, bias, ab, cov, wid, wmed = _stats(d, est, std, sel)
            print(f"| {variant} | {grade:+.2f} | {name} | {n} | {rel:.3f} | {p90:.3f} | {bias:+.3f} | {ab:.2f} | "
                  f"{cov:.3f} | {wid:.1f} | {wmed:.1f} |")
    return 0


if __name__ == "__main__":
    from _common import sweep_dir_main

    sweep_dir_main(main, "bench_grade.py")
