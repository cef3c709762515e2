"""The options shared by ``monorarp sweep`` and ``monorarp scorecard``: where and how the runs go."""

from __future__ import annotations

import argparse

from monorarp.app.common_options import positive_int
from monorarp.core.errors import UserError


def add_executor_arguments(p: argparse.ArgumentParser) -> None:
    """``--executor``, ``--workers``, ``--address``, ``--resume``, ``--run-timeout``, ``--no-progress``."""
    p.add_argument("--executor", choices=("local", "ray"), default="local",
                   help="local: this machine (process pool when --workers > 1); ray: Ray tasks (default: local)")
    p.add_argument("--workers", type=positive_int, default=1, metavar="N",
                   help="parallel runs: processes (local) or CPUs of the local Ray instance (default 1)")
    p.add_argument("--address", default=None, metavar="auto|HOST:PORT",
                   help="Ray cluster to connect to (with --executor ray); default: start a local Ray instance")
    p.add_argument("--resume", action="store_true",
                   help="skip runs already finished in DIR with the same parameters (also after the run was "
                        "killed: what it left half-done is removed and run again)")
    p.add_argument("--run-timeout", type=float, default=None, metavar="S",
                   help="end a run that takes longer than S seconds and record it as failed ('timeout after S s'); "
                        "local runs then go to worker processes even with --workers 1 (default: no limit)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")


def check_executor_arguments(args: argparse.Namespace) -> None:
    """One-line :class:`UserError` for a value the options above refuse."""
    if args.run_timeout is not None and not 0 < args.run_timeout < float("inf"):
        raise UserError(f"--run-timeout: must be a positive number of seconds, got {args.run_timeout:g}")
    if args.address is not None and args.executor != "ray":
        raise UserError("--address is only for --executor ray")
