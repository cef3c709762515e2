"""Executors: run a list of :class:`RunTask` and yield each :class:`RunOutcome` as it completes.

* :class:`SerialExecutor` — in this process, one run after the other (``--workers 1``).
* :class:`~harness.sweep.pool.ProcessExecutor` — N worker processes started with
  ``spawn``: worker processes never inherit a forked copy of this process (an EGL
  context must not cross a fork), and die with it (``PR_SET_PDEATHSIG``); workers
  are reused across runs and each gets ``cpu_count // workers`` threads for
  OpenCV/BLAS/ONNX Runtime so that N workers do not oversubscribe the cores.
  Used for ``--workers 1`` too when a per-run timeout is set.
* :class:`RayExecutor` — tasks on a Ray cluster (``--address``) or on a local
  Ray instance; workers return the run's files and the driver writes them, so
  a multi-machine cluster needs no shared filesystem.

Every executor gives the same metrics: a run is a pure function of its task.
A worker process that dies (SIGKILL, segfault, OOM) or overruns ``run_timeout_s`` fails
its run, with the cause, not the sweep; the other runs go on.

With a frame cache (:mod:`harness.run.frame_cache`), the parallel executors hand out
tasks through :class:`RenderOnceQueue`: the first run of each scenario instance
renders it, the runs sharing its frames start only when it has finished (and
read them from the cache); meanwhile the other workers render other instances.
"""

from __future__ import annotations

import os
import socket
from collections.abc import Iterator, Sequence
from pathlib import Path

from harness.sweep import faults, worker
from harness.sweep.expand import RunTask
from harness.sweep.execution import Executor, ExecutorError, RenderOnceQueue
from harness.sweep.pool import ProcessExecutor, record_failure
from harness.sweep.worker import RunOutcome


def _record_crash(task: RunTask, runs_dir: Path, error: str) -> RunOutcome:
    return record_failure(task, runs_dir, error)


# -------------------------------------------------------------------- local
class SerialExecutor:
    """Runs in the calling process (lets tests monkeypatch :func:`harness.run.runner.run_scenario`)."""

    workers = 1

    def run(self, tasks: Sequence[RunTask], runs_dir: Path) -> Iterator[RunOutcome]:
        for task in tasks:
            yield worker.execute(task, str(runs_dir))


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

    def __init__(self, workers: int, address: str | None = None, probe_timeout_s: float = 3.0,
                 run_timeout_s: float | None = None) -> None:
        try:
            import ray  # noqa: F401
        except ImportError:
            raise ExecutorError("--executor ray needs Ray: pip install 'monorarp[ray]' (or 'ray[default]')") from None
        if workers < 1:
            raise ExecutorError(f"--workers must be >= 1, got {workers}")
        self.workers = workers
        self.run_timeout_s = run_timeout_s
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
        if os.environ.get(faults.ENV):                  # test-only fault injection reaches the workers
            env["env_vars"][faults.ENV] = os.environ[faults.ENV]
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
        """Submit, collect, write. A task whose worker or node is lost fails with Ray's cause (no retry:
        ``--resume`` runs it again); with ``run_timeout_s`` a task running longer is cancelled (its worker
        killed) and fails with "timeout after S s" -- timed from submission, so then no more tasks are in
        flight than the cluster has CPUs."""
        import time

        import ray

        if not hasattr(self, "_started"):
            self.start()
        pending: dict = {}
        try:
            remote = ray.remote(num_cpus=1, max_retries=0)(worker.execute_detached)
            queue = RenderOnceQueue(tasks)
            limited = queue.grouped or self.run_timeout_s is not None
            cpus = int(ray.cluster_resources().get("CPU", self.workers)) if limited else 0
            if self.run_timeout_s is not None:
                window = max(1, cpus)
            else:
                window = 2 * max(self.workers, cpus) if queue.grouped else max(1, len(tasks))
            started: dict = {}
            while True:
                while len(pending) < window and (task := queue.next()) is not None:
                    ref = remote.remote(task)
                    pending[ref], started[ref] = task, time.monotonic()
                if not pending:
                    break
                timeout = None
                if self.run_timeout_s is not None:
                    timeout = max(0.0, min(started[r] for r in pending) + self.run_timeout_s - time.monotonic())
                done, _ = ray.wait(list(pending), num_returns=1, timeout=timeout)
                now = time.monotonic()
                overdue = [] if done or self.run_timeout_s is None else \
                    [r for r in pending if now - started[r] >= self.run_timeout_s]
                for ref in overdue:
                    ray.cancel(ref, force=True)
                    task = pending.pop(ref)
                    queue.done(task)
                    yield record_failure(task, runs_dir, f"timeout after {self.run_timeout_s:g} s (task cancelled)")
                for ref in done:
                    task = pending.pop(ref)
                    queue.done(task)
                    try:
                        outcome, files = ray.get(ref)
                    except Exception as e:  # noqa: BLE001 - worker crashed / node lost
                        yield record_failure(task, runs_dir, f"ray task failed: {' '.join(str(e).split())[:500]}")
                        continue
                    try:
                        worker.write_run_files(runs_dir, task.id, files)
                    except OSError as e:     # e.g. the driver's disk is full
                        yield record_failure(task, runs_dir, f"cannot write the run's files: {worker.describe_error(e)}")
                        continue
                    yield outcome
        finally:
            for ref in pending:
                ray.cancel(ref, force=True)


def make_executor(kind: str, workers: int, address: str | None = None,
                  run_timeout_s: float | None = None) -> Executor:
    """``run_timeout_s``: per-run limit in seconds (None: none); a local sweep then runs in worker processes
    even with ``workers == 1`` (a run in the calling process cannot be ended)."""
    if run_timeout_s is not None and not run_timeout_s > 0:
        raise ExecutorError(f"--run-timeout must be > 0 seconds, got {run_timeout_s}")
    if kind == "local":
        if address is not None:
            raise ExecutorError("--address is only for --executor ray")
        if workers == 1 and run_timeout_s is None:
            return SerialExecutor()
        return ProcessExecutor(workers, run_timeout_s)
    if kind == "ray":
        return RayExecutor(workers, address, run_timeout_s=run_timeout_s)
    raise ExecutorError(f"unknown executor {kind!r}; use local or ray")
