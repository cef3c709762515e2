"""``monorarp export RUN_DIR|SCENARIO.yaml --format kitti|kitti-tracking|mot --out DIR [--frames N] [--detector NAME]``.

Writes the frames and their exact labels in KITTI object, KITTI tracking or
MOTChallenge layout (:mod:`harness.export`); DIR appears complete or not at all.
Exit status 0, or 2 on bad input (one line on stderr, nothing written).
"""

from __future__ import annotations

import argparse
from pathlib import Path

from harness.commands.look_args import add_look_arguments, apply_look
from monorarp.app.common_options import add_frames_option, add_out_option
from monorarp.core.errors import UserError
from monorarp.pipeline.config import PipelineConfig

DEFAULT_MOT_DETECTOR = PipelineConfig().detector.name


def register(sub: argparse._SubParsersAction) -> None:
    from harness.export.exporter import FORMATS

    p = sub.add_parser(
        "export", help="export frames and exact labels as a KITTI or MOTChallenge dataset",
        description="Export a scenario (rendered now) or a run directory (its frames.mp4, camera.json and "
                    "ground_truth.jsonl) as a KITTI object dataset (image_2, label_2, calib), a KITTI tracking "
                    "sequence (image_02, label_02, calib) or a MOTChallenge sequence (img1, gt/gt.txt, det/det.txt "
                    "from a detector, seqinfo.ini). Labels are in the pitched camera's own frame with R0_rect = I; "
                    "the pitch and mounting are in Tr_velo_to_cam / Tr_imu_to_velo. DIR is replaced as a whole "
                    "only when everything succeeded.")
    p.add_argument("source", type=Path, metavar="RUN_DIR|SCENARIO.yaml",
                   help="a directory written by `monorarp run`/`monorarp render`, or a scenario file")
    p.add_argument("--format", required=True, choices=FORMATS, help="dataset layout")
    add_out_option(p, required=True, help="output directory (created; a previous export there is replaced)")
    add_frames_option(p, help="export only the first N frames (1 .. the source's frames; default: all)")
    p.add_argument("--detector", default=None, metavar="NAME|PATH.onnx|oracle|none",
                   help=f"mot: the detector whose boxes go to det/det.txt (default {DEFAULT_MOT_DETECTOR}; "
                        "'none' writes no det/); not used by the KITTI formats")
    add_look_arguments(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from harness.export.exporter import export
    from harness.export.source import open_source

    det_name = args.detector
    if args.format != "mot":
        if det_name is not None:
            raise UserError(f"--detector: only --format mot writes detections (det/det.txt), not --format {args.format}")
    elif det_name is None:
        det_name = DEFAULT_MOT_DETECTOR
    if args.source.is_dir() and any(v is not None for v in (args.look, args.look_family, args.look_seed)):
        raise UserError(f"--look: {args.source} is a run directory, rendered already; give a scenario file")
    source = open_source(args.source, args.frames, lambda sc: apply_look(sc, args))
    detector = None
    if det_name is not None and det_name.lower() != "none":
        from monorarp.pipeline.detectors import build_detector
        from monorarp.pipeline.config import ComponentConfig

        detector = build_detector(ComponentConfig(name=det_name), source.camera)
    stats = export(source, args.format, args.out, detector=detector,
                   detector_name=det_name if detector is not None else None)
    extra = f", {stats['detections']} detections ({det_name})" if detector is not None else ""
    print(f"exported {stats['frames']} frames of '{source.name}' as {args.format}: {stats['objects']} labelled "
          f"objects{extra}; {source.origin}; {stats['frames'] / max(stats['seconds'], 1e-9):.1f} frames/s -> {args.out}")
    return 0
