"""The pipeline on real data: a labelled KITTI dataset and, optionally, a dashcam clip, per detector.

Usage: python benchmarks/bench_real.py --data DIR [--video FILE --camera CAMERA.yaml] [--annotation gt.txt]
                                       [--detectors centernet centernet_robust yolox yolox_full_view labels]
                                       [--camera-height M]

For each detector (a registered name, an ONNX file, ``yolox_full_view`` = ``yolox`` without its fovea
pass, or ``labels`` = the label boxes) it runs ``monorarp eval kitti`` on ``--data``
(:func:`harness.kitti_eval.evaluate.evaluate_kitti`, into a temporary directory) and prints Car AP_R40
easy/moderate/hard at IoU 0.5 and 0.7, precision/recall at IoU 0.5, the distance relative error median
over 5-40 m and 40-80 m of true distance (``distance.by_span``: label boxes for ``labels``, detected
boxes otherwise), the pipeline's frames/s (``metrics.json`` ``fps``) and the CPU time per frame of
the whole evaluation (``time.process_time``, all threads: decoding, pipeline, scoring).

With ``--video`` (and its ``--camera``), each detector but ``labels`` runs ``monorarp video``
(:func:`monorarp.app.video.run.run_video`, no annotated video) and the table gives tracks per frame
(every track of ``predictions.jsonl``, coasting ones too), frames with a track whose TTC is under the
paper's 2 s cue, the warning stage's episodes, the pipeline's frames/s (1000 / ``run.json``'s mean
``total`` ms) and CPU ms per frame. ``--annotation`` (the clip's MOTChallenge ``gt.txt``) adds
precision/recall/MOTA/IDF1 against it, scored by the harness's :class:`harness.scoring.mot.MotScorer`
(no function reads a MOTChallenge file into it, so the small adapter is here: :func:`read_mot_gt`).
Wall-clock figures depend on the machine's load; CPU times much less.
"""

from __future__ import annotations

import argparse
import json
import math
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path

from harness.bench.script import run_script
from monorarp.core.errors import UserError

LABELS = "labels"
FULL_VIEW = "yolox_full_view"           # yolox with foveate=False, registered here for the run
DEFAULT_DETECTORS = ("centernet", "centernet_robust", "yolox", FULL_VIEW, LABELS)
KITTI_HEIGHT_M = 1.65                   # KITTI's camera above the road (its calibration does not say)
MIN_HEIGHT_PX = 20.0                    # annotated vehicles shorter than this are ignored (the rule)


def full_view_yolox(**kwargs):
    """``yolox`` with its second (fovea) pass off."""
    from monorarp.detection.yolox import YoloxDetector

    return YoloxDetector(**{**kwargs, "foveate": False})


full_view_yolox.uses_camera = True      # type: ignore[attr-defined]  (the registry passes the run's camera)


def check_detectors(names: Sequence[str]) -> None:
    """Every name is ``labels``, an existing .onnx file or a registered detector (one line otherwise)."""
    from monorarp.detection.model_file import is_model_path
    from monorarp.pipeline.registry import get_factory

    for name in names:
        if name == LABELS:
            continue
        if is_model_path(name):
            if not Path(name).is_file():
                raise UserError(f"--detectors: {name}: no such model file")
        else:
            get_factory("detector", name)


def read_mot_gt(path: Path) -> dict[int, list[tuple[int, tuple[float, float, float, float], bool]]]:
    """MOTChallenge ``gt.txt`` -> {frame index (0-based): [(id, project box x1y1x2y2, counted)]}.

    A row counts unless its ``conf`` is 0 (MOTChallenge's "not considered") or its box is under
    :data:`MIN_HEIGHT_PX` tall. Frames scored: those from the first to the last annotated one in steps of
    the gcd of their gaps (an annotated frame with no vehicle has no row).
    """
    from harness.export.mot import mot_to_box
    from monorarp.core.readers import read_text

    rows: dict[int, list] = {}
    for k, line in enumerate(read_text(path, "annotation").splitlines(), 1):
        if not line.strip():
            continue
        f = line.split(",")
        try:
            frame, oid, left, top, w, h = int(f[0]), int(f[1]), *(float(v) for v in f[2:6])
            conf = float(f[6]) if len(f) > 6 else 1.0
        except (ValueError, IndexError):
            raise UserError(f"{path}:{k}: expected 'frame, id, bb_left, bb_top, bb_width, bb_height, conf, ...', "
                            f"got {line.strip()[:80]!r}") from None
        if frame < 1 or not (w > 0 and h > 0) or not all(map(math.isfinite, (left, top, w, h))):
            raise UserError(f"{path}:{k}: frame must be >= 1 and the box finite with a positive size")
        rows.setdefault(frame - 1, []).append((oid, mot_to_box(left, top, w, h), conf != 0 and h >= MIN_HEIGHT_PX))
    if not rows:
        raise UserError(f"{path}: no annotation rows")
    frames = sorted(rows)
    step = math.gcd(*(b - a for a, b in zip(frames, frames[1:]))) if len(frames) > 1 else 1
    return {f: rows.get(f, []) for f in range(frames[0], frames[-1] + 1, step)}


def score_clip(gt: dict, predictions: list[dict]) -> dict[str, float]:
    """Precision, recall, MOTA, IDF1 of the predicted tracks on the annotated frames (MotScorer, IoU 0.5)."""
    from harness.scoring.mot import MotScorer
    from harness.scoring.rules import EvalConfig

    by_frame = {p["frame"]: p["tracks"] for p in predictions}
    missing = [f for f in gt if f not in by_frame]
    if missing:
        raise UserError(f"--annotation: frame {missing[0] + 1} (MOT numbering) is not in the clip's "
                        f"{len(predictions)} frames")
    cfg = EvalConfig()
    mot = MotScorer(cfg.min_iou, hota=False)
    for f, objs in gt.items():
        tracks = by_frame[f]
        mot.update([o[0] for o in objs], [o[1] for o in objs], [o[2] for o in objs],
                   [t["id"] for t in tracks], [t["box"] for t in tracks], frame=f, ignore_cover=cfg.ignore_cover)
    m = mot.compute(("precision", "recall", "mota", "idf1"))
    return {k: (v if math.isfinite(v) else float("nan")) for k, v in m.items()}


def run_kitti(ds, detector: str, height: float | None, out: Path) -> dict:
    """One ``eval kitti``: the figures of the table's row."""
    from harness.kitti_eval.evaluate import KittiEvalOptions, evaluate_kitti

    c0 = time.process_time()
    m = evaluate_kitti(ds, KittiEvalOptions(detector=detector, camera_height_m=height), out)
    cpu = time.process_time() - c0
    ap = {thr: [m["kitti_ap"][f"iou_{thr}"][d]["ap_r40"] for d in ("easy", "moderate", "hard")]
          for thr in ("0.5", "0.7")}
    span = m["distance"]["by_span"]
    return {"frames": m["frames"], "ap": ap, "precision": m["detection"]["precision"],
            "recall": m["detection"]["recall"],
            "dist": {s: (span[s]["rel_err_median"], span[s]["count"]) for s in ("5-40", "40-80")},
            "fps": m["fps"], "cpu_ms": cpu / m["frames"] * 1e3}


def run_clip(video: Path, camera, detector: str, out: Path, gt: dict | None) -> dict:
    """One ``monorarp video`` run (no annotated video): the figures of the clip table's row."""
    from monorarp.app.options import REAL_FRAMES, default_pipeline_config
    from monorarp.app.video.run import VideoRunOptions, run_video
    from monorarp.pipeline.config import ComponentConfig
    from monorarp.warning.thresholds import TTC_CUE_THRESHOLD_S

    cfg = default_pipeline_config(REAL_FRAMES).model_copy(update={"detector": ComponentConfig(name=detector)})
    c0 = time.process_time()
    s = run_video(video, camera, out, VideoRunOptions(pipeline=cfg, write_video=False), log=None)
    cpu = time.process_time() - c0
    preds = [json.loads(x) for x in (out / "predictions.jsonl").read_text().splitlines()]
    run = json.loads((out / "run.json").read_text())
    episodes = {p["warning"]["episode"] for p in preds if p["warning"]["episode"] is not None}
    row = {"frames": s.frames, "tracks": sum(len(p["tracks"]) for p in preds) / len(preds),
           "ttc_frames": sum(any(t["ttc"] is not None and t["ttc"] < TTC_CUE_THRESHOLD_S for t in p["tracks"])
                             for p in preds),
           "episodes": len(episodes), "fps": 1e3 / run["timings_ms_mean"]["total"], "cpu_ms": cpu / s.frames * 1e3}
    if gt is not None:
        row.update(score_clip(gt, preds))
    return row


def num(v: float | None, fmt: str = "{:.3f}") -> str:
    return "-" if v is None or (isinstance(v, float) and not math.isfinite(v)) else fmt.format(v)


def kitti_table(rows: dict[str, dict]) -> str:
    head = (f"{'detector':<18} {'AP_R40@0.5 E/M/H':<19} {'AP_R40@0.7 E/M/H':<19} {'prec/rec':<12} "
            f"{'dist 5-40 m (n)':<16} {'40-80 m (n)':<14} {'frames/s':>8} {'CPU ms':>7}")
    lines = [head]
    for name, r in rows.items():
        ap = {t: "/".join(num(v, "{:.3f}") for v in r["ap"][t]) for t in r["ap"]}
        dist = {s: f"{num(v, '{:.1%}')} ({n})" for s, (v, n) in r["dist"].items()}
        lines.append(f"{name:<18} {ap['0.5']:<19} {ap['0.7']:<19} "
                     f"{num(r['precision'], '{:.2f}') + '/' + num(r['recall'], '{:.2f}'):<12} "
                     f"{dist['5-40']:<16} {dist['40-80']:<14} {num(r['fps'], '{:.1f}'):>8} "
                     f"{num(r['cpu_ms'], '{:.1f}'):>7}")
    return "\n".join(lines)


def clip_table(rows: dict[str, dict], scored: bool) -> str:
    head = f"{'detector':<18} {'tracks/frame':>12} {'TTC<2s frames':>13} {'episodes':>8} {'frames/s':>8} {'CPU ms':>7}"
    if scored:
        head += f" {'prec':>5} {'rec':>5} {'MOTA':>6} {'IDF1':>5}"
    lines = [head]
    for name, r in rows.items():
        line = (f"{name:<18} {r['tracks']:>12.2f} {r['ttc_frames']:>13d} {r['episodes']:>8d} "
                f"{num(r['fps'], '{:.1f}'):>8} {num(r['cpu_ms'], '{:.1f}'):>7}")
        if scored:
            line += (f" {num(r['precision'], '{:.2f}'):>5} {num(r['recall'], '{:.2f}'):>5} "
                     f"{num(r['mota'], '{:.2f}'):>6} {num(r['idf1'], '{:.2f}'):>5}")
        lines.append(line)
    return "\n".join(lines)


def targets(kitti: dict | None, clip: dict | None, labels: dict | None, size: str, clip_size: str) -> str:
    """The issue's targets for the real-world detector (``yolox``) and the label boxes, where measured."""
    from harness.bench.targets import target_table

    rows = []
    if kitti is not None:
        rows += [("Car AP_R40 moderate @0.5 (yolox)", ">= 0.90", num(kitti["ap"]["0.5"][1])),
                 ("Car AP_R40 moderate @0.7 (yolox)", ">= 0.70", num(kitti["ap"]["0.7"][1])),
                 (f"pipeline frames/s on {size} (yolox)", ">= 25", num(kitti["fps"], "{:.1f}")),
                 ("distance 5-40 m, detected boxes (yolox)", "<= 6 %",
                  num(kitti["dist"]["5-40"][0], "{:.1%}"))]
    if labels is not None:
        rows += [("distance 5-40 m, label boxes", "<= 4 %", num(labels["dist"]["5-40"][0], "{:.1%}")),
                 ("distance 40-80 m, label boxes", "<= 7 %", num(labels["dist"]["40-80"][0], "{:.1%}"))]
    if clip is not None:
        rows += [(f"clip pipeline frames/s at {clip_size} (yolox)", ">= 30", num(clip["fps"], "{:.1f}")),
                 ("clip frames with a track under 2 s TTC", "0", str(clip["ttc_frames"])),
                 ("clip warning episodes", "0", str(clip["episodes"]))]
        if "idf1" in clip:
            rows += [("clip precision", ">= 0.95", num(clip["precision"])),
                     ("clip recall", ">= 0.90", num(clip["recall"])),
                     ("clip IDF1", ">= 0.85", num(clip["idf1"]))]
    return target_table("targets (issue 42)", rows)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path, required=True, help="KITTI object or tracking dataset (eval kitti's DIR)")
    ap.add_argument("--video", type=Path, default=None, help="a dashcam clip (needs --camera)")
    ap.add_argument("--camera", type=Path, default=None, help="the clip's camera file (docs/formats.md)")
    ap.add_argument("--annotation", type=Path, default=None, help="the clip's MOTChallenge gt.txt (needs --video)")
    ap.add_argument("--detectors", nargs="+", default=list(DEFAULT_DETECTORS), metavar="NAME",
                    help=f"default: {' '.join(DEFAULT_DETECTORS)}")
    ap.add_argument("--camera-height", type=float, default=None, metavar="M",
                    help=f"camera height above the road (m); default: the calibration's for a `monorarp export`, "
                         f"else {KITTI_HEIGHT_M} (KITTI's rig)")
    args = ap.parse_args()

    from harness.kitti_eval.cameras import read_manifest
    from harness.kitti_eval.reader import open_dataset
    from monorarp.core.camera import CameraModel
    from monorarp.pipeline import registry

    if not args.data.is_dir():
        raise UserError(f"--data {args.data}: no such directory")
    if args.video is not None and args.camera is None:
        raise UserError("--video needs --camera CAMERA.yaml (the clip's calibration: docs/formats.md#camera-file)")
    if args.camera is not None and args.video is None:
        raise UserError("--camera is the clip's calibration: it needs --video")
    if args.annotation is not None and args.video is None:
        raise UserError("--annotation scores the clip: it needs --video")
    if args.video is not None and not args.video.is_file():
        raise UserError(f"--video {args.video}: no such file")
    if args.camera_height is not None and not (math.isfinite(args.camera_height) and args.camera_height > 0):
        raise UserError(f"--camera-height: must be a positive number, got {args.camera_height}")
    registry.add("detector", FULL_VIEW, full_view_yolox)
    check_detectors(args.detectors)
    camera = CameraModel.load(args.camera) if args.camera is not None else None
    gt = read_mot_gt(args.annotation) if args.annotation is not None else None
    ds = open_dataset(args.data)
    height = args.camera_height if args.camera_height is not None or read_manifest(ds.root) else KITTI_HEIGHT_M

    kitti, clip = {}, {}
    with tempfile.TemporaryDirectory() as tmp:
        for k, det in enumerate(args.detectors):
            kitti[det] = run_kitti(ds, det, height, Path(tmp) / f"kitti-{k}")
        if args.video is not None:
            for k, det in enumerate(d for d in args.detectors if d != LABELS):
                clip[det] = run_clip(args.video, camera, det, Path(tmp) / f"video-{k}", gt)
    first = next(iter(kitti.values()))
    h_text = "calibration's" if height is None else f"{height} m"
    print(f"{ds.root}: {ds.kind} dataset, {first['frames']} frames, camera height {h_text}; "
          f"Car AP_R40, precision/recall @IoU 0.5, distance relative error median by true distance")
    print(kitti_table(kitti))
    if clip:
        print(f"\n{args.video.name}: {next(iter(clip.values()))['frames']} frames, camera {args.camera}"
              + (f"; scored against {args.annotation} ({len(gt)} frames, vehicles >= {MIN_HEIGHT_PX:.0f} px)"
                 if gt is not None else ""))
        print(clip_table(clip, gt is not None))
    print()
    print(targets(kitti.get("yolox"), clip.get("yolox"), kitti.get(LABELS), "the dataset's frames",
                  f"{camera.width}x{camera.height}" if camera is not None else ""))


if __name__ == "__main__":
    run_script(main)
