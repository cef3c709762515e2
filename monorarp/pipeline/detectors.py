"""The pipeline's detector stage from a name: a registered detector or an ``.onnx`` path."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

from monorarp.core.types import Detector
from monorarp.detection.model_file import is_model_path, load_model_file
from monorarp.pipeline import registry

if TYPE_CHECKING:
    from monorarp.pipeline.config import ComponentConfig


def build_detector(component: "ComponentConfig", camera: Any = None) -> Detector:
    """The detector stage of a pipeline config: :func:`load_detector` of its name with its kwargs."""
    return load_detector(component.name, camera=camera, **component.kwargs)


def is_centernet(name_or_path: str) -> bool:
    """Whether options of CenterNet's apply: a model file, or a registered detector whose class is
    (a subclass of) :class:`~monorarp.detection.centernet.CenterNetDetector`. An unknown name: False
    (the caller refuses it, naming its option)."""
    if is_model_path(str(name_or_path)):
        return True
    from monorarp.detection.centernet import CenterNetDetector

    try:
        factory = registry.get_factory("detector", str(name_or_path))
    except registry.UnknownComponentError:
        return False
    return isinstance(factory, type) and issubclass(factory, CenterNetDetector)


def load_detector(name_or_path: str | Path, camera: Any = None, **kw: Any) -> Detector:
    """A detector from a registered name (``centernet``, ``yolo``, plug-ins) or an ``.onnx`` path
    (:func:`~monorarp.detection.model_file.load_model_file`). ``kw`` go to the detector's constructor;
    ``camera`` (a :class:`~monorarp.core.camera.CameraModel`) to detectors that use one (CenterNet's fovea).
    Raises :class:`~monorarp.core.errors.UserError` (one line) for an unknown name, a missing or
    invalid file, or an unrecognised layout."""
    s = str(name_or_path)
    if not is_model_path(s):
        return registry.build("detector", s, kw, camera)
    return load_model_file(s, camera=camera, **kw)
