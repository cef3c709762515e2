"""Executors: run a list of :class:`RunTask` and yield each :class:`RunOutcome` as it completes.

* :class:`SerialExecutor` — in this process, one run after the other (``--workers 1``).
* :class:`ProcessExecutor` — a ``concurrent.futures`` process pool started with
  ``forkserver`` (``spawn`` where unavailable): worker processes never inherit a
  forked copy of this process (an EGL context must not cross a fork); workers
  are reused across runs and each gets ``cpu_count // workers`` threads for
  OpenCV/BLAS/ONNX Runtime so that N workers do not oversubscribe the cores.
* :class:`RayExecutor` — tasks on a Ray cluster (``--address``) or on a local
  Ray instance; workers return the run's files and the driver writes them, so
  a multi-machine cluster needs no shared filesystem.

Every executor gives the same metrics: a run is a pure function of its task.
A worker process that dies (segfault, OOM) fails its run, not the sweep.

With a frame cache (:mod:`harness.frame_cache`), the parallel executors hand out
tasks through :class:`RenderOnceQueue`: the first run of each scenario instance
renders it, the runs sharing its frames start only when it has finished (and
read them from the cache); meanwhile the other workers render other instances.
"""

from __future__ import annotations

import multiprocessing
import os
import socket
from collections import deque
from collections.abc import Iterator, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from pathlib import Path
from typing import Protocol

from harness.sweep import worker
from harness.sweep.expand import RunTask
from harness.sweep.worker import RunOutcome
from monorarp.errors import UserError

#: Thread-count variables set in each worker: BLAS/OpenMP, and Mesa llvmpipe's rasteriser threads.
THREAD_ENV = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMEXPR_NUM_THREADS", "LP_NUM_THREADS")


class ExecutorError(UserError, RuntimeError):
    """An executor that cannot start (e.g. an unreachable Ray address)."""


class Executor(Protocol):
    def run(self, tasks: Sequence[RunTask], runs_dir: Path) -> Iterator[RunOutcome]: ...


def _record_crash(task: RunTask, runs_dir: Path, error: str) -> RunOutcome:
    worker.write_run_files(runs_dir, task.id, worker.failed_outcome_files(task, error))
    return RunOutcome(task.id, "failed", error)


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

    def done(self, task: RunTask) -> None:
        """``task`` finished (whatever its outcome): the tasks that share its frames become ready."""
        key = self._group.pop(task.id, None)
        if key is not None:
            self._followers.extend(self._waiting.pop(key))


# -------------------------------------------------------------------- local
class SerialExecutor:
    """Runs in the calling process (lets tests monkeypatch :func:`harness.run.run_scenario`)."""

    workers = 1

    def run(self, tasks: Sequence[RunTask], runs_dir: Path) -> Iterator[RunOutcome]:
        for task in tasks:
            yield worker.execute(task, str(runs_dir))


def _init_process(threads: int) -> None:
    for k in THREAD_ENV:
        os.environ[k] = str(threads)
    os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
    try:
        import cv2

        cv2.setNumThreads(threads)
    except Exception:  # noqa: BLE001 - best effort
        pass


def _mp_context() -> multiprocessing.context.BaseContext:
    methods = multiprocessing.get_all_start_methods()
    return multiprocessing.get_context("forkserver" if "forkserver" in methods else "spawn")


class ProcessExecutor:
    def __init__(self, workers: int) -> None:
        if workers < 1:
            raise ExecutorError(f"--workers must be >= 1, got {workers}")
        self.workers = workers

    def run(self, tasks: Sequence[RunTask], runs_dir: Path) -> Iterator[RunOutcome]:
        threads = max(1, (os.cpu_count() or 1) // self.workers)
        queue = RenderOnceQueue(tasks)
        window = 2 * self.workers if queue.grouped else max(1, len(tasks))   # tasks in the pool at a time
        with ProcessPoolExecutor(max_workers=self.workers, mp_context=_mp_context(),
                                 initializer=_init_process, initargs=(threads,)) as pool:
            pending: dict[Future, RunTask] = {}

            def fill() -> list[RunOutcome]:
                crashed = []
                while len(pending) < window and (task := queue.next()) is not None:
                    try:
                        pending[pool.submit(worker.execute, task, str(runs_dir))] = task
                    except Exception as e:  # noqa: BLE001 - the pool broke (a worker died)
                        queue.done(task)
                        crashed.append(_record_crash(task, runs_dir, f"worker failed: {type(e).__name__}: {e}"))
                return crashed

            try:
                yield from fill()
                while pending:
                    done, _ = wait(pending, return_when=FIRST_COMPLETED)
                    for fut in sorted(done, key=lambda f: pending[f].index):
                        task = pending.pop(fut)
                        queue.done(task)
                        try:
                            yield fut.result()
                        except Exception as e:  # noqa: BLE001 - worker died (BrokenProcessPool) etc.
                            yield _record_crash(task, runs_dir, f"worker failed: {type(e).__name__}: {e}")
                    yield from fill()
            finally:
                for fut in pending:
                    fut.cancel()


# ---------------------------------------------------------------------- ray
DEFAULT_RAY_PORT = 6379


def _split_address(address: str) -> tuple[str, int]:
    rest = address.split("://", 1)[1] if "://" in address else address
    host, sep, port = rest.rpartition(":")
    if not sep:
        return rest, (10001 if address.startswith("ray://") else DEFAULT_RAY_PORT)
    if not port.isdigit() or not host:
        raise ExecutorError(f"--address {address!r}: expected HOST:PORT (e.g. 10.0.0.5:6379), 'auto' or ray://HOST:PORT")
    return host.strip("[]"), int(port)


def resolve_auto_address() -> str:
    """What ``ray.init(address='auto')`` would use: ``RAY_ADDRESS``, else the address of the cluster that
    ``ray start`` last started on this machine."""
    env = os.environ.get("RAY_ADDRESS", "").strip()
    if env and env != "auto":
        return env
    tmp = Path(os.environ.get("RAY_TMPDIR", "/tmp")) / "ray" / "ray_current_cluster"
    try:
        text = tmp.read_text().strip()
    except OSError:
        text = ""
    if not text:
        raise ExecutorError("--address auto: no running Ray cluster found on this machine (no RAY_ADDRESS and no "
                            f"{tmp}); start one with `ray start --head` or give --address HOST:PORT")
    return text.splitlines()[0].strip()


def probe(address: str, timeout_s: float = 3.0) -> None:
    """Fail fast (one line) when no Ray GCS answers at ``address`` — ``ray.init`` would retry for minutes.

    First a TCP connection; then (GCS addresses, not ``ray://``) one gRPC call to the
    GCS with a deadline: a server that is not gRPC at all (e.g. an HTTP proxy) or
    does not answer is refused. Any gRPC answer, even "unauthenticated" or
    "unknown method", counts as reachable and is left to ``ray.init``.
    """
    host, port = _split_address(address)
    hint = "is `ray start --head` running there and the port open?"
    try:
        with socket.create_connection((host, port), timeout=timeout_s):
            pass
    except OSError as e:
        reason = "timed out" if isinstance(e, TimeoutError) else (e.strerror or str(e))
        raise ExecutorError(f"cannot reach the Ray cluster at {host}:{port} ({reason} after at most {timeout_s:g} s); "
                            f"{hint}") from None
    if address.startswith("ray://"):
        return
    try:
        import grpc
    except ImportError:
        return
    channel = grpc.insecure_channel(f"{host}:{port}")
    try:
        call = channel.unary_unary("/ray.rpc.NodeInfoGcsService/GetClusterId")
        call(b"", timeout=timeout_s)
    except grpc.RpcError as e:
        code, details = e.code(), (e.details() or "")
        not_grpc = code == grpc.StatusCode.UNIMPLEMENTED and "http2 header" in details.lower()
        if not_grpc or code in (grpc.StatusCode.UNAVAILABLE, grpc.StatusCode.DEADLINE_EXCEEDED):
            raise ExecutorError(f"no Ray cluster answers at {host}:{port} ({code.name.lower()}: "
                                f"{' '.join(details.split())[:120]}); {hint}") from None
    finally:
        channel.close()


class RayExecutor:
    """Ray tasks (1 CPU each). ``address=None`` starts a local instance with ``workers`` CPUs."""

    def __init__(self, workers: int, address: str | None = None, probe_timeout_s: float = 3.0) -> None:
        try:
            import ray  # noqa: F401
        except ImportError:
            raise ExecutorError("--executor ray needs Ray: pip install 'monorarp[ray]' (or 'ray[default]')") from None
        if workers < 1:
            raise ExecutorError(f"--workers must be >= 1, got {workers}")
        self.workers = workers
        self.address = None
        if address is not None:   # checked now, before any run starts
            self.address = resolve_auto_address() if address == "auto" else address
            probe(self.address, probe_timeout_s)

    def start(self) -> None:
        """Initialise Ray (before the output directory is touched)."""
        self._started = self._connect()

    def close(self) -> None:
        import ray

        if getattr(self, "_started", False):
            ray.shutdown()
            self._started = False

    def _connect(self) -> bool:
        """Initialise Ray; returns whether this call started it (and must shut it down)."""
        import ray

        if ray.is_initialized():
            return False
        # one CPU per task: one rasteriser thread (Ray itself sets OMP_NUM_THREADS=1 for such tasks)
        env = {"env_vars": {"PYOPENGL_PLATFORM": os.environ.get("PYOPENGL_PLATFORM", "egl"), "LP_NUM_THREADS": "1"}}
        if self.address is None:
            ray.init(num_cpus=self.workers, include_dashboard=False, log_to_driver=False, runtime_env=env,
                     configure_logging=False)
            return True
        address = self.address
        try:
            ray.init(address=address, log_to_driver=False, runtime_env=env, configure_logging=False)
        except Exception as e:  # noqa: BLE001 - version mismatch, auth, ...
            raise ExecutorError(f"cannot connect to the Ray cluster at {address}: {' '.join(str(e).split())}") from None
        return True

    def run(self, tasks: Sequence[RunTask], runs_dir: Path) -> Iterator[RunOutcome]:
        import ray

        if not hasattr(self, "_started"):
            self.start()
        try:
            remote = ray.remote(num_cpus=1, max_retries=0)(worker.execute_detached)
            queue = RenderOnceQueue(tasks)
            cpus = int(ray.cluster_resources().get("CPU", self.workers)) if queue.grouped else 0
            window = 2 * max(self.workers, cpus) if queue.grouped else max(1, len(tasks))
            pending: dict = {}
            while True:
                while len(pending) < window and (task := queue.next()) is not None:
                    pending[remote.remote(task)] = task
                if not pending:
                    break
                done, _ = ray.wait(list(pending), num_returns=1)
                for ref in done:
                    task = pending.pop(ref)
                    queue.done(task)
                    try:
                        outcome, files = ray.get(ref)
                    except Exception as e:  # noqa: BLE001 - worker crashed / node lost
                        yield _record_crash(task, runs_dir, f"ray task failed: {' '.join(str(e).split())[:500]}")
                        continue
                    worker.write_run_files(runs_dir, task.id, files)
                    yield outcome
        finally:
            for ref in list(locals().get("pending", {})):
                ray.cancel(ref, force=True)


def make_executor(kind: str, workers: int, address: str | None = None) -> Executor:
    if kind == "local":
        if address is not None:
            raise ExecutorError("--address is only for --executor ray")
        return SerialExecutor() if workers == 1 else ProcessExecutor(workers)
    if kind == "ray":
        return RayExecutor(workers, address)
    raise ExecutorError(f"unknown executor {kind!r}; use local or ray")
