"""Output files that are never left half-written (shared by the pipeline's and the harness's commands).

* :func:`atomic_output_dir` — build a whole output directory in a temporary
  directory beside the target, move it into place only when everything worked.
* :func:`write_atomic` — one file (text or bytes) via a temp file beside it,
  fsync, then ``os.replace``; :func:`write_json_atomic` is it for strict JSON.
* :class:`JsonlWriter` — one JSON object per line, committed (the same way) on clean close.

On any error (a full disk included) the temp file is removed and the target is untouched.

All JSON written here is strict (RFC 8259): non-finite floats become ``null``
and numpy scalars/arrays become plain numbers/lists (:func:`to_jsonable`).
"""

from __future__ import annotations

import json
import math
import os
import shutil
import signal
import tempfile
import threading
import uuid
from collections.abc import Collection, Iterator
from contextlib import contextmanager
from pathlib import Path
from types import TracebackType
from typing import Any, IO

import numpy as np

from monorarp.core.errors import UserError


class OutputError(UserError, OSError):
    """An output location that cannot be used (not a directory, foreign content, no permission)."""


# ----------------------------------------------------------------------- JSON
def to_jsonable(obj: Any) -> Any:
    """Recursively convert to strict-JSON types: NaN/inf -> None, numpy -> Python, tuples -> lists."""
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if obj is None or isinstance(obj, (str, bool, int)):
        return obj
    if isinstance(obj, dict):
        return {str(k): to_jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [to_jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return to_jsonable(obj.tolist())
    if isinstance(obj, np.bool_):
        return bool(obj)
    if isinstance(obj, np.integer):
        return int(obj)
    if isinstance(obj, np.floating):
        return to_jsonable(float(obj))
    if isinstance(obj, Path):
        return str(obj)
    raise TypeError(f"cannot write {type(obj).__name__} to JSON")


def dumps(obj: Any, *, indent: int | None = None) -> str:
    """Strict, deterministic JSON text (key order as given, shortest float repr)."""
    separators = (",", ": ") if indent is not None else (",", ":")
    return json.dumps(to_jsonable(obj), allow_nan=False, indent=indent, separators=separators)


# ------------------------------------------------------------ atomic files
def _open_temp(path: Path, *, binary: bool = False) -> tuple[IO[Any], Path]:
    """A new file ``.NAME.*.tmp`` beside ``path`` (same filesystem: the final move is a rename), open to write."""
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    if binary:
        return os.fdopen(fd, "wb"), Path(tmp)
    return os.fdopen(fd, "w", encoding="utf-8", newline=""), Path(tmp)


def _commit_file(f: IO[Any], tmp: Path, path: Path, data: str | bytes | None = None) -> None:
    """Write ``data`` (if any) to the temp file ``f``, fsync and close it, move it onto ``path``.

    On any error the temp file is removed and the exception propagates.
    """
    try:
        with f:
            if data is not None:
                f.write(data)
            f.flush()
            os.fsync(f.fileno())
        _chmod_default(tmp, 0o666)
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def write_atomic(path: str | Path, data: str | bytes) -> None:
    """Write ``data`` (UTF-8 text, written as is, or bytes) to ``path``: all of it or, on an error, nothing."""
    path = Path(path)
    f, tmp = _open_temp(path, binary=isinstance(data, bytes))
    _commit_file(f, tmp, path, data)


def write_json_atomic(path: str | Path, obj: Any, *, indent: int | None = 2) -> None:
    """Write ``obj`` as strict JSON (one trailing newline) to ``path`` with :func:`write_atomic`."""
    write_atomic(path, dumps(obj, indent=indent) + "\n")


class JsonlWriter:
    """Append one strict-JSON object per line; the file appears at ``path`` only on clean close.

    Use as a context manager: on an exception the partial file is deleted.
    """

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        self._f: IO[str] | None
        self._f, self._tmp = _open_temp(self.path)
        self.count = 0

    def write(self, record: Any) -> None:
        if self._f is None:
            raise ValueError(f"{self.path}: writer is closed")
        self._f.write(dumps(record) + "\n")
        self.count += 1

    def close(self) -> None:
        """Flush and move the file into place."""
        if self._f is None:
            return
        f, self._f = self._f, None
        _commit_file(f, self._tmp, self.path)

    def abort(self) -> None:
        """Discard everything written."""
        if self._f is not None:
            self._f.close()
            self._f = None
        self._tmp.unlink(missing_ok=True)

    def __enter__(self) -> "JsonlWriter":
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        if exc_type is None:
            self.close()
        else:
            self.abort()


@contextmanager
def interrupts_deferred() -> Iterator[None]:
    """Hold SIGINT and SIGTERM until the block ends (main thread), then act on the first that came.

    For the last writes of files that belong together (a sweep's summary and its report): a
    Ctrl-C or ``kill`` in between would leave one without the other. (Python-level handlers,
    not a signal mask: a process-directed signal goes to any thread that does not block it.)
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    held: list[int] = []
    previous = {s: signal.signal(s, lambda signum, frame: held.append(signum))
                for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield
    finally:
        for s, handler in previous.items():
            if handler is not None:          # None: a handler not set from Python, left as it is
                signal.signal(s, handler)
        if held:
            handler = previous[held[0]]
            if callable(handler):
                handler(held[0], None)       # e.g. KeyboardInterrupt, or the CLI's Terminated
            elif handler == signal.SIG_DFL:
                signal.raise_signal(held[0])


# -------------------------------------------------------------- output dirs
def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def _chmod_default(path: Path, mode: int) -> None:
    """Give a mkstemp/mkdtemp result (0600/0700) the permissions a plain create would have."""
    os.chmod(path, mode & ~_umask())


def _check_replaceable(target: Path, owned_names: Collection[str]) -> None:
    if not target.exists() and not target.is_symlink():
        return
    if target.is_symlink():
        raise OutputError(f"{target}: output path is a symbolic link (the output would replace the link); "
                          f"give the path it points to, {os.path.realpath(target)}")
    if not target.is_dir():
        raise OutputError(f"{target}: output path exists and is not a directory")
    foreign = sorted(p.name for p in target.iterdir() if p.name not in owned_names)
    if foreign:
        shown = ", ".join(foreign[:3]) + (" ..." if len(foreign) > 3 else "")
        raise OutputError(f"{target}: refusing to replace a directory holding files this command "
                          f"did not write ({shown}); choose another --out or remove it")


@contextmanager
def atomic_output_dir(path: str | Path, *, owned_names: Collection[str] = ()) -> Iterator[Path]:
    """Yield a fresh temporary directory; on success it replaces ``path`` as a whole.

    The temporary directory is created beside ``path`` (same filesystem, so the
    final move is a rename). Missing parent directories are created and removed
    again on failure. If ``path`` already exists it must be a directory whose
    entries are all in ``owned_names`` (i.e. a previous run of the same command,
    or empty): otherwise :class:`OutputError` is raised before anything is
    written. On success the old directory is renamed away, the new one renamed
    in, then the old one deleted (a crash between the two renames leaves the
    previous run under a ``.NAME.old-*`` sibling, never a half-written ``path``).
    On any exception (including KeyboardInterrupt) the temporary directory is
    removed and ``path`` is left untouched.

    A ``path`` that exists but cannot be renamed (a mount point such as a container
    volume, or a directory in a parent we may not write) is probed before anything is
    computed; its new contents are then built in a temporary directory inside it and
    moved in entry by entry after its previous entries are removed (not atomic as a whole).
    """
    target = Path(path).absolute()
    if target.name in ("", ".", ".."):
        raise OutputError(f"{path}: not a usable output directory name")
    owned = frozenset(owned_names)
    _check_replaceable(target, owned)

    if target.is_dir() and not _renamable(target):
        with _output_dir_in_place(target, owned) as tmp:
            yield tmp
        return

    created_parents: list[Path] = []
    parent = target.parent
    while not parent.exists():
        created_parents.append(parent)
        parent = parent.parent
    try:
        for p in reversed(created_parents):
            p.mkdir()
        tmp = Path(tempfile.mkdtemp(dir=target.parent, prefix=f".{target.name}.tmp-"))
    except OSError as e:
        _remove_empty(created_parents)
        raise OutputError(f"{target}: cannot create output directory ({e.strerror or e})") from None

    try:
        _chmod_default(tmp, 0o777)
        yield tmp
        _check_replaceable(target, owned)  # re-check: something may have appeared meanwhile
        _commit(tmp, target)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        _remove_empty(created_parents)
        raise


def _renamable(target: Path) -> bool:
    """Whether the existing directory ``target`` can be renamed (tried: renamed away and back at once)."""
    probe = target.with_name(f".{target.name}.probe-{uuid.uuid4().hex[:8]}")
    try:
        os.rename(target, probe)
    except OSError:
        return False
    os.rename(probe, target)
    return True


@contextmanager
def _output_dir_in_place(target: Path, owned: frozenset[str]) -> Iterator[Path]:
    """:func:`atomic_output_dir` for a directory that cannot be renamed: staged inside it."""
    try:
        tmp = Path(tempfile.mkdtemp(dir=target, prefix=".tmp-"))
    except OSError as e:
        raise OutputError(f"{target}: cannot write in the output directory ({e.strerror or e})") from None
    try:
        _chmod_default(tmp, 0o777)
        yield tmp
        _check_replaceable(target, owned | {tmp.name})   # re-check: something may have appeared meanwhile
        for p in target.iterdir():
            if p != tmp:
                shutil.rmtree(p) if p.is_dir() and not p.is_symlink() else p.unlink()
        for p in tmp.iterdir():
            os.rename(p, target / p.name)
        tmp.rmdir()
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise


def _commit(tmp: Path, target: Path) -> None:
    if not target.exists():
        os.rename(tmp, target)
        return
    old = target.with_name(f".{target.name}.old-{uuid.uuid4().hex[:8]}")
    os.rename(target, old)
    try:
        os.rename(tmp, target)
    except BaseException:
        os.rename(old, target)
        raise
    shutil.rmtree(old, ignore_errors=True)


def _remove_empty(dirs: list[Path]) -> None:
    """Remove directories we created (innermost first) if they are still empty."""
    for d in dirs:
        try:
            d.rmdir()
        except OSError:
            break
