"""``monorarp check RESULTS --baseline FILE [--update]``: compare metrics with a committed baseline.

Exit status: 0 every check holds, 1 regression (or a baseline run missing or
failed in the results), 2 bad input (unreadable/malformed results or baseline).
The baseline format and default tolerances are described in :mod:`harness.check.baseline`.
"""

from __future__ import annotations

import argparse
from pathlib import Path


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "check", help="regression-check a run or sweep directory against a baseline",
        description="Compare the metrics of RESULTS (a run directory with metrics.json or a sweep directory "
                    "with summary.json) with the per-metric values and tolerances of a baseline file; print "
                    "a table; exit 1 on regression, 0 when everything holds, 2 on bad input.")
    p.add_argument("results", type=Path, metavar="RESULTS", help="run or sweep directory")
    p.add_argument("--baseline", type=Path, default=Path("results/baseline.json"), metavar="FILE",
                   help="baseline JSON (default: results/baseline.json, relative to the current directory)")
    p.add_argument("--update", action="store_true",
                   help="write a new baseline from RESULTS (keeping existing tolerances) instead of checking")
    p.add_argument("--failures-only", action="store_true", help="print only the rows that fail")
    p.set_defaults(func=run, needs_harness=False)   # pydantic, numpy and yaml only


def run(args: argparse.Namespace) -> int:
    from harness.check.baseline import (CheckInputError, checked_exists, compare, format_table, load_baseline, load_results,
                               updated_baseline, write_baseline)

    results = load_results(args.results)
    if args.update:
        old = load_baseline(args.baseline) if checked_exists(args.baseline) else None
        failed = sorted(rid for rid, r in results.items() if r.status != "ok")
        if failed:
            print(f"check: not updating {args.baseline}: {len(failed)} run(s) failed: {', '.join(failed[:5])}"
                  f"{' ...' if len(failed) > 5 else ''}")
            return 1
        new = updated_baseline(old, results)
        write_baseline(args.baseline, new)
        dropped = sorted(set((old or {}).get("runs", {})) - set(new["runs"]))
        n = sum(len(m) for m in new["runs"].values())
        print(f"check: wrote {args.baseline}: {len(new['runs'])} run(s), {n} metric(s)"
              + (f"; dropped {len(dropped)} run(s) not in the results: {', '.join(dropped[:5])}" if dropped else ""))
        return 0

    baseline = load_baseline(args.baseline)
    if not baseline["runs"]:
        raise CheckInputError(f"{args.baseline}: the baseline holds no runs (write one with --update)")
    rows = compare(baseline, results)
    fails = [r for r in rows if r.failed]
    shown = fails if args.failures_only else rows
    if shown:
        print(format_table(shown))
    new = [r.run for r in rows if r.status == "new"]
    if new:
        print(f"\nnote: {len(new)} run(s) not in the baseline (not checked): {', '.join(new[:5])}"
              f"{' ...' if len(new) > 5 else ''}")
    improved = sum(r.status == "improved" for r in rows)
    if improved:
        print(f"note: {improved} metric(s) improved beyond tolerance; `--update` tightens the baseline")
    checked = sum(r.status != "new" for r in rows)
    if fails:
        print(f"\ncheck: REGRESSION: {len(fails)} of {checked} check(s) failed against {args.baseline}:")
        for r in fails:
            what = r.status if r.delta is None else f"{r.status}, {r.delta:+.4g} vs tolerance {r.tolerance:.4g}"
            print(f"  {r.run}  {r.metric}: {what}")
        return 1
    print(f"\ncheck: OK: all {checked} check(s) within tolerance of {args.baseline}")
    return 0
