"""Cost of the sub-pixel bottom-edge refinement: the whole pipeline with it on and off, interleaved.

Usage: PYOPENGL_PLATFORM=egl python benchmarks/bench_bottom_edge.py [--frames 60] [--reps 3]

Renders the first ``--frames`` frames of ``scenarios/highway_cruise.yaml`` (640x360) once, then
runs the shipped pipeline (foveated CenterNet, particle tracker, Kalman state, TTC risk,
ground-track ego speed, FCW warning) over them ``--reps`` times with ``refine_bottom`` off and
on, alternating, so both variants see the same machine load. Figures: mean ms per frame of the
detector stage and of all stages (frames/s = 1000 / that), the process's CPU time per frame
(``time.process_time``: the cost on a core of its own, unlike wall time on a shared machine),
the refinement alone per frame and per box (``refine_bottom`` on the detector's boxes), and
boxes per frame.
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

os.environ.setdefault("PYOPENGL_PLATFORM", "egl")

import numpy as np  # noqa: E402

from harness.bench.script import run_script  # noqa: E402
from harness.render.renderer import Renderer  # noqa: E402
from harness.run.runner import with_scenario_markings  # noqa: E402
from harness.world.scenario import load_scenario  # noqa: E402
from harness.simulation.simulator import simulate  # noqa: E402
from monorarp.detection.bottom_edge import refine_bottom  # noqa: E402
from monorarp.pipeline.config import ComponentConfig, PipelineConfig  # noqa: E402
from monorarp.pipeline.runner import Pipeline  # noqa: E402
from monorarp.core.types import Frame  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=60)
    ap.add_argument("--reps", type=int, default=3)
    a = ap.parse_args()
    scen = load_scenario(ROOT / "scenarios" / "highway_cruise.yaml")
    cam = scen.camera.model()
    with Renderer(scen) as r:
        frames = [Frame(w.frame, w.frame / scen.fps, r.render(w).image) for w in simulate(scen, a.frames)]
    pipes = {}
    for on in (False, True):
        cfg = PipelineConfig(detector=ComponentConfig(name="centernet", kwargs={"refine_bottom": on}),
                             ego_speed=ComponentConfig(name="ground_track"))
        pipes[on] = Pipeline.from_config(with_scenario_markings(cfg, scen), cam)
    det_ms = {False: [], True: []}
    tot_ms = {False: [], True: []}
    cpu_ms = {False: [], True: []}
    for _ in range(a.reps):
        for on in (False, True):
            p = pipes[on]
            p.reset()
            c0 = time.process_time()
            for f in frames:
                res = p.process(f)
                det_ms[on].append(res.timings_ms["detector"])
                tot_ms[on].append(sum(v for k, v in res.timings_ms.items() if k != "total"))
            cpu_ms[on].append((time.process_time() - c0) * 1e3 / len(frames))
    det = pipes[False].detector
    boxes = [det.detect_arrays(f.image)[0] for f in frames]
    n_box = sum(len(b) for b in boxes)
    t, c = time.perf_counter(), time.process_time()
    for _ in range(a.reps):
        for f, b in zip(frames, boxes):
            refine_bottom(f.image, b)
    ref_ms = (time.perf_counter() - t) * 1e3 / (a.reps * len(frames))
    ref_cpu = (time.process_time() - c) * 1e3 / (a.reps * len(frames))
    print(f"highway_cruise, {len(frames)} frames 640x360, {a.reps} reps each, {os.cpu_count()} CPUs")
    print(f"boxes per frame (detector, before the tracker): {n_box / len(frames):.2f}")
    print(f"refine_bottom alone: wall {ref_ms:.3f} ms/frame, CPU {ref_cpu:.3f} ms/frame "
          f"({ref_cpu * len(frames) / max(n_box, 1) * 1e3:.0f} us/box)")
    for on in (False, True):
        d, s, c = np.mean(det_ms[on]), np.mean(tot_ms[on]), np.mean(cpu_ms[on])
        print(f"refine_bottom={'on ' if on else 'off'}  wall: detector {d:.3f}, all stages {s:.3f} ms/frame "
              f"= {1e3 / s:.1f} frames/s;  CPU (whole process): {c:.3f} ms/frame = {1e3 / c:.1f} frames/s")
    print("CPU time (time.process_time) is what a frame costs on a core of its own; wall time includes "
          "waiting for a core on a shared machine")


if __name__ == "__main__":
    run_script(main)
