"""Helpers shared by the benchmark scripts in this folder (not a benchmark itself)."""

from __future__ import annotations

import sys
from typing import Callable


def sweep_dir_main(main: Callable[[str], int], script: str) -> None:
    """``python benchmarks/<script> SWEEP_DIR``: run ``main(SWEEP_DIR)`` and exit with its status (2 on bad usage)."""
    if len(sys.argv) != 2:
        print(f"usage: python benchmarks/{script} SWEEP_DIR", file=sys.stderr)
        sys.exit(2)
    sys.exit(main(sys.argv[1]))
