"""Components chosen by name: the mechanism only (what exists is declared elsewhere).

Kinds: ``detector``, ``tracker``, ``state``, ``risk``, ``ego_speed``, ``warning``, ``horizon``.
A name resolves, in this order, to a factory given by :func:`add` (an explicit call, e.g. in a
test), a built-in of :mod:`monorarp.pipeline.catalogue`, or an entry point of the group
``monorarp.<kind>`` (how other packages plug in)::

    [project.entry-points."monorarp.tracker"]
    mytracker = "mypkg.trackers:MyTracker"

Built-ins are imported only when asked for. A factory receives the run's camera only when it
declares ``uses_camera = True`` (a class attribute); see :func:`uses`.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Mapping
from importlib.metadata import entry_points
from typing import Any

from monorarp.pipeline.catalogue import BUILTINS
from monorarp.core.errors import UserError

KINDS = ("detector", "tracker", "state", "risk", "ego_speed", "warning", "horizon")
_ADDED: dict[str, dict[str, Callable[..., Any] | str]] = {k: {} for k in KINDS}


class UnknownComponentError(UserError, LookupError):
    """A component name that is neither built in nor provided by an entry point."""


def _check_kind(kind: str) -> None:
    if kind not in KINDS:
        raise ValueError(f"unknown component kind {kind!r}; kinds: {', '.join(KINDS)}")


def add(kind: str, name: str, factory: Callable[..., Any] | str) -> None:
    """Make ``factory`` (a callable or a ``"module:Class"`` string) available as ``kind``/``name``."""
    _check_kind(kind)
    _ADDED[kind][name] = factory


def remove(kind: str, name: str) -> None:
    """Undo :func:`add` (no error when ``name`` was not added)."""
    _check_kind(kind)
    _ADDED[kind].pop(name, None)


def resolve(target: str) -> Callable[..., Any]:
    """The object named by ``"package.module:Attr"`` (imported now)."""
    module, _, attr = target.partition(":")
    obj: Any = importlib.import_module(module)
    for part in attr.split("."):
        obj = getattr(obj, part)
    return obj


def available(kind: str) -> list[str]:
    """Every name of ``kind``: added, built in, or from an entry point."""
    _check_kind(kind)
    names = set(_ADDED[kind]) | set(BUILTINS[kind]) | {ep.name for ep in entry_points(group=f"monorarp.{kind}")}
    return sorted(names)


def get_factory(kind: str, name: str) -> Callable[..., Any]:
    """The factory of ``kind``/``name``; :class:`UnknownComponentError` when there is none."""
    _check_kind(kind)
    target = _ADDED[kind].get(name, BUILTINS[kind].get(name))
    if target is not None:
        return resolve(target) if isinstance(target, str) else target
    for ep in entry_points(group=f"monorarp.{kind}"):
        if ep.name == name:
            return ep.load()
    raise UnknownComponentError(f"unknown {kind} {name!r}; available: {', '.join(available(kind)) or 'none'}")


def uses(component: Any, what: str) -> bool:
    """Whether a factory or stage declares it uses ``what`` (``uses_<what> = True``).

    Declared inputs: ``camera`` (the factory gets the run's :class:`~monorarp.core.camera.CameraModel`),
    ``seed`` (a sweep gives it the run's seed), ``ego_speed`` (a risk stage whose result depends
    on the ``ego_speed`` it is given; the harness may then fall back to the true speed), ``truth``
    (a detector that needs each frame's ground truth: it runs on simulated frames only), ``image``
    (a state estimator that takes each frame's image as ``image=``), ``weak_detections`` (a detector
    that gives weak detections, :attr:`monorarp.core.types.Detection.weak`, from ``detect(image, weak=True)``;
    a tracker that is given them too).
    """
    return bool(getattr(component, f"uses_{what}", False))


def create(kind: str, name: str, **kwargs: Any) -> Any:
    """Instantiate the component ``kind``/``name`` with ``kwargs`` (nothing added)."""
    return get_factory(kind, name)(**kwargs)


def build(kind: str, name: str, kwargs: Mapping[str, Any] | None = None, camera: Any = None) -> Any:
    """The component ``kind``/``name`` built with ``kwargs`` and, when its factory uses one and ``kwargs``
    does not set it, the camera model."""
    factory = get_factory(kind, name)
    kwargs = dict(kwargs or {})
    if camera is not None and "camera" not in kwargs and uses(factory, "camera"):
        kwargs["camera"] = camera
    return factory(**kwargs)
