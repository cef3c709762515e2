"""Shared onnxruntime session creation (CPU provider) with one-line :class:`UserError` messages."""

from __future__ import annotations

import contextlib
import hashlib
import io
from dataclasses import dataclass
from pathlib import Path

from monorarp.core.errors import UserError

MAX_SESSIONS = 8     # sessions kept for reuse (oldest dropped)
_sessions: dict[tuple, object] = {}


class ModelError(UserError, ValueError):
    """A detector model file that is missing, unreadable or has an unexpected layout."""


@dataclass(frozen=True)
class TensorInfo:
    name: str
    shape: tuple  # ints for fixed dims, str/None for symbolic ones
    dtype: str    # onnxruntime type string, e.g. "tensor(float)"


def open_session(path: str | Path, intra_op_num_threads: int = 1):
    """An ``onnxruntime.InferenceSession`` on the CPU provider for the model at ``path``.

    ``intra_op_num_threads``: threads for one operator (0 = onnxruntime's default, all cores).
    Raises :class:`ModelError` naming the file when it is missing or not a loadable ONNX model.
    A session is shared by the callers that open the same file with the same content (sha256, ~2 ms for the
    shipped 1.6 MB model) with the same threads (``run`` is stateless and thread-safe): the runs of
    a sweep load the model once per process instead of once each (10-30 ms).
    """
    path = Path(path)
    try:
        if not path.is_file():
            raise ModelError(f"{path}: model file not found" if not path.exists() else f"{path}: not a regular file")
        digest = hashlib.sha256(path.read_bytes()).hexdigest()
    except PermissionError:
        raise ModelError(f"{path}: cannot read model file (permission denied)") from None
    except OSError as e:   # e.g. a name too long
        raise ModelError(f"{str(path)[:200]}: cannot open model file ({e.strerror or e})") from None
    key = (str(path.resolve()), digest, int(intra_op_num_threads))
    session = _sessions.get(key)
    if session is None:
        session = _new_session(path, intra_op_num_threads)
        while len(_sessions) >= MAX_SESSIONS:
            del _sessions[next(iter(_sessions))]
        _sessions[key] = session
    return session


def _new_session(path: Path, intra_op_num_threads: int):
    import onnxruntime as ort

    opts = ort.SessionOptions()
    opts.intra_op_num_threads = int(intra_op_num_threads)
    opts.inter_op_num_threads = 1
    opts.execution_mode = ort.ExecutionMode.ORT_SEQUENTIAL
    opts.graph_optimization_level = ort.GraphOptimizationLevel.ORT_ENABLE_ALL
    opts.log_severity_level = 3
    try:
        # onnxruntime prints its provider fallback ("EP Error ... Falling back") to stdout: the reason
        # comes back in the exception, so keep stdout clean.
        with contextlib.redirect_stdout(io.StringIO()):
            return ort.InferenceSession(str(path), sess_options=opts, providers=["CPUExecutionProvider"])
    except PermissionError:
        raise ModelError(f"{path}: cannot read model file (permission denied)") from None
    except Exception as e:  # noqa: BLE001 - onnxruntime raises its own exception types
        reason = str(e).strip().splitlines()[0] if str(e).strip() else type(e).__name__
        raise ModelError(f"{path}: not a valid ONNX model ({reason[:200]})") from None


def inputs(session) -> list[TensorInfo]:
    return [TensorInfo(i.name, tuple(i.shape), i.type) for i in session.get_inputs()]


def outputs(session) -> list[TensorInfo]:
    return [TensorInfo(o.name, tuple(o.shape), o.type) for o in session.get_outputs()]


def fixed_dim(d) -> int | None:
    """A dimension as an int, or None when symbolic/unknown."""
    return d if isinstance(d, int) and d > 0 else None


def expect_image_input(session, path: str | Path) -> tuple[str, int | None, int | None]:
    """Check the model has exactly one float input of shape (1|N, 3, H, W); return (name, H, W).

    H and W are None when the model declares them symbolic.
    """
    ins = inputs(session)
    if len(ins) != 1:
        raise ModelError(f"{path}: expected one image input (1,3,H,W), found {len(ins)} inputs")
    i = ins[0]
    if len(i.shape) != 4 or fixed_dim(i.shape[1]) != 3 or i.dtype != "tensor(float)":
        raise ModelError(f"{path}: expected a float input of shape (1,3,H,W), found {i.dtype} {list(i.shape)}")
    return i.name, fixed_dim(i.shape[2]), fixed_dim(i.shape[3])
