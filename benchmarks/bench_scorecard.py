"""The collision-warning scorecard's targets, measured: runs the suites and prints target vs measured.

    python benchmarks/bench_scorecard.py [--suite nhtsa ...] [--detector centernet|oracle]
        [--trials N] [--workers N] [--out DIR] [--resume]

Targets (issue "collision-warning scorecard"): all three NHTSA tests pass in 7 of 7 trials; in
the Euro NCAP grid the first warning at true TTC >= 2.0 s in >= 95 % of the runs above 30 km/h;
at most 1 false alarm per hour over >= 2 h of nominal traffic (the ``nominal`` suite is 16 min:
``--trials`` raises the seeds per scenario, 90 seeds x 4 scenarios x 20 s = 2 h); risk AUROC
>= 0.95 at the 2 s horizon for at least one estimator. Each suite is a ``monorarp scorecard`` run
into ``--out`` (``--resume`` continues it); nothing here is asserted, the figures are printed.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

from harness.bench.script import run_script
from harness.bench.targets import target_table
from harness.scorecard.run import SUITES, ScorecardOptions, run_scorecard


def _fmt(v, spec: str = "") -> str:
    return "–" if v is None else format(v, spec)


def report(card: dict, seconds: float) -> list[tuple[str, str, str]]:
    """(target, required, measured) rows from a scorecard.json mapping."""
    rows = []
    tests = card["tests"]
    nhtsa = [t for t in tests if t["suite"] == "nhtsa"]
    if nhtsa:
        per = ", ".join(f"{t['test']} {t['trials_passed']}/{t['trials']}" for t in nhtsa)
        rows.append(("NHTSA tests, trials passed", "3 tests, 7/7 each", per))
    s = card["summary"]
    if "ncap_above_30kmh_ttc_ge_2s" in s:
        rows.append(("Euro NCAP runs > 30 km/h warned at TTC >= 2.0 s", ">= 95 %",
                     f"{100 * s['ncap_above_30kmh_ttc_ge_2s']:.1f} % of {s['ncap_above_30kmh_runs']}"))
    for t in tests:
        if t["suite"] == "cut_in":
            params = ", ".join(f"{k} {v:g}" for k, v in t["params"].items() if isinstance(v, (int, float)))
            rows.append((f"cut_in {t['test']} {params}", "pass", f"{t['trials_passed']}/{t['trials']}"))
    fa = card["false_alarms"]
    if fa["runs"]:
        rows.append(("false alarms per hour (nominal)", "<= 1 over >= 2 h",
                     f"{fa['episodes']} in {fa['hours']:.2f} h = {_fmt(fa['per_hour'], '.1f')}/h"
                     + (f" ({fa['braking']} for a truly braking vehicle)" if fa.get("braking") else "")))
    risk = card.get("risk")
    if risk:
        for name, r in (risk.get("2s") or {}).items():
            target = "(the ceiling: no estimator)" if name == "truth_reference" else ">= 0.95 (one estimator)"
            rows.append((f"risk AUROC at 2 s, {name}", target,
                         f"{_fmt(r['auroc'], '.3f')} (AP {_fmt(r['ap'], '.3f')}, {r['runs']} runs)"))
    rows.append(("wall time", "", f"{seconds:.0f} s"))
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--suite", action="append", choices=SUITES, default=None)
    ap.add_argument("--detector", default="centernet")
    ap.add_argument("--trials", type=int, default=None)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--out", type=Path, default=Path("out/bench_scorecard"))
    ap.add_argument("--resume", action="store_true")
    args = ap.parse_args()
    opts = ScorecardOptions(suites=tuple(args.suite or SUITES), detector=args.detector, trials=args.trials,
                            workers=args.workers, resume=args.resume, progress=False)
    t0 = time.perf_counter()
    run_scorecard(args.out, opts)
    card = json.loads((args.out / "scorecard.json").read_text())
    rows = report(card, time.perf_counter() - t0)
    print(target_table(f"scorecard targets — detector {args.detector}, suites {', '.join(opts.suites)}", rows))


if __name__ == "__main__":
    run_script(main)
