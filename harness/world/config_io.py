"""Validating a loaded config file with pydantic, errors as one line (reading it: :mod:`monorarp.core.readers`)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any, TypeVar

from pydantic import BaseModel, Field, Strict, ValidationError

M = TypeVar("M", bound=BaseModel)

#: A seed read from a config file: a non-negative integer, strictly (``true``, ``"7"`` and ``7.0`` are refused).
Seed = Annotated[int, Strict(), Field(ge=0)]
#: A name that becomes one directory name (a scenario's default output ``runs/NAME``): letters, digits,
#: ``_ . + -``, not starting with ``.`` -- never empty, ``.``, ``..``, hidden, absolute or with a ``/``.
SAFE_NAME = r"^[A-Za-z0-9_\-][A-Za-z0-9_.+\-]*$"


def validate_config(model: type[M], data: Any, source: str | Path, error: type[Exception], what: str) -> M:
    """``model`` built from the loaded document ``data``; ``error`` naming ``source`` (field, reason) otherwise."""
    if not isinstance(data, dict):
        raise error(f"{source}: a {what} must be a YAML mapping")
    try:
        return model.model_validate(data)
    except ValidationError as e:
        raise error(format_validation_error(source, e)) from None


def format_validation_error(source: str | Path, err: ValidationError) -> str:
    """``FILE: dotted.field: reason (got VALUE) (and N more)`` for the first error of ``err``."""
    first = err.errors()[0]
    loc = ".".join(str(p) for p in first["loc"] if not str(p).startswith("function-"))
    msg = first["msg"].removeprefix("Value error, ")
    if first["type"] not in ("value_error", "missing", "extra_forbidden") and "input" in first:
        given = first["input"]
        if isinstance(given, (int, float, str, bool)) or given is None:
            msg += f" (got {_shown(given)})"
    more = f" (and {err.error_count() - 1} more)" if err.error_count() > 1 else ""
    return f"{source}: {loc + ': ' if loc else ''}{msg}{more}"


def _shown(value: Any, limit: int = 80) -> str:
    """``repr(value)``, shortened (a 100 kB string or an int too long to print stays one short line)."""
    try:
        text = repr(value)
    except ValueError:   # int beyond sys.get_int_max_str_digits()
        return f"<integer of {value.bit_length()} bits>"
    return text if len(text) <= limit else text[:limit - 3] + "..."

