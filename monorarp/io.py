"""Output files that are never left half-written (shared by the pipeline's and the harness's commands).

* :func:`atomic_output_dir` — build a whole output directory in a temporary
  directory beside the target, move it into place only when everything worked.
* :func:`write_json_atomic` — one JSON file via temp file + ``os.replace``.
* :class:`JsonlWriter` — one JSON object per line, committed on clean close.

All JSON written here is strict (RFC 8259): non-finite floats become ``null``
and numpy scalars/arrays become plain numbers/lists (:func:`to_jsonable`).
"""

from __future__ import annotations

import json
import math
import os
import shutil
import tempfile
import uuid
from collections.abc import Collection, Iterator
from contextlib import contextmanager
from pathlib import Path
from types import TracebackType
from typing import Any, IO

import numpy as np

from monorarp.errors import UserError


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


def write_json_atomic(path: str | Path, obj: Any, *, indent: int | None = 2) -> None:
    """Write ``obj`` as strict JSON to ``path``: temp file in the same directory, then ``os.replace``."""
    path = Path(path)
    text = dumps(obj, indent=indent) + "\n"
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as f:
            f.write(text)
            f.flush()
            os.fsync(f.fileno())
        _chmod_default(Path(tmp), 0o666)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


class JsonlWriter:
    """Append one strict-JSON object per line; the file appears at ``path`` only on clean close.

    Use as a context manager: on an exception the partial file is deleted.
    """

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        fd, tmp = tempfile.mkstemp(dir=self.path.parent, prefix=f".{self.path.name}.", suffix=".tmp")
        self._tmp = Path(tmp)
        self._f: IO[str] | None = os.fdopen(fd, "w", encoding="utf-8")
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
        try:
            f.flush()
            os.fsync(f.fileno())
            f.close()
            _chmod_default(self._tmp, 0o666)
            os.replace(self._tmp, self.path)
        except BaseException:
            self._tmp.unlink(missing_ok=True)
            raise

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
    if target.is_symlink() or not target.is_dir():
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
    """
    target = Path(path).absolute()
    if target.name in ("", ".", ".."):
        raise OutputError(f"{path}: not a usable output directory name")
    owned = frozenset(owned_names)
    _check_replaceable(target, owned)

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
