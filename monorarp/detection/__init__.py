"""Detectors: image (BGR uint8) -> list of :class:`monorarp.core.types.Detection`.

Every detector has ``detect(image) -> list[Detection]`` (:class:`monorarp.core.types.Detector`).
Built in (:mod:`monorarp.pipeline.catalogue`): ``centernet`` (the project's own model, the default) and ``yolo``
(Ultralytics YOLOv8/YOLO11 ONNX exports). :func:`load_detector` takes a
registered name or a path to an ``.onnx`` file whose layout it recognises;
:func:`build_detector` builds a pipeline config's detector stage with it.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

from monorarp.detection.centernet import CenterNetDetector, is_centernet_layout
from monorarp.detection.onnx_runtime import ModelError, open_session, outputs
from monorarp.detection.yolo import YoloDetector, output_layout
from monorarp.core.types import Detector

if TYPE_CHECKING:
    from monorarp.pipeline.runner import ComponentConfig


def is_model_path(name: str | Path) -> bool:
    """Whether a detector ``name`` is a model file (``.onnx``, any case) rather than a registered name."""
    return str(name).lower().endswith(".onnx")


def build_detector(component: "ComponentConfig", camera: Any = None) -> Detector:
    """The detector stage of a pipeline config: :func:`load_detector` of its name with its kwargs."""
    return load_detector(component.name, camera=camera, **component.kwargs)


def is_centernet(name_or_path: str) -> bool:
    """Whether options of CenterNet's apply: a model file, or a registered detector whose class is
    (a subclass of) :class:`~monorarp.detection.centernet.CenterNetDetector`. An unknown name: False
    (the caller refuses it, naming its option)."""
    if is_model_path(str(name_or_path)):
        return True
    from monorarp.pipeline import registry
    from monorarp.detection.centernet import CenterNetDetector

    try:
        factory = registry.get_factory("detector", str(name_or_path))
    except registry.UnknownComponentError:
        return False
    return isinstance(factory, type) and issubclass(factory, CenterNetDetector)


def load_detector(name_or_path: str | Path, camera: Any = None, **kw: Any) -> Detector:
    """A detector from a registered name (``centernet``, ``yolo``, plug-ins) or an ``.onnx`` path.

    For a path the output layout decides: outputs ``heatmap`` + ``ltrb`` -> CenterNet,
    one ``(1, 4+80, N)`` output -> YOLO. ``kw`` go to the detector's constructor; ``camera``
    (a :class:`~monorarp.core.camera.CameraModel`) to detectors that use one (CenterNet's fovea).
    Raises :class:`~monorarp.core.errors.UserError` (one line) for an unknown name, a missing or
    invalid file, or an unrecognised layout.
    """
    s = str(name_or_path)
    if not is_model_path(s):
        from monorarp.pipeline.registry import build

        return build("detector", s, kw, camera)
    path = Path(s).expanduser()
    session = open_session(path, 1)
    if is_centernet_layout(session):
        return CenterNetDetector(model_path=path, camera=camera, **kw)
    outs = outputs(session)
    if len(outs) == 1:
        try:
            output_layout(outs[0].shape, 80 if kw.get("class_map") is None else None)
        except ValueError:
            pass
        else:
            return YoloDetector(model_path=path, **kw)
    found = ", ".join(f"{o.name} {list(o.shape)}" for o in outs)
    raise ModelError(f"{path}: unrecognised detector layout: expected CenterNet outputs 'heatmap'+'ltrb' "
                     f"or one YOLO output (1, 84, N); found {found}")
