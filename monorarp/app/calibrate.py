"""``monorarp calibrate VIDEO``: a camera file estimated from the clip's lane markings (entry point of
``monorarp.commands``; the maths: :mod:`monorarp.horizon.calibration`)."""

from __future__ import annotations

import argparse
import math
from pathlib import Path
from typing import TYPE_CHECKING

from monorarp.app.common_options import add_frames_option, metres_in
from monorarp.core.errors import UserError

if TYPE_CHECKING:
    from monorarp.horizon.calibration import CalibrationEstimate


def _out_file(text: str) -> Path:
    if not text:
        raise argparse.ArgumentTypeError("must name a camera file, got ''")
    return Path(text)


def register(sub: argparse._SubParsersAction) -> None:
    from monorarp.horizon.calibration import US_LANE_WIDTH_M, US_STRIPE_PERIOD_M

    p = sub.add_parser(
        "calibrate", help="estimate a camera file (horizon, focal length, height) from a clip's lane markings",
        description="Estimate the horizon row (lane lines' vanishing point), the focal length (the period of "
                    "dashed lane markings) and the camera height (the lane width) from a clip on a straight, "
                    "flat road, print them with one-sigmas and write a camera file for `monorarp video`.")
    p.add_argument("input", metavar="VIDEO", help="video file")
    p.add_argument("--out", type=_out_file, default=None, metavar="CAMERA.yaml",
                   help="camera file to write (default: <video name>.camera.yaml here)")
    add_frames_option(p, default=300, help="frames to use from the start (default 300)")
    g = p.add_mutually_exclusive_group()
    g.add_argument("--lane-width", type=metres_in(2.0, 6.0), default=US_LANE_WIDTH_M, metavar="M",
                   help=f"lane width, gives the height (default {US_LANE_WIDTH_M} m, US)")
    g.add_argument("--height", type=metres_in(0.2, 5.0), default=None, metavar="M",
                   help="known camera height above the road (the lane width is then measured)")
    p.add_argument("--stripe-period", type=metres_in(2.0, 50.0), default=US_STRIPE_PERIOD_M, metavar="M",
                   help=f"dashed markings' period, stripe + gap (default {US_STRIPE_PERIOD_M} m, US)")
    p.set_defaults(func=calibrate_command)


def camera_yaml(est: "CalibrationEstimate", source: str, stripe_period_m: float) -> str:
    """The camera file's text: its fields, the estimate's one-sigmas as comments."""
    cam, e = est.camera(), est
    basis = "given" if e.height_given else f"from a {e.lane_width_m.value:g} m lane width"
    return "\n".join([
        f"# monorarp calibrate {source}: {e.frames_seen} frames; one-sigmas take the lane width / height and",
        f"# the {stripe_period_m:g} m stripe period as exact",
        f"width: {cam.width}", f"height: {cam.height}",
        f"fx: {cam.fx:.2f}    # +- {e.focal_px.sigma:.2f} px; hfov {e.hfov_deg.value:.2f} +- {e.hfov_deg.sigma:.2f} deg",
        f"fy: {cam.fy:.2f}", f"cx: {cam.cx:.2f}", f"cy: {cam.cy:.2f}",
        f"height_m: {cam.height_m:.3f}    # +- {e.height_m.sigma:.3f} m, {basis}",
        f"horizon_row: {e.horizon_row.value:.2f}    # +- {e.horizon_row.sigma:.2f} px; pitch "
        f"{math.degrees(cam.pitch_rad):.3f} deg",
        f"# lane width {e.lane_width_m.value:.3f} +- {e.lane_width_m.sigma:.3f} m; vanishing point column "
        f"{e.vp_column:.1f} px", ""])


def calibrate_command(args: argparse.Namespace) -> int:
    from monorarp.app.io import write_atomic
    from monorarp.app.video.source import VideoSource
    from monorarp.core.camera import CameraModel
    from monorarp.horizon.calibration import calibrate

    out = args.out if args.out is not None else Path(f"{Path(args.input).stem or 'video'}.camera.yaml")
    if out.is_dir():
        raise UserError(f"{out}: is a directory; --out names the camera file to write")
    if not out.parent.is_dir():
        raise UserError(f"{out}: no directory {out.parent} to write it in")
    with VideoSource(args.input) as source:
        if source.is_webcam:
            raise UserError(f"{source.name}: calibrate reads a video file, not a webcam")
        est = calibrate((f.image for f in source.frames(args.frames)), lane_width_m=args.lane_width,
                        height_m=args.height, stripe_period_m=args.stripe_period)
    text = camera_yaml(est, source.name, args.stripe_period)
    from monorarp.core.readers import parse_yaml
    CameraModel.from_dict(parse_yaml(text, out, UserError), source=str(out))   # what `video` will read
    e = est
    print(f"{source.name}: vanishing point in {e.frames_vp} of {e.frames_seen} frames; lane lines in "
          f"{e.blocks_lanes} and dashes in {e.blocks_dashes} blocks of frames")
    print(f"horizon row  {e.horizon_row.value:8.2f} +- {e.horizon_row.sigma:.2f} px")
    print(f"focal length {e.focal_px.value:8.2f} +- {e.focal_px.sigma:.2f} px  (hfov {e.hfov_deg.value:.2f} "
          f"+- {e.hfov_deg.sigma:.2f} deg)")
    print(f"height       {e.height_m.value:8.3f} +- {e.height_m.sigma:.3f} m  "
          f"({'given' if e.height_given else 'from the lane width'})")
    print(f"lane width   {e.lane_width_m.value:8.3f} +- {e.lane_width_m.sigma:.3f} m  "
          f"({'implied' if e.height_given else 'assumed'})")
    write_atomic(out, text)
    print(f"wrote {out}")
    return 0
