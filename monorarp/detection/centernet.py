"""The project's own vehicle detector: a small CenterNet-style net run with onnxruntime.

Model layout (``monorarp/models/centernet_vehicle.onnx``, produced by ``training/``):

* input ``image`` ``(1, 3, H, W)`` float, RGB in [0, 1]; the camera image is
  **letterboxed** into W x H (aspect ratio kept, grey 114 padding centred), so any
  source resolution or aspect ratio works (640x360 -> 320x180 + 6 px bands);
* output ``heatmap`` ``(1, 1, H/s, W/s)``: vehicle-centre probability (sigmoid applied);
* output ``ltrb`` ``(1, 4, H/s, W/s)``: distances (input px) from the cell's centre
  ``(s*j + (s-1)/2, s*i + (s-1)/2)`` to the box's left, top, right and bottom edges.
  Regressing the four edges replaces CenterNet's size + offset heads (the offset is
  implied), so the bottom edge -- what the distance estimator reads -- is predicted directly.

Decoding (numpy/cv2, no NMS in the graph): peaks = cells equal to their 3x3 max
(``cv2.dilate``) above ``score_threshold``; each peak's box is the heatmap-weighted
mean of the boxes predicted by its 3x3 neighbours that agree with it (IoU > 0.6);
boxes are mapped back to the source image's continuous pixel coordinates.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from monorarp.detection.letterbox import Letterbox, to_blob
from monorarp.detection.onnx_runtime import ModelError, expect_image_input, open_session, outputs
from monorarp.registry import register
from monorarp.types import Detection

DEFAULT_MODEL = Path(__file__).resolve().parent.parent / "models" / "centernet_vehicle.onnx"
OUTPUT_NAMES = ("heatmap", "ltrb")


@dataclass(frozen=True)
class CenterNetMeta:
    """What inference needs from ``<model>.json`` (defaults when the file is absent)."""

    stride: int = 4
    score_threshold: float = 0.3
    pad_value: int = 114
    label: str = "car"
    max_detections: int = 100

    @classmethod
    def load(cls, model_path: Path) -> "CenterNetMeta":
        p = model_path.with_suffix(".json")
        if not p.is_file():
            return cls()
        try:
            d = json.loads(p.read_text())
            return cls(stride=int(d.get("stride", 4)), score_threshold=float(d.get("score_threshold", 0.3)),
                       pad_value=int(d.get("pad_value", 114)), label=str(d.get("label", "car")),
                       max_detections=int(d.get("max_detections", 100)))
        except (OSError, ValueError, TypeError, AttributeError) as e:
            raise ModelError(f"{p}: unreadable detector metadata ({e})") from None


def is_centernet_layout(session) -> bool:
    """True when the session's outputs are named ``heatmap`` and ``ltrb``."""
    return {o.name for o in outputs(session)} >= set(OUTPUT_NAMES)


def _box_iou_rows(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """IoU of (..., 4) boxes ``a`` with broadcastable ``b``."""
    iw = np.clip(np.minimum(a[..., 2], b[..., 2]) - np.maximum(a[..., 0], b[..., 0]), 0, None)
    ih = np.clip(np.minimum(a[..., 3], b[..., 3]) - np.maximum(a[..., 1], b[..., 1]), 0, None)
    inter = iw * ih
    area = lambda x: np.clip(x[..., 2] - x[..., 0], 0, None) * np.clip(x[..., 3] - x[..., 1], 0, None)  # noqa: E731
    return inter / np.maximum(area(a) + area(b) - inter, 1e-9)


def decode(heatmap: np.ndarray, ltrb: np.ndarray, stride: int, score_threshold: float,
           max_detections: int = 100, agree_iou: float = 0.6) -> tuple[np.ndarray, np.ndarray]:
    """Net outputs -> (boxes (K, 4) in input pixels, scores (K,)), sorted by score.

    ``heatmap``: (h, w) probabilities; ``ltrb``: (4, h, w) edge distances in input px.
    """
    hm = np.ascontiguousarray(heatmap, dtype=np.float32)
    h, w = hm.shape
    peaks = (hm >= cv2.dilate(hm, np.ones((3, 3), np.uint8))) & (hm >= score_threshold)
    ii, jj = np.nonzero(peaks)
    if ii.size == 0:
        return np.zeros((0, 4)), np.zeros(0)
    sc = hm[ii, jj]
    order = np.argsort(-sc, kind="stable")[:max_detections]
    ii, jj, sc = ii[order], jj[order], sc[order]
    # 3x3 neighbourhood of every peak (edge-padded: out-of-grid neighbours get weight 0)
    d = np.array([-1, 0, 1])
    ni = (ii[:, None, None] + d[None, :, None]).repeat(3, 2).reshape(-1, 9)
    nj = (jj[:, None, None] + d[None, None, :]).repeat(3, 1).reshape(-1, 9)
    inside = (ni >= 0) & (ni < h) & (nj >= 0) & (nj < w)
    ni, nj = np.clip(ni, 0, h - 1), np.clip(nj, 0, w - 1)
    cx = stride * nj + (stride - 1) / 2.0
    cy = stride * ni + (stride - 1) / 2.0
    e = ltrb[:, ni, nj].astype(np.float64)                          # (4, K, 9)
    boxes = np.stack([cx - e[0], cy - e[1], cx + e[2], cy + e[3]], axis=-1)  # (K, 9, 4)
    centre = boxes[:, 4:5, :]
    wts = hm[ni, nj].astype(np.float64) * inside * (_box_iou_rows(boxes, centre) > agree_iou)
    wts[:, 4] = np.maximum(wts[:, 4], 1e-6)
    merged = (boxes * wts[..., None]).sum(1) / wts.sum(1, keepdims=True)
    return merged, sc.astype(np.float64)


@register("detector", "centernet")
class CenterNetDetector:
    """The project's CenterNet-style vehicle detector (onnxruntime, CPU).

    ``model_path``: defaults to the committed ``monorarp/models/centernet_vehicle.onnx``;
    its sidecar ``.json`` supplies stride and score threshold unless given here.
    """

    def __init__(self, model_path: str | Path | None = None, score_threshold: float | None = None,
                 intra_op_num_threads: int = 1, max_detections: int | None = None, **_ignored) -> None:
        self.path = Path(model_path) if model_path is not None else DEFAULT_MODEL
        self.session = open_session(self.path, intra_op_num_threads)
        self.input_name, self.input_h, self.input_w = expect_image_input(self.session, self.path)
        if self.input_h is None or self.input_w is None:
            raise ModelError(f"{self.path}: expected a fixed input size (1,3,H,W), found a dynamic one")
        if not is_centernet_layout(self.session):
            found = [o.name for o in outputs(self.session)]
            raise ModelError(f"{self.path}: expected CenterNet outputs 'heatmap' (1,1,h,w) and 'ltrb' (1,4,h,w), found {found}")
        self.meta = CenterNetMeta.load(self.path)
        shapes = {o.name: o.shape for o in outputs(self.session)}
        s = self.meta.stride
        want_hm = (1, 1, self.input_h // s, self.input_w // s)
        want_lt = (1, 4, self.input_h // s, self.input_w // s)
        if tuple(shapes["heatmap"]) != want_hm or tuple(shapes["ltrb"]) != want_lt:
            raise ModelError(f"{self.path}: expected outputs heatmap {list(want_hm)} and ltrb {list(want_lt)} "
                             f"for stride {s}, found {list(shapes['heatmap'])} and {list(shapes['ltrb'])}")
        self.score_threshold = self.meta.score_threshold if score_threshold is None else float(score_threshold)
        self.max_detections = self.meta.max_detections if max_detections is None else int(max_detections)
        self._lb: Letterbox | None = None

    def raw(self, image: np.ndarray) -> tuple[np.ndarray, np.ndarray, Letterbox]:
        """Run the net: (heatmap (h, w), ltrb (4, h, w), the letterbox used)."""
        h, w = image.shape[:2]
        if self._lb is None or (self._lb.src_w, self._lb.src_h) != (w, h):
            self._lb = Letterbox.fit(w, h, self.input_w, self.input_h)
        blob = to_blob(self._lb.apply(image, self.meta.pad_value))
        hm, lt = self.session.run(list(OUTPUT_NAMES), {self.input_name: blob})
        return hm[0, 0], lt[0], self._lb

    def detect(self, image: np.ndarray) -> list[Detection]:
        """BGR uint8 image -> vehicle detections in its pixel coordinates."""
        hm, lt, lb = self.raw(image)
        boxes, scores = decode(hm, lt, self.meta.stride, self.score_threshold, self.max_detections)
        boxes = lb.to_src(boxes)
        keep = (boxes[:, 2] - boxes[:, 0] > 1.0) & (boxes[:, 3] - boxes[:, 1] > 1.0)
        return [Detection(tuple(map(float, b)), float(sc), self.meta.label)
                for b, sc in zip(boxes[keep], scores[keep])]

    __call__ = detect
