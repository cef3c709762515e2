"""``monorarp eval kitti``: a KITTI dataset -> detector (or the labels) -> state estimator (and tracker
on sequences) -> the run scoring of :mod:`harness.scoring.evaluate` + KITTI AP, written atomically.

Frames: an object dataset's images are independent (each is its own one-frame sequence: every
stage is reset before it, and each detection is its own track, so no tracker runs); a tracking
sequence's frames run in order through the tracker, at ``t = frame / fps`` (KITTI: 10 Hz).

Truth per frame (:class:`KittiFrameTruth`, the :class:`~harness.world.truth.FrameTruth` that
:func:`harness.scoring.evaluate.evaluate` reads, plus the label's KITTI fields): each label's box,
``d_long``/``d_lat`` from its location, size and yaw (:mod:`harness.kitti_eval.geometry`); on
tracking sequences ``v_long``/``v_lat`` = finite differences of those over the frame times of the
same track id (central, one-sided at a track's ends); no TTC or ego speed (null in ``metrics.json``).

A label **counts** (must be found; a track matching it is scored for distance) when its type is
``Car``, ``Van`` or ``Truck`` and it passes KITTI's *moderate* filter (object datasets: box height
> 25 px, occlusion <= 1, truncation <= 0.30) or KITTI tracking's (box height > 25 px, occlusion
<= 2, truncation level 0), and lies within 80 m; every other label (other types, ``DontCare``,
harder vehicles) is *ignored*: neither missed nor, when a detection or track matches it, a false
positive (the run scoring's rule).

Outputs in ``OUT``: ``metrics.json`` (the run keys, ``tracking`` null for object datasets, plus
``kitti_ap`` from :mod:`harness.scoring.kitti_ap` and ``dataset``) and ``per_object.csv`` (the run's
columns plus ``sample``, ``type``, ``truncated``, ``occluded``, ``difficulty``, ``label``).
"""

from __future__ import annotations

import csv
import math
import threading
import time
from collections import OrderedDict
from collections.abc import Callable, Iterator
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from harness.kitti_eval import geometry as geo
from harness.kitti_eval.reader import Dataset, KittiInputError, Sample
from harness.scoring import kitti_ap
from harness.scoring.evaluate import EvalConfig, evaluate
from harness.scoring.records import COLUMNS, _cell
from harness.world.truth import EgoTruth, FrameTruth, ObjectTruth
from monorarp.pipeline import registry
from monorarp.core.camera import CameraError, CameraModel
from monorarp.pipeline.runner import ComponentConfig, Pipeline, PipelineConfig
from monorarp.core.readers import MAX_CONFIG_BYTES, read_json
from monorarp.core.types import Detection, Frame, FrameResult, RiskEstimate, Track, WarningState, strong

METRICS_NAME = "metrics.json"
PER_OBJECT_NAME = "per_object.csv"
OUTPUT_NAMES = (METRICS_NAME, PER_OBJECT_NAME)
MANIFEST_NAME = "export.json"
VEHICLE_TYPES = ("Car", "Van", "Truck")
DEFAULT_FPS = 10.0
LABELS_DETECTOR = "labels"
#: Track and object ids of sequence k are offset by k * ID_STRIDE (ids stay unique across sequences).
ID_STRIDE = 1_000_000
KITTI_COLUMNS = ("sample", "type", "truncated", "occluded", "difficulty", "label")
PREFETCH = 4


@dataclass(frozen=True)
class KittiEvalOptions:
    detector: str = PipelineConfig().detector.name    # registry name, .onnx path, or "labels"
    tracker: str = PipelineConfig().tracker.name      # tracking sequences only
    camera_height_m: float | None = None
    horizon_row: float | None = None
    fps: float | None = None          # tracking sequences; default: export.json's, else 10 Hz
    frames: int | None = None         # evaluate only the first N frames (all sequences together)


class QueuedDetector:
    """The pipeline's detector stage here: hands back the detections queued for the frame, made beforehand
    (the detector runs on the decoding threads, in parallel with the rest of the pipeline) or, for
    ``--detector labels``, the frame's vehicle label boxes (``Car``, ``Van``, ``Truck``), score 1, labelled
    with their type in lower case (an oracle with KITTI's label precision). The queue holds the weak
    detections too (:attr:`~monorarp.core.types.Detection.weak`), for a tracker that takes them."""

    uses_weak_detections = True

    def __init__(self) -> None:
        self.queued: list[Detection] = []

    def detect(self, image: np.ndarray, weak: bool = False) -> list[Detection]:
        return list(self.queued) if weak else strong(self.queued)


class PerImageTracker:
    """Object datasets: each detection is its own track (ids 0..n-1), nothing carried between images."""

    def update(self, image: np.ndarray, detections: list[Detection], t: float) -> list[Track]:
        return [Track(id=k, box=d.box, score=d.score, label=d.label) for k, d in enumerate(detections)]


# --------------------------------------------------------------------------------- truth
def is_counted(sample_kind: str, types: list[str], box: np.ndarray, occluded: np.ndarray,
               truncated: np.ndarray) -> np.ndarray:
    """(N,) does each label count (module docstring)? Range is applied by the scoring."""
    vehicle = np.array([t in VEHICLE_TYPES for t in types], dtype=bool)
    if sample_kind == "tracking":
        h = box[:, 3] - box[:, 1] if len(box) else np.zeros(0)
        return vehicle & (h > 25.0) & (occluded <= 2) & (truncated <= 0)
    return vehicle & geo.passes(box, occluded, truncated, "moderate")


@dataclass(frozen=True)
class KittiObjectTruth(ObjectTruth):
    """A label as scored truth, with its KITTI fields (``label``: the label file and line)."""

    type: str = ""
    truncated: float = 0.0
    occluded: int = 0
    difficulty: str = ""
    label: str = ""


@dataclass(frozen=True)
class KittiFrameTruth(FrameTruth):
    """A frame's labels as scored truth, with the sample's name."""

    sample: str = ""


def truth_record(sample: Sample, kind: str, camera: CameraModel, offset: np.ndarray, frame: int, t: float,
                 id_base: int) -> KittiFrameTruth:
    """The frame's truth: no visibility (the ``counted`` flag replaces it), velocity, TTC or ego speed."""
    lab = sample.labels
    n = len(lab)
    d_long = np.full(n, np.nan)
    d_lat = np.full(n, np.nan)
    real = np.array([t != "DontCare" for t in lab.type], dtype=bool)
    if real.any():
        dl, dx = geo.rear_face_distance(lab.dimensions[real], lab.location[real], lab.rotation_y[real], camera,
                                        offset)
        d_long[real], d_lat[real] = dl, dx
    counted = is_counted(kind, lab.type, lab.box, lab.occluded, lab.truncated) if n else np.zeros(0, bool)
    difficulty = geo.difficulty_names(lab.box, lab.occluded, lab.truncated) if n else []
    objects = []
    for k in range(n):
        tid = int(lab.track_id[k])
        objects.append(KittiObjectTruth(
            id=id_base + tid if tid >= 0 else -(id_base + k + 1), box=tuple(lab.box[k].tolist()),
            visibility=float("nan"), counted=bool(counted[k]), d_long=float(d_long[k]), d_lat=float(d_lat[k]),
            v_long=None, v_lat=None, ttc=None, type=lab.type[k], truncated=float(lab.truncated[k]),
            occluded=int(lab.occluded[k]), difficulty=difficulty[k], label=lab.source[k]))
    return KittiFrameTruth(frame=frame, t=t, ego=EgoTruth(speed=float("nan"), crashed=False),
                           objects=tuple(objects), sample=sample.name)


def add_velocities(truths: list[KittiFrameTruth]) -> list[KittiFrameTruth]:
    """``truths`` with ``v_long``/``v_lat`` (m/s) of tracked labels filled: finite differences of
    ``d_long``/``d_lat`` over the frame times of the same track id in consecutive frames
    (:func:`geometry.finite_difference`)."""
    tracks: dict[int, list[tuple[int, int]]] = {}          # track id -> (frame k, object j)
    for k, tr in enumerate(truths):
        for j, o in enumerate(tr.objects):
            if o.id >= 0 and np.isfinite(o.d_long):
                tracks.setdefault(o.id, []).append((k, j))
    filled: dict[tuple[int, int], dict[str, float | None]] = {}
    for rows in tracks.values():
        f = np.array([truths[k].frame for k, _ in rows])
        t = np.array([truths[k].t for k, _ in rows])
        for key, src in (("v_long", "d_long"), ("v_lat", "d_lat")):
            v = geo.finite_difference(f, t, np.array([getattr(truths[k].objects[j], src) for k, j in rows]))
            for kj, val in zip(rows, v):
                filled.setdefault(kj, {})[key] = float(val) if np.isfinite(val) else None
    return [replace(tr, objects=tuple(replace(o, **filled[(k, j)]) if (k, j) in filled else o
                                      for j, o in enumerate(tr.objects))) for k, tr in enumerate(truths)]


# ------------------------------------------------------------------------------ cameras
def read_manifest(root: Path) -> dict:
    """``export.json`` of a ``monorarp export`` dataset at ``root`` (for KITTI's ``DIR/training`` layout, also in
    ``DIR``); {} when there is none. One that is there is checked, as its ``fps`` sets the frame times and its
    ``camera`` the image size: a JSON object whose ``fps``, when present, is a positive number and whose
    ``camera``, when present, is a camera (:meth:`CameraModel.from_dict`); :class:`KittiInputError` naming
    the file and field otherwise."""
    places = [root / MANIFEST_NAME] + ([root.parent / MANIFEST_NAME] if root.name == "training" else [])
    p = next((p for p in places if p.exists()), None)
    if p is None:
        return {}
    data = read_json(p, "export manifest", KittiInputError, MAX_CONFIG_BYTES)
    if not isinstance(data, dict):
        raise KittiInputError(f"{p}: {MANIFEST_NAME} must hold a JSON object, got {type(data).__name__}")
    if "fps" in data:
        fps = data["fps"]
        if isinstance(fps, bool) or not isinstance(fps, (int, float)) or not (math.isfinite(fps) and fps > 0):
            raise KittiInputError(f"{p}: field fps must be a positive number (frames per second), got {fps!r:.60}")
    if "camera" in data:
        try:
            CameraModel.from_dict(data["camera"], source=f"{p}: field camera")
        except CameraError as e:
            raise KittiInputError(str(e)) from None
    return data


class Cameras:
    """Camera (and label offset) per calibration and image size, checked against the images (thread-safe)."""

    def __init__(self, opts: KittiEvalOptions, manifest: dict) -> None:
        self.opts = opts
        self.lock = threading.Lock()
        cam = manifest.get("camera")          # checked by read_manifest
        self.size = (int(cam["width"]), int(cam["height"])) if cam else None
        self.cache: dict[tuple, tuple[CameraModel, np.ndarray, dict]] = {}

    def get(self, sample: Sample, width: int, height: int) -> tuple[CameraModel, np.ndarray, dict]:
        if self.size is not None and (width, height) != tuple(self.size):
            raise KittiInputError(f"{sample.image}: {width}x{height} image, but the dataset's camera (export.json) "
                                  f"is {self.size[0]}x{self.size[1]}: image of another size than the calibration")
        key = (str(sample.calib_path), width, height)
        with self.lock:
            return self._get(key, sample, width, height)

    def _get(self, key: tuple, sample: Sample, width: int, height: int) -> tuple[CameraModel, np.ndarray, dict]:
        if key not in self.cache:
            try:
                K, _ = geo.intrinsics(sample.calib["P2"])
            except ValueError as e:
                raise KittiInputError(f"{sample.calib_path}: {e}") from None
            if not (0 <= K[0, 2] <= width - 1 and 0 <= K[1, 2] <= height - 1):
                raise KittiInputError(f"{sample.image}: {width}x{height} image, but the principal point of "
                                      f"{sample.calib_path} ({K[0, 2]:.1f}, {K[1, 2]:.1f}) lies outside it: image "
                                      "of another size than the calibration")
            self.cache[key] = geo.camera_from_calib(sample.calib, width, height, self.opts.camera_height_m,
                                                    self.opts.horizon_row, where=str(sample.calib_path))
        return self.cache[key]


# ------------------------------------------------------------------------------ frames
def _read_image(path: Path) -> np.ndarray:
    import cv2

    image = cv2.imread(str(path), cv2.IMREAD_COLOR)
    if image is None:
        raise KittiInputError(f"{path}: cannot read image")
    return image


def _prefetch(samples: list[Sample], work: Callable[[Sample], Any]) -> Iterator[Any]:
    """``work(sample)`` of each sample, computed ahead on two threads (image decoding and ONNX inference
    release the GIL), yielded in order."""
    with ThreadPoolExecutor(max_workers=2) as pool:
        pending = [pool.submit(work, s) for s in samples[:PREFETCH]]
        for k in range(len(samples)):
            out = pending[k].result()
            pending[k] = None
            if k + PREFETCH < len(samples):
                pending.append(pool.submit(work, samples[k + PREFETCH]))
            yield out


def _offset_ids(res: FrameResult, off: int) -> FrameResult:
    """``res`` with every track id moved by ``off``."""
    if not off:
        return res
    w = res.warning
    return replace(res, tracks=[replace(t, id=t.id + off) for t in res.tracks],
                   states={k + off: replace(s, track_id=s.track_id + off) for k, s in res.states.items()},
                   risk=RiskEstimate(res.risk.risk, {k + off: v for k, v in res.risk.ttc.items()}, res.risk.kind),
                   warning=WarningState(w.active, None if w.track_id is None else w.track_id + off, w.ttc, w.episode,
                                        w.onset_t, tuple(i + off for i in w.threat_ids)))


class _Pipelines:
    """One pipeline per camera (the detector's fovea and the state estimator read it); its detector stage is
    the shared :class:`QueuedDetector`, the real detector of each camera runs on the decoding threads."""

    def __init__(self, opts: KittiEvalOptions, kind: str) -> None:
        self.opts, self.kind = opts, kind
        self.labels = opts.detector == LABELS_DETECTOR
        self.queue = QueuedDetector()
        self.cache: OrderedDict[CameraModel, Pipeline] = OrderedDict()
        self.detectors: dict[CameraModel, Any] = {}
        self.lock = threading.Lock()

    def config(self) -> PipelineConfig:
        det = "oracle" if self.labels else self.opts.detector                 # "oracle": a placeholder, replaced
        tracker = "sort" if self.kind == "object" else self.opts.tracker      # replaced for object datasets
        return PipelineConfig(detector=ComponentConfig(name=det), tracker=ComponentConfig(name=tracker))

    def get(self, camera: CameraModel) -> Pipeline:
        with self.lock:
            if camera not in self.cache:
                p = Pipeline.from_config(self.config(), camera)
                self.detectors[camera] = None if self.labels else p.detector
                p.detector = self.queue
                if self.kind == "object":
                    p.tracker = PerImageTracker()
                self.cache[camera] = p
            return self.cache[camera]

    def detector(self, camera: CameraModel) -> Any:
        """The real detector of ``camera``'s pipeline (None for ``--detector labels``)."""
        self.get(camera)
        return self.detectors[camera]

    def describe(self) -> dict:
        return {"detector": self.opts.detector,
                "tracker": "none (each image alone)" if self.kind == "object" else self.opts.tracker,
                "state": "geometric", "risk": "ttc", "warning": "fcw"}


# ---------------------------------------------------------------------------------- run
def run_dataset(ds: Dataset, opts: KittiEvalOptions) -> tuple[list[KittiFrameTruth], list[FrameResult], dict]:
    """Run the pipeline over ``ds``; returns truths, results (global frame indices) and run facts."""
    manifest = read_manifest(ds.root)
    fps = opts.fps or manifest.get("fps") or DEFAULT_FPS
    cameras = Cameras(opts, manifest)
    pipes = _Pipelines(opts, ds.kind)
    truths: list[KittiFrameTruth] = []
    results: list[FrameResult] = []
    infos: list[dict] = []
    limit = opts.frames if opts.frames is not None else ds.n_frames
    pipeline_s = 0.0
    t_offset = 0.0
    todo = [(s_idx, k == 0, sample) for s_idx, seq in enumerate(ds.sequences) for k, sample in enumerate(seq.samples)]
    todo = todo[:limit]
    first_size: tuple[int, int] | None = None
    seq_start = 0
    pipe = None

    def work(sample: Sample) -> tuple[np.ndarray, tuple, list[Detection] | None, float]:
        """Decode, find the camera, detect (on a prefetch thread): (image, camera, detections, ms)."""
        image = _read_image(sample.image)
        cam = cameras.get(sample, image.shape[1], image.shape[0])
        det = pipes.detector(cam[0])
        if det is None:
            return image, cam, None, 0.0
        t0 = time.perf_counter()
        dets = list(det.detect(image, weak=True) if registry.uses(det, "weak_detections") else det.detect(image))
        return image, cam, dets, (time.perf_counter() - t0) * 1e3

    for (s_idx, starts, sample), (image, (camera, offset, info), dets, det_ms) in zip(
            todo, _prefetch([x[2] for x in todo], work)):
        h, w = image.shape[:2]
        if starts:
            first_size, seq_start = (w, h), sample.frame
            if truths:
                t_offset = truths[-1].t + 1.0          # a gap between sequences
        elif (w, h) != first_size:
            raise KittiInputError(f"{sample.image}: {w}x{h} image, but the sequence's first image is "
                                  f"{first_size[0]}x{first_size[1]} (one calibration per sequence)")
        if info not in infos:
            infos.append(info)
        k = len(truths)
        id_base = s_idx * ID_STRIDE if ds.kind == "tracking" else 0
        t = t_offset + (sample.frame - seq_start) / fps if ds.kind == "tracking" else float(k)
        truth = truth_record(sample, ds.kind, camera, offset, k, t, id_base)
        p = pipes.get(camera)
        if starts or p is not pipe:
            p.reset()
            pipe = p
        pipes.queue.queued = dets if dets is not None else [
            Detection(box=o.box, score=1.0, label=o.type.lower())
            for o in truth.objects if o.type in VEHICLE_TYPES]
        t0 = time.perf_counter()
        res = p.process(Frame(index=k, t=t, image=image))
        pipeline_s += time.perf_counter() - t0 + det_ms / 1e3
        if dets is not None:                                # the detector's own time, measured on its thread
            tm = res.timings_ms
            tm["total"] += det_ms - tm.get("detector", 0.0)
            tm["detector"] = det_ms
        truths.append(truth)
        results.append(_offset_ids(res, id_base))
    if ds.kind == "tracking":
        truths = add_velocities(truths)
    facts = {"fps": fps, "pipeline_s": pipeline_s, "camera": infos, "components": pipes.describe()}
    if pipes.cache:
        facts["camera_model"] = next(iter(pipes.cache)).to_dict()
    return truths, results, facts


def ap_inputs(truths: list[KittiFrameTruth], results: list[FrameResult]) -> tuple[list, list]:
    """Per-image :class:`~harness.scoring.kitti_ap.ImageTruth` / ``ImageDetections`` of the detector's output."""
    tr, de = [], []
    for truth, res in zip(truths, results):
        objs = truth.objects
        tr.append(kitti_ap.ImageTruth(types=[o.type for o in objs],
                                      boxes=np.array([o.box for o in objs], dtype=float).reshape(-1, 4),
                                      occluded=np.array([o.occluded for o in objs], dtype=int),
                                      truncated=np.array([o.truncated for o in objs], dtype=float)))
        de.append(kitti_ap.ImageDetections(boxes=np.array([d.box for d in res.detections], dtype=float).reshape(-1, 4),
                                           scores=np.array([d.score for d in res.detections], dtype=float),
                                           labels=[d.label for d in res.detections]))
    return tr, de


def score(ds: Dataset, truths: list[KittiFrameTruth], results: list[FrameResult], facts: dict, opts: KittiEvalOptions,
          wall_s: float) -> tuple[dict, list[dict]]:
    """``(metrics, per-object rows)``."""
    cfg = EvalConfig()
    run_info = {"dataset": str(ds.root), "kind": ds.kind, "components": facts["components"],
                "fps_sequence": facts["fps"] if ds.kind == "tracking" else None}
    metrics, records = evaluate(truths, results, cfg, wall_time_s=facts["pipeline_s"], run_info=run_info,
                                tracking=ds.kind == "tracking")
    tr, de = ap_inputs(truths, results)
    metrics["kitti_ap"] = kitti_ap.kitti_ap(tr, de, "Car")
    metrics["dataset"] = {
        "root": str(ds.root), "kind": ds.kind, "frames": len(truths),
        "sequences": len({t.sample.split("/")[0] for t in truths}) if ds.kind == "tracking" else None,
        "labels": sum(len(t.objects) for t in truths),
        "counted_rule": ("Car/Van/Truck, box height > 25 px, occluded <= 1, truncated <= 0.30, d_long <= 80 m"
                         if ds.kind == "object" else
                         "Car/Van/Truck, box height > 25 px, occluded <= 2, truncation level 0, d_long <= 80 m"),
        "distance_truth": "nearest ego-y of the label's footprint (location, w, l, rotation_y; heading "
                          "(cos ry, -sin ry / cos pitch)); lateral: ego-x of the bottom-face centre",
        "camera": facts["camera"], "camera_model": facts.get("camera_model"),
        "frames_per_s_total": len(truths) / wall_s if wall_s > 0 else None,
        "frames_per_s_pipeline": metrics["fps"]}
    rows = per_object_rows(truths, records)
    return metrics, rows


def per_object_rows(truths: list[KittiFrameTruth], records) -> list[dict]:
    """The run's per-object records with the KITTI columns of each label beside them."""
    by_key = {(t.frame, o.id): o for t in truths for o in t.objects}
    samples = {t.frame: t.sample for t in truths}
    rows = []
    for r in records:
        d = {c: getattr(r, c) for c in COLUMNS}
        o = by_key.get((r.frame, r.gt_id)) if r.gt_id is not None else None
        d.update({"sample": samples.get(r.frame, ""), "type": o.type if o else "",
                  "truncated": o.truncated if o else None, "occluded": o.occluded if o else None,
                  "difficulty": o.difficulty if o else "", "label": o.label if o else ""})
        rows.append(d)
    return rows


def write_rows(rows: list[dict], path: Path) -> None:
    cols = list(COLUMNS) + list(KITTI_COLUMNS)
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(cols)
        for r in rows:
            w.writerow([_cell(r.get(c)) for c in cols])


def evaluate_kitti(ds: Dataset, opts: KittiEvalOptions, out: str | Path) -> dict:
    """Run, score and write ``OUT/metrics.json`` and ``OUT/per_object.csv`` (all or nothing); returns metrics."""
    from harness.scoring.evaluate import write_metrics
    from monorarp.app.io import atomic_output_dir

    start = time.perf_counter()
    with atomic_output_dir(out, owned_names=OUTPUT_NAMES) as tmp:
        truths, results, facts = run_dataset(ds, opts)
        metrics, rows = score(ds, truths, results, facts, opts, time.perf_counter() - start)
        write_metrics(metrics, tmp / METRICS_NAME)
        write_rows(rows, tmp / PER_OBJECT_NAME)
    return metrics


def dataset_summary(metrics: dict) -> str:
    """A few lines for the terminal."""
    ap = metrics["kitti_ap"]
    d, lat, det = metrics["distance"], metrics["lateral"], metrics["detection"]

    def num(v: Any, fmt: str = "{:.3f}") -> str:
        return "-" if v is None or (isinstance(v, float) and not np.isfinite(v)) else fmt.format(v)

    lines = [f"{metrics['dataset']['kind']} dataset, {metrics['frames']} frames, "
             f"{metrics['dataset']['labels']} labels; detector {metrics['config']['components']['detector']}",
             f"distance |d_y - d_long| median {num(d['abs_err_median_m'])} m, rel. median "
             f"{num(d['rel_err_median'])} ({d['count']} pairs); lateral median {num(lat['abs_err_median_m'])} m",
             f"detection @IoU 0.5: precision {num(det['precision'])}, recall {num(det['recall'])}"]
    for thr in ("0.7", "0.5"):
        a = ap[f"iou_{thr}"]
        lines.append(f"Car AP_R40 @IoU {thr}: easy {num(a['easy']['ap_r40'])}, moderate "
                     f"{num(a['moderate']['ap_r40'])}, hard {num(a['hard']['ap_r40'])}")
    t = metrics.get("tracking") or {}
    if t.get("mota") is not None:
        lines.append(f"tracking: MOTA {num(t['mota'])}, IDF1 {num(t['idf1'])}, HOTA {num(t.get('hota'))}")
    lines.append(f"{num(metrics['dataset']['frames_per_s_total'], '{:.1f}')} frames/s overall, "
                 f"{num(metrics['fps'], '{:.1f}')} frames/s in the pipeline")
    return "\n".join(lines)
