"""Local worker processes that survive their runs' faults: :class:`ProcessExecutor`.

Each of N worker processes (``spawn``: a fresh interpreter, no forked copy of an EGL
context, and the driver is its parent, see below) runs one task at a time, sent over its own pipe, so the driver always knows
which run a worker holds. Then:

* a worker that is killed (SIGKILL, OOM killer) fails exactly its run, with the
  cause ("worker process died (killed by SIGKILL)"); a new worker takes its place and
  the other workers' runs go on untouched;
* a worker that crashes in native code (SIGSEGV, SIGABRT, SIGBUS, SIGILL, SIGFPE: a fault in
  a C library, not a kill) gets its run retried once in a new worker, with a line on stderr;
  runs are deterministic, so the retry writes what an uncrashed run would have. A second
  crash fails the run ("... (killed by SIGSEGV), twice");
* with ``run_timeout_s``, a run that takes longer is ended by killing its worker
  (SIGKILL) and fails with "timeout after S s";
* a worker whose driver dies (``kill -9`` of the sweep) is killed by the kernel
  (``PR_SET_PDEATHSIG`` on Linux), so no orphan commits a run behind a resumed sweep.

A failed run's record (``run.json`` + ``error.json``) is written by the driver; any
temporary directory the dead worker left behind is removed when the sweep ends
(:func:`harness.sweep.orchestrate.clean_leftovers`).
"""

from __future__ import annotations

import ctypes
import faulthandler
import multiprocessing
import os
import signal
import sys
import time
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from multiprocessing.connection import Connection, wait
from pathlib import Path
from typing import Any

from harness.sweep import worker
from harness.sweep.execution import ExecutorError, RenderOnceQueue, init_process
from harness.sweep.expand import RunTask
from harness.sweep.worker import RunOutcome

PR_SET_PDEATHSIG = 1
#: Deaths by these signals are crashes inside the process (not kills): the run is retried once.
NATIVE_CRASHES = frozenset({signal.SIGSEGV, signal.SIGABRT, signal.SIGBUS, signal.SIGILL, signal.SIGFPE})
STARTED, DONE = "started", "done"      # worker -> driver messages
RETRY = object()                        # _collect: run the task again


def _die_with_parent(parent_pid: int) -> None:
    """Linux: SIGKILL this process when its parent exits (best effort elsewhere)."""
    try:
        ctypes.CDLL(None, use_errno=True).prctl(PR_SET_PDEATHSIG, signal.SIGKILL)
    except (OSError, AttributeError):
        return
    if os.getppid() != parent_pid:       # the parent died before prctl took effect
        os._exit(1)


def _worker_main(conn: Connection, threads: int, parent_pid: int) -> None:
    """A worker process: run each task received, send its outcome back; ``None`` ends it.

    A native crash (SIGSEGV, SIGABRT, ...) prints every thread's Python stack to stderr first
    (faulthandler), so the run recorded as "worker process died" can be traced.
    """
    faulthandler.enable()
    _die_with_parent(parent_pid)

    init_process(threads)
    try:                     # imported before the first run starts its clock (errors show in that run)
        import harness.run.runner  # noqa: F401
        import harness.scoring.evaluate  # noqa: F401
    except Exception:  # noqa: BLE001
        pass
    while True:
        try:
            msg = conn.recv()
        except (EOFError, OSError):
            return
        if msg is None:
            return
        task, runs_dir = msg
        try:
            conn.send((STARTED, None))
            try:
                outcome = worker.execute(task, runs_dir)
            except Exception as e:  # noqa: BLE001 - e.g. a full disk while recording the failure
                outcome = RunOutcome(task.id, "failed", worker.describe_error(e))
            conn.send((DONE, outcome))
        except (OSError, ValueError):    # the driver is gone
            return


def death_cause(exitcode: int | None) -> str:
    """Why a worker process ended, in words."""
    if exitcode is not None and exitcode < 0:
        try:
            name = signal.Signals(-exitcode).name
        except ValueError:
            name = f"signal {-exitcode}"
        return f"worker process died (killed by {name})"
    return f"worker process died (exit code {exitcode})"


def record_failure(task: RunTask, runs_dir: Path, error: str) -> RunOutcome:
    """Write the failed run's ``run.json``/``error.json`` (best effort: a full disk may refuse them;
    the summary then carries the cause from the returned outcome)."""
    try:
        worker.write_run_files(runs_dir, task.id, worker.failed_outcome_files(task, error))
    except OSError as e:
        error = f"{error}; its failure record could not be written ({worker.describe_error(e)})"
    return RunOutcome(task.id, "failed", error)


@dataclass
class _Worker:
    process: Any
    conn: Connection
    task: RunTask | None = None
    started: float | None = None          # monotonic time the worker said it started the task


class ProcessExecutor:
    """``workers`` local processes; see the module docstring. ``run_timeout_s``: None = no limit."""

    def __init__(self, workers: int, run_timeout_s: float | None = None) -> None:

        if workers < 1:
            raise ExecutorError(f"--workers must be >= 1, got {workers}")
        if run_timeout_s is not None and not run_timeout_s > 0:
            raise ExecutorError(f"--run-timeout must be > 0 seconds, got {run_timeout_s}")
        self.workers = workers
        self.run_timeout_s = run_timeout_s

    def _spawn(self, threads: int) -> _Worker:
        ctx = multiprocessing.get_context("spawn")
        ours, theirs = ctx.Pipe(duplex=True)
        p = ctx.Process(target=_worker_main, args=(theirs, threads, os.getpid()), daemon=True,
                        name="monorarp-sweep-worker")
        p.start()
        theirs.close()
        return _Worker(p, ours)

    def run(self, tasks: Sequence[RunTask], runs_dir: Path) -> Iterator[RunOutcome]:

        threads = max(1, (os.cpu_count() or 1) // self.workers)
        queue = RenderOnceQueue(tasks)
        retried: set[str] = set()
        idle: list[_Worker] = []
        busy: list[_Worker] = []
        n_workers = 0
        try:
            while True:
                for w in [w for w in idle if not w.process.is_alive()]:   # died between runs (OOM killer)
                    idle.remove(w)
                    self._kill(w)
                    n_workers -= 1
                while (idle or n_workers < self.workers) and (task := queue.next()) is not None:
                    if not idle:
                        idle.append(self._spawn(threads))
                        n_workers += 1
                    w = idle.pop()
                    w.task, w.started = task, None
                    try:
                        w.conn.send((task, str(runs_dir)))
                    except OSError:      # it died just now: its sentinel reports it below
                        pass
                    busy.append(w)
                if not busy:
                    return
                timeout = None
                timed = [w.started for w in busy if w.started is not None]
                if self.run_timeout_s is not None and timed:
                    timeout = max(0.0, min(timed) + self.run_timeout_s - time.monotonic())
                ready = set(wait([w.conn for w in busy] + [w.process.sentinel for w in busy], timeout))
                now = time.monotonic()
                for w in list(busy):
                    outcome = None
                    if w.conn in ready or w.process.sentinel in ready:
                        outcome = self._collect(w, runs_dir, retry=w.task.id not in retried)
                    elif (self.run_timeout_s is not None and w.started is not None
                          and now - w.started >= self.run_timeout_s):
                        self._kill(w)
                        outcome = record_failure(w.task, runs_dir, f"timeout after {self.run_timeout_s:g} s "
                                                                   "(worker killed)")
                    if outcome is None:
                        continue
                    busy.remove(w)
                    if outcome is RETRY:
                        sys.stderr.write(f"run {w.task.id}: {death_cause(w.process.exitcode)}; retried once in a new "
                                         "worker\n")
                        retried.add(w.task.id)
                        queue.retry(w.task)
                        w.conn.close()
                        n_workers -= 1
                        continue
                    queue.done(w.task)
                    if w.process.is_alive():
                        w.task = None
                        idle.append(w)
                    else:
                        w.conn.close()
                        n_workers -= 1
                    yield outcome
        finally:
            for w in idle:
                self._stop(w)
            for w in busy:
                self._kill(w)

    def _collect(self, w: _Worker, runs_dir: Path, retry: bool = False) -> RunOutcome | object | None:
        """The outcome a ready worker sent, its death recorded as the run's failure, :data:`RETRY`
        (``retry`` and it crashed in native code: nothing recorded), or None (it only said it started)."""
        try:
            while w.conn.poll():
                kind, outcome = w.conn.recv()
                if kind == DONE:
                    return outcome
                w.started = time.monotonic()
            if w.process.is_alive():
                return None
        except (EOFError, OSError):
            pass
        w.process.join(5)
        if w.process.is_alive():         # closed its pipe but lingers: end it
            self._kill(w)
        code = w.process.exitcode
        crashed = code is not None and code < 0 and -code in NATIVE_CRASHES
        if crashed and retry:
            return RETRY
        return record_failure(w.task, runs_dir, death_cause(code) + (", twice" if crashed else ""))

    @staticmethod
    def _kill(w: _Worker) -> None:
        if w.process.is_alive():
            w.process.kill()
        w.process.join()
        w.conn.close()

    @staticmethod
    def _stop(w: _Worker) -> None:
        try:
            w.conn.send(None)
        except (OSError, ValueError):
            pass
        w.process.join(10)
        if w.process.is_alive():
            w.process.kill()
            w.process.join()
        w.conn.close()
