"""Scoring orchestration: per-frame truths + pipeline FrameResults -> records and ``metrics.json``.

Tracks are matched to counted ground-truth objects per frame (Hungarian on IoU), then distance,
lateral, velocity (m, m/s), TTC-warning, lane-speed, tracking, detection and risk metrics are
computed, all configurable in :class:`EvalConfig`. The rules in full: docs/metrics.md.
"""

from __future__ import annotations

import csv
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from harness.scoring import algo
from harness.scoring.match import MIN_IOU, as_boxes, match_boxes, split_ignored
from harness.scoring.mot import MotScorer
from harness.scoring.records import ObjectRecord, _cell
from harness.scoring.warnings import warning_metrics
from harness.world.truth import FrameTruth, ObjectTruth
from monorarp.core.camera import CameraModel
from monorarp.app.io import write_json_atomic
from monorarp.warning.thresholds import TTC_CUE_THRESHOLD_S
from monorarp.core.types import FrameResult, RiskEstimate

NAN = float("nan")
#: Keys of ``metrics["tracking"]`` (all null when tracking is not scored).
TRACKING_KEYS = ("mota", "motp", "idf1", "idp", "idr", "id_switches", "false_positives", "misses", "objects",
                 "unique_objects", "fragmentations", "mostly_tracked", "partially_tracked", "mostly_lost",
                 "precision", "recall", "hota", "deta", "assa", "loca", "hota_by_alpha", "by_range")
#: What each range bin of ``tracking.by_range`` is given (motmetrics names).
BIN_METRICS = ("mota", "idf1", "idr", "num_switches", "num_false_positives", "num_misses", "num_objects")
STAGES = ("detector", "ego_speed", "tracker", "state", "risk", "warning", "total")


@dataclass(frozen=True)
class EvalConfig:
    warning_threshold_s: float = TTC_CUE_THRESHOLD_S
    min_iou: float = MIN_IOU
    min_visibility: float = 0.3
    max_range_m: float = 80.0
    ignore_cover: float | None = 0.5
    risk_horizon_s: float = 10.0
    near_miss_ttc_s: float = 1.0


def _f(v) -> float:
    return NAN if v is None else float(v)


def counted_mask(objects: Sequence[ObjectTruth], cfg: EvalConfig) -> np.ndarray:
    """Which GT objects count (visibility and range rule of the module docstring).

    An object carrying its own ``counted`` flag (a labelled dataset whose labels say what must be
    found, e.g. KITTI's difficulty levels) uses it in place of the visibility rule; range still applies.
    """
    return np.array([(o.counted if o.counted is not None else o.visibility >= cfg.min_visibility)
                     and o.d_long <= cfg.max_range_m for o in objects], dtype=bool)


def ground_range(boxes: np.ndarray, camera: CameraModel) -> np.ndarray:
    """(N,) forward distance (m) at which each box's bottom edge meets the ground; NaN at or above the horizon."""
    b = as_boxes(boxes)
    return camera.ground_point_from_pixel(np.full(len(b), camera.cx), b[:, 3])[:, 1]


def out_of_range(boxes: np.ndarray, camera: CameraModel | None, max_range_m: float) -> np.ndarray | None:
    """Boxes whose bottom edge meets the ground beyond ``max_range_m`` (or never); None without a camera."""
    if camera is None:
        return None
    return ~(ground_range(boxes, camera) <= max_range_m)


def frame_records(truth: FrameTruth, result: FrameResult, cfg: EvalConfig,
                  camera: CameraModel | None = None) -> list[ObjectRecord]:
    """Side-by-side records of one frame (see :mod:`harness.scoring.records`)."""
    objects = truth.objects
    counted = counted_mask(objects, cfg)
    tracks = result.tracks
    gt_boxes = as_boxes([o.box for o in objects])
    tr_boxes = as_boxes([t.box for t in tracks])
    match = {g: (e, iou) for g, e, iou in match_boxes(gt_boxes, tr_boxes, cfg.min_iou)}
    _, set_aside = split_ignored(gt_boxes, counted, tr_boxes, cfg.min_iou, cfg.ignore_cover,
                                 out_of_range(tr_boxes, camera, cfg.max_range_m))
    frame, t = truth.frame, truth.t
    recs: list[ObjectRecord] = []
    used = set()

    def fill_track(r: ObjectRecord, tr) -> None:
        r.track_id, r.coasting = tr.id, tr.coasting
        r.est_x1, r.est_y1, r.est_x2, r.est_y2 = map(float, tr.box)
        st = result.states.get(tr.id)
        if st is not None:
            r.d_y_est, r.d_x_est, r.v_y_est, r.v_x_est = st.d_y, st.d_x, st.v_y, st.v_x
            r.d_y_std, r.d_x_std, r.v_y_std, r.v_x_std = map(_f, (st.d_y_std, st.d_x_std, st.v_y_std, st.v_x_std))
            r.a_y_est, r.a_y_std, r.age_s, r.expansion_rate, r.expansion_rate_std = map(
                _f, (st.a_y, st.a_y_std, st.age_s, st.expansion_rate, st.expansion_rate_std))
            r.registered_rate, r.registered_rate_std = _f(st.registered_rate), _f(st.registered_rate_std)
            r.registered_v_x, r.registered_v_x_std = _f(st.registered_v_x), _f(st.registered_v_x_std)
        r.ttc_est = _f(result.risk.ttc.get(tr.id))

    for g, o in enumerate(objects):
        r = ObjectRecord(frame=frame, t=t, gt_id=o.id, counted=bool(counted[g]),
                         visibility=float(o.visibility), d_long_gt=_f(o.d_long), d_lat_gt=_f(o.d_lat),
                         v_long_gt=_f(o.v_long), v_lat_gt=_f(o.v_lat), ttc_gt=_f(o.ttc))
        r.gt_x1, r.gt_y1, r.gt_x2, r.gt_y2 = map(float, o.box)
        if g in match:
            e, iou = match[g]
            used.add(e)
            r.matched, r.iou = True, iou
            fill_track(r, tracks[e])
        recs.append(r)
    for e, tr in enumerate(tracks):
        if e not in used:
            r = ObjectRecord(frame=frame, t=t, set_aside=bool(set_aside[e]))
            fill_track(r, tr)
            recs.append(r)
    return recs


def _column(recs: Sequence[ObjectRecord], name: str) -> np.ndarray:
    return np.array([getattr(r, name) for r in recs], dtype=float)


def state_metrics(records: Sequence[ObjectRecord], cfg: EvalConfig) -> dict[str, Any]:
    """Distance, lateral, velocity and TTC sections of ``metrics.json``."""
    pairs = [r for r in records if r.counted and r.matched]
    d_gt = _column(pairs, "d_long_gt")
    in_range = (d_gt >= 0) & (d_gt < max(hi for _, hi in algo.RANGE_BINS.values()))
    scored = [r for r, ok in zip(pairs, in_range) if ok]
    col = {n: _column(scored, n) for n in ("d_long_gt", "d_y_est", "d_lat_gt", "d_x_est", "v_long_gt",
                                           "v_y_est", "v_lat_gt", "v_x_est", "d_y_std")}
    distance = algo.error_stats(col["d_y_est"], col["d_long_gt"], relative=True, unit="_m")
    distance["by_range"] = algo.binned_error_stats(col["d_y_est"], col["d_long_gt"], col["d_long_gt"])
    distance["by_span"] = algo.binned_error_stats(col["d_y_est"], col["d_long_gt"], col["d_long_gt"],
                                                  bins=algo.TARGET_SPANS)
    distance.update(algo.interval_stats(col["d_y_est"], col["d_y_std"], col["d_long_gt"]))
    for name, (lo, hi) in algo.TARGET_SPANS.items():
        sel = (col["d_long_gt"] >= lo) & (col["d_long_gt"] < hi)
        distance["by_span"][name].update(algo.interval_stats(col["d_y_est"][sel], col["d_y_std"][sel],
                                                             col["d_long_gt"][sel]))
    lateral = algo.error_stats(col["d_x_est"], col["d_lat_gt"], relative=False, unit="_m")
    velocity = algo.error_stats(col["v_y_est"], col["v_long_gt"], relative=False, unit="_mps")
    velocity["lateral"] = algo.error_stats(col["v_x_est"], col["v_lat_gt"], relative=False, unit="_mps")

    ttc_est, ttc_gt = _column(pairs, "ttc_est"), _column(pairs, "ttc_gt")
    ttc = {"warning": algo.warning_classification(ttc_est, ttc_gt, cfg.warning_threshold_s)}
    both = algo.error_stats(ttc_est, ttc_gt, relative=False, unit="_s")  # pairs where both have a TTC
    ttc.update({k: v for k, v in both.items()})
    return {"distance": distance, "lateral": lateral, "rel_velocity": velocity, "ttc": ttc,
            "pairs": {"matched_counted": len(pairs), "in_range": len(scored),
                      "with_state": int(np.isfinite(col["d_y_est"]).sum())}}


def frame_warning_metrics(truths: Sequence[FrameTruth], results: Sequence[FrameResult], cfg: EvalConfig) -> dict:
    """Scene-level warnings: does the frame contain any TTC below the threshold?"""
    thr = cfg.warning_threshold_s
    est = [bool(algo.warnings_from_ttc(list(r.risk.ttc.values()), thr).any()) for r in results]
    gt = []
    for tr in truths:
        objs = [o for o, c in zip(tr.objects, counted_mask(tr.objects, cfg)) if c]
        gt.append(bool(algo.warnings_from_ttc([o.ttc for o in objs], thr).any()))
    est_a, gt_a = np.array(est, dtype=bool), np.array(gt, dtype=bool)
    return algo.precision_recall(int((est_a & gt_a).sum()), int(est_a.sum()), int(gt_a.sum()))


def detection_tracking_metrics(truths: Sequence[FrameTruth], results: Sequence[FrameResult],
                               cfg: EvalConfig, camera: CameraModel | None = None,
                               tracking: bool = True) -> tuple[dict, dict]:
    """Detection precision/recall at ``min_iou`` and motmetrics tracking metrics.

    ``tracking=False`` (independent images, e.g. a KITTI object dataset): every tracking value is null.
    ``tracking.by_range`` (with a camera): the CLEAR MOT and identity metrics of each range bin alone
    (:func:`range_bins_of`); null without a camera, which places unmatched tracks.
    """
    mot = MotScorer(cfg.min_iou) if tracking else None
    bins = {name: MotScorer(cfg.min_iou, hota=False) for name in algo.RANGE_BINS} \
        if tracking and camera is not None else {}
    tp = n_pred = n_true = 0
    for truth, res in zip(truths, results):
        objs = truth.objects
        counted = counted_mask(objs, cfg)
        gt_boxes = as_boxes([o.box for o in objs])
        det_boxes = as_boxes([d.box for d in res.detections])
        kept, ignored = split_ignored(gt_boxes, counted, det_boxes, cfg.min_iou, cfg.ignore_cover,
                                      out_of_range(det_boxes, camera, cfg.max_range_m))
        tp += len(kept)
        n_pred += int((~ignored).sum())
        n_true += int(counted.sum())
        if mot is None:
            continue
        gt_ids, tr_ids = [o.id for o in objs], [t.id for t in res.tracks]
        tr_boxes = as_boxes([t.box for t in res.tracks])
        split = mot.update(gt_ids, gt_boxes, counted, tr_ids, tr_boxes, frame=truth.frame,
                           ignore_cover=cfg.ignore_cover, track_out_of_range=out_of_range(tr_boxes, camera, cfg.max_range_m))
        if bins:
            gt_bin, tr_bin = range_bins_of(objs, counted, tr_boxes, camera, split)
            for name, scorer in bins.items():
                g, e = gt_bin == name, tr_bin == name
                scorer.add([i for i, k in zip(gt_ids, g) if k], gt_boxes[g], [i for i, k in zip(tr_ids, e) if k],
                           tr_boxes[e], frame=truth.frame)
    detection = algo.precision_recall(tp, n_pred, n_true)
    detection["min_iou"] = cfg.min_iou
    if mot is None:
        return detection, dict.fromkeys(TRACKING_KEYS)
    m = _finite(mot.compute())
    tracking = {"mota": m["mota"], "motp": m["motp"], "idf1": m["idf1"], "idp": m["idp"], "idr": m["idr"],
                **_counts(m),
                "unique_objects": int(m["num_unique_objects"]), "fragmentations": int(m["num_fragmentations"]),
                "mostly_tracked": int(m["mostly_tracked"]), "partially_tracked": int(m["partially_tracked"]),
                "mostly_lost": int(m["mostly_lost"]), "precision": m["precision"], "recall": m["recall"]}
    h = mot.hota_result()
    nothing = not (h.tp + h.fn + h.fp).any()     # no counted object and no track: null, as MOTA (TrackEval says 0)
    tracking.update({k: NAN if nothing else v for k, v in h.summary().items() if k in ("hota", "deta", "assa", "loca")})
    tracking["hota_by_alpha"] = h.to_dict()      # per-threshold statistics: sequences combine exactly (hota.combine)
    tracking["by_range"] = {name: {"mota": b["mota"], "idf1": b["idf1"], "idr": b["idr"], **_counts(b)}
                            for name, b in ((n, _finite(s.compute(BIN_METRICS))) for n, s in bins.items())} \
        if bins else None
    return detection, tracking


def range_bins_of(objects: Sequence[ObjectTruth], counted: np.ndarray, tr_boxes: np.ndarray, camera: CameraModel,
                  split: tuple[list[tuple[int, int, float]], np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """The range bin (:data:`algo.RANGE_BINS` label, None: no bin) of each object and each track of a frame.

    A counted object is in the bin of its true ``d_long``. A track matched (IoU >= ``min_iou``) to a
    counted object is in that object's bin; any other track the whole-run scoring keeps is in the bin
    of its own claim, the ground range of its bottom edge (nuScenes' per-distance convention:
    a false positive is a vehicle claimed at that range). Tracks the whole run sets aside are in no bin.
    ``split``: the whole run's (matches, set-aside mask) of the frame (:meth:`MotScorer.update`).
    So each counted object, miss and false positive of the run falls in one bin.
    """
    gt_bin = algo.bin_labels([o.d_long for o in objects])
    gt_bin[~np.asarray(counted, dtype=bool)] = None
    tr_bin = algo.bin_labels(ground_range(tr_boxes, camera))
    kept, set_aside = split
    for g, e, _ in kept:
        tr_bin[e] = gt_bin[g]
    tr_bin[set_aside] = None
    return gt_bin, tr_bin


def _finite(m: Mapping[str, float]) -> dict[str, float]:
    """Undefined ratios (e.g. MOTA with no counted object is -inf in motmetrics) become nan -> null."""
    return {k: (v if np.isfinite(v) else NAN) for k, v in m.items()}


def _counts(m: Mapping[str, float]) -> dict[str, int]:
    return {"id_switches": int(m["num_switches"]), "false_positives": int(m["num_false_positives"]),
            "misses": int(m["num_misses"]), "objects": int(m["num_objects"])}


def runtime_metrics(results: Sequence[FrameResult], wall_time_s: float | None) -> tuple[dict, float]:
    """Mean (and p90) per-frame time of each stage (ms) and frames per second of wall time."""
    keys = list(STAGES) + sorted({k for r in results for k in r.timings_ms} - set(STAGES))
    rt: dict[str, Any] = {}
    p90: dict[str, float] = {}
    for k in keys:
        x = np.array([r.timings_ms[k] for r in results if k in r.timings_ms], dtype=float)
        rt[k] = float(x.mean()) if x.size else NAN
        p90[k] = float(np.percentile(x, 90)) if x.size else NAN
    rt["p90"] = p90
    fps = len(results) / wall_time_s if wall_time_s and wall_time_s > 0 else NAN
    return rt, fps


def evaluate(truths: Sequence[FrameTruth], results: Sequence[FrameResult], cfg: EvalConfig = EvalConfig(),
             wall_time_s: float | None = None, run_info: Mapping | None = None,
             camera: CameraModel | None = None, baseline_risk: Sequence[RiskEstimate] | None = None,
             ego_speed_method: str | None = None, fcw_threshold_s: float | None = None,
             tracking: bool = True) -> tuple[dict, list[ObjectRecord]]:
    """Score a run. ``truths[i]`` and ``results[i]`` must describe the same frame.

    ``camera`` (the one that rendered the frames) enables the range filter on predictions.
    ``baseline_risk``: the 1/TTC estimator's output on the same frames (``risk.baseline_ttc``).
    ``ego_speed_method``: name of the ego-speed stage (None: the run has none).
    ``fcw_threshold_s``: the warning stage's TTC threshold, which defines a truth conflict
    for ``warning.*`` (:mod:`harness.scoring.warnings`); None: ``cfg.warning_threshold_s``.
    ``tracking=False``: the frames are independent images, ``tracking.*`` is all null.

    Returns ``(metrics, records)``; ``metrics`` is JSON-ready after :func:`monorarp.app.io.to_jsonable`.
    """
    if len(truths) != len(results):
        raise ValueError(f"{len(truths)} truths but {len(results)} results")
    for tr, res in zip(truths, results):
        if tr.frame != res.index:
            raise ValueError(f"truth frame {tr.frame} paired with result frame {res.index}")
    records = [r for tr, res in zip(truths, results) for r in frame_records(tr, res, cfg, camera)]
    sm = state_metrics(records, cfg)
    sm["ttc"]["frame_warning"] = frame_warning_metrics(truths, results, cfg)
    detection, tracking = detection_tracking_metrics(truths, results, cfg, camera, tracking)
    runtime, fps = runtime_metrics(results, wall_time_s)
    metrics = {
        "frames": len(results),
        **{k: sm[k] for k in ("distance", "lateral", "rel_velocity", "ttc")},
        "tracking": tracking,
        "detection": detection,
        "lane_speed": lane_speed_metrics(truths, results, ego_speed_method),
        "risk": risk_metrics(truths, results, cfg, baseline_risk),
        "warning": warning_metrics(truths, results, fcw_threshold_s or cfg.warning_threshold_s, cfg.min_iou),
        "runtime_ms": runtime,
        "fps": fps,
        "wall_time_s": NAN if wall_time_s is None else float(wall_time_s),
        "counts": {"gt_object_frames": sum(len(t.objects) for t in truths),
                   "counted_object_frames": int(sum(r.counted for r in records if r.gt_id is not None)),
                   "track_frames": sum(len(r.tracks) for r in results),
                   "detections": sum(len(r.detections) for r in results), **sm["pairs"]},
        "scoring": {**asdict(cfg), "range_filter_on_predictions": camera is not None},
        "config": dict(run_info or {}),
    }
    horizon = horizon_metrics(truths, results, camera)
    if horizon is not None:
        metrics["horizon"] = horizon
    return metrics, records


def horizon_metrics(truths: Sequence[FrameTruth], results: Sequence[FrameResult],
                    camera: CameraModel | None) -> dict | None:
    """The horizon stage's row against the true horizon row of each frame (None without a stage).

    True row: the truth's ``camera.horizon_row`` (a moving camera) or the calibration's.
    ``abs_err_*_px`` over all frames; ``coverage_90``: share of frames whose true row lies in
    ``row +- 1.645 std_px``; ``sources``: frames per reading source; ``calibrated_abs_err_*_px``:
    the calibrated row's error on the same frames (what the stage improves on).
    """
    if not results or all(r.horizon is None for r in results):
        return None
    est, std, true, nominal, sources = [], [], [], [], {}
    for tr, r in zip(truths, results):
        if r.horizon is None:
            continue
        cam_true = tr.camera.horizon_row if tr.camera is not None else None
        if cam_true is None and camera is None:
            continue
        true.append(float(cam_true) if cam_true is not None else camera.horizon_row)
        nominal.append(camera.horizon_row if camera is not None else np.nan)
        est.append(r.horizon.row)
        std.append(r.horizon.std_px)
        sources[r.horizon.source] = sources.get(r.horizon.source, 0) + 1
    est, std, true, nominal = map(np.asarray, (est, std, true, nominal))
    err = np.abs(est - true)
    out = {"count": int(err.size), **algo.summary(err, "abs_err_", "_px"),
           **algo.summary(np.abs(nominal - true), "calibrated_abs_err_", "_px"),
           "coverage_90": float(np.mean(err <= algo.Z90 * std)) if err.size else NAN,
           "std_median_px": float(np.median(std)) if std.size else NAN, "sources": sources}
    return out


# ------------------------------------------------------------------------ lane speed, risk
def lane_speed_metrics(truths: Sequence[FrameTruth], results: Sequence[FrameResult], method: str | None) -> dict:
    """Ego-speed estimate (m/s) against the truth's ``ego.speed`` (see the module docstring)."""
    est = np.array([NAN if r.ego_speed is None else float(r.ego_speed) for r in results], dtype=float)
    gt = np.array([t.ego.speed for t in truths], dtype=float)
    out: dict[str, Any] = {"method": method}
    out.update(algo.error_stats(est, gt, relative=True, unit="_mps"))
    n_valid = int(np.isfinite(est).sum())
    out["valid_fraction"] = algo.ratio(n_valid, len(results)) if method is not None else NAN
    out["frames_with_estimate"] = n_valid
    return out


def risk_event(truth: FrameTruth, near_miss_ttc_s: float) -> bool:
    """Collision (ego's or a visible vehicle's ``crashed`` flag) or near miss (a visible vehicle's TTC < threshold)."""
    if truth.ego.crashed:
        return True
    return any(o.crashed or (o.ttc is not None and o.ttc < near_miss_ttc_s) for o in truth.objects)


def horizon_frames(truths: Sequence[FrameTruth], horizon_s: float) -> int:
    """The label window in frames: ``round(horizon_s / dt)`` with dt the median frame interval."""
    t = np.array([tr.t for tr in truths], dtype=float)
    if t.size < 2:
        return 1 << 30                        # one frame: no window fits, only positives are labelled
    dt = float(np.median(np.diff(t)))
    return int(round(horizon_s / dt)) if dt > 0 else 1 << 30


def risk_labels(truths: Sequence[FrameTruth], cfg: EvalConfig) -> tuple[np.ndarray, np.ndarray]:
    """(events, labels) per frame: bool events and float labels (nan = excluded; see the module docstring)."""
    events = np.array([risk_event(t, cfg.near_miss_ttc_s) for t in truths], dtype=bool)
    return events, algo.horizon_labels(events, horizon_frames(truths, cfg.risk_horizon_s))


def risk_probability(estimates: Sequence[RiskEstimate], near_miss_ttc_s: float) -> np.ndarray:
    """Each risk as a probability: as is for ``kind == "probability"``, else 1/TTC mapped (module docstring)."""
    return np.array([min(max(e.risk, 0.0), 1.0) if e.kind == "probability"
                     else float(algo.inverse_ttc_probability(e.risk, near_miss_ttc_s)) for e in estimates],
                    dtype=float)


def _risk_scores(estimates: Sequence[RiskEstimate], labels: np.ndarray, near_miss_ttc_s: float) -> dict:
    ok = np.isfinite(labels)
    y = labels[ok].astype(bool)
    score = np.array([e.risk for e in estimates], dtype=float)[ok]
    prob = risk_probability(estimates, near_miss_ttc_s)[ok]
    kinds = sorted({e.kind for e in estimates})
    return {"kind": kinds[0] if len(kinds) == 1 else kinds, "auroc": algo.auroc(score, y),
            "brier": algo.brier(prob, y)}


def risk_metrics(truths: Sequence[FrameTruth], results: Sequence[FrameResult], cfg: EvalConfig,
                 baseline: Sequence[RiskEstimate] | None = None) -> dict:
    """``risk.*`` of ``metrics.json``: AUROC and Brier score against the horizon labels."""
    events, labels = risk_labels(truths, cfg)
    ok = np.isfinite(labels)
    out: dict[str, Any] = _risk_scores([r.risk for r in results], labels, cfg.near_miss_ttc_s)
    out.update({"horizon_s": cfg.risk_horizon_s, "near_miss_ttc_s": cfg.near_miss_ttc_s,
                "inverse_ttc_probability": f"min(1, risk * {cfg.near_miss_ttc_s:g} s)",
                "frames_scored": int(ok.sum()), "positives": int((labels[ok] == 1).sum()),
                "negatives": int((labels[ok] == 0).sum()), "excluded_past_end": int((~ok).sum()),
                "event_frames": int(events.sum())})
    if baseline is not None:
        if len(baseline) != len(results):
            raise ValueError(f"{len(baseline)} baseline risks for {len(results)} frames")
        out["baseline_ttc"] = _risk_scores(list(baseline), labels, cfg.near_miss_ttc_s)
    return out


FRAME_COLUMNS = ("frame", "t", "ego_speed_est", "ego_speed_gt", "risk", "risk_kind", "risk_probability",
                 "baseline_ttc_risk", "fcw_ttc_risk", "manoeuvre_ttc_risk", "risk_event", "risk_label",
                 "warning_active", "warning_track", "warning_ttc", "ego_crashed", "true_min_ttc")


def frame_rows(truths: Sequence[FrameTruth], results: Sequence[FrameResult], cfg: EvalConfig,
               baseline: Sequence[RiskEstimate] | None = None, fcw_risk: Sequence[float] | None = None,
               manoeuvre_risk: Sequence[float] | None = None) -> list[dict]:
    """One row per frame (``per_frame.csv``): ego speed estimate/truth (m/s), risk, its label (nan = excluded),
    the warning decision (active, track, its TTC) and the truth's crash flag and lowest TTC (s)."""
    events, labels = risk_labels(truths, cfg)
    prob = risk_probability([r.risk for r in results], cfg.near_miss_ttc_s)
    rows = []
    for k, (tr, res) in enumerate(zip(truths, results)):
        rows.append({"frame": res.index, "t": res.t,
                     "ego_speed_est": NAN if res.ego_speed is None else float(res.ego_speed),
                     "ego_speed_gt": tr.ego.speed, "risk": float(res.risk.risk),
                     "risk_kind": res.risk.kind, "risk_probability": float(prob[k]),
                     "baseline_ttc_risk": NAN if baseline is None else float(baseline[k].risk),
                     "fcw_ttc_risk": NAN if fcw_risk is None else float(fcw_risk[k]),
                     "manoeuvre_ttc_risk": NAN if manoeuvre_risk is None else float(manoeuvre_risk[k]),
                     "risk_event": bool(events[k]), "risk_label": labels[k],
                     "warning_active": bool(res.warning.active), "warning_track": res.warning.track_id,
                     "warning_ttc": _f(res.warning.ttc), "ego_crashed": tr.ego.crashed,
                     "true_min_ttc": _f(tr.min_ttc)})
    return rows


def write_frame_csv(rows: Sequence[Mapping], path: str | Path) -> None:
    """Write :func:`frame_rows` as CSV (empty cell = missing / NaN / excluded)."""
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(FRAME_COLUMNS)
        for r in rows:
            w.writerow([_cell(int(r[c]) if c == "risk_label" and np.isfinite(r[c]) else r[c])
                        for c in FRAME_COLUMNS])


def write_metrics(metrics: Mapping, path: str | Path) -> None:
    """Strict JSON (NaN -> null), written atomically."""
    write_json_atomic(path, metrics, indent=2)
