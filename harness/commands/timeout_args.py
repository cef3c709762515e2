"""The ``--run-timeout`` option shared by ``monorarp sweep`` and ``monorarp scorecard``."""

from __future__ import annotations

import argparse

from monorarp.errors import UserError


def add_run_timeout_argument(p: argparse.ArgumentParser) -> None:
    p.add_argument("--run-timeout", type=float, default=None, metavar="S",
                   help="end a run that takes longer than S seconds and record it as failed ('timeout after S s'); "
                        "local runs then go to worker processes even with --workers 1 (default: no limit)")


def check_run_timeout(value: float | None) -> None:
    if value is not None and not 0 < value < float("inf"):
        raise UserError(f"--run-timeout: must be a positive number of seconds, got {value:g}")
