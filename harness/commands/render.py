"""``monorarp render SCENARIO.yaml --out DIR [--frames N]``.

Simulates the scenario, renders every frame and writes, atomically (the
directory appears complete or not at all):

* ``DIR/frames.mp4`` — H.264 video, one frame per simulation step at the scenario's fps;
* ``DIR/camera.json`` — :meth:`monorarp.core.camera.CameraModel.to_dict` of the rendering camera;
* ``DIR/ground_truth.jsonl`` — one :func:`harness.world.ground_truth.frame_truth` record per frame.
"""

from __future__ import annotations

import argparse
import itertools
import sys
import time
from pathlib import Path

from monorarp.app.common_options import add_frames_option, add_out_option
from harness.commands.look_args import add_look_arguments, apply_look
from monorarp.core.errors import UserError

VIDEO_NAME = "frames.mp4"
CAMERA_NAME = "camera.json"
GROUND_TRUTH_NAME = "ground_truth.jsonl"
OUTPUT_NAMES = (VIDEO_NAME, CAMERA_NAME, GROUND_TRUTH_NAME)


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "render",
        help="simulate and render a scenario to frames + ground truth",
        description="Simulate SCENARIO.yaml with highway-env, render dashcam frames offscreen and "
                    f"write DIR/{VIDEO_NAME}, DIR/{CAMERA_NAME} and DIR/{GROUND_TRUTH_NAME}. "
                    "DIR is replaced as a whole only when everything succeeded.",
    )
    p.add_argument("scenario", type=Path, metavar="SCENARIO.yaml", help="scenario file")
    add_out_option(p, required=True, help="output directory (created; a previous render there is replaced)")
    add_frames_option(p, help="render only the first N frames (1 .. duration_s * fps; default: all)")
    add_look_arguments(p)
    p.add_argument("--crf", type=int, default=18, metavar="Q",
                   help="H.264 quality, x264 constant rate factor 0..51 (lower = better; default 18)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from harness.world.scenario import ScenarioError, frames_to_simulate, load_scenario

    if not 0 <= args.crf <= 51:
        raise UserError(f"--crf: must be in 0..51, got {args.crf}")
    scenario = apply_look(load_scenario(args.scenario), args)
    n_frames = frames_to_simulate(scenario, args.frames, args.scenario, "render")
    try:
        stats = render_scenario(scenario, args.out, n_frames, crf=args.crf)
    except ScenarioError as e:  # found by the simulation: make sure the message names the file
        msg = str(e).removeprefix(f"scenario {scenario.name!r}: ")
        raise ScenarioError(msg if msg.startswith(str(args.scenario)) else f"{args.scenario}: {msg}") from None
    print(f"rendered {stats['frames']} frames ({stats['frames'] / scenario.fps:.2f} s at "
          f"{scenario.fps:g} fps) of '{scenario.name}', {stats['objects']} vehicles in view, "
          f"{stats['frames_per_s']:.1f} frames/s -> {args.out}")
    return 0


def render_scenario(scenario, out: str | Path, n_frames: int, *, crf: int = 18,
                    progress: bool | None = None) -> dict:
    """Render ``n_frames`` of ``scenario`` into ``out`` (atomically); returns summary figures.

    ``progress``: show a tqdm bar on stderr; ``None`` = only when stderr is a terminal.
    """
    from tqdm import tqdm

    from harness.world.ground_truth import frame_truth
    from harness.render.renderer import Renderer
    from harness.simulation.simulator import simulate
    from monorarp.app.io import JsonlWriter, atomic_output_dir, write_json_atomic
    from monorarp.app.video.writer import VideoWriter

    if progress is None:
        progress = sys.stderr.isatty()
    seen: set[int] = set()
    frames = 0
    start = time.perf_counter()
    # Set the simulation up (and let it reject what it cannot simulate) before any output exists.
    worlds = simulate(scenario, n_frames=n_frames)
    first = next(worlds, None)
    with atomic_output_dir(out, owned_names=OUTPUT_NAMES) as tmp:
        with Renderer(scenario) as renderer:
            camera = renderer.camera
            write_json_atomic(tmp / CAMERA_NAME, camera.to_dict())
            with VideoWriter(tmp / VIDEO_NAME, scenario.fps, (camera.width, camera.height), crf=crf) as video, \
                    JsonlWriter(tmp / GROUND_TRUTH_NAME) as truth:
                all_worlds = worlds if first is None else itertools.chain([first], worlds)
                bar = tqdm(all_worlds, total=n_frames, unit="frame",
                           desc=f"render {scenario.name}", file=sys.stderr, disable=not progress,
                           dynamic_ncols=True)
                with bar:
                    for world in bar:
                        rendered = renderer.render(world)
                        video.write(rendered.image)
                        record = frame_truth(world, camera, rendered)
                        truth.write(record.to_json())
                        seen.update(o.id for o in record.objects)
                        frames += 1
    elapsed = time.perf_counter() - start
    return {"frames": frames, "objects": len(seen),
            "frames_per_s": frames / elapsed if elapsed > 0 else float("nan")}
