"""``monorarp sweep SPEC.yaml --out DIR``: run every scenario x seed x grid x variant of a sweep spec.

Exit status: 0 all runs finished (and, with ``--baseline``, every check held), 1 some
run failed (the others still ran and are summarised; a run whose worker died or that
overran ``--run-timeout`` is one of them, with its cause) or a check against
``--baseline`` failed, 2 bad input (spec, output directory, executor, baseline) — then
no run started — or a summary that could not be written (e.g. a full disk).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from harness.commands.cache_args import add_cache_arguments, cache_from_args
from harness.commands.executor_args import add_executor_arguments, check_executor_arguments
from monorarp.app.common_options import add_out_option


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "sweep", help="run a sweep spec (scenarios x seeds x grid x variants), summarise and report",
        description="Expand SPEC.yaml into runs with stable ids, run each (simulate, render, pipeline, score) "
                    "isolated and atomically into DIR/runs/<id>/, then write DIR/summary.json, DIR/summary.csv "
                    "and a self-contained DIR/report.html. Exits 1 if any run failed, 2 on bad input.")
    p.add_argument("spec", type=Path, metavar="SPEC.yaml", help="sweep spec file")
    add_out_option(p, required=True, help="output directory (new or empty, or a previous sweep's with --resume)")
    add_executor_arguments(p)
    p.add_argument("--videos", action="store_true", help="also write annotated.mp4 for every run (slower)")
    add_cache_arguments(p)
    p.add_argument("--baseline", type=Path, default=None, metavar="FILE",
                   help="regression-check the runs against this baseline (as `monorarp check`) and put the "
                        "verdict, with the failing checks, at the top of report.html; exit 1 on a regression")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from harness.sweep.orchestrate import REPORT_HTML, run_sweep

    check_executor_arguments(args)
    baseline = None
    if args.baseline is not None:                  # a bad baseline fails here, before anything runs
        from harness.check.baseline import CheckInputError, load_baseline

        baseline = load_baseline(args.baseline)
        if not baseline["runs"]:
            raise CheckInputError(f"--baseline {args.baseline}: the baseline holds no runs "
                                  f"(write one with `monorarp check DIR --baseline FILE --update`)")
    res = run_sweep(args.spec, args.out, executor=args.executor, workers=args.workers, resume=args.resume,
                    address=args.address, videos=args.videos, progress=not args.no_progress,
                    cache=lambda: cache_from_args(args), run_timeout_s=args.run_timeout, baseline=baseline,
                    baseline_path=None if args.baseline is None else str(args.baseline))
    n = len(res.rows)
    ok = n - len(res.failed)
    skipped = f", {len(res.skipped)} skipped (already finished)" if res.skipped else ""
    print(f"sweep {res.expansion.spec.name}: {ok}/{n} runs ok{skipped} in {res.wall_time_s:.1f} s")
    for r in res.failed:
        print(f"  FAILED {r['id']}: {r['error']}")
    if res.checks is not None:
        checked = sum(c.status != "new" for c in res.checks)
        if res.regressions:
            print(f"check: REGRESSION: {len(res.regressions)} of {checked} check(s) failed against {args.baseline}:")
            for c in res.regressions[:20]:
                what = c.status if c.delta is None else f"{c.status}, {c.delta:+.4g} vs tolerance {c.tolerance:.4g}"
                print(f"  {c.run}  {c.metric}: {what}")
        else:
            print(f"check: OK: all {checked} check(s) within tolerance of {args.baseline}")
    print(f"wrote {args.out}/summary.json, summary.csv, {REPORT_HTML}")
    measured = {k for r in res.rows for k in r["metrics"]}
    absent = [m for m in res.expansion.spec.metrics if m not in measured]
    if absent and ok:
        print(f"monorarp sweep: warning: spec metrics in no run's metrics.json (misspelled? names: "
              f"docs/metrics.md): {', '.join(absent)}", file=sys.stderr)
    return 1 if res.failed or res.regressions else 0
