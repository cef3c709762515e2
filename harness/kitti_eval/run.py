"""The pipeline over a KITTI dataset's frames: truths, results and the run's facts (:func:`run_dataset`).

An object dataset's images are independent (each is its own one-frame sequence: every stage is reset
before it, and each detection is its own track, :class:`PerImageTracker`); a tracking sequence's frames
run in order through the tracker, at ``t = frame / fps`` (s). Images are decoded and detected ahead
on two threads (:func:`_prefetch`); the pipeline's detector stage hands back those detections
(:class:`QueuedDetector`), or the frame's vehicle labels for ``--detector labels``.
"""

from __future__ import annotations

import threading
import time
from collections import OrderedDict
from collections.abc import Callable, Iterator
from concurrent.futures import ThreadPoolExecutor
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from harness.kitti_eval.cameras import Cameras, read_manifest
from harness.kitti_eval.options import LABELS_DETECTOR, KittiEvalOptions
from harness.kitti_eval.reader import Dataset, KittiInputError, Sample
from harness.kitti_eval.truth import VEHICLE_TYPES, KittiFrameTruth, add_velocities, truth_record
from monorarp.core.camera import CameraModel
from monorarp.core.types import Detection, Frame, FrameResult, RiskEstimate, Track, WarningState, strong
from monorarp.pipeline import registry
from monorarp.pipeline.config import ComponentConfig, PipelineConfig
from monorarp.pipeline.runner import Pipeline

DEFAULT_FPS = 10.0
#: Track and object ids of sequence k are offset by k * ID_STRIDE (ids stay unique across sequences).
ID_STRIDE = 1_000_000
PREFETCH = 4


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

    def __init__(self, opts: KittiEvalOptions, kind: str, rendered: bool = False) -> None:
        self.opts, self.kind = opts, kind
        self.state_kwargs = opts.state_settings(rendered)
        self.labels = opts.detector == LABELS_DETECTOR
        self.queue = QueuedDetector()
        self.cache: OrderedDict[CameraModel, Pipeline] = OrderedDict()
        self.detectors: dict[CameraModel, Any] = {}
        self.lock = threading.Lock()

    def config(self) -> PipelineConfig:
        det = "oracle" if self.labels else self.opts.detector                 # "oracle": a placeholder, replaced
        tracker = "sort" if self.kind == "object" else self.opts.tracker      # replaced for object datasets
        kw = {} if self.labels or self.opts.score_threshold is None else {"score_threshold": self.opts.score_threshold}
        return PipelineConfig(detector=ComponentConfig(name=det, kwargs=kw), tracker=ComponentConfig(name=tracker),
                              state=ComponentConfig(name="geometric", kwargs=self.state_kwargs))

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
                "state": "geometric" + (f" {self.state_kwargs}" if self.state_kwargs else ""), "risk": "ttc",
                "warning": "fcw"}


def run_dataset(ds: Dataset, opts: KittiEvalOptions) -> tuple[list[KittiFrameTruth], list[FrameResult], dict]:
    """Run the pipeline over ``ds``; returns truths, results (global frame indices) and run facts."""
    manifest = read_manifest(ds.root)
    fps = opts.fps or manifest.get("fps") or DEFAULT_FPS
    cameras = Cameras(opts, manifest)
    pipes = _Pipelines(opts, ds.kind, rendered=bool(manifest))
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
    facts = {"fps": fps, "pipeline_s": pipeline_s, "camera": infos, "components": pipes.describe(),
             "score_threshold": opts.score_threshold}
    if pipes.cache:
        facts["camera_model"] = next(iter(pipes.cache)).to_dict()
    return truths, results, facts
