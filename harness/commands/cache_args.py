"""The frame-cache options shared by ``monorarp sweep`` and ``monorarp bench trackers``."""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from harness.run.frame_cache import FrameCache


def add_cache_arguments(p: argparse.ArgumentParser) -> None:
    from harness.run.frame_cache import DEFAULT_MAX_GB, ENV_DIR

    p.add_argument("--cache", default=None, metavar="DIR|off",
                   help="frame cache: each scenario instance is rendered once and its frames, ground truth and camera "
                        f"reused by every run that shares them, now and later (default: ${ENV_DIR}, else "
                        "~/.cache/monorarp/frames); 'off': every run renders its own frames")
    p.add_argument("--cache-max-gb", type=float, default=DEFAULT_MAX_GB, metavar="GB",
                   help=f"size limit of the frame cache; least recently used entries go first (default {DEFAULT_MAX_GB:g})")


def cache_from_args(args: argparse.Namespace) -> FrameCache | None:
    """The cache the options describe (created and checked now), or None for ``--cache off``."""
    from harness.run.frame_cache import open_cache

    return open_cache(args.cache, args.cache_max_gb)
