"""One helper thread per process on which a detector runs its second pass while the caller runs the first.

onnxruntime releases the GIL inside ``InferenceSession.run``, and one session's ``run`` may be called
from several threads at once, so CenterNet's fovea pass on this thread overlaps its full-view pass on
the caller's: the outputs are the same, the wall time per frame drops by the shorter pass
(docs/pipeline.md, the detector). A process forked after first use starts without the thread (it is
not inherited) and creates its own on first use.
"""

from __future__ import annotations

import os
import threading
from concurrent.futures import ThreadPoolExecutor

_pool: ThreadPoolExecutor | None = None
_lock = threading.Lock()


def helper_pool() -> ThreadPoolExecutor:
    """The process's single-thread executor for second passes (created on first use)."""
    global _pool
    with _lock:
        if _pool is None:
            _pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="monorarp-second-pass")
        return _pool


def _forget_after_fork() -> None:
    global _pool, _lock
    _pool, _lock = None, threading.Lock()


if hasattr(os, "register_at_fork"):     # not on Windows, which has no fork
    os.register_at_fork(after_in_child=_forget_after_fork)
