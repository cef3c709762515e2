"""Detectors: image (BGR uint8) -> list of :class:`monorarp.core.types.Detection`.

Every detector has ``detect(image) -> list[Detection]`` (:class:`monorarp.core.types.Detector`).
Built in (:mod:`monorarp.pipeline.catalogue`): ``centernet`` (the project's own model, the default) and ``yolo``
(Ultralytics YOLOv8/YOLO11 ONNX exports). :mod:`monorarp.detection.model_file` recognises an ``.onnx`` file's layout;
:mod:`monorarp.pipeline.detectors` builds a pipeline config's detector stage from a name or a file.
"""
