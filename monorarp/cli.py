"""The ``monorarp`` command. Sub-commands are plug-ins (entry-point group
``monorarp.commands``): each entry point is a function ``register(subparsers)``
that adds its parser and sets ``func``. This keeps :mod:`monorarp` free of any
import of the harness while ``monorarp render``/``run``/``sweep`` live there.
"""

from __future__ import annotations

import argparse
import os
import sys
from importlib.metadata import entry_points

from monorarp import __version__
from monorarp.errors import UserError


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="monorarp", description="Monocular collision-risk pipeline and its simulation harness.")
    parser.add_argument("--version", action="version", version=f"monorarp {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    seen: set[str] = set()
    for ep in sorted(entry_points(group="monorarp.commands"), key=lambda e: e.name):
        if ep.name in seen:  # the same distribution seen twice (e.g. a stray egg-info on sys.path)
            continue
        seen.add(ep.name)
        ep.load()(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    try:
        return int(args.func(args) or 0)
    except UserError as e:
        message = " ".join(str(e).split())
        print(f"monorarp {args.command}: error: {message}", file=sys.stderr)
        return 2
    except BrokenPipeError:  # e.g. `monorarp ... | head`: the reader left (recipe of Python's signal docs)
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 1
    except KeyboardInterrupt:
        print(f"monorarp {args.command}: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
