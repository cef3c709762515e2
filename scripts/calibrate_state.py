"""Measure the state estimator's noise from the tuning set's cached tracks, and check its sigmas.

Over the runs cached by ``scripts/tune_warning.py`` (detector + tracker output of
``scenarios/fcw/tuning.yaml``), every non-coasting track matched to a ground-truth vehicle
(IoU >= 0.5, whole box, 5-60 m) gives:

* the **box-edge error in pixels**: the distance error of its box (equation 3 + contact line)
  turned back into bottom-edge rows (``e_y h_c F / d^2``), and the lateral error into columns
  (``e_x F / d``); robust std (1.4826 MAD) and the lag-1 / lag-5 / lag-15 autocorrelation of the
  per-track error series (correlated errors are what differencing turns into velocity);
* the **calibration of the filter**: ``|v - v_true| / sigma`` of the output lateral and
  longitudinal velocity, 50th / 90th percentile (a calibrated Gaussian: 0.67 / 1.64).

    python scripts/calibrate_state.py [--cache DIR] [--state '{"pixel_std": 1.0}']

Prints figures only; needs the cache (run ``scripts/tune_warning.py`` once).
"""

from __future__ import annotations

import argparse
import json
import pickle
from pathlib import Path

import numpy as np

from harness.scoring.match import as_boxes, match_boxes
from monorarp.pipeline import registry
from monorarp.state.geometry import border_flags, measure_boxes


def autocorr(series: list[np.ndarray], lag: int) -> float:
    """Pooled autocorrelation at ``lag`` (frames) of per-track zero-mean error series."""
    num = den = 0.0
    for s in series:
        s = s - s.mean()
        if s.size > lag:
            num += float(np.dot(s[:-lag], s[lag:]))
            den += float(np.dot(s, s)) * (s.size - lag) / s.size
    return num / den if den > 0 else float("nan")


def run_stats(data: dict, state_kw: dict) -> dict:
    """Per-run lists: pixel errors (per track) and normalised velocity errors."""
    cam = data["camera"]
    est = registry.build("state", "geometric", dict(state_kw), cam)
    ex, ey, nx, ny, ax, ay = {}, {}, [], [], [], []
    for (index, t, tracks), truth in zip(data["frames"], data["truths"]):
        states = est.update(tracks, t)
        objs = list(truth.objects)
        live = [tr for tr in tracks if not tr.coasting]
        if not objs or not live:
            continue
        boxes = as_boxes([tr.box for tr in live])
        pairs = match_boxes(as_boxes([o.box for o in objs]), boxes, 0.5)
        z = measure_boxes(cam, boxes)
        whole = ~border_flags(cam, boxes, 4.0).any(axis=1)
        for g, e, _ in pairs:
            o, tr = objs[g], live[e]
            if not (whole[e] and 5.0 <= o.d_long <= 60.0 and np.isfinite(z[e]).all()):
                continue
            d = o.d_long
            ey.setdefault(tr.id, []).append((z[e, 1] - d) * cam.height_m * cam.fy / d ** 2)
            ex.setdefault(tr.id, []).append((z[e, 0] - o.d_lat) * cam.fx / d)
            st = states.get(tr.id)
            if st is not None and st.v_x_std and st.v_y_std:
                nx.append(abs(st.v_x - o.v_lat) / st.v_x_std)
                ny.append(abs(st.v_y - o.v_long) / st.v_y_std)
                ax.append(abs(st.v_x - o.v_lat))
                ay.append(abs(st.v_y - o.v_long))
    return {"ex": [np.array(v) for v in ex.values()], "ey": [np.array(v) for v in ey.values()],
            "nx": nx, "ny": ny, "ax": ax, "ay": ay}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cache", type=Path, default=Path(".cache/tune_warning"))
    ap.add_argument("--state", default="{}", help="JSON: state-estimator parameters")
    ap.add_argument("--only", default="", help="only cached runs whose name contains this")
    args = ap.parse_args()
    runs = [pickle.loads(p.read_bytes()) for p in sorted(args.cache.glob("*.pkl")) if args.only in p.name]
    if not runs:
        raise SystemExit(f"error: no cached runs in {args.cache} (run scripts/tune_warning.py first)")
    acc: dict[str, list] = {"ex": [], "ey": [], "nx": [], "ny": [], "ax": [], "ay": []}
    for data in runs:
        for k, v in run_stats(data, json.loads(args.state)).items():
            acc[k] += v
    for axis, key in (("lateral (columns)", "ex"), ("bottom edge (rows)", "ey")):
        allv = np.concatenate(acc[key])
        mad = 1.4826 * float(np.median(np.abs(allv - np.median(allv))))
        print(f"box-edge error, {axis}: n {allv.size}, median {np.median(allv):+.2f} px, robust std {mad:.2f} px, "
              f"p90 |e| {np.percentile(np.abs(allv), 90):.2f} px, autocorrelation lag 1/5/15: "
              + " / ".join(f"{autocorr(acc[key], lag):.2f}" for lag in (1, 5, 15)))
    for axis, n, a in (("lateral", "nx", "ax"), ("longitudinal", "ny", "ay")):
        v = np.array(acc[n])
        print(f"velocity {axis}: n {v.size}, |err|/sigma p50 {np.percentile(v, 50):.2f} p90 {np.percentile(v, 90):.2f} "
              f"(calibrated 0.67 / 1.64); |err| p50 {np.percentile(acc[a], 50):.2f} p90 {np.percentile(acc[a], 90):.2f} m/s")


if __name__ == "__main__":
    main()
