"""Reading declarative YAML config files and reporting pydantic errors as one line."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml
from pydantic import ValidationError


def format_validation_error(source: str | Path, err: ValidationError) -> str:
    """``FILE: dotted.field: reason (got VALUE) (and N more)`` for the first error of ``err``."""
    first = err.errors()[0]
    loc = ".".join(str(p) for p in first["loc"] if not str(p).startswith("function-"))
    msg = first["msg"].removeprefix("Value error, ")
    if first["type"] not in ("value_error", "missing", "extra_forbidden") and "input" in first:
        given = first["input"]
        if isinstance(given, (int, float, str, bool)) or given is None:
            msg += f" (got {given!r})"
    more = f" (and {err.error_count() - 1} more)" if err.error_count() > 1 else ""
    return f"{source}: {loc + ': ' if loc else ''}{msg}{more}"


def read_yaml(path: str | Path, error: type[Exception], what: str) -> Any:
    """The parsed content of YAML file ``path``; unreadable or malformed files raise ``error``."""
    path = Path(path)
    try:
        text = path.read_text()
    except OSError as e:
        raise error(f"{path}: cannot read {what} ({e.strerror or e})") from None
    try:
        return yaml.safe_load(text)
    except yaml.YAMLError as e:
        mark = getattr(e, "problem_mark", None)
        where = f" at line {mark.line + 1}" if mark else ""
        raise error(f"{path}: invalid YAML{where}: {getattr(e, 'problem', e)}") from None
