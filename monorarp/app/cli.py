"""The ``monorarp`` command. Sub-commands are plug-ins (entry-point group
``monorarp.commands``): each entry point is a function ``register(subparsers)``
that adds its parser and sets ``func``. This keeps :mod:`monorarp` free of any
import of the harness while ``monorarp render``/``run``/``sweep`` live there.

The harness's third-party dependencies (simulator, renderer, scoring) are the
``harness`` extra. Without it the harness commands are still listed, and running
one prints one line naming what to install (exit 2) before it writes anything: the
extra's packages are checked first (a command that needs none sets ``needs_harness=False``),
and an import that still fails, while the command registers or when it runs, says the same.
"""

from __future__ import annotations

import argparse
import importlib.util
import os
import re
import signal
import sys
import threading
from collections.abc import Iterator
from typing import NoReturn
from contextlib import contextmanager
from importlib.metadata import PackageNotFoundError, distribution, entry_points, requires

from monorarp import __version__
from monorarp.core.errors import UserError

HARNESS_HINT = "needs the simulation harness: pip install 'monorarp[harness]'"


def _missing_dependency(error: ModuleNotFoundError) -> str | None:
    """Top-level name of the missing third-party module, or None when a module of this project is missing."""
    name = (error.name or "").split(".")[0]
    return name if name and name not in ("monorarp", "harness") else None


def _top_modules(dist) -> set[str]:
    """Top-level import names a distribution installs (``top_level.txt``, else its file list)."""
    listed = (dist.read_text("top_level.txt") or "").split()
    if listed:
        return set(listed)
    parts = {f.parts[0].removesuffix(".py") for f in dist.files or () if f.parts}
    return {p for p in parts if p.isidentifier() and not p.startswith("__")}


def missing_harness_module() -> str | None:
    """The first distribution (not installed) or module (not importable) of the ``harness`` extra,
    None when all are there or this package's metadata is unavailable (a source tree on sys.path)."""
    try:
        reqs = requires("monorarp") or []
    except PackageNotFoundError:
        return None
    for req in reqs:
        if not re.search(r"extra\s*==\s*.harness.", req):
            continue
        name = re.match(r"[A-Za-z0-9._-]+", req).group(0)
        try:
            dist = distribution(name)
        except PackageNotFoundError:
            return name
        for module in sorted(_top_modules(dist)):
            try:
                if importlib.util.find_spec(module) is None:
                    return module
            except (ImportError, ValueError):
                return module
    return None


def _needs_harness(command: str, missing: str) -> int:
    print(f"monorarp {command}: {HARNESS_HINT} (missing: {missing})", file=sys.stderr)
    return 2


def _add_unavailable(sub: argparse._SubParsersAction, command: str, missing: str) -> None:
    """A stand-in for a harness command whose dependencies are not installed: takes any arguments
    (``prefix_chars`` no argument starts with, so options land in ``args`` too) and prints the hint."""
    p = sub.add_parser(command, help=f"({HARNESS_HINT})", add_help=False, prefix_chars="\0")
    p.add_argument("args", nargs="*")
    p.set_defaults(func=lambda args: _needs_harness(command, missing))


class OneLineErrorParser(argparse.ArgumentParser):
    """argparse with its errors on one line (``monorarp run: error: ... (see monorarp run --help)``, exit 2)
    instead of the usage block and then the error; sub-command parsers are of this class too."""

    def error(self, message: str) -> NoReturn:
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def build_parser() -> argparse.ArgumentParser:
    parser = OneLineErrorParser(prog="monorarp", description="Monocular collision-risk pipeline and its simulation harness.")
    parser.add_argument("--version", action="version", version=f"monorarp {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    seen: set[str] = set()
    for ep in sorted(entry_points(group="monorarp.commands"), key=lambda e: e.name):
        if ep.name in seen:  # the same distribution seen twice (e.g. a stray egg-info on sys.path)
            continue
        seen.add(ep.name)
        try:
            ep.load()(sub)
        except ModuleNotFoundError as e:
            missing = _missing_dependency(e)
            if missing is None or not ep.module.startswith("harness."):
                raise
            _add_unavailable(sub, ep.name, missing)
    return parser


class Terminated(BaseException):
    """SIGTERM arrived (``kill``, ``timeout``, a container stopping): unwinds as Ctrl-C does, so the
    temporary output of the command is removed and nothing half-written stays."""


_SIGTERM_SEEN = threading.Event()


def _raise_terminated(signum: int, frame: object) -> None:
    _SIGTERM_SEEN.set()   # a C call may wrap the exception in its own (ctypes.ArgumentError): main checks this
    raise Terminated


@contextmanager
def _sigterm_unwinds() -> Iterator[None]:
    """While the command runs, SIGTERM raises :class:`Terminated` (main thread only; restored after)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    _SIGTERM_SEEN.clear()
    previous = signal.signal(signal.SIGTERM, _raise_terminated)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    try:
        args, unknown = parser.parse_known_args(argv)
    except SystemExit as e:   # argparse refused a value (one line printed) or printed --help (code 0)
        if e.code in (0, None):
            raise
        return e.code if isinstance(e.code, int) else 2
    if unknown:   # named after the sub-command they were given to (argparse names the top level)
        sub = f"monorarp {args.command}" if getattr(args, "command", None) else "monorarp"
        print(f"{sub}: error: unrecognized arguments: {' '.join(unknown)} (see {sub} --help)", file=sys.stderr)
        return 2
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    if getattr(args, "needs_harness", getattr(args.func, "__module__", "").startswith("harness.")):
        missing = missing_harness_module()   # before the command writes anything
        if missing is not None:
            return _needs_harness(args.command, missing)
    try:
        with _sigterm_unwinds():
            return int(args.func(args) or 0)
    except UserError as e:
        message = " ".join(str(e).split())
        print(f"monorarp {args.command}: error: {message}", file=sys.stderr)
        return 2
    except ModuleNotFoundError as e:
        missing = _missing_dependency(e)
        if missing is None or not getattr(args.func, "__module__", "").startswith("harness."):
            raise
        return _needs_harness(args.command, missing)
    except BrokenPipeError:  # e.g. `monorarp ... | head`: the reader left (recipe of Python's signal docs)
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 1
    except KeyboardInterrupt:
        print(f"monorarp {args.command}: interrupted", file=sys.stderr)
        return 130
    except Exception:
        if not _SIGTERM_SEEN.is_set():
            raise
        return _terminated(args.command)
    except Terminated:
        return _terminated(args.command)


def _terminated(command: str) -> int:
    print(f"monorarp {command}: terminated", file=sys.stderr)
    return 128 + signal.SIGTERM


if __name__ == "__main__":
    sys.exit(main())
