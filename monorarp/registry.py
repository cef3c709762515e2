"""Components chosen by name: a small registry plus ``importlib.metadata`` entry points.

Kinds: ``detector``, ``tracker``, ``state``, ``risk``, ``ego_speed``, ``warning``, ``horizon``. A plug-in
package exposes a factory under the entry-point group ``monorarp.<kind>``::

    [project.entry-points."monorarp.tracker"]
    mytracker = "mypkg.trackers:MyTracker"
"""

from __future__ import annotations

import inspect
from collections.abc import Callable, Mapping
from importlib.metadata import entry_points
from typing import Any

from monorarp.errors import UserError

KINDS = ("detector", "tracker", "state", "risk", "ego_speed", "warning", "horizon")
_REGISTRY: dict[str, dict[str, Callable[..., Any]]] = {k: {} for k in KINDS}


class UnknownComponentError(UserError, LookupError):
    """A component name that is neither built in nor provided by an entry point."""


def register(kind: str, name: str) -> Callable[[Callable[..., Any]], Callable[..., Any]]:
    """Decorator registering a component factory (usually a class) under ``kind``/``name``."""
    if kind not in _REGISTRY:
        raise ValueError(f"unknown component kind {kind!r}; kinds: {', '.join(KINDS)}")

    def deco(factory: Callable[..., Any]) -> Callable[..., Any]:
        _REGISTRY[kind][name] = factory
        return factory

    return deco


def _load_builtins() -> None:
    # Importing the modules runs their @register decorators.
    from monorarp import detection, ego_speed, horizon, risk, risk_mc, state, tracking, warning  # noqa: F401


def available(kind: str) -> list[str]:
    _load_builtins()
    names = set(_REGISTRY[kind]) | {ep.name for ep in entry_points(group=f"monorarp.{kind}")}
    return sorted(names)


def get_factory(kind: str, name: str) -> Callable[..., Any]:
    _load_builtins()
    if name in _REGISTRY[kind]:
        return _REGISTRY[kind][name]
    for ep in entry_points(group=f"monorarp.{kind}"):
        if ep.name == name:
            return ep.load()
    raise UnknownComponentError(f"unknown {kind} {name!r}; available: {', '.join(available(kind)) or 'none'}")


def create(kind: str, name: str, **kwargs: Any) -> Any:
    """Instantiate the component registered as ``kind``/``name`` with ``kwargs``."""
    return get_factory(kind, name)(**kwargs)


def takes(factory: Callable[..., Any], parameter: str) -> bool:
    """Whether ``factory`` accepts a keyword ``parameter`` (False when it has no inspectable signature)."""
    try:
        return parameter in inspect.signature(factory).parameters
    except (TypeError, ValueError):
        return False


def instantiate(factory: Callable[..., Any], kwargs: Mapping[str, Any], camera: Any = None) -> Any:
    """Call ``factory(**kwargs)``, adding ``camera`` when the factory takes one and kwargs don't set it."""
    kwargs = dict(kwargs)
    if camera is not None and "camera" not in kwargs and takes(factory, "camera"):
        kwargs["camera"] = camera
    return factory(**kwargs)


def build(kind: str, name: str, kwargs: Mapping[str, Any] | None = None, camera: Any = None) -> Any:
    """The component ``kind``/``name`` built with ``kwargs`` and, where it takes one, the camera model."""
    return instantiate(get_factory(kind, name), kwargs or {}, camera)
