"""Running a benchmark script (``benchmarks/*.py``): bad input is one line and exit status 2, as on the
command line (a bad option, an unknown component, a missing scenario or model file), never a traceback."""

from __future__ import annotations

import sys
from collections.abc import Callable
from pathlib import Path

from monorarp.core.errors import UserError


def run_script(main: Callable[[], object]) -> None:
    """Call ``main()``; a :class:`~monorarp.core.errors.UserError` it raises is printed as
    ``<script>: error: <message>`` on stderr and the process exits with status 2."""
    try:
        main()
    except UserError as e:
        print(f"{Path(sys.argv[0]).name}: error: {e}", file=sys.stderr)
        raise SystemExit(2) from None
