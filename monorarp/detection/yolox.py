"""The real-world vehicle detector: COCO-trained YOLOX-Nano (Megvii, Apache-2.0) run with onnxruntime.

Model layout (``monorarp/models/yolox_nano_coco.onnx``; provenance and figures: docs/pipeline.md,
the real-world detector): input ``(1, 3, H, W)`` float BGR 0..255, the image resized by
``min(W/w, H/h)`` into the canvas's top-left corner on grey 114; one output ``(1, N, 85)``, one row per
cell of the stride-8/16/32 grids (row-major, stride 8 first; N = 3549 for 416x416): ``x, y, log w,
log h`` relative to the cell, then objectness and 80 class probabilities (both already sigmoided).

Decoding (the project's): centre ``(p + cell) * stride``, size ``exp(p) * stride`` (input px, edge
convention: the canvas spans [0, W]); score = objectness x best class probability; a box is kept when
its best class is a vehicle of :data:`COCO_VEHICLES` and its score reaches the threshold; then
class-agnostic NMS (a COCO car and truck box on one vehicle is one vehicle). Boxes come back in the
source image's continuous pixel convention (:mod:`monorarp.core.types`). A wide frame (KITTI's
1242x375) is seen as two overlapping halves stacked in the canvas (``mosaic``,
:mod:`monorarp.detection.mosaic`: scale 0.539 instead of the letterbox's 0.335, same one run); an
optional second pass (``foveate``) runs the net on a crop near the horizon at up to native
resolution (:mod:`monorarp.detection.fovea`) for small far vehicles.
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from monorarp.core.camera import CameraModel
from monorarp.core.types import Detection
from monorarp.detection.fovea import Fovea, FoveaPass, merge
from monorarp.detection.letterbox import Letterbox
from monorarp.detection.mosaic import Mosaic, join
from monorarp.detection.onnx_runtime import ModelError, expect_image_input, open_session, outputs
from monorarp.detection.second_pass import helper_pool

DEFAULT_MODEL = Path(__file__).resolve().parent.parent / "models" / "yolox_nano_coco.onnx"
STRIDES = (8, 16, 32)
N_CLASSES = 80
ROW = 5 + N_CLASSES                                   # x, y, w, h, objectness, 80 classes
COCO_VEHICLES: dict[int, str] = {2: "car", 3: "motorcycle", 5: "bus", 7: "truck"}   # COCO index -> label
PAD_VALUE = 114


def grid(input_w: int, input_h: int, strides: tuple[int, ...] = STRIDES) -> tuple[np.ndarray, np.ndarray]:
    """(cells (N, 2) as (column, row), stride (N,)) of the output rows, stride 8's grid first, row-major."""
    cells, step = [], []
    for s in strides:
        rows, cols = np.mgrid[0:input_h // s, 0:input_w // s]
        cells.append(np.stack([cols.ravel(), rows.ravel()], axis=1))
        step.append(np.full(cols.size, s))
    return np.concatenate(cells).astype(np.float64), np.concatenate(step).astype(np.float64)


def n_cells(input_w: int, input_h: int, strides: tuple[int, ...] = STRIDES) -> int:
    """Output rows of a YOLOX head on a ``input_w`` x ``input_h`` input (3549 for 416x416)."""
    return sum((input_h // s) * (input_w // s) for s in strides)


def is_yolox_layout(session) -> bool:
    """True for one float input (1, 3, H, W) of fixed size and one output (1, N, 85) with N the cells of
    strides 8/16/32 on it."""
    ins, outs = session.get_inputs(), outputs(session)
    if len(ins) != 1 or len(outs) != 1:
        return False
    shape_in = tuple(ins[0].shape)
    if len(shape_in) != 4 or not all(isinstance(d, int) for d in shape_in[2:]):
        return False
    h, w = shape_in[2], shape_in[3]
    return tuple(outs[0].shape) == (1, n_cells(w, h), ROW)


def decode(raw: np.ndarray, input_w: int, input_h: int, score_threshold: float,
           class_map: dict[int, str] | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Net output (N, 85) -> (boxes (K, 4) x1y1x2y2 in input px, edge convention; scores (K,); COCO class (K,)).

    Keeps the rows whose best class is in ``class_map`` (default :data:`COCO_VEHICLES`) scoring at least
    ``score_threshold``; no NMS here (:func:`nms`).
    """
    class_map = COCO_VEHICLES if class_map is None else class_map
    p = np.asarray(raw, dtype=np.float64).reshape(-1, ROW)
    cells, step = grid(input_w, input_h)
    if len(p) != len(cells):
        raise ValueError(f"expected {len(cells)} rows for a {input_w}x{input_h} input, got {len(p)}")
    cls = p[:, 5:].argmax(axis=1)
    score = p[:, 4] * p[np.arange(len(p)), 5 + cls]
    keep = (score >= score_threshold) & np.isin(cls, np.fromiter(class_map, dtype=np.int64, count=len(class_map)))
    p, cells, step, cls, score = p[keep], cells[keep], step[keep], cls[keep], score[keep]
    cxy = (p[:, :2] + cells) * step[:, None]
    half = np.exp(np.minimum(p[:, 2:4], 20.0)) * step[:, None] / 2   # exp capped: a wild row stays finite
    return np.concatenate([cxy - half, cxy + half], axis=1), score, cls


def nms(boxes: np.ndarray, scores: np.ndarray, iou_threshold: float) -> np.ndarray:
    """Indices of the boxes kept by greedy class-agnostic NMS (descending score, ties by index): a box is
    dropped when its IoU with a kept higher-scoring box exceeds ``iou_threshold``."""
    b = np.asarray(boxes, dtype=np.float64).reshape(-1, 4)
    if len(b) == 0:
        return np.zeros(0, dtype=np.int64)
    xywh = np.stack([b[:, 0], b[:, 1], b[:, 2] - b[:, 0], b[:, 3] - b[:, 1]], axis=1)
    idx = cv2.dnn.NMSBoxes(xywh.tolist(), np.asarray(scores, dtype=np.float32).tolist(), 0.0,
                           float(iou_threshold))
    idx = np.asarray(idx, dtype=np.int64).reshape(-1)
    return idx[np.argsort(-np.asarray(scores)[idx], kind="stable")]


def to_blob(canvas_bgr: np.ndarray) -> np.ndarray:
    """(H, W, 3) BGR uint8 canvas -> (1, 3, H, W) float32 BGR 0..255 (YOLOX's input: no scaling, no swap)."""
    return np.ascontiguousarray(canvas_bgr.transpose(2, 0, 1)[None], dtype=np.float32)


class YoloxDetector(FoveaPass):
    """Vehicles from COCO-trained YOLOX-Nano (``yolox``; the default where the frames are real).

    ``model_path``: default the shipped ``monorarp/models/yolox_nano_coco.onnx`` (any YOLOX export with
    the layout of the module docstring works). ``score_threshold``: objectness x class probability
    (0..1); ``nms_iou``: class-agnostic NMS IoU; ``class_map``: COCO index -> label kept (default
    :data:`COCO_VEHICLES`: car, motorcycle, bus, truck; persons and bicycles are never vehicles).
    ``foveate`` (default on: Car AP_R40 moderate at IoU 0.5 0.68 -> 0.86 on the KITTI development frames,
    docs/pipeline.md): also run the net on a crop around ``camera``'s horizon and principal column (the image
    centre without a camera) at ``fovea_zoom`` x the full view's scale, capped at native resolution, merged
    with :func:`monorarp.detection.fovea.merge` (``fovea_below``, ``fovea_dup_iou``, ``fovea_margin_px``,
    ``fovea_max_height`` as there; plain union). ``parallel_passes``: the fovea pass on a helper thread.
    ``mosaic`` (default on): the full view of a frame wide enough to gain (:meth:`Mosaic.plan`: at least
    1.2 x the letterbox's scale; KITTI, not 16:9) is its two halves stacked in the canvas
    (``mosaic_gap_px`` grey rows between them; boxes within ``mosaic_margin_px`` canvas px of a tile's
    inner side are cut, :func:`monorarp.detection.mosaic.join`): on the KITTI development frames Car
    AP_R40 moderate 0.858 -> 0.910 at IoU 0.5, 0.662 -> 0.705 at IoU 0.7 with the fovea, for no extra run.
    """

    uses_camera = True   # the registry passes the run's camera (it places the fovea)

    def __init__(self, model_path: str | Path | None = None, score_threshold: float = 0.3, nms_iou: float = 0.45,
                 class_map: dict[int, str] | None = None, max_detections: int = 100,
                 intra_op_num_threads: int = 1, camera: CameraModel | dict | None = None, foveate: bool = True,
                 fovea_zoom: float = 4.0, fovea_below: float = 0.25, fovea_dup_iou: float = 0.3,
                 fovea_margin_px: float = 2.0, fovea_max_height: float = 0.35, parallel_passes: bool = True,
                 mosaic: bool = True, mosaic_gap_px: int = 12, mosaic_margin_px: float = 8.0,
                 **_ignored) -> None:
        self.path = Path(model_path) if model_path is not None else DEFAULT_MODEL
        self.session = open_session(self.path, intra_op_num_threads)
        self.input_name, self.input_h, self.input_w = expect_image_input(self.session, self.path)
        if not is_yolox_layout(self.session):
            found = ", ".join(f"{o.name} {list(o.shape)}" for o in outputs(self.session))
            raise ModelError(f"{self.path}: expected one YOLOX output (1, N, 85) with N the stride-8/16/32 cells "
                             f"of a fixed input, found {found}")
        self.output_name = outputs(self.session)[0].name
        for name, v in (("score_threshold", score_threshold), ("nms_iou", nms_iou)):
            if not 0 <= float(v) <= 1:
                raise ValueError(f"{name} must be in [0, 1], got {v}")
        for name, v in (("foveate", foveate), ("parallel_passes", parallel_passes), ("mosaic", mosaic)):
            if not isinstance(v, bool):
                raise ValueError(f"{name} must be true or false, got {v!r}")
        self.score_threshold, self.nms_iou = float(score_threshold), float(nms_iou)
        self.class_map = dict(COCO_VEHICLES) if class_map is None else {int(k): str(v) for k, v in class_map.items()}
        self.max_detections = int(max_detections)
        self.camera = CameraModel.from_dict(camera) if isinstance(camera, dict) else camera
        self.foveate, self.parallel_passes = foveate, parallel_passes
        self.fovea_zoom, self.fovea_below = float(fovea_zoom), float(fovea_below)
        self.fovea_dup_iou, self.fovea_margin_px = float(fovea_dup_iou), float(fovea_margin_px)
        self.fovea_max_height = float(fovea_max_height)
        self.mosaic = mosaic
        if not 0 <= int(mosaic_gap_px) < self.input_h // 2 or not 0 <= float(mosaic_margin_px) < self.input_w / 2:
            raise ValueError(f"mosaic_gap_px must be in [0, {self.input_h // 2}) and mosaic_margin_px in "
                             f"[0, {self.input_w / 2:g}), got {mosaic_gap_px} and {mosaic_margin_px}")
        self.mosaic_gap_px, self.mosaic_margin_px = int(mosaic_gap_px), float(mosaic_margin_px)
        self._mosaic: tuple[tuple[int, int], Mosaic | None] | None = None
        self._lb: Letterbox | None = None
        self._fovea: tuple[tuple[int, int], Fovea | None, Letterbox | None] | None = None

    def set_camera(self, camera: CameraModel | None) -> None:
        """Use another calibration from the next frame on (the fovea follows)."""
        self.camera = camera
        self._fovea = None

    def run_net(self, canvas_bgr: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The net on one input-sized BGR canvas: :func:`decode`'s (boxes in canvas px, edge convention;
        scores; COCO classes), no NMS."""
        raw = self.session.run([self.output_name], {self.input_name: to_blob(canvas_bgr)})[0]
        return decode(raw[0], self.input_w, self.input_h, self.score_threshold, self.class_map)

    def pass_arrays(self, image: np.ndarray, letterbox: Letterbox | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """One pass of the net over ``image`` (BGR uint8) letterboxed: (boxes (K, 4) in its continuous pixels,
        unclipped; scores (K,); COCO classes (K,)), after NMS, by descending score."""
        h, w = image.shape[:2]
        if letterbox is None:
            if self._lb is None or (self._lb.src_w, self._lb.src_h) != (w, h):
                self._lb = Letterbox.top_left(w, h, self.input_w, self.input_h)
            letterbox = self._lb
        boxes, scores, cls = self.run_net(letterbox.apply(image, PAD_VALUE, cv2.INTER_LINEAR))
        keep = nms(boxes, scores, self.nms_iou)[:self.max_detections]
        # edge convention (canvas spans [0, W]) -> pixel centres, then undo the letterbox
        return letterbox.to_src(boxes[keep] - 0.5, clip=False), scores[keep], cls[keep]

    def mosaic_plan(self, w: int, h: int) -> Mosaic | None:
        """The full view's mosaic for a ``w`` x ``h`` frame (None: letterboxed), cached per size."""
        if self._mosaic is None or self._mosaic[0] != (w, h):
            plan = Mosaic.plan(w, h, self.input_w, self.input_h, self.mosaic_gap_px) if self.mosaic else None
            self._mosaic = ((w, h), plan)
        return self._mosaic[1]

    def full_view_arrays(self, image: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The full view's pass: (boxes (K, 4) source px, unclipped; scores (K,); COCO classes (K,)) by
        descending score; through the mosaic where it gains (each tile's own NMS, :func:`join`, then NMS)."""
        mos = self.mosaic_plan(image.shape[1], image.shape[0])
        if mos is None:
            return self.pass_arrays(image)
        boxes, scores, cls = self.run_net(mos.apply(image, PAD_VALUE, cv2.INTER_LINEAR))
        src, tile, cut = mos.to_src(boxes, self.mosaic_margin_px)
        keep = np.concatenate([np.flatnonzero(tile == t)[nms(src[tile == t], scores[tile == t], self.nms_iou)]
                               for t in (0, 1)])
        joined, idx = join(src[keep], scores[keep], tile[keep], cut[keep])
        idx = keep[idx]
        order = nms(joined, scores[idx], self.nms_iou)[:self.max_detections]
        return joined[order], scores[idx][order], cls[idx][order]

    def fovea_letterbox(self, w: int, h: int) -> Letterbox:
        """How the net sees a ``w`` x ``h`` fovea crop."""
        return Letterbox.top_left(w, h, self.input_w, self.input_h)

    def detect_arrays(self, image: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """BGR uint8 image -> (boxes (K, 4) source px, unclipped; scores (K,); COCO classes (K,)), both passes merged."""
        fov, flb = self.fovea(image.shape[1], image.shape[0])
        second = None
        if fov is not None and self.parallel_passes:
            second = helper_pool().submit(self.pass_arrays, fov.cut(image), flb)
        boxes, scores, cls = self.full_view_arrays(image)
        if fov is None:
            return boxes, scores, cls
        fb, fs, fc = second.result() if second is not None else self.pass_arrays(fov.cut(image), flb)
        fb = fov.to_src(fb)
        # merge() knows boxes and scores only: carry each box's class as a third array matched back by box
        merged, mscores = merge(boxes, scores, fb, fs, fov, self.score_threshold, None, self.fovea_margin_px,
                                self.fovea_dup_iou, "auto", self.fovea_max_height)
        return merged, mscores, _classes_of(merged, np.concatenate([boxes, fb]), np.concatenate([cls, fc]))

    def detect(self, image: np.ndarray) -> list[Detection]:
        """BGR uint8 image -> vehicle detections in its pixel coordinates, labelled by :attr:`class_map`."""
        boxes, scores, cls = self.detect_arrays(image)
        h, w = image.shape[:2]
        boxes[:, [0, 2]] = np.clip(boxes[:, [0, 2]], -0.5, w - 0.5)
        boxes[:, [1, 3]] = np.clip(boxes[:, [1, 3]], -0.5, h - 0.5)
        keep = (boxes[:, 2] - boxes[:, 0] > 1.0) & (boxes[:, 3] - boxes[:, 1] > 1.0)
        return [Detection(tuple(map(float, b)), float(s), self.class_map[int(c)])
                for b, s, c in zip(boxes[keep], scores[keep], cls[keep])]

    __call__ = detect


def _classes_of(boxes: np.ndarray, sources: np.ndarray, classes: np.ndarray) -> np.ndarray:
    """The class of each merged box: that of the pass box nearest to it (a fused box is the mean of two)."""
    if len(boxes) == 0:
        return np.zeros(0, dtype=np.int64)
    d = np.abs(boxes[:, None, :] - sources[None, :, :]).sum(axis=2)
    return classes[d.argmin(axis=1)]
