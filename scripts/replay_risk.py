"""Replay the adverse-manoeuvre risk over a risk scorecard's runs and score it, with held-out splits.

How ``manoeuvre_ttc``'s defaults (``monorarp/risk/estimators.py``, :class:`ManoeuvreTTCRisk`) were chosen and
checked: ``monorarp scorecard --suite risk --out DIR`` writes every run's per-object states
(``per_object.csv``); this script rebuilds each frame's states from them (the estimates, or with
``--truth`` the true states), scores :class:`ManoeuvreTTCRisk` for every brake x lateral x hold x looming
(x looming sigma bound, ``--max-std``, x registered patch weight, ``--registered``) setting of the grid, and prints the pooled AUROC / AP per horizon beside the estimators the runs scored themselves,
with the scorecard's own labels (:func:`harness.scorecard.score.pooled_risk`).

    python scripts/replay_risk.py DIR/runs [--brake 4 ...] [--lateral 1 ...] [--hold 0.45 ...] [--looming 0.5 ...]
        [--max-std 0.5|none ...] [--registered 0.5 ...] [--truth]
        [--only SUFFIX | --exclude SUFFIX]        # e.g. --only __t0, --exclude __t0: the held-out runs

Needs the harness.
"""

from __future__ import annotations

import argparse
import csv
import json
from pathlib import Path

import numpy as np

from harness.scorecard.run import _frame_arrays
from harness.scorecard.score import HORIZONS_S, pooled_risk
from monorarp.core.camera import CameraModel
from monorarp.risk.estimators import ManoeuvreTTCRisk
from monorarp.core.types import ObjectState

EST = ("track_id", "d_x_est", "d_y_est", "v_x_est", "v_y_est")
TRUTH = ("gt_id", "d_lat_gt", "d_long_gt", "v_lat_gt", "v_long_gt")


def frame_states(run_dir: Path, n_frames: int, truth: bool = False) -> list[dict[int, ObjectState]]:
    """Per frame index, ``{id: ObjectState}`` from ``per_object.csv``: the estimated states, or the true ones."""
    keys = TRUTH if truth else EST
    states: list[dict[int, ObjectState]] = [{} for _ in range(n_frames)]
    with open(run_dir / "per_object.csv", newline="") as f:
        for row in csv.DictReader(f):
            if any(row[k] in ("", None) for k in keys):
                continue
            k, i = int(row["frame"]), int(row[keys[0]])
            if 0 <= k < n_frames:
                rate, rate_std, reg, reg_std = (
                    None if truth or row.get(c) in ("", None) else float(row[c])
                    for c in ("expansion_rate", "expansion_rate_std", "registered_rate", "registered_rate_std"))
                states[k][i] = ObjectState(i, *(float(row[c]) for c in keys[1:]), expansion_rate=rate,
                                           expansion_rate_std=rate_std, registered_rate=reg,
                                           registered_rate_std=reg_std)
    return states


def replay(runs_dir: Path, settings: list[tuple], truth: bool = False,
           only: str | None = None, exclude: str | None = None) -> list[dict[str, np.ndarray]]:
    """Each run's per-frame arrays (:func:`harness.scorecard.run._frame_arrays`) plus one column per setting
    ``(brake, lateral, hold, looming[, max_std[, registered]])``, replayed on its states:
    ``manoeuvre_b{brake}_l{lateral}_h{hold}_w{looming}``, with ``_s{max_std}`` (``_snone``) where the setting gives
    the looming sigma bound and ``_r{registered}`` where it gives the registered patch's weight (else the defaults)."""
    runs = []
    for d in sorted(p for p in runs_dir.iterdir() if p.is_dir()):
        if (only and not d.name.endswith(only)) or (exclude and d.name.endswith(exclude)):
            continue
        arrays = _frame_arrays(d)
        if arrays is None:
            continue
        camera = CameraModel.from_dict(json.loads((d / "camera.json").read_text()))
        states = frame_states(d, len(arrays["t"]), truth)
        for brake, lateral, hold, looming, *rest in settings:
            kw = dict(zip(("looming_max_std", "registered_weight"), rest))
            stage = ManoeuvreTTCRisk(brake_mps2=brake, lateral_mps=lateral, hold_s=hold, looming_weight=looming,
                                     camera=camera, **kw)
            name = f"manoeuvre_b{brake:g}_l{lateral:g}_h{hold:g}_w{looming:g}"
            if rest:
                name += "_snone" if rest[0] is None else f"_s{rest[0]:g}"
            if len(rest) > 1:
                name += f"_r{rest[1]:g}"
            arrays[name] = np.array(
                [stage.assess(s, t).risk for s, t in zip(states, arrays["t"])])
        runs.append(arrays)
    return runs


def _bound(text: str) -> float | None:
    """``--max-std`` value: a positive number (1/s) or ``none``."""
    return None if text.lower() == "none" else float(text)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("runs_dir", type=Path, help="a risk scorecard's runs/ folder")
    ap.add_argument("--brake", type=float, nargs="+", default=[4.0], help="m/s^2 (default 4)")
    ap.add_argument("--lateral", type=float, nargs="+", default=[1.0], help="m/s (default 1)")
    ap.add_argument("--hold", type=float, nargs="+", default=[0.45], help="peak hold, s (default 0.45)")
    ap.add_argument("--looming", type=float, nargs="+", default=[0.5],
                    help="weight of the looming cue's closing speed, 0-1 (default 0.5)")
    ap.add_argument("--max-std", type=_bound, nargs="+", default=[0.5],
                    help="the looming rate's largest one-sigma the mix uses, 1/s, or none (default 0.5)")
    ap.add_argument("--registered", type=float, nargs="+", default=[0.5],
                    help="weight of the registered patch's closing speed, 0-1 (default 0.5)")
    ap.add_argument("--truth", action="store_true", help="replay on the true states instead of the estimates")
    split = ap.add_mutually_exclusive_group()
    split.add_argument("--only", metavar="SUFFIX", help="only the runs whose name ends so")
    split.add_argument("--exclude", metavar="SUFFIX", help="all runs but those whose name ends so")
    args = ap.parse_args()
    if not args.runs_dir.is_dir():
        raise SystemExit(f"replay_risk: {args.runs_dir}: no such folder")
    settings = [(b, lat, h, w, m, r) for b in args.brake for lat in args.lateral for h in args.hold
                for w in args.looming for m in args.max_std for r in args.registered]
    try:
        runs = replay(args.runs_dir, settings, args.truth, args.only, args.exclude)
    except (OSError, ValueError, KeyError, TypeError) as e:   # a run folder without its files, a bad setting
        raise SystemExit(f"replay_risk: {args.runs_dir}: {e}") from None
    if not runs:
        raise SystemExit(f"replay_risk: {args.runs_dir}: no run with a per_frame.csv")
    print(f"{len(runs)} runs, {'true' if args.truth else 'estimated'} states")
    for horizon, per in pooled_risk(runs, HORIZONS_S).items():
        print(horizon)
        for name, r in sorted(per.items()):
            print(f"  {name:36s} AUROC {r['auroc']:.3f}  AP {r['ap']:.3f}  ({r['positives']}/{r['frames']} positive)")


if __name__ == "__main__":
    main()
