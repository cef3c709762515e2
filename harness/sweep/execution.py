"""What every executor shares: the executor contract and its error, the render-once task order,
and the set-up of a worker process (its thread counts)."""

from __future__ import annotations

import os
from collections import deque
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Protocol

from harness.sweep.expand import RunTask
from harness.sweep.worker import RunOutcome
from monorarp.core.errors import UserError

#: Thread-count variables set in each worker: BLAS/OpenMP, and Mesa llvmpipe's rasteriser threads.
THREAD_ENV = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMEXPR_NUM_THREADS", "LP_NUM_THREADS")


class ExecutorError(UserError, RuntimeError):
    """An executor that cannot start (e.g. an unreachable Ray address)."""


class Executor(Protocol):
    def run(self, tasks: Sequence[RunTask], runs_dir: Path) -> Iterator[RunOutcome]: ...


class RenderOnceQueue:
    """Tasks in an order that renders each scenario instance once (:meth:`RunTask.frames_key`).

    The first task of an instance (its *leader*) is ready at once; the others become ready
    when it has finished (:meth:`done`), and are handed out before further leaders, so that
    an instance's entry is used while it is fresh in the cache. Tasks without a key (no
    cache, invalid scenario) are leaders of their own. Expansion order otherwise.
    """

    def __init__(self, tasks: Sequence[RunTask]) -> None:
        self._leaders: deque[RunTask] = deque()
        self._followers: deque[RunTask] = deque()
        self._waiting: dict[str, list[RunTask]] = {}
        self._group: dict[str, str] = {}            # leader id -> its key
        for t in tasks:
            key = t.frames_key()
            if key is None:
                self._leaders.append(t)
            elif key in self._waiting:
                self._waiting[key].append(t)
            else:
                self._waiting[key] = []
                self._group[t.id] = key
                self._leaders.append(t)
        self.grouped = any(self._waiting.values())

    def next(self) -> RunTask | None:
        """The next ready task, or None (none ready now)."""
        if self._followers:
            return self._followers.popleft()
        return self._leaders.popleft() if self._leaders else None

    def retry(self, task: RunTask) -> None:
        """Hand ``task`` out again, before anything else (its worker crashed); the tasks that share
        its frames keep waiting for it."""
        self._followers.appendleft(task)

    def done(self, task: RunTask) -> None:
        """``task`` finished (whatever its outcome): the tasks that share its frames become ready."""
        key = self._group.pop(task.id, None)
        if key is not None:
            self._followers.extend(self._waiting.pop(key))


def init_process(threads: int) -> None:
    """Set a worker process's BLAS/OpenMP/llvmpipe and OpenCV thread counts to ``threads``."""
    for k in THREAD_ENV:
        os.environ[k] = str(threads)
    os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
    try:
        import cv2

        cv2.setNumThreads(threads)
    except Exception:  # noqa: BLE001 - best effort
        pass
