"""Test-only fault injection for sweeps: ``MONORARP_FAULT="KIND:RUN_ID[,KIND:RUN_ID...]"``.

The worker reads the variable at the start of each run (any executor, any process),
so a test makes one chosen run of a real sweep fail in a real way:

* ``kill:ID`` — the worker process sends itself SIGKILL once the run's files are written
  into its temporary directory and before they are committed (a process dying mid-run);
* ``hang:ID`` — the worker sleeps forever at the same point (a hung run);
* ``segv:ID`` — the worker dereferences a null pointer at the same point (a native crash:
  SIGSEGV), every time; ``segv_once:ID`` only the first time in a sweep (the retry runs);
* ``enospc:ID`` / ``enospc=BYTES:ID`` — while the run writes its outputs the disk is
  full: once BYTES bytes (default 0) have been written in all, every further write fails
  with ``OSError(ENOSPC)`` after writing the part that fits (a partial file, as on a real
  full disk). Space comes back when the run's own writing ends (so its failure record can
  be written). Writers in C (the video encoder) are not affected.

Unset (the normal case), each run costs one environment lookup. Nothing in the
product sets it.
"""

from __future__ import annotations

import builtins
import ctypes
import errno
import io
import os
import signal
import tempfile
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

ENV = "MONORARP_FAULT"
KINDS = ("kill", "hang", "enospc", "segv", "segv_once")


def planned(run_id: str) -> tuple[str, int] | None:
    """The fault planned for ``run_id``: (kind, bytes) or None. Malformed entries raise ValueError."""
    spec = os.environ.get(ENV, "").strip()
    if not spec:
        return None
    for entry in spec.split(","):
        head, sep, rid = entry.strip().partition(":")
        kind, _, arg = head.partition("=")
        if not sep or kind not in KINDS or (arg and not arg.isdigit()):
            raise ValueError(f"{ENV}: bad entry {entry!r}; expected kill:ID, hang:ID, segv:ID, segv_once:ID "
                             "or enospc[=BYTES]:ID")
        if rid == run_id:
            return kind, int(arg or 0)
    return None


def before_commit(run_id: str) -> None:
    """Called by the worker when the run's files are written, before they are moved into place."""
    fault = planned(run_id)
    if fault is None:
        return
    if fault[0] == "kill":
        os.kill(os.getpid(), signal.SIGKILL)
        time.sleep(60)                    # the signal is delivered before this returns
    elif fault[0] == "hang":
        while True:
            time.sleep(3600)
    elif fault[0] in ("segv", "segv_once"):
        # once per sweep: a marker named after the driver (the worker's parent) and the run
        marker = Path(tempfile.gettempdir()) / f"monorarp-fault-{os.getppid()}-{run_id}"
        if fault[0] == "segv_once":
            if marker.exists():
                return
            marker.touch()
        ctypes.string_at(0)               # SIGSEGV


@contextmanager
def writing(run_id: str) -> Iterator[None]:
    """Around the run's own writing: a full disk when ``enospc`` is planned for it, else nothing."""
    fault = planned(run_id)
    if fault is None or fault[0] != "enospc":
        yield
        return
    with full_disk(fault[1]):
        yield


class _Budget:
    def __init__(self, free: int) -> None:
        self.free = free


class _FullDiskFile:
    """A writable file object whose writes fail with ENOSPC once the shared budget is spent."""

    def __init__(self, f: Any, budget: _Budget, name: str) -> None:
        self._f, self._budget, self._name = f, budget, name

    def write(self, data: Any) -> int:
        n = len(data)
        if n <= self._budget.free:
            self._budget.free -= n
            return self._f.write(data)
        part = data[:self._budget.free]
        self._budget.free = 0
        self._f.write(part)
        self._f.flush()
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), self._name)

    def writelines(self, lines: Any) -> None:
        for line in lines:
            self.write(line)

    def __getattr__(self, name: str) -> Any:
        return getattr(self._f, name)

    def __iter__(self) -> Any:
        return iter(self._f)

    def __enter__(self) -> "_FullDiskFile":
        return self

    def __exit__(self, *exc: Any) -> None:
        self._f.close()


def _is_write_mode(mode: str) -> bool:
    return any(c in mode for c in "wax+")


@contextmanager
def full_disk(free_bytes: int) -> Iterator[None]:
    """Within the block, files opened for writing through ``open`` / ``io.open`` (``os.fdopen``,
    ``Path.write_text`` and ``tempfile`` writers go through it) share ``free_bytes`` of free
    space; writes beyond it raise ``OSError(ENOSPC)``."""
    budget = _Budget(free_bytes)
    real_open = builtins.open

    def fake_open(file: Any, mode: str = "r", *args: Any, **kw: Any) -> Any:
        f = real_open(file, mode, *args, **kw)
        if not _is_write_mode(mode):
            return f
        name = str(file)
        if isinstance(file, int):
            try:
                name = os.readlink(f"/proc/self/fd/{file}")
            except OSError:
                name = f"fd {file}"
        return _FullDiskFile(f, budget, name)

    builtins.open = io.open = fake_open
    try:
        yield
    finally:
        builtins.open = io.open = real_open
