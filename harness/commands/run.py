"""``monorarp run SCENARIO.yaml``: simulate, render, run the pipeline, score, print a summary.

Writes ``DIR/metrics.json``, ``DIR/per_object.csv``, ``DIR/per_frame.csv``, ``DIR/annotated.mp4`` and the
rendered ``frames.mp4``/``camera.json``/``ground_truth.jsonl`` (see
:mod:`harness.run`); the directory appears complete or not at all.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from harness.commands.detector_args import add_detector_arguments, detector_config
from monorarp.errors import UserError


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "run", help="simulate + render a scenario, run the pipeline on it and score it",
        description="Simulate SCENARIO.yaml, render its dashcam frames, run the MonoRARP pipeline on them "
                    "and score every output against ground truth. Prints a summary (distance error by "
                    "range, tracking, detection, TTC warnings, the paper's Table II) and writes "
                    "DIR/metrics.json, DIR/per_object.csv, DIR/per_frame.csv, DIR/annotated.mp4, DIR/frames.mp4, "
                    "DIR/camera.json and DIR/ground_truth.jsonl.")
    p.add_argument("scenario", type=Path, metavar="SCENARIO.yaml", help="scenario file")
    add_detector_arguments(p)
    p.add_argument("--tracker", default="particle", metavar="NAME", help="registered tracker (default: particle)")
    p.add_argument("--velocity", choices=("kalman", "difference"), default="kalman",
                   help="relative velocity of the state estimator (default: kalman)")
    p.add_argument("--ego-speed", choices=("ground_track", "lsd_period", "none"), default="ground_track",
                   help="lane-marking ego-speed estimator, told the scenario's marking dimensions "
                        "(road.markings); scored against the true ego speed (default: ground_track)")
    p.add_argument("--risk", choices=("ttc", "monte_carlo"), default="ttc",
                   help="risk estimator: the paper's 1/TTC or Monte Carlo IDM/MOBIL rollouts (which take the "
                        "ego speed from the ego-speed estimator; default: ttc)")
    p.add_argument("--gps-speed", action="store_true",
                   help="monte_carlo: use the true ego speed (as a GPS would give) on frames where the "
                        "ego-speed estimator has no estimate (otherwise the estimator's fallback)")
    p.add_argument("--risk-horizon", type=float, default=10.0, metavar="S",
                   help="risk scoring: a frame is positive when a collision or near miss follows within S s "
                        "(default 10)")
    p.add_argument("--horizon", choices=("calibrated", "online"), default="calibrated",
                   help="horizon row of equation 3: the calibration's every frame, or this frame's lane-line "
                        "vanishing point (monorarp.horizon; for a camera that pitches on its mount; "
                        "default: calibrated)")
    p.add_argument("--frames", type=int, default=None, metavar="N",
                   help="number of frames (default: the scenario's duration x fps)")
    p.add_argument("--out", type=Path, default=None, metavar="DIR",
                   help="output directory (default: runs/<scenario name>; a previous run there is replaced)")
    p.add_argument("--threaded", action="store_true", help="one thread per stage (as in the paper)")
    p.add_argument("--no-video", action="store_true", help="write neither annotated.mp4 nor frames.mp4")
    p.add_argument("--warning-threshold", type=float, default=2.0, metavar="S",
                   help="TTC below which a warning is raised, s (default 2.0)")
    p.set_defaults(func=run)


def pipeline_config(args: argparse.Namespace):
    """The :class:`PipelineConfig` the command line describes."""
    from monorarp.pipeline import ComponentConfig, PipelineConfig

    ego = getattr(args, "ego_speed", "none")
    horizon = getattr(args, "horizon", "calibrated")
    return PipelineConfig(detector=detector_config(args),
                          tracker=ComponentConfig(name=args.tracker),
                          state=ComponentConfig(name="geometric", kwargs={"velocity": args.velocity}),
                          risk=ComponentConfig(name=getattr(args, "risk", "ttc")),
                          ego_speed=None if ego == "none" else ComponentConfig(name=ego),
                          horizon=None if horizon == "calibrated" else ComponentConfig(name=horizon))


def run(args: argparse.Namespace) -> int:
    from harness.run import run_scenario
    from harness.scenario import ScenarioError, load_scenario
    from harness.scoring.evaluate import EvalConfig
    from harness.scoring.tables import summary_table

    if args.frames is not None and args.frames <= 0:
        raise UserError(f"--frames: must be a positive integer, got {args.frames}")
    if not args.warning_threshold > 0:
        raise UserError(f"--warning-threshold: must be positive (s), got {args.warning_threshold}")
    if not args.risk_horizon > 0:
        raise UserError(f"--risk-horizon: must be positive (s), got {args.risk_horizon}")
    cfg = pipeline_config(args)
    scenario = load_scenario(args.scenario)
    if (args.frames or scenario.n_frames) <= 0:
        raise UserError(f"{args.scenario}: duration_s * fps gives no frames")
    out = args.out if args.out is not None else Path("runs") / scenario.name
    try:
        metrics = run_scenario(scenario, cfg, n_frames=args.frames, out_dir=out, threaded=args.threaded,
                               annotate=not args.no_video, write_frames=not args.no_video,
                               gps_speed=args.gps_speed,
                               eval_config=EvalConfig(warning_threshold_s=args.warning_threshold,
                                                      risk_horizon_s=args.risk_horizon))
    except ScenarioError as e:   # found by the simulation: make sure the message names the file
        msg = str(e)
        raise ScenarioError(msg if msg.startswith(str(args.scenario)) else f"{args.scenario}: {msg}") from None
    print(summary_table(metrics))
    print(f"\nwrote {out}/")
    return 0
