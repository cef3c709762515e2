"""What a detector makes of each rendered body type: found and labelled-as, per type of a mixed fleet.

Usage: python benchmarks/bench_body_types.py [--detector yolox] [--seeds N] [--frames N] [--look-family train]

Renders ``scenarios/looks/kitti_camera.yaml`` (KITTI's camera over three-lane traffic, the realistic look)
with ``traffic.fleet: mixed`` (:mod:`harness.world.fleet`) at ``--seeds`` seeds (each its own draw of the
look), ``--frames`` frames each (1 s apart, after 1 s), runs the detector on every frame and, for every
vehicle at most 80 m ahead, at least 25 px tall (KITTI's moderate height) and at least half visible,
counts whether a detection covers it at IoU >= 0.5 and the label of the best one. KITTI's Car AP counts
only detections labelled ``car`` on hatchbacks, saloons, estates, SUVs and pickups (all ``Car`` in KITTI):
a ``truck`` on an SUV is a miss there. Prints one row per body type.
"""

from __future__ import annotations

import argparse
import collections
from pathlib import Path

import numpy as np

from harness.bench.script import run_script
from monorarp.core.errors import UserError

ROOT = Path(__file__).resolve().parent.parent
SCENARIO = ROOT / "scenarios" / "looks" / "kitti_camera.yaml"
MIN_HEIGHT_PX, MIN_VISIBILITY, MAX_DISTANCE_M, MIN_IOU = 25.0, 0.5, 80.0, 0.5


def count(detector: str, seeds: int, frames: int, family: str) -> dict[str, collections.Counter]:
    """Body type -> counts of ``n`` (vehicles), ``found`` and ``label:<name>`` of the best detection."""
    from harness.render.renderer import Renderer
    from harness.simulation.simulator import simulate
    from harness.world.ground_truth import frame_truth
    from harness.world.scenario import load_scenario
    from monorarp.core.boxes import iou
    from monorarp.pipeline.detectors import load_detector

    base = load_scenario(SCENARIO)
    det = load_detector(detector, camera=base.camera.model())
    step = max(int(round(base.fps)), 1)
    stats: dict[str, collections.Counter] = collections.defaultdict(collections.Counter)
    for seed in range(seeds):
        sc = base.model_copy(update={
            "seed": seed, "traffic": base.traffic.model_copy(update={"fleet": "mixed"}),
            "render": base.render.model_copy(update={"look": "realistic", "look_family": family, "look_seed": seed})})
        states = list(simulate(sc, step * (frames + 1)))[step::step][:frames]
        with Renderer(sc) as r:
            for world in states:
                fr = r.render(world)
                truth = frame_truth(world, sc.camera.model(), fr.id_mask, fr.full_pixels)
                dets = det.detect(fr.image)
                boxes = np.array([d.box for d in dets], float).reshape(-1, 4)
                for o in truth.objects:
                    if o.visibility < MIN_VISIBILITY or o.box[3] - o.box[1] < MIN_HEIGHT_PX or o.d_long > MAX_DISTANCE_M:
                        continue
                    c = stats[o.body or "none"]
                    c["n"] += 1
                    if len(boxes):
                        overlap = iou(boxes, np.array(o.box, float)[None]).ravel()
                        k = int(np.argmax(overlap))
                        if overlap[k] >= MIN_IOU:
                            c["found"] += 1
                            c[f"label:{dets[k].label}"] += 1
    return stats


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--detector", default="yolox")
    ap.add_argument("--seeds", type=int, default=12)
    ap.add_argument("--frames", type=int, default=5)
    ap.add_argument("--look-family", choices=("train", "heldout"), default="train")
    args = ap.parse_args()
    if args.seeds < 1 or args.frames < 1:
        raise UserError("--seeds and --frames must be positive")
    stats = count(args.detector, args.seeds, args.frames, args.look_family)
    print(f"| body | vehicles | found (IoU >= {MIN_IOU}) | labelled |")
    print("|---|---|---|---|")
    for body, c in sorted(stats.items()):
        labels = ", ".join(f"{k[6:]} {v}" for k, v in sorted(c.items(), key=lambda kv: -kv[1]) if k.startswith("label:"))
        print(f"| {body} | {c['n']} | {c['found']} ({c['found'] / c['n']:.0%}) | {labels or '-'} |")


if __name__ == "__main__":
    run_script(main)
