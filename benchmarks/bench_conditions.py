"""Detector recall within 40 m and rendering frames/s under each light/weather condition.

Usage: python benchmarks/bench_conditions.py [--frames N] [--conditions day,dusk,...] [--fps-only | --recall-only]
       [--dehaze] [--detector NAME[,NAME...]]

Recall: highway_cruise (640x360, its seed) rendered with each ``conditions:`` block; the
shipped detector (centernet) runs on every frame; a ground-truth vehicle counts when its
visibility (id pass, so fog and darkness do not hide it) is >= 0.3 and its d_long <= 40 m;
a detection matches at IoU >= 0.5 (harness.scoring.match.split_ignored, as the scorer).
``--dehaze``: the detector removes haze first (``centernet`` with ``dehaze: true``).
``--detector``: registered detector names or .onnx paths (default ``centernet``), comma-separated:
each runs on the same rendered frames and gets its own line.
Recall = matched counted / counted, pooled over frames; ratio = recall / recall(day).
Precision = matched / detections, leaving out (as the scorer) detections matched to or covering
an uncounted vehicle and those whose box bottom meets the ground beyond 40 m.
Frames/s: render() alone (colour + id pass + depth + effects, no simulation), wall clock
and process CPU time per frame.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from harness.bench.script import run_script
from harness.world.ground_truth import frame_truth
from harness.render.renderer import Renderer
from harness.world.scenario import load_scenario_dict, parse_scenario
from harness.scoring.rules import out_of_range
from harness.scoring.match import MIN_IOU, as_boxes, split_ignored
from harness.simulation.simulator import simulate
from monorarp.pipeline.detectors import build_detector
from monorarp.pipeline.config import ComponentConfig

CONDITIONS = {
    "day": None,
    "low_sun": {"time_of_day": "low_sun"},
    "dusk": {"time_of_day": "dusk"},
    "night": {"time_of_day": "night"},
    "fog_200m": {"fog_visibility_m": 200.0},
    "fog_100m": {"fog_visibility_m": 100.0},
    "dusk_fog_100m": {"time_of_day": "dusk", "fog_visibility_m": 100.0},
    "rain": {"rain": 1.0},
    "lens": {"exposure_s": 0.02, "readout_s": 0.03, "jpeg_quality": 40},
    "all": {"time_of_day": "dusk", "fog_visibility_m": 100.0, "rain": 1.0, "exposure_s": 0.02,
            "readout_s": 0.03, "jpeg_quality": 40},
}
MAX_RANGE_M = 40.0
MIN_VISIBILITY = 0.3


def scenario(cond: dict | None, width: int = 640, height: int = 360, seed: int | None = None):
    d = load_scenario_dict("scenarios/highway_cruise.yaml")
    if seed is not None:
        d["seed"] = seed
    d["camera"] = {"width": width, "height": height}
    d["conditions"] = cond
    return parse_scenario(d)


def recall(cond: dict | None, n_frames: int, dehaze: bool = False, seed: int | None = None,
           detectors: tuple[str, ...] = ("centernet",)) -> list[tuple[float, int, int, float]]:
    """Per detector: (recall, matched, counted, precision) on the same frames."""
    sc = scenario(cond, seed=seed)
    kw = {"dehaze": True} if dehaze else {}
    built = [build_detector(ComponentConfig(name=name, kwargs=kw), sc.camera.model()) for name in detectors]
    tp, n_pred = np.zeros(len(built), int), np.zeros(len(built), int)
    n = 0
    with Renderer(sc) as r:
        for world in simulate(sc, n_frames):
            f = r.render(world)
            truth = frame_truth(world, r.camera, f.id_mask, f.full_pixels)
            objs = truth.objects
            counted = np.array([o.visibility >= MIN_VISIBILITY and o.d_long <= MAX_RANGE_M for o in objs],
                               dtype=bool)
            for k, detector in enumerate(built):
                dets = as_boxes([d.box for d in detector.detect(f.image)])
                kept, ignored = split_ignored(as_boxes([o.box for o in objs]), counted, dets, MIN_IOU, 0.5,
                                              out_of_range(dets, r.camera, MAX_RANGE_M))
                tp[k] += len(kept)
                n_pred[k] += int((~ignored).sum())
            n += int(counted.sum())
    return [((t / n if n else float("nan")), int(t), n, (t / p if p else float("nan"))) for t, p in zip(tp, n_pred)]


def render_fps(cond: dict | None, n_frames: int) -> tuple[float, float]:
    sc = scenario(cond)
    worlds = list(simulate(sc, n_frames + 3))
    with Renderer(sc) as r:
        for w in worlds[:3]:
            r.render(w)
        t0, c0 = time.perf_counter(), time.process_time()
        for w in worlds[3:]:
            r.render(w)
        wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    return n_frames / wall, 1000 * cpu / n_frames


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=300)
    ap.add_argument("--conditions", default=",".join(CONDITIONS))
    ap.add_argument("--fps-only", action="store_true")
    ap.add_argument("--recall-only", action="store_true")
    ap.add_argument("--dehaze", action="store_true", help="detector with dehaze: true")
    ap.add_argument("--seed", type=int, default=None, help="scenario seed (default: highway_cruise's, 1)")
    ap.add_argument("--detector", default="centernet",
                    help="detector name(s) or .onnx path(s), comma-separated, run on the same frames")
    args = ap.parse_args()
    names = args.conditions.split(",")
    unknown = [n for n in names if n not in CONDITIONS]
    if unknown:
        ap.error(f"--conditions: unknown {', '.join(unknown)}; available: {', '.join(CONDITIONS)}")
    detectors = tuple(args.detector.split(","))
    day: dict[str, float] = {}
    for name in names:
        line = f"{name:15s}"
        if not args.recall_only:
            fps, cpu_ms = render_fps(CONDITIONS[name], min(args.frames, 60))
            line += f" render {fps:5.1f} frames/s ({cpu_ms:5.1f} ms CPU/frame)"
        if args.fps_only:
            print(line, flush=True)
            continue
        for det, (rec, tp, n, prec) in zip(detectors, recall(CONDITIONS[name], args.frames, args.dehaze, args.seed,
                                                             detectors)):
            if name == "day":
                day[det] = rec
            ratio = f"{rec / day[det]:.3f}" if day.get(det) else "-"
            tag = f" [{det}]" if len(detectors) > 1 else ""
            print(line + f"  recall<=40m {rec:.3f} ({tp}/{n})  ratio to day {ratio}  precision {prec:.3f}{tag}",
                  flush=True)


if __name__ == "__main__":
    run_script(main)
