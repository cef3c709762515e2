"""A component's settings: a pydantic model of every keyword a component takes, its defaults and
ranges (``StateConfig``, ``WarningConfig``, ``MonteCarloConfig``), and the one way keyword
overrides from YAML, the command line or code are validated into it, with a one-line refusal that
names the setting."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, TypeVar

from pydantic import BaseModel, ValidationError

M = TypeVar("M", bound=BaseModel)


def with_overrides(model: type[M], base: M | None, overrides: Mapping[str, Any] | None, what: str,
                   error: type[Exception]) -> M:
    """``base`` (None: the defaults) with ``overrides`` validated in; raises ``error`` with one line
    (``"<what> setting NAME: problem, got VALUE"``) for a bad one."""
    if base is not None and not isinstance(base, model):
        raise error(f"{what} config must be a {model.__name__} or None, got {type(base).__name__}")
    if not overrides:
        return model() if base is None else base
    try:
        return model.model_validate({**(dict(base) if base is not None else {}), **overrides})
    except ValidationError as e:
        raise error(one_line(e, model, what)) from None


def one_line(e: ValidationError, model: type[BaseModel], what: str) -> str:
    """The first error of ``e`` as ``<what> setting NAME: problem, got VALUE`` (NAME the field; the
    member names of a union dropped), or ``unknown <what> setting 'NAME'; settings: ...``."""
    err = e.errors()[0]
    name = str(err["loc"][0]) if err["loc"] else "?"
    if err["type"] == "extra_forbidden":
        return f"unknown {what} setting {name!r}; settings: {', '.join(model.model_fields)}"
    msg = err["msg"].removeprefix("Value error, ")
    return f"{what} setting {name}: {msg[:1].lower() + msg[1:]}, got {shown(err.get('input'))}"


def shown(value: Any, limit: int = 80) -> str:
    """``repr(value)``, shortened to one short line."""
    text = repr(value)
    return text if len(text) <= limit else text[:limit - 3] + "..."
