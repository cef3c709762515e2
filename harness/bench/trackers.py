"""Tracker benchmark: the paper's Table III (tracker runtime) with tracking accuracy added.

Every tracker sees identical frames and identical detections:

1. each scenario is simulated and rendered once (:func:`harness.run.frame_feed.rendered_frames`), or read
   from the frame cache (:mod:`harness.run.frame_cache`, shared with ``monorarp sweep``) when an
   earlier benchmark or sweep rendered the same instance; its frames (made read-only) and
   ground truths are kept in memory;
2. the detector runs once per frame; its detections and its time are cached;
3. each tracker then runs over the cached frames and detections, followed by
   the same state estimator and risk estimator (fresh instances per tracker),
   and the run is scored by :func:`harness.scoring.evaluate.evaluate`.

Per tracker: tracker-only ms per frame (mean, p95; ``time.perf_counter``),
the shared detector ms, MOTA, IDF1, ID switches (motmetrics, pooled over the
scenarios) and the downstream distance error (median relative |d_y - d_long| /
d_long of counted matched object-frames within 0-80 m, pooled the same way).
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from harness.bench.defaults import DEFAULT_FRAMES, DEFAULT_TRACKERS, default_scenarios
from harness.world.scenario import Scenario, frames_to_simulate, load_scenario
from harness.scoring.bootstrap import SequenceCounts, tracker_intervals
from harness.scoring.evaluate import EvalConfig, evaluate
from harness.scoring.records import ObjectRecord
from harness.scoring.state_errors import state_metrics
from harness.world.truth import FrameTruth
from monorarp.core.camera import CameraModel
from monorarp.core.errors import UserError
from monorarp.pipeline.config import ComponentConfig, PipelineConfig, check_weak_detections
from monorarp.pipeline.runner import tracker_input
from monorarp.pipeline.registry import build, get_factory, uses
from monorarp.core.types import Detection, Frame, FrameResult, strong

if TYPE_CHECKING:
    from harness.run.frame_cache import FrameCache

JSON_NAME, MD_NAME = "trackers.json", "trackers.md"
OUTPUT_NAMES = (JSON_NAME, MD_NAME)
#: The paper's Table III (s per frame): KCF alone; FasterRCNN detector + particle tracker.
PAPER_TABLE_III_S = {"kcf": 0.5010, "detector": 0.1319, "particle": 0.0050}


class BenchError(UserError, ValueError):
    """A benchmark request that cannot be run (no trackers, no scenarios, bad frame count)."""


# ------------------------------------------------------------------------------------ inputs
@dataclass
class CachedSequence:
    """One scenario rendered and detected once: what every tracker is given."""

    name: str
    camera: CameraModel
    frames: list[Frame]
    truths: list[FrameTruth]
    detections: list[tuple[Detection, ...]]
    detector_ms: np.ndarray


def check_trackers(names: Sequence[str]) -> list[str]:
    """The tracker names, each checked against the registry (raises ``UnknownComponentError``)."""
    names = [n.strip() for n in names if n.strip()]
    if not names:
        raise BenchError("no trackers given")
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise BenchError(f"tracker listed twice: {', '.join(dup)}")
    for n in names:
        get_factory("tracker", n)
    return names


def cache_sequence(scenario: Scenario, detector: Any, n_frames: int, name: str | None = None,
                   log: Callable[[str], None] | None = None, cache: FrameCache | None = None) -> CachedSequence:
    """Render ``n_frames`` of ``scenario`` (or read them from ``cache``) and run ``detector`` once on each
    frame (timed)."""
    from harness.run.frame_feed import rendered_frames

    if hasattr(detector, "reset"):
        detector.reset()
    set_truth = getattr(detector, "set_truth", None)       # the oracle detector reads the truth
    weak = uses(detector, "weak_detections")               # kept; each tracker gets what it takes (tracker_input)
    frames, truths, dets, ms = [], [], [], []
    source = rendered_frames(scenario, n_frames) if cache is None else cache.frames(scenario, n_frames)
    how = "rendered" if cache is None or cache.last == "rendered" else "read from the frame cache"
    for frame, truth in source:
        frame.image.setflags(write=False)                  # no tracker may alter what the next one sees
        if set_truth is not None:
            set_truth(truth, frame.image)
        t0 = time.perf_counter()
        d = tuple(detector.detect(frame.image, weak=True) if weak else detector.detect(frame.image))
        ms.append((time.perf_counter() - t0) * 1e3)
        frames.append(frame)
        truths.append(truth)
        dets.append(d)
    if log:
        log(f"{name or scenario.name}: {len(frames)} frames {how}, detector {np.mean(ms) if ms else float('nan'):.2f} ms/frame")
    return CachedSequence(name=name or scenario.name, camera=scenario.camera.model(), frames=frames,
                          truths=truths, detections=dets, detector_ms=np.asarray(ms, dtype=float))


# ------------------------------------------------------------------------------------- one run
@dataclass
class TrackerRun:
    """One tracker over one cached sequence."""

    metrics: dict
    records: list[ObjectRecord]
    tracker_ms: np.ndarray


def run_tracker(seq: CachedSequence, tracker: ComponentConfig, state: ComponentConfig, risk: ComponentConfig,
                eval_config: EvalConfig = EvalConfig()) -> TrackerRun:
    """Run ``tracker`` + ``state`` + ``risk`` (fresh instances) over the cached frames and detections; score."""
    trk = build("tracker", tracker.name, tracker.kwargs, seq.camera)
    est = build("state", state.name, state.kwargs, seq.camera)
    rsk = build("risk", risk.name, risk.kwargs, seq.camera)
    results: list[FrameResult] = []
    tracker_ms = np.empty(len(seq.frames))
    for k, (frame, dets, det_ms) in enumerate(zip(seq.frames, seq.detections, seq.detector_ms)):
        t0 = time.perf_counter()
        tracks = list(trk.update(frame.image, tracker_input(trk, list(dets)), frame.t))
        t1 = time.perf_counter()
        states = dict(est.update(tracks, frame.t))
        t2 = time.perf_counter()
        risk_est = rsk.assess(states, frame.t)
        t3 = time.perf_counter()
        tracker_ms[k] = (t1 - t0) * 1e3
        results.append(FrameResult(index=frame.index, t=frame.t, detections=strong(dets), tracks=tracks, states=states,
                                   risk=risk_est, timings_ms={"detector": float(det_ms), "tracker": tracker_ms[k],
                                                              "state": (t2 - t1) * 1e3, "risk": (t3 - t2) * 1e3}))
    for r in results:
        r.timings_ms["total"] = sum(r.timings_ms.values())
    metrics, records = evaluate(seq.truths, results, eval_config, camera=seq.camera,
                                run_info={"scenario": seq.name, "components": {"tracker": tracker.name}})
    return TrackerRun(metrics=metrics, records=records, tracker_ms=tracker_ms)


# ------------------------------------------------------------------------------- aggregation
def pooled_tracking(tracking: Sequence[Mapping]) -> dict[str, float | int]:
    """MOTA, IDF1 and ID switches over several sequences from their per-sequence counts.

    As motmetrics' "OVERALL" row: MOTA = 1 - (misses + FP + switches) / objects;
    IDF1 = 2 IDTP / (objects + predictions), with IDTP = IDR x objects and
    predictions = matches + FP = objects - misses + FP (each sequence's
    ``tracking`` section of ``metrics.json``; :class:`~harness.scoring.bootstrap.SequenceCounts`
    with every sequence counted once). HOTA, DetA and AssA are pooled as TrackEval
    combines sequences (:func:`harness.scoring.hota.combine`) from each section's
    ``hota_by_alpha``; NaN when a section lacks it.
    """
    from harness.scoring.hota import HotaResult, combine

    obj = sum(int(t["objects"]) for t in tracking)
    fp = sum(int(t["false_positives"]) for t in tracking)
    miss = sum(int(t["misses"]) for t in tracking)
    sw = sum(int(t["id_switches"]) for t in tracking)
    counts, every_once = SequenceCounts.from_tracking(tracking), np.ones((1, len(tracking)))
    nan = float("nan")
    hota = {"hota": nan, "deta": nan, "assa": nan}
    if tracking and all(t.get("hota_by_alpha") for t in tracking):
        pooled = combine([HotaResult.from_dict(t["hota_by_alpha"]) for t in tracking])
        if (pooled.tp + pooled.fn + pooled.fp).any():
            hota = {k: v for k, v in pooled.summary().items() if k in hota}
    return {"mota": float(counts.mota(every_once)[0]), "idf1": float(counts.idf1(every_once)[0]),
            **hota, "id_switches": sw, "false_positives": fp, "misses": miss, "objects": obj}


def _ms_stats(x: np.ndarray) -> dict[str, float]:
    return {"mean": float(np.mean(x)) if x.size else float("nan"),
            "p95": float(np.percentile(x, 95)) if x.size else float("nan")}


def _summary(runs: Sequence[TrackerRun], detector_ms: np.ndarray) -> dict:
    tr_ms = np.concatenate([r.tracker_ms for r in runs]) if runs else np.empty(0)
    dist = state_metrics([rec for r in runs for rec in r.records])["distance"]
    return {"tracker_ms": _ms_stats(tr_ms), "detector_ms": _ms_stats(detector_ms),
            **pooled_tracking([r.metrics["tracking"] for r in runs]),
            "distance_rel_err_median": dist["rel_err_median"], "distance_abs_err_median_m": dist["abs_err_median_m"],
            "distance_pairs": dist["count"],
            "tracks_per_frame": (sum(r.metrics["counts"]["track_frames"] for r in runs) / max(1, tr_ms.size)),
            "by_range": pooled_by_range([r.metrics["tracking"] for r in runs])}


def pooled_by_range(tracking: Sequence[Mapping]) -> dict | None:
    """:func:`pooled_tracking` of each range bin (``tracking.by_range``); None when a section lacks it."""
    if not tracking or not all(t.get("by_range") for t in tracking):
        return None
    keep = ("mota", "idf1", "id_switches", "false_positives", "misses", "objects")
    return {name: {k: v for k, v in pooled_tracking([t["by_range"][name] for t in tracking]).items() if k in keep}
            for name in tracking[0]["by_range"]}


# ------------------------------------------------------------------------------------ the bench
@dataclass
class BenchConfig:
    #: scenario files (relative: to the current directory); default: the shipped ones, from any directory
    scenarios: Sequence[str | Path] = field(default_factory=default_scenarios)
    trackers: Sequence[str] = DEFAULT_TRACKERS
    frames: int | None = DEFAULT_FRAMES    # per scenario, capped at its duration x fps; None: the whole scenario
    #: False: a scenario shorter than ``frames`` is refused instead of capped (the command line's ``--frames N``)
    cap_frames: bool = True
    #: run each scenario at each of these seeds (one sequence per scenario and seed); None: its own seed
    seeds: Sequence[int] | None = None
    #: the detector, state and risk stages every tracker shares (its tracker stage is replaced by each of ``trackers``)
    pipeline: PipelineConfig = field(default_factory=PipelineConfig)
    eval: EvalConfig = EvalConfig()
    #: frame cache (harness.run.frame_cache), or a callable giving it once the inputs are checked; None: render
    cache: FrameCache | Callable[[], FrameCache | None] | None = None
    #: applied to every scenario as loaded (e.g. the command line's ``--look``); None: as written
    adjust: Callable[[Scenario], Scenario] | None = None


def _load_scenarios(paths: Sequence[str | Path], seeds: Sequence[int] | None = None,
                    exact_frames: int | None = None,
                    adjust: Callable[[Scenario], Scenario] | None = None) -> list[tuple[str, Scenario]]:
    """(unique name, scenario) of every sequence: each scenario as written, or at each of ``seeds``
    (named ``"<name> seed <s>"``). A file listed twice is refused (it would count its sequences twice),
    and with ``exact_frames`` a scenario shorter than that."""
    if not paths:
        raise BenchError("no scenarios given")
    if seeds is not None and (not len(seeds) or any(int(s) != s or s < 0 for s in seeds)):
        raise BenchError(f"seeds must be non-negative integers, got {list(seeds)}")
    files = [(p, Path(p).resolve()) for p in paths if not isinstance(p, Scenario)]
    dup = next((str(p) for p, f in files if [g for _, g in files].count(f) > 1), None)
    if dup is not None:
        raise BenchError(f"scenario listed twice: {dup}")
    out: list[tuple[str, Scenario]] = []
    for p in paths:
        base = p if isinstance(p, Scenario) else load_scenario(p)
        base = base if adjust is None else adjust(base)
        if exact_frames is not None:
            frames_to_simulate(base, exact_frames, p if not isinstance(p, Scenario) else base.name, "benchmark")
        variants = [(base.name, base)] if seeds is None else \
            [(f"{base.name} seed {s}", base.model_copy(update={"seed": int(s)})) for s in seeds]
        for label, sc in variants:
            name, k = label, 2
            while name in {n for n, _ in out}:
                name, k = f"{label}#{k}", k + 1
            out.append((name, sc))
    return out


def bench_trackers(config: BenchConfig = BenchConfig(), log: Callable[[str], None] | None = None) -> dict:
    """Run the benchmark; returns the JSON-ready result (NaN kept; see :func:`write_outputs`).

    Every tracker name, every scenario and the detector are checked before anything is rendered.
    """
    trackers = check_trackers(config.trackers)
    if config.frames is not None and config.frames <= 0:
        raise BenchError(f"frames must be a positive integer, got {config.frames}")
    scenarios = _load_scenarios(config.scenarios, config.seeds, None if config.cap_frames else config.frames,
                                config.adjust)
    from monorarp.pipeline.detectors import build_detector

    check_weak_detections(config.pipeline.detector, trackers, "--weak-detections")
    cfg = config.pipeline.validate_names()
    detectors = [build_detector(cfg.detector, sc.camera.model()) for _, sc in scenarios]
    cache = config.cache() if callable(config.cache) else config.cache

    per_tracker: dict[str, list[TrackerRun]] = {t: [] for t in trackers}
    per_scenario: dict[str, dict] = {}
    det_ms: list[np.ndarray] = []
    for (name, sc), detector in zip(scenarios, detectors):
        n = sc.n_frames if config.frames is None else min(int(config.frames), sc.n_frames)
        seq = cache_sequence(sc, detector, n, name=name, log=log, cache=cache)
        det_ms.append(seq.detector_ms)
        per_scenario[name] = {"frames": len(seq.frames), "detector_ms": _ms_stats(seq.detector_ms),
                              "detections": int(sum(len(d) for d in seq.detections)), "trackers": {}}
        for t in trackers:
            run = run_tracker(seq, ComponentConfig(name=t), cfg.state, cfg.risk, config.eval)
            per_tracker[t].append(run)
            per_scenario[name]["trackers"][t] = _summary([run], seq.detector_ms)
            if log:
                s = per_scenario[name]["trackers"][t]
                log(f"  {t:<11} {s['tracker_ms']['mean']:8.2f} ms  MOTA {s['mota']:.3f}  IDF1 {s['idf1']:.3f}  HOTA {s['hota']:.3f}")
        del seq
    all_det_ms = np.concatenate(det_ms) if det_ms else np.empty(0)
    return {
        "config": {"scenarios": [str(p) for p in config.scenarios], "scenario_names": [n for n, _ in scenarios],
                   "seeds": None if config.seeds is None else [int(s) for s in config.seeds],
                   "frames_per_scenario": {n: v["frames"] for n, v in per_scenario.items()},
                   "detector": cfg.detector.model_dump(), "trackers": trackers,
                   "state": cfg.state.model_dump(), "risk": cfg.risk.model_dump(), "scoring": asdict(config.eval)},
        "detector_ms": _ms_stats(all_det_ms),
        "trackers": {t: _summary(per_tracker[t], all_det_ms) for t in trackers},
        "per_scenario": per_scenario,
        "bootstrap": sequence_bootstrap(per_tracker),
        "paper_table_iii_s": PAPER_TABLE_III_S,
    }


#: Fewer sequences than this get no interval: a bootstrap of 2-4 sequences has too few distinct draws to mean much.
MIN_BOOTSTRAP_SEQUENCES = 5


def sequence_bootstrap(per_tracker: Mapping[str, Sequence[TrackerRun]]) -> dict | None:
    """95 % sequence-bootstrap intervals of each tracker's pooled MOTA and IDF1, and of its difference from the
    first tracker, from the same draws (:mod:`harness.scoring.bootstrap`); None with fewer than
    :data:`MIN_BOOTSTRAP_SEQUENCES` sequences."""
    if not per_tracker or len(next(iter(per_tracker.values()))) < MIN_BOOTSTRAP_SEQUENCES:
        return None
    counts = {t: SequenceCounts.from_tracking([r.metrics["tracking"] for r in runs]) for t, runs in per_tracker.items()}
    return tracker_intervals(counts, reference=next(iter(per_tracker)))


# --------------------------------------------------------------------------------------- tables
def _f(v, fmt: str) -> str:
    return "-" if v is None or v != v else fmt.format(v)


def table_iii(result: Mapping) -> str:
    """The paper's Table III with accuracy added, as a Markdown table (also readable as plain text)."""
    head = ("| Tracker | tracker ms/frame (mean) | tracker ms (p95) | detector ms/frame | detector + tracker (s) "
            "| MOTA | IDF1 | HOTA | ID switches | distance error (median) | tracks/frame |")
    lines = ["TABLE III: Tracker runtime and accuracy (identical frames and detections)", "", head,
             "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for name, s in result["trackers"].items():
        tm, dm = s["tracker_ms"]["mean"], s["detector_ms"]["mean"]
        total = None if tm is None or dm is None else (tm + dm) / 1e3
        lines.append(f"| {name} | {_f(tm, '{:.3f}')} | {_f(s['tracker_ms']['p95'], '{:.3f}')} | {_f(dm, '{:.3f}')} "
                     f"| {_f(total, '{:.4f}')} | {_f(s['mota'], '{:.3f}')} | {_f(s['idf1'], '{:.3f}')} "
                     f"| {_f(s.get('hota'), '{:.3f}')} | {s['id_switches']} | {_f(None if s['distance_rel_err_median'] is None else 100 * s['distance_rel_err_median'], '{:.2f} %')} "
                     f"| {_f(s.get('tracks_per_frame'), '{:.1f}')} |")
    p = result.get("paper_table_iii_s", PAPER_TABLE_III_S)
    cfg = result["config"]
    per_seq = cfg["frames_per_scenario"]
    lo, hi = min(per_seq.values()), max(per_seq.values())
    frames = (", ".join(f"{n}: {k}" for n, k in per_seq.items()) if len(per_seq) <= 4 else
              f"{len(per_seq)} sequences of {lo if lo == hi else f'{lo}-{hi}'} frames")
    if cfg.get("seeds"):
        frames += f" (each scenario at seeds {', '.join(map(str, cfg['seeds']))})"
    lines += ["", f"Paper (FasterRCNN, GTX 1070, 1080p): KCF tracker {p['kcf']:.4f} s; object detector + particle "
                  f"tracker {p['detector']:.4f} + {p['particle']:.4f} s. No accuracy: the paper had no ground truth.",
              f"Detector: {cfg['detector']['name']}; frames: {frames}. MOTA/IDF1/ID switches: motmetrics, IoU >= "
              f"{cfg['scoring']['min_iou']:g}; HOTA: mean over IoU thresholds 0.05..0.95 (TrackEval's); all pooled "
              f"over scenarios. Distance error: median |d_y - d_long| / d_long "
              f"({cfg['state']['name']} state estimator) over matched counted objects within 0-80 m."]
    ranged = {name: s["by_range"] for name, s in result["trackers"].items() if s.get("by_range")}
    if ranged:
        bins = list(next(iter(ranged.values())))
        lines += ["", "By range of the true distance (each bin scored alone: metrics.md), MOTA / IDF1 (objects):", "",
                  "| Tracker | " + " | ".join(f"{b} m" for b in bins) + " |", "|---|" + "---:|" * len(bins)]
        for name, by in ranged.items():
            lines.append(f"| {name} | " + " | ".join(
                f"{_f(by[b]['mota'], '{:.3f}')} / {_f(by[b]['idf1'], '{:.3f}')} ({by[b]['objects']})" for b in bins) + " |")
    lines += bootstrap_lines(result.get("bootstrap"))
    per = result.get("per_scenario", {})
    if len(per) > 1:
        lines += ["", "Per scenario:", "", "| Scenario | Tracker | tracker ms (mean) | MOTA | IDF1 | HOTA | ID switches "
                  "| distance error (median) |", "|---|---|---:|---:|---:|---:|---:|---:|"]
        for sc, v in per.items():
            for name, s in v["trackers"].items():
                d = s["distance_rel_err_median"]
                lines.append(f"| {sc} | {name} | {_f(s['tracker_ms']['mean'], '{:.3f}')} | {_f(s['mota'], '{:.3f}')} "
                             f"| {_f(s['idf1'], '{:.3f}')} | {_f(s.get('hota'), '{:.3f}')} | {s['id_switches']} | "
                             f"{_f(None if d is None else 100 * d, '{:.2f} %')} |")
    return "\n".join(lines)


def bootstrap_lines(boot: Mapping | None) -> list[str]:
    """The table of :func:`sequence_bootstrap`'s intervals (nothing when there are none)."""
    if not boot:
        return []

    def ci(v, fmt: str = ".3f") -> str:
        return "-" if v is None else f"{v[0]:{fmt}} .. {v[1]:{fmt}}"

    ref = boot["reference"]
    lines = ["", f"Uncertainty over sequences ({boot['level']:.0%} intervals, bootstrap: {boot['resamples']} draws of the "
                 f"{boot['sequences']} sequences with replacement, the same draws for every tracker; metrics.md):", "",
             f"| Tracker | MOTA | IDF1 | MOTA - {ref} | IDF1 - {ref} |", "|---|---:|---:|---:|---:|"]
    for name, e in boot["trackers"].items():
        lines.append(f"| {name} | {ci(e['mota'])} | {ci(e['idf1'])} | {ci(e.get('mota_minus_reference'), '+.3f')} "
                     f"| {ci(e.get('idf1_minus_reference'), '+.3f')} |")
    return lines


def run_bench(config: BenchConfig = BenchConfig(), out_dir: str | Path | None = None,
              log: Callable[[str], None] | None = None) -> dict:
    """:func:`bench_trackers`, then ``DIR/trackers.json`` and ``DIR/trackers.md``.

    The output directory is checked before anything is rendered and replaced as
    a whole only when the benchmark succeeded (nothing is left on failure).
    """
    check_trackers(config.trackers)              # the cheapest refusal first
    if out_dir is None:
        return bench_trackers(config, log)
    from monorarp.app.io import atomic_output_dir, to_jsonable, write_json_atomic

    with atomic_output_dir(out_dir, owned_names=OUTPUT_NAMES) as tmp:
        result = bench_trackers(config, log)
        clean = to_jsonable(result)
        write_json_atomic(tmp / JSON_NAME, clean)
        (tmp / MD_NAME).write_text(table_iii(clean) + "\n")
    return result


def stderr_log(msg: str) -> None:
    print(msg, file=sys.stderr, flush=True)
