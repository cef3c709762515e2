"""Loader for standard Ultralytics YOLOv8 / YOLO11 ONNX exports (COCO classes).

Expected layout (``yolo export format=onnx``, no NMS in the graph):

* input ``(1, 3, H, W)`` float, RGB in [0, 1], letterboxed with grey (114) padding;
* output ``(1, 4 + C, N)`` -- rows ``cx, cy, w, h`` in input pixels (edge convention:
  the input spans [0, W]) then C class scores; the transposed ``(1, N, 4 + C)`` is
  accepted too. With C = 80 (COCO) car (2), bus (5) and truck (7) are kept.

Decoding: best class per candidate, confidence threshold, class-wise NMS
(``cv2.dnn.NMSBoxesBatched``), then the letterbox is undone so boxes are in the
original image's continuous pixel convention (:mod:`monorarp.core.types`).
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from monorarp.detection.letterbox import Letterbox, to_blob
from monorarp.detection.onnx_runtime import ModelError, expect_image_input, open_session, outputs
from monorarp.core.types import Detection

COCO_VEHICLES: dict[int, str] = {2: "car", 5: "bus", 7: "truck"}


def output_layout(shape: tuple, n_classes: int | None = None) -> str:
    """'cn' for (1, 4+C, N), 'nc' for (1, N, 4+C); raises ValueError otherwise.

    ``shape`` may hold None/str for symbolic dims. When ``n_classes`` is given the
    channel axis must have exactly 4 + n_classes entries.
    """
    if len(shape) != 3:
        raise ValueError(f"expected a 3-D output (1, 4+C, N), found {len(shape)}-D {list(shape)}")
    a, b = (d if isinstance(d, int) and d > 0 else None for d in shape[1:])
    want = None if n_classes is None else 4 + n_classes
    if want is not None:
        if a == want and b != want:
            return "cn"
        if b == want and a != want:
            return "nc"
        if a == want == b:
            return "cn"
        raise ValueError(f"expected an output (1, {want}, N) or (1, N, {want}), found {list(shape)}")
    if a is not None and (b is None or a < b) and a >= 5:
        return "cn"
    if b is not None and (a is None or b < a) and b >= 5:
        return "nc"
    raise ValueError(f"expected an output (1, 4+C, N), found {list(shape)}")


def decode(raw: np.ndarray, layout: str, class_map: dict[int, str], conf_threshold: float,
           iou_threshold: float, max_detections: int = 300) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Raw YOLO output -> (boxes (K,4) x1y1x2y2 in input pixels, edge convention; scores (K,); class ids (K,)).

    Keeps only classes in ``class_map``; class-wise NMS at ``iou_threshold``.
    """
    p = raw[0] if layout == "cn" else raw[0].T          # (4 + C, N)
    scores_all = p[4:]
    cls = scores_all.argmax(axis=0)
    conf = scores_all[cls, np.arange(p.shape[1])]
    keep = conf >= conf_threshold
    if class_map:
        keep &= np.isin(cls, np.fromiter(class_map.keys(), dtype=np.int64))
    if not keep.any():
        return np.zeros((0, 4)), np.zeros(0), np.zeros(0, dtype=np.int64)
    cx, cy, w, h = p[:4, keep].astype(np.float64)
    conf, cls = conf[keep].astype(np.float64), cls[keep]
    xywh = np.stack([cx - w / 2, cy - h / 2, w, h], axis=1)
    idx = cv2.dnn.NMSBoxesBatched(xywh, conf.astype(np.float32), cls.astype(np.int32),
                                  float(conf_threshold), float(iou_threshold))
    idx = np.asarray(idx, dtype=np.int64).reshape(-1)
    idx = idx[np.argsort(-conf[idx], kind="stable")][:max_detections]
    b = xywh[idx]
    boxes = np.stack([b[:, 0], b[:, 1], b[:, 0] + b[:, 2], b[:, 1] + b[:, 3]], axis=1)
    return boxes, conf[idx], cls[idx]


class YoloDetector:
    """Vehicles from an Ultralytics YOLOv8/YOLO11 ONNX export (COCO car/bus/truck by default).

    ``model_path``: the ``.onnx`` file. ``input_size``: (width, height) when the model's
    input is dynamic (default 640x640). ``class_map``: class index -> label to keep
    (default COCO vehicles; required when the model has other than 80 classes).
    """

    def __init__(self, model_path: str | Path | None = None, conf_threshold: float = 0.25, iou_threshold: float = 0.45,
                 input_size: tuple[int, int] | None = None, class_map: dict[int, str] | None = None,
                 intra_op_num_threads: int = 1, **_ignored) -> None:
        if model_path is None:       # the registered name alone: no YOLO weights are shipped
            raise ModelError("detector 'yolo' needs a model file (none is shipped): give a YOLOv8/YOLO11 ONNX "
                             "export as --detector PATH.onnx, or detector_kwargs {model_path: PATH.onnx}")
        self.path = Path(model_path)
        self.session = open_session(self.path, intra_op_num_threads)
        self.input_name, h, w = expect_image_input(self.session, self.path)
        if input_size is not None:
            w, h = int(input_size[0]), int(input_size[1])
        self.input_w, self.input_h = w or 640, h or 640
        outs = outputs(self.session)
        if len(outs) != 1:
            raise ModelError(f"{self.path}: expected one YOLO output (1, 4+80, N), found {len(outs)} outputs")
        self.output_name = outs[0].name
        shape = outs[0].shape
        chans = [d for d in shape[1:] if isinstance(d, int)] if len(shape) == 3 else []
        if class_map is None:
            class_map = dict(COCO_VEHICLES)
            n_classes = 80
        else:
            n_classes = None
            class_map = {int(k): str(v) for k, v in class_map.items()}
        try:
            self.layout = output_layout(shape, n_classes)
        except ValueError as e:
            hint = " (5+C channels: a YOLOv5-style objectness layout is not supported)" if 85 in chans else ""
            raise ModelError(f"{self.path}: not a YOLOv8/YOLO11 detection export: {e}{hint}") from None
        self.class_map = class_map
        self.conf_threshold = float(conf_threshold)
        self.iou_threshold = float(iou_threshold)
        self._lb: Letterbox | None = None

    def detect(self, image: np.ndarray) -> list[Detection]:
        """BGR uint8 image -> detections in its pixel coordinates."""
        h, w = image.shape[:2]
        if self._lb is None or (self._lb.src_w, self._lb.src_h) != (w, h):
            self._lb = Letterbox.fit(w, h, self.input_w, self.input_h)
        blob = to_blob(self._lb.apply(image, 114))
        raw = self.session.run([self.output_name], {self.input_name: blob})[0]
        if raw.ndim != 3 or raw.shape[0] != 1:
            raise ModelError(f"{self.path}: expected a YOLO output (1, 4+C, N), got {list(raw.shape)}")
        boxes, scores, cls = decode(raw, self.layout, self.class_map, self.conf_threshold, self.iou_threshold)
        boxes = self._lb.to_src(boxes - 0.5)   # edge convention -> pixel-centre convention, then un-letterbox
        return [Detection(tuple(map(float, b)), float(s), self.class_map.get(int(c), str(int(c))))
                for b, s, c in zip(boxes, scores, cls)]

    __call__ = detect
