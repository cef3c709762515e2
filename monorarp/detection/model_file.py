"""Detector model files: whether a detector name is an ``.onnx`` path, and the detector a file's
output layout says it is (CenterNet, YOLOX or YOLO). Names are resolved by :mod:`monorarp.pipeline.detectors`."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from monorarp.detection.centernet import CenterNetDetector, is_centernet_layout
from monorarp.detection.onnx_runtime import ModelError, open_session, outputs
from monorarp.detection.yolo import YoloDetector, output_layout
from monorarp.detection.yolox import YoloxDetector, is_yolox_layout
from monorarp.core.types import Detector


def is_model_path(name: str | Path) -> bool:
    """Whether a detector ``name`` is a model file (``.onnx``, any case) rather than a registered name."""
    return str(name).lower().endswith(".onnx")


def load_model_file(path: str | Path, camera: Any = None, **kw: Any) -> Detector:
    """The detector of an ``.onnx`` file, by its output layout: outputs ``heatmap`` + ``ltrb`` -> CenterNet,
    one ``(1, N, 85)`` output with N the stride-8/16/32 cells of the input -> YOLOX, one ``(1, 4+80, N)``
    output -> YOLO. ``kw`` go to the detector's constructor; ``camera`` to CenterNet and YOLOX (the fovea). Raises :class:`~monorarp.detection.onnx_runtime.ModelError` (one line) for a missing or
    invalid file or an unrecognised layout."""
    path = Path(str(path)).expanduser()
    session = open_session(path, 1)
    if is_centernet_layout(session):
        return CenterNetDetector(model_path=path, camera=camera, **kw)
    if is_yolox_layout(session):
        return YoloxDetector(model_path=path, camera=camera, **kw)
    outs = outputs(session)
    if len(outs) == 1:
        try:
            output_layout(outs[0].shape, 80 if kw.get("class_map") is None else None)
        except ValueError:
            pass
        else:
            return YoloDetector(model_path=path, **kw)
    found = ", ".join(f"{o.name} {list(o.shape)}" for o in outs)
    raise ModelError(f"{path}: unrecognised detector layout: expected CenterNet outputs 'heatmap'+'ltrb', "
                     f"one YOLOX output (1, N, 85) or one YOLO output (1, 84, N); found {found}")
