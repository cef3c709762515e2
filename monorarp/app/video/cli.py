"""``monorarp video`` and ``monorarp calibrate-horizon`` (entry points of ``monorarp.commands``)."""

from __future__ import annotations

import argparse
import math
from dataclasses import replace
from pathlib import Path

from monorarp.app.common_options import (add_camera_option, add_frames_option, add_no_video_option, add_out_option,
                                         add_threaded_option)
from monorarp.app.options import REAL_FRAMES, add_pipeline_options


def _speed(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a speed in m/s, got {text!r}") from None
    if not (math.isfinite(v) and v >= 0):
        raise argparse.ArgumentTypeError(f"must be a non-negative speed in m/s, got {text}")
    return v


def _default_out(input_spec: str) -> Path:
    s = input_spec.strip()
    return Path("runs") / (f"video-webcam{s}" if s.isdigit() else f"video-{Path(s).stem or 'input'}")


# ------------------------------------------------------------------------- video
def register_video(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "video", help="run the pipeline on a video file or webcam",
        description="Run the MonoRARP pipeline on a video file (timestamps from the container) or a webcam "
                    "(INPUT = its index, e.g. 0; timestamps from a monotonic capture clock). Writes "
                    "DIR/predictions.jsonl (per frame: tracks with box, d_x, d_y, v_x, v_y, TTC; risk; ego "
                    "speed), DIR/annotated.mp4 and DIR/run.json; the directory appears complete or not at all.")
    p.add_argument("input", metavar="INPUT", help="video file, or webcam index (an integer)")
    add_camera_option(p, help="camera file (YAML or JSON: resolution, intrinsics, mounting height, pitch or "
                              "horizon_row)")
    add_pipeline_options(p, defaults=REAL_FRAMES)
    p.add_argument("--speed", type=_speed, default=None, metavar="MPS",
                   help="known ego speed (m/s, e.g. GPS): used by the Monte Carlo risk when the ego-speed "
                        "estimator has no value, and reported as ego_speed then")
    add_out_option(p, help="output directory (default: runs/video-<input name>; a previous run there is replaced)")
    p.add_argument("--display", action="store_true",
                   help="show annotated frames in a window (needs a screen and OpenCV with GUI support; "
                        "q or Esc stops early)")
    add_frames_option(p, help="stop after N frames (default: all)", hidden_aliases=("--max-frames",))
    add_no_video_option(p, help="do not write annotated.mp4")
    add_threaded_option(p)
    p.set_defaults(func=video_command)


def video_command(args: argparse.Namespace) -> int:
    from monorarp.app.options import pipeline_config
    from monorarp.lanes.geometry import EgoSpeedStageError
    from monorarp.app.video.run import VideoRunOptions, run_video

    # names are checked by run_video, after the camera and the input (one error at a time, in that order)
    options = VideoRunOptions(pipeline=pipeline_config(args, check=False), speed_mps=args.speed, threaded=args.threaded,
                              max_frames=args.frames, write_video=not args.no_video, display=args.display)
    out = args.out if args.out is not None else _default_out(args.input)
    try:
        summary = run_video(args.input, args.camera, out, options)
    except EgoSpeedStageError as e:   # e.g. a camera that sees too little road for it
        raise EgoSpeedStageError(f"{args.camera}: {e}; --ego-speed none runs without it") from None
    span = "" if summary.t_first is None else f", t {summary.t_first:.3f}..{summary.t_last:.3f} s"
    pipe = "" if summary.pipeline_ms_mean is None else f"; pipeline {summary.pipeline_ms_mean:.1f} ms/frame"
    print(f"processed {summary.frames} frames{span}{pipe}; {summary.fps:.1f} frames/s overall "
          f"(decode, pipeline, drawing, encoding)")
    print(f"wrote {out}/")
    return 0


# ------------------------------------------------------------------ calibrate-horizon
def register_calibrate(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "calibrate-horizon", help="estimate the horizon row / camera pitch from lane lines",
        description="Estimate the horizon row from the vanishing point of the lane lines (LSD segments, RANSAC "
                    "+ reweighted least squares, combined over frames) of a video taken on a straight, flat "
                    "road, and print horizon_row and the pitch_deg to put in the camera file.")
    p.add_argument("input", metavar="INPUT", help="video file, or webcam index (an integer)")
    add_camera_option(p, help="camera file (its fy and cy turn the row into a pitch)")
    add_frames_option(p, default=150, help="frames to use from the start (default 150)")
    p.set_defaults(func=calibrate_command)


def calibrate_command(args: argparse.Namespace) -> int:
    from monorarp.core.camera import CameraModel
    from monorarp.horizon.vanishing import estimate_horizon
    from monorarp.app.video.run import camera_for
    from monorarp.app.video.source import VideoSource
    from monorarp.state.pinhole_view import pinhole_view

    camera = CameraModel.load(args.camera)
    with VideoSource(args.input) as source:
        cam, scaled = camera_for(camera, source.info)
        if cam.distorted:   # lane lines are straight in the lens's virtual pinhole view (docs/lens.md)
            view = pinhole_view(cam, None)
            est = estimate_horizon((view.image(f.image) for f in source.frames(args.frames)), cam.fy, cam.cy - view.y0)
            est = replace(est, row=est.row + view.y0, u=est.u + view.x0)   # the real camera's ideal pixels
        else:
            est = estimate_horizon((f.image for f in source.frames(args.frames)), cam.fy, cam.cy)
    print(f"# {source.name}: vanishing point found in {est.frames_used} of {est.frames_seen} frames, "
          f"spread {est.spread_px:.2f} px (scaled MAD), column {est.u:.1f} px")
    row_file = (est.row + 0.5) * camera.height / cam.height - 0.5   # rows in the camera file's image
    if scaled:
        print(f"# horizon row {est.row:.2f} px at the video's {cam.width}x{cam.height}; "
              f"in the camera file's {camera.width}x{camera.height}:")
    print(f"horizon_row: {row_file:.2f}")
    print(f"pitch_deg: {est.pitch_deg:.3f}")
    print(f"# the camera file puts the horizon at {camera.horizon_row:.2f} px (pitch_deg "
          f"{math.degrees(camera.pitch_rad):.3f}); difference {row_file - camera.horizon_row:+.2f} px")
    return 0
