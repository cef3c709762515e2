"""``monorarp scorecard``: the collision-warning test protocols, scored as regulators and buyers judge them.

Exit status: 0 every test passed and no run failed, 1 a test failed or a run failed
(the scorecard is still written), 2 bad input (a protocol file or option) — nothing written.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from monorarp.app.common_options import add_frames_option, add_out_option, int_in
from monorarp.core.errors import UserError

SUITE_CHOICES = ("nhtsa", "ncap", "cut_in", "nominal", "risk", "all")
MAX_TRIALS = 1000          # --trials: a protocol file's own limit


def register(sub: argparse._SubParsersAction) -> None:
    from harness.commands.executor_args import add_executor_arguments
    from harness.commands.look_args import add_look_arguments
    from monorarp.app.options import add_pipeline_options

    p = sub.add_parser(
        "scorecard", help="run the FCW test protocols (NHTSA, Euro NCAP, cut-ins), false alarms, risk family",
        description="Run the collision-warning protocols of scenarios/fcw/ (or --protocol files), score the "
                    "first warning's true TTC per trial, false alarms per hour of nominal traffic and the risk "
                    "estimators over a scenario family; write DIR/scorecard.json and DIR/report.html and print "
                    "the scorecard. Exits 1 when a test or run failed, 2 on bad input.")
    p.add_argument("--suite", action="append", choices=SUITE_CHOICES, default=None,
                   help="suite(s) to run (repeatable; default all)")
    p.add_argument("--protocol", action="append", type=Path, default=None, metavar="FILE.yaml",
                   help="protocol file(s) to run instead of the shipped suites")
    add_pipeline_options(p, stages=("detector", "tracker"))
    p.add_argument("--warning-threshold", type=float, default=None, metavar="S",
                   help="TTC threshold of the warning stage, s (default: the stage's own, 3.0)")
    p.add_argument("--trials", type=int_in(1, MAX_TRIALS), default=None, metavar="N",
                   help=f"trials per test, 1..{MAX_TRIALS} (nominal tests: seeds per scenario; default: the protocol's)")
    add_frames_option(p, help="cap on frames per run (default none)")
    add_out_option(p, required=True, help="output directory")
    add_executor_arguments(p)
    add_look_arguments(p)
    p.set_defaults(func=run)


def check_protocol_files(paths: list[Path]) -> None:
    """``--protocol`` files: each a file (not a directory), none given twice; :class:`UserError` otherwise."""
    seen: set[Path] = set()
    for path in paths:
        try:
            if path.is_dir():
                raise UserError(f"--protocol {path}: is a directory; give protocol files (FILE.yaml)")
            key = path.resolve()
        except (OSError, RuntimeError):   # a name too long, a symlink loop: the scorecard's own check says so
            continue
        if key in seen:
            raise UserError(f"--protocol {path}: given twice")
        seen.add(key)


def run(args: argparse.Namespace) -> int:
    from harness.scorecard.report import console_table
    from harness.scorecard.run import SUITES, ScorecardOptions, run_scorecard

    from harness.commands.detector_args import pipeline_config
    from harness.commands.executor_args import check_executor_arguments
    from harness.commands.look_args import look_update

    check_executor_arguments(args)
    if args.warning_threshold is not None and not 0 < args.warning_threshold <= 10:
        raise UserError(f"--warning-threshold: must be in (0, 10] s, got {args.warning_threshold}")
    if args.protocol and args.suite:
        raise UserError("--protocol and --suite: give one or the other")
    check_protocol_files(args.protocol or [])
    suites = SUITES if not args.suite or "all" in args.suite else tuple(dict.fromkeys(args.suite))
    cfg = pipeline_config(args)
    opts = ScorecardOptions(suites=suites, protocol_files=tuple(args.protocol or ()), detector=cfg.detector.name,
                            detector_kwargs=cfg.detector.kwargs, tracker=cfg.tracker.name, trials=args.trials,
                            frames=args.frames,
                            warning_kwargs={} if args.warning_threshold is None else
                            {"ttc_threshold_s": args.warning_threshold},
                            executor=args.executor, workers=args.workers, address=args.address,
                            resume=args.resume, progress=not args.no_progress, run_timeout_s=args.run_timeout,
                            look=look_update(args))
    card = run_scorecard(args.out, opts)
    print(console_table(card))
    print(f"wrote {args.out}/scorecard.json, report.html")
    failed = card["failed_runs"] or not all(t["passed"] for t in card["tests"])
    return 1 if failed else 0
