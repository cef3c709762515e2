"""``monorarp eval kitti DIR [--detector NAME|PATH.onnx|labels] [--camera-height M] [--horizon-row PX]
[--tracker NAME] [--fps HZ] [--frames N] [--lenient] --out OUT``.

Scores the pipeline on a KITTI object or tracking dataset (:mod:`harness.kitti_eval`): ``OUT/metrics.json``
(the run keys plus ``kitti_ap`` and ``dataset``) and ``OUT/per_object.csv``, written all or nothing.
Exit status 0, or 2 on bad input (one line on stderr naming the file and line, or the option, nothing written):
also ``--frames`` beyond the dataset's frames and ``--tracker`` given for an object dataset (which runs none).
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

from monorarp.app.common_options import add_frames_option, add_out_option, frames_within
from monorarp.app.options import add_pipeline_options, default_name, pipeline_config
from monorarp.core.errors import UserError
from monorarp.pipeline.config import REAL_WORLD_DETECTOR, PipelineConfig


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("eval", help="score the pipeline on a labelled dataset (KITTI)",
                       description="Score the pipeline on real labelled data.")
    datasets = p.add_subparsers(dest="dataset", metavar="DATASET")
    k = datasets.add_parser(
        "kitti", help="a KITTI object or tracking dataset",
        description="Run the detector (or take the label boxes, --detector labels), the state estimator and, "
                    "on tracking sequences, the tracker over a KITTI object dataset (image_2, label_2, calib) or "
                    "tracking dataset (image_02, label_02, calib), and score them with the rules and keys of "
                    "metrics.json plus KITTI's Car AP (R40 and R11, IoU 0.7 and 0.5, easy/moderate/hard). "
                    "Camera height and pitch come from the calibration of a `monorarp export` dataset; a real "
                    "rig's calibration needs --camera-height (KITTI: 1.65) and is taken as level unless "
                    "--horizon-row is given.")
    k.add_argument("root", type=Path, metavar="DIR", help="dataset directory (or its parent holding training/)")
    k.add_argument("--detector", default=None, metavar="NAME|PATH.onnx|labels",
                   help="registered detector, an ONNX model, or 'labels' (the label boxes of Car/Van/Truck as "
                        f"detections: an oracle); default {REAL_WORLD_DETECTOR} on real frames, "
                        f"{PipelineConfig().detector.name} on a `monorarp export` of renders (with export.json)")
    k.add_argument("--score-threshold", type=float, default=None, metavar="S",
                   help="the detector's score threshold (0..1; default: its own). AP ranks every detection kept, so "
                        "a low one (0.05) gives the AP of the detector's whole ranked list, as KITTI's benchmark "
                        "takes it; precision and recall are those at this threshold")
    add_pipeline_options(k, stages=("tracker",))   # tracking sequences only; object datasets use none
    k.set_defaults(tracker=_Default(default_name("tracker")))   # told from a given --tracker (refused on objects)
    k.add_argument("--camera-height", type=float, default=None, metavar="M",
                   help="camera height above the road (m); overrides the calibration's")
    k.add_argument("--horizon-row", type=float, default=None, metavar="PX",
                   help="image row of the horizon (px); default: from the calibration, else cy of P2 (level)")
    k.add_argument("--fps", type=float, default=None, metavar="HZ",
                   help="frame rate of tracking sequences (default: export.json's, else KITTI's 10 Hz)")
    add_frames_option(k, help="evaluate only the first N frames (1 .. the dataset's frames, all sequences together)")
    k.add_argument("--lenient", action="store_true",
                   help="for a dataset known to be dirty: skip label lines outside KITTI's definitions instead of "
                        "refusing the dataset (counted and listed in metrics.json's dataset.skipped_lines)")
    add_out_option(k, required=True, metavar="OUT",
                   help="output directory (created; a previous evaluation there is replaced)")
    k.set_defaults(func=run_kitti)
    p.set_defaults(func=_no_dataset)


class _Default(str):
    """The default of an option, told apart from the same name given on the command line."""


def _no_dataset(args: argparse.Namespace) -> int:
    raise UserError("name a dataset format: monorarp eval kitti DIR --out OUT")


def _positive(name: str, v: float | None) -> None:
    if v is not None and not (math.isfinite(v) and v > 0):
        raise UserError(f"{name}: must be a positive number, got {v}")


def default_detector(root: Path) -> str:
    """``--detector``'s default for the dataset at ``root``: the simulation default (``centernet``, trained on
    renders) for a ``monorarp export`` of rendered frames (an ``export.json`` beside it), else the real-world
    detector (:data:`~monorarp.pipeline.config.REAL_WORLD_DETECTOR`)."""
    from harness.kitti_eval.cameras import read_manifest

    return PipelineConfig().detector.name if read_manifest(root) else REAL_WORLD_DETECTOR


def run_kitti(args: argparse.Namespace) -> int:
    from harness.kitti_eval.evaluate import LABELS_DETECTOR, KittiEvalOptions, dataset_summary, evaluate_kitti
    from harness.kitti_eval.reader import open_dataset
    from monorarp.detection.model_file import is_model_path
    from monorarp.pipeline.registry import get_factory

    _positive("--camera-height", args.camera_height)
    _positive("--fps", args.fps)
    if args.horizon_row is not None and not math.isfinite(args.horizon_row):
        raise UserError(f"--horizon-row: must be finite, got {args.horizon_row}")
    thr = args.score_threshold
    if thr is not None and not (math.isfinite(thr) and 0.0 <= thr <= 1.0):
        raise UserError(f"--score-threshold: must be a number in 0..1, got {thr}")
    if thr is not None and args.detector == LABELS_DETECTOR:
        raise UserError("--score-threshold: the label boxes (--detector labels) have no scores to threshold")
    detector = args.detector or REAL_WORLD_DETECTOR     # None: decided by the dataset, below
    if is_model_path(detector):
        detector = str(Path(detector).expanduser())
        if not Path(detector).is_file():
            raise UserError(f"--detector: {detector}: no such ONNX model file")
    elif detector != LABELS_DETECTOR:
        if detector == "oracle":
            raise UserError("--detector: the run oracle needs simulation truth; on KITTI use --detector labels")
        get_factory("detector", detector)            # unknown names fail before anything is read
    tracker_given = not isinstance(args.tracker, _Default)
    tracker = pipeline_config(args).tracker.name
    ds = open_dataset(args.root, lenient=args.lenient)
    if args.detector is None:
        detector = default_detector(ds.root)
    if tracker_given and ds.kind == "object":
        raise UserError(f"--tracker: {ds.root} is a KITTI object dataset, whose images are scored one by one "
                        "without a tracker; --tracker applies to tracking datasets (image_02/, label_02/)")
    seqs = f" ({len(ds.sequences)} sequences together)" if ds.kind == "tracking" and len(ds.sequences) > 1 else ""
    frames_within(args.frames, ds.n_frames, "dataset's", f"{seqs} in {ds.root}")
    opts = KittiEvalOptions(detector=detector, tracker=tracker, camera_height_m=args.camera_height,
                            horizon_row=args.horizon_row, fps=args.fps, frames=args.frames, score_threshold=thr)
    metrics = evaluate_kitti(ds, opts, args.out)
    print(dataset_summary(metrics))
    if ds.skipped:
        print(f"--lenient: skipped {len(ds.skipped)} bad label lines (listed in metrics.json), first: {ds.skipped[0]}")
    print(f"-> {args.out}/metrics.json, per_object.csv")
    return 0
