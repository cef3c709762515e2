"""Figures of the pitch-vibration sweep: distance error, interval coverage/width, horizon error.

Run the sweep first, then print its table (one row per variant and amplitude, seeds pooled by
object-frame from each run's ``per_object.csv``; the same selection as ``metrics.json``:
counted, matched object-frames with a state and ``0 <= d_long < 80``)::

    monorarp sweep scenarios/conditions/pitch_vibration.yaml --out /tmp/pv
    python benchmarks/bench_pitch.py /tmp/pv

Columns: median |d_y - d_long| over 5-40 m (m) and its ratio to the same variant's still camera
(amplitude 0); 90 % interval coverage and median width (m) over 5-40 m and over 0-80 m; median
|horizon row error| (px, from metrics.json, median of the runs' medians).
"""

from __future__ import annotations

import json
import re
from collections import defaultdict
from pathlib import Path

import numpy as np

from harness.scoring.algo import Z90
from harness.scoring.records import read_csv

_AMP = re.compile(r"pitch_amplitude_deg=([0-9.]+)")


def _rows(run: Path) -> np.ndarray:
    """(N, 3) d_long, d_y_est, d_y_std of the scored object-frames of one run."""
    out = [(r.d_long_gt, r.d_y_est, r.d_y_std) for r in read_csv(run / "per_object.csv")
           if r.matched and r.counted and np.isfinite(r.d_y_est) and 0 <= r.d_long_gt < 80]
    return np.array(out).reshape(-1, 3)


def main(sweep: str) -> int:
    pooled: dict[tuple[str, float], list[np.ndarray]] = defaultdict(list)
    horizon: dict[tuple[str, float], list[float]] = defaultdict(list)
    for run in sorted(Path(sweep, "runs").iterdir()):
        m = _AMP.search(run.name)
        if m is None or not (run / "per_object.csv").exists():
            continue
        variant = run.name.rsplit("__", 1)[1]
        key = (variant, float(m.group(1)))
        pooled[key].append(_rows(run))
        h = json.loads((run / "metrics.json").read_text()).get("horizon")
        if h and h.get("abs_err_median_px") is not None:
            horizon[key].append(h["abs_err_median_px"])
    still = {}
    table = []
    for (variant, amp) in sorted(pooled, key=lambda k: (k[0], k[1])):
        a = np.concatenate(pooled[(variant, amp)])
        d, est, std = a.T
        span = (d >= 5) & (d < 40)
        err = np.abs(est - d)
        med = float(np.median(err[span]))
        if amp == 0:
            still[variant] = med
        ok = np.isfinite(std)
        cov = lambda s: float(np.mean(err[s & ok] <= Z90 * std[s & ok]))  # noqa: E731
        wid = lambda s: float(np.median(2 * Z90 * std[s & ok]))         # noqa: E731
        hz = horizon.get((variant, amp))
        table.append((variant, amp, int(span.sum()), med, cov(span), wid(span), cov(np.ones_like(span)),
                      wid(np.ones_like(span)), float(np.median(hz)) if hz else float("nan")))
    print("| variant | amplitude (deg) | object-frames 5-40 m | median error 5-40 m (m) | x still | "
          "coverage 5-40 m | width 5-40 m (m) | coverage 0-80 m | width 0-80 m (m) | horizon error (px) |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for variant, amp, n, med, c1, w1, c2, w2, hz in table:
        ratio = med / still[variant] if variant in still else float("nan")
        print(f"| {variant} | {amp:g} | {n} | {med:.3f} | {ratio:.2f} | {c1:.3f} | {w1:.2f} | {c2:.3f} | {w2:.2f} | "
              f"{hz:.2f} |")
    return 0


if __name__ == "__main__":
    from _common import sweep_dir_main

    sweep_dir_main(main, "bench_pitch.py")
