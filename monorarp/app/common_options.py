"""The command-line options several sub-commands share: one definition and one validation each.

Each ``add_*_option`` adds an option with its validator as the argparse ``type``, so a bad value is
refused while the command line is parsed, before anything is read or written, in the same words by
every command (exit 2, one line)::

    monorarp run: error: argument --frames: must be a positive integer, got 0 (see monorarp run --help)
    monorarp video: error: argument --frames: must be a positive integer, got 0 (see monorarp video --help)

A refusal that needs the input as well as the value (``--frames`` beyond the frames a scenario, run
directory or dataset holds) is :func:`frames_within`, called where that input is read; the library
functions behind the commands repeat the value check with :func:`check_frames`. Both word it as the
parser does, after ``--frames:``.

This lives in :mod:`monorarp.app`, not the harness, because ``monorarp video`` and
``monorarp calibrate-horizon`` use it without the harness installed.
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from monorarp.core.errors import UserError

POSITIVE_INTEGER = "must be a positive integer"


def _shown(text: str) -> str:
    """``text`` as a refusal quotes it (shortened: a refusal is one line)."""
    return repr(text if len(text) <= 40 else text[:37] + "...")


# ------------------------------------------------------------------ validators (argparse types)
def positive_int(text: str) -> int:
    """An integer >= 1 (``--frames``, ``--workers``); anything else is refused in one wording."""
    try:
        n = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{POSITIVE_INTEGER}, got {_shown(text)}") from None
    if n < 1:
        raise argparse.ArgumentTypeError(f"{POSITIVE_INTEGER}, got {n}")
    return n


def int_in(lo: int, hi: int) -> Callable[[str], int]:
    """A type for an integer in ``lo..hi`` (e.g. ``--trials``)."""
    return _number_in(int, lo, hi, "", f"int_in_{lo}_{hi}")


def metres_in(lo: float, hi: float) -> Callable[[str], float]:
    """A type for a finite length in ``lo..hi`` metres (e.g. ``--lane-width``)."""
    return _number_in(float, lo, hi, " m", f"metres_in_{lo:g}_{hi:g}")


def _number_in(kind: type, lo: float, hi: float, unit: str, name: str) -> Callable[[str], Any]:
    span = f"{lo}..{hi}" if kind is int else f"{lo:g}..{hi:g}"     # ints in full, not as 4.29497e+09

    def parse(text: str):
        try:
            n = kind(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"must be {span}{unit}, got {_shown(text)}") from None
        if not (math.isfinite(n) and lo <= n <= hi):
            raise argparse.ArgumentTypeError(f"must be {span}{unit}, got {n}")
        return n

    parse.__name__ = name
    return parse


def out_dir(text: str) -> Path:
    """An output directory path. Refused: the empty one, the current directory (``.``, ``./``, its absolute
    path) and any directory above it (``..``, ``/``): the outputs replace the directory as a whole, so the
    current one would be renamed away under the user's shell and a parent of it would hold the user's work."""
    if not text:
        raise argparse.ArgumentTypeError("must name a directory, got ''")
    try:
        here, target = Path.cwd().resolve(), Path(text).resolve()
    except (OSError, RuntimeError, ValueError):   # a deleted cwd, a link loop, a NUL byte: the writer reports it
        return Path(text)
    if target == here:
        raise argparse.ArgumentTypeError(f"must name a directory of its own, not the current directory, "
                                         f"got {_shown(text)}")
    if target in here.parents:
        raise argparse.ArgumentTypeError(f"must name a directory of its own, not one above the current "
                                         f"directory, got {_shown(text)}")
    return Path(text)


def camera_file(text: str) -> Path:
    """A camera file path (read by :meth:`~monorarp.core.camera.CameraModel.load`); not empty."""
    if not text:
        raise argparse.ArgumentTypeError("must name a camera file, got ''")
    return Path(text)


# ------------------------------------------------------------------ checks after parsing
def check_frames(frames: int | None, error: type[UserError] = UserError) -> None:
    """``--frames N`` (None: not given) as the library functions receive it: ``error`` unless N >= 1."""
    if frames is not None and frames < 1:
        raise error(f"--frames: {POSITIVE_INTEGER}, got {frames}")


def frames_within(frames: int | None, available: int, whose: str, detail: str = "",
                  error: type[UserError] = UserError) -> int:
    """The frames to use: ``frames`` (None: all ``available``), refused when more than ``available``,
    as ``--frames: N exceeds the {whose} M frames{detail}`` (``whose``: e.g. ``"scenario's"``)."""
    check_frames(frames, error)
    if frames is not None and frames > available:
        raise error(f"--frames: {frames} exceeds the {whose} {available} frames{detail}")
    return available if frames is None else frames


# ------------------------------------------------------------------ the options
def add_frames_option(p: argparse.ArgumentParser, *, help: str, default: int | None = None,
                      hidden_aliases: Sequence[str] = ()) -> None:
    """``--frames N`` (:func:`positive_int`); ``hidden_aliases`` (e.g. ``--max-frames``) are accepted
    with the same meaning but not shown by ``--help``."""
    p.add_argument("--frames", type=positive_int, default=default, metavar="N", help=help)
    for alias in hidden_aliases:
        p.add_argument(alias, dest="frames", type=positive_int, default=argparse.SUPPRESS, metavar="N",
                       help=argparse.SUPPRESS)


def add_out_option(p: argparse.ArgumentParser, *, help: str, required: bool = False,
                   default: Path | None = None, metavar: str = "DIR") -> None:
    """``--out DIR`` (:func:`out_dir`); ``default`` is used as given (not validated)."""
    p.add_argument("--out", type=out_dir, required=required, default=default, metavar=metavar, help=help)


def add_camera_option(p: argparse.ArgumentParser, *, help: str) -> None:
    """``--camera CAMERA.yaml`` (required; :func:`camera_file`)."""
    p.add_argument("--camera", type=camera_file, required=True, metavar="CAMERA.yaml", help=help)


def add_threaded_option(p: argparse.ArgumentParser) -> None:
    """``--threaded``: one thread per pipeline stage (identical outputs)."""
    p.add_argument("--threaded", action="store_true", help="one thread per pipeline stage (as in the paper)")


def add_no_video_option(p: argparse.ArgumentParser, *, help: str) -> None:
    """``--no-video``: write no video file (``help`` names the files the command then leaves out)."""
    p.add_argument("--no-video", action="store_true", help=help)
