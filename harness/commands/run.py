"""``monorarp run SCENARIO.yaml``: simulate, render, run the pipeline, score, print a summary.

Writes ``DIR/metrics.json``, ``DIR/per_object.csv``, ``DIR/per_frame.csv``, ``DIR/annotated.mp4`` and the
rendered ``frames.mp4``/``camera.json``/``ground_truth.jsonl`` (see
:mod:`harness.run.runner`); the directory appears complete or not at all.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from harness.commands.detector_args import add_oracle_arguments, pipeline_config
from monorarp.app.common_options import add_frames_option, add_no_video_option, add_out_option, add_threaded_option
from monorarp.app.options import add_pipeline_options
from monorarp.warning.thresholds import TTC_CUE_THRESHOLD_S
from harness.commands.look_args import add_look_arguments, apply_look
from monorarp.core.errors import UserError


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "run", help="simulate + render a scenario, run the pipeline on it and score it",
        description="Simulate SCENARIO.yaml, render its dashcam frames, run the MonoRARP pipeline on them "
                    "and score every output against ground truth. Prints a summary (distance error by "
                    "range, tracking, detection, TTC warnings, the paper's Table II) and writes "
                    "DIR/metrics.json, DIR/per_object.csv, DIR/per_frame.csv, DIR/annotated.mp4, DIR/frames.mp4, "
                    "DIR/camera.json and DIR/ground_truth.jsonl.")
    p.add_argument("scenario", type=Path, metavar="SCENARIO.yaml", help="scenario file")
    add_pipeline_options(p)
    add_oracle_arguments(p)
    p.add_argument("--gps-speed", action="store_true",
                   help="monte_carlo: use the true ego speed (as a GPS would give) on frames where the "
                        "ego-speed estimator has no estimate (otherwise the estimator's fallback)")
    p.add_argument("--risk-horizon", type=float, default=10.0, metavar="S",
                   help="risk scoring: a frame is positive when a collision or near miss follows within S s "
                        "(default 10)")
    add_frames_option(p, help="run only the first N frames (1 .. duration_s * fps; default: all)")
    add_out_option(p, help="output directory (default: runs/<scenario name>; a previous run there is replaced)")
    add_look_arguments(p)
    add_threaded_option(p)
    add_no_video_option(p, help="write neither annotated.mp4 nor frames.mp4")
    p.add_argument("--warning-threshold", type=float, default=TTC_CUE_THRESHOLD_S, metavar="S",
                   help="scoring and display: TTC below which a frame counts as a warning, s "
                        f"(default {TTC_CUE_THRESHOLD_S}; the warning stage keeps its own threshold)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from harness.run.runner import run_scenario
    from harness.world.scenario import ScenarioError, frames_to_simulate, load_scenario
    from harness.scoring.evaluate import EvalConfig
    from harness.scoring.tables import summary_table
    from monorarp.lanes.geometry import EgoSpeedStageError

    if not args.warning_threshold > 0:
        raise UserError(f"--warning-threshold: must be positive (s), got {args.warning_threshold}")
    if not args.risk_horizon > 0:
        raise UserError(f"--risk-horizon: must be positive (s), got {args.risk_horizon}")
    cfg = pipeline_config(args)
    scenario = apply_look(load_scenario(args.scenario), args)
    n_frames = frames_to_simulate(scenario, args.frames, args.scenario, "run")
    out = args.out if args.out is not None else Path("runs") / scenario.name
    try:
        metrics = run_scenario(scenario, cfg, n_frames=n_frames, out_dir=out, threaded=args.threaded,
                               annotate=not args.no_video, write_frames=not args.no_video,
                               gps_speed=args.gps_speed,
                               eval_config=EvalConfig(warning_threshold_s=args.warning_threshold,
                                                      risk_horizon_s=args.risk_horizon))
    except ScenarioError as e:   # found by the simulation: make sure the message names the file
        msg = str(e)
        raise ScenarioError(msg if msg.startswith(str(args.scenario)) else f"{args.scenario}: {msg}") from None
    except EgoSpeedStageError as e:   # e.g. the scenario's camera sees too little road for it
        raise EgoSpeedStageError(f"{args.scenario}: {e}; --ego-speed none runs without it") from None
    print(summary_table(metrics))
    print(f"\nwrote {out}/")
    return 0
