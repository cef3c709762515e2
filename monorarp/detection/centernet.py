"""The project's own vehicle detector: a small CenterNet-style net run with onnxruntime.

The camera image (BGR) is letterboxed into the net's input; a heatmap of vehicle centres and
each cell's distances (px) to the box's four edges are decoded into boxes in the source image's
continuous pixel coordinates, with a foveated second pass near the horizon (``foveate``) and a
sub-pixel bottom edge (``refine_bottom``). Model layout, decoding and figures: docs/pipeline.md
(the detector).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from monorarp.core.boxes import iou
from monorarp.core.camera import CameraModel
from monorarp.detection.bottom_edge import refine_bottom as refine_bottom_edges
from monorarp.detection.fovea import Fovea, FoveaPass, merge
from monorarp.detection.letterbox import Letterbox, to_blob
from monorarp.detection.onnx_runtime import ModelError, expect_image_input, open_session, outputs
from monorarp.detection.second_pass import helper_pool
from monorarp.core.types import Detection, strong

REFINE_DEFAULT = True     # sub-pixel bottom-edge refinement (A/B figures: notes/edge.md)
DEFAULT_MODEL = Path(__file__).resolve().parent.parent / "models" / "centernet_vehicle.onnx"
ROBUST_MODEL = DEFAULT_MODEL.with_name("centernet_vehicle_robust.onnx")
DENSE_MODEL = DEFAULT_MODEL.with_name("centernet_vehicle_dense.onnx")
REALISTIC_MODEL = DEFAULT_MODEL.with_name("centernet_vehicle_realistic.onnx")
STREET_MODEL = DEFAULT_MODEL.with_name("centernet_vehicle_street.onnx")
OUTPUT_NAMES = ("heatmap", "ltrb")


@dataclass(frozen=True)
class CenterNetMeta:
    """What inference needs from ``<model>.json`` (defaults when the file is absent)."""

    stride: int = 4
    score_threshold: float = 0.3
    pad_value: int = 114
    label: str = "car"
    max_detections: int = 100
    weak_score_threshold: float | None = None   # weak detections from here up to score_threshold (None: none)

    @classmethod
    def load(cls, model_path: Path) -> "CenterNetMeta":
        from monorarp.core.readers import parse_json, read_text

        p = model_path.with_suffix(".json")
        if not p.is_file():
            return cls()
        d = parse_json(read_text(p, "detector metadata", ModelError, 1 << 20), p, "detector metadata", ModelError)
        try:
            meta = cls(stride=int(d.get("stride", 4)), score_threshold=float(d.get("score_threshold", 0.3)),
                       pad_value=int(d.get("pad_value", 114)), label=str(d.get("label", "car")),
                       max_detections=int(d.get("max_detections", 100)),
                       weak_score_threshold=None if d.get("weak_score_threshold") is None
                       else float(d["weak_score_threshold"]))
        except (ValueError, TypeError, AttributeError, OverflowError) as e:
            raise ModelError(f"{p}: unreadable detector metadata ({e})") from None
        bad = [f"{k} {v!r} (want {want})" for k, v, ok, want in (
            ("stride", meta.stride, 1 <= meta.stride <= 64, "1..64"),
            ("score_threshold", meta.score_threshold, 0 <= meta.score_threshold <= 1, "0..1"),
            ("pad_value", meta.pad_value, 0 <= meta.pad_value <= 255, "0..255"),
            ("max_detections", meta.max_detections, 1 <= meta.max_detections <= 100_000, "1..100000"),
            ("weak_score_threshold", meta.weak_score_threshold,
             meta.weak_score_threshold is None or 0 <= meta.weak_score_threshold <= 1, "0..1 or null")) if not ok]
        if bad:
            raise ModelError(f"{p}: invalid detector metadata: {', '.join(bad)}")
        return meta


def is_centernet_layout(session) -> bool:
    """True when the session's outputs are named ``heatmap`` and ``ltrb``."""
    return {o.name for o in outputs(session)} >= set(OUTPUT_NAMES)


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
    wts = hm[ni, nj].astype(np.float64) * inside * (iou(boxes, centre) > agree_iou)
    wts[:, 4] = np.maximum(wts[:, 4], 1e-6)
    merged = (boxes * wts[..., None]).sum(1) / wts.sum(1, keepdims=True)
    return merged, sc.astype(np.float64)


class CenterNetDetector(FoveaPass):
    """The project's CenterNet-style vehicle detector (onnxruntime, CPU).

    ``model_path``: defaults to the committed ``monorarp/models/centernet_vehicle.onnx``;
    its sidecar ``.json`` supplies stride and score threshold unless given here.
    ``camera``: the calibrated camera (or its dict); places the fovea. ``foveate``: run the
    second pass (default: when a camera is given). ``fovea_*``: see :func:`monorarp.detection.fovea.merge`
    and :meth:`~monorarp.detection.fovea.Fovea.place` (``zoom``, ``below``, ``margin_px``,
    ``dup_iou``, ``support`` (None: plain union), ``box``, ``max_height``).
    ``weak_score_threshold``: ``detect(image, weak=True)`` also returns the boxes scoring from it up to
    the score threshold, marked ``weak`` (for a tracker's second association pass; None: the model
    file's ``weak_score_threshold``, if any; at or above the score threshold: none).
    ``refine_bottom``: move each box's bottom edge to the vehicle/road transition found in the
    image to a fraction of a pixel (:func:`monorarp.detection.bottom_edge.refine_bottom`;
    the detector's edge stays where no clear edge lies within a few px of it). ``dehaze``: remove haze
    (:func:`monorarp.detection.dehaze.dehaze`, dark channel prior) from each image before both passes.
    ``parallel_passes``: run the fovea pass on a helper thread while the full view runs on the
    caller's (:mod:`monorarp.detection.second_pass`; the same detections, in less wall time).
    """

    uses_camera = True   # the registry passes the run's camera
    uses_weak_detections = True   # detect(image, weak=True) gives them

    FOVEA_DEFAULTS = {"fovea_zoom": 2.0, "fovea_below": 0.25}

    def __init__(self, model_path: str | Path | None = None, score_threshold: float | None = None,
                 intra_op_num_threads: int = 1, max_detections: int | None = None,
                 camera: CameraModel | dict | None = None, foveate: bool | None = None,
                 fovea_zoom: float = FOVEA_DEFAULTS["fovea_zoom"], fovea_below: float = FOVEA_DEFAULTS["fovea_below"],
                 fovea_margin_px: float = 2.0, fovea_dup_iou: float = 0.3, fovea_support: float | None = 0.2,
                 fovea_box: str = "auto", fovea_max_height: float = 0.35, refine_bottom: bool = REFINE_DEFAULT,
                 dehaze: bool = False, weak_score_threshold: float | None = None,
                 parallel_passes: bool = True, **_ignored) -> None:
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
        weak = self.meta.weak_score_threshold if weak_score_threshold is None else float(weak_score_threshold)
        if weak is not None and not 0 <= weak <= 1:
            raise ValueError(f"weak_score_threshold must be in [0, 1], got {weak}")
        self.weak_score_threshold = weak
        self._lb: Letterbox | None = None
        self.camera = CameraModel.from_dict(camera) if isinstance(camera, dict) else camera
        self._foveate_arg = foveate
        self.foveate = (self.camera is not None) if foveate is None else bool(foveate)
        self.fovea_zoom, self.fovea_below = float(fovea_zoom), float(fovea_below)
        self.fovea_margin_px, self.fovea_dup_iou = float(fovea_margin_px), float(fovea_dup_iou)
        self.fovea_support = None if fovea_support is None else min(float(fovea_support), self.score_threshold)
        if fovea_box not in ("auto", "mean", "fovea"):
            raise ValueError(f"fovea_box must be 'auto', 'mean' or 'fovea', got {fovea_box!r}")
        self.fovea_box = fovea_box
        self.fovea_max_height = float(fovea_max_height)
        if not isinstance(refine_bottom, bool):
            raise ValueError(f"refine_bottom must be true or false, got {refine_bottom!r}")
        self.refine_bottom = refine_bottom
        if not isinstance(parallel_passes, bool):
            raise ValueError(f"parallel_passes must be true or false, got {parallel_passes!r}")
        self.parallel_passes = parallel_passes
        self._fovea: tuple[tuple[int, int], Fovea | None, Letterbox | None] | None = None
        self.dehaze = bool(dehaze)

    def set_camera(self, camera: CameraModel | None) -> None:
        """Use another calibration from the next frame on (the fovea follows; ``foveate`` as at construction)."""
        self.camera = camera
        self.foveate = (camera is not None) if self._foveate_arg is None else bool(self._foveate_arg)
        self._fovea = None

    def raw(self, image: np.ndarray, letterbox: Letterbox | None = None) -> tuple[np.ndarray, np.ndarray, Letterbox]:
        """Run the net: (heatmap (h, w), ltrb (4, h, w), the letterbox used)."""
        h, w = image.shape[:2]
        if letterbox is None:
            if self._lb is None or (self._lb.src_w, self._lb.src_h) != (w, h):
                self._lb = Letterbox.fit(w, h, self.input_w, self.input_h)
            letterbox = self._lb
        blob = to_blob(letterbox.apply(image, self.meta.pad_value))
        hm, lt = self.session.run(list(OUTPUT_NAMES), {self.input_name: blob})
        return hm[0, 0], lt[0], letterbox

    def fovea_letterbox(self, w: int, h: int) -> Letterbox:
        """How the net sees a ``w`` x ``h`` fovea crop."""
        return Letterbox.fit(w, h, self.input_w, self.input_h)

    def detect_arrays(self, image: np.ndarray, threshold: float | None = None) -> tuple[np.ndarray, np.ndarray]:
        """BGR uint8 image -> (boxes (K, 4) source px, unclipped; scores (K,)), both passes merged.

        ``threshold``: decode down to this score (at most the score threshold; None: the score threshold).
        """
        thr = self.score_threshold if threshold is None else min(float(threshold), self.score_threshold)
        support = None if self.fovea_support is None else min(self.fovea_support, thr)
        if self.dehaze:
            from monorarp.detection.dehaze import dehaze

            image = dehaze(image)
        fov, flb = self.fovea(image.shape[1], image.shape[0])
        second = helper_pool().submit(self.raw, fov.cut(image), flb) if fov is not None and self.parallel_passes \
            else None
        hm, lt, lb = self.raw(image)
        boxes, scores = decode(hm, lt, self.meta.stride, thr, self.max_detections)
        boxes = lb.to_src(boxes, clip=False)
        if fov is not None:
            hm, lt, _ = second.result() if second is not None else self.raw(fov.cut(image), flb)
            fb, fs = decode(hm, lt, self.meta.stride, thr if support is None else support, self.max_detections)
            fb = fov.to_src(flb.to_src(fb, clip=False))
            boxes, scores = merge(boxes, scores, fb, fs, fov, thr, support,
                                  self.fovea_margin_px, self.fovea_dup_iou, self.fovea_box,
                                  self.fovea_max_height)
        if self.refine_bottom and len(boxes):
            boxes, _ = refine_bottom_edges(image, boxes)
        return boxes, scores

    def detect(self, image: np.ndarray, weak: bool = False) -> list[Detection]:
        """BGR uint8 image -> vehicle detections in its pixel coordinates (``weak``: the weak ones too).

        Both are decoded at the weak threshold, so the detections are the same either way.
        """
        boxes, scores = self.detect_arrays(image, self.weak_score_threshold)
        h, w = image.shape[:2]
        boxes[:, [0, 2]] = np.clip(boxes[:, [0, 2]], -0.5, w - 0.5)
        boxes[:, [1, 3]] = np.clip(boxes[:, [1, 3]], -0.5, h - 0.5)
        keep = (boxes[:, 2] - boxes[:, 0] > 1.0) & (boxes[:, 3] - boxes[:, 1] > 1.0)
        dets = [Detection(tuple(map(float, b)), float(sc), self.meta.label, weak=bool(sc < self.score_threshold))
                for b, sc in zip(boxes[keep], scores[keep])]
        return dets if weak else strong(dets)

    __call__ = detect


class RobustCenterNetDetector(CenterNetDetector):
    """:class:`CenterNetDetector` with the appearance-randomised model ``centernet_vehicle_robust.onnx``
    (registered as ``centernet_robust``; training and figures: docs/weather.md, retraining)."""

    def __init__(self, model_path: str | Path | None = None, camera: CameraModel | dict | None = None,
                 **kw) -> None:
        super().__init__(ROBUST_MODEL if model_path is None else model_path, camera=camera, **kw)


class DenseCenterNetDetector(CenterNetDetector):
    """:class:`CenterNetDetector` with the model fine-tuned also on dense occluding traffic,
    ``centernet_vehicle_dense.onnx`` (registered as ``centernet_dense``; training and figures:
    docs/tracking.md, dense traffic)."""

    def __init__(self, model_path: str | Path | None = None, camera: CameraModel | dict | None = None,
                 **kw) -> None:
        super().__init__(DENSE_MODEL if model_path is None else model_path, camera=camera, **kw)


class RealisticCenterNetDetector(CenterNetDetector):
    """:class:`CenterNetDetector` with the model trained from scratch on realistic-look renders only,
    ``centernet_vehicle_realistic.onnx`` (registered as ``centernet_realistic``; training and figures:
    docs/looks.md)."""

    def __init__(self, model_path: str | Path | None = None, camera: CameraModel | dict | None = None,
                 **kw) -> None:
        super().__init__(REALISTIC_MODEL if model_path is None else model_path, camera=camera, **kw)


class StreetCenterNetDetector(CenterNetDetector):
    """:class:`CenterNetDetector` with ``centernet_vehicle_street.onnx``: trained from scratch on realistic
    renders of motorways and urban streets (registered as ``centernet_street``; training
    and figures: docs/streets.md)."""

    def __init__(self, model_path: str | Path | None = None, camera: CameraModel | dict | None = None,
                 **kw) -> None:
        super().__init__(STREET_MODEL if model_path is None else model_path, camera=camera, **kw)
