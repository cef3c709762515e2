"""Per-frame time of the pure pipeline stages (tracker, state, risk) with 10 vehicles.

Usage: python benchmarks/bench_pipeline.py [--frames 2000] [--vehicles 10]

Synthetic input: ``--vehicles`` boxes moving and growing steadily at 640x360 with
1 px jitter and 5 % missed detections (so some tracks coast). Each stage is timed
with ``time.perf_counter`` around its own call, after a 100-frame warm-up; the
figures are mean / median / p95 ms per frame. Also times the two runners with a
zero-cost detector, to show the runner overhead per frame.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from harness.bench.script import run_script
from monorarp.core.camera import CameraModel
from monorarp.pipeline.runner import Pipeline, run_sync, run_threaded
from monorarp.risk.estimators import TTCRiskEstimator
from monorarp.state.estimator import StateEstimator
from monorarp.tracking.particle import ParticleTracker
from monorarp.core.types import Detection, Frame

CAM = CameraModel.from_fov(640, 360, 60.0, 1.3)


def synthetic_detections(n_frames: int, n_vehicles: int, seed: int = 0) -> list[list[Detection]]:
    rng = np.random.default_rng(seed)
    cx = np.linspace(60, 580, n_vehicles)
    vx = rng.uniform(-0.1, 0.1, n_vehicles)
    w = rng.uniform(20, 45, n_vehicles)
    bottom = CAM.horizon_row + w * 0.9
    out = []
    for k in range(n_frames):
        s = 1 + 0.0005 * k
        bot = CAM.horizon_row + (bottom - CAM.horizon_row) * s
        boxes = np.stack([cx + vx * k - w * s / 2, bot - 0.8 * w * s, cx + vx * k + w * s / 2, bot], axis=1)
        boxes = boxes + rng.normal(0, 1.0, boxes.shape)
        keep = rng.random(n_vehicles) > 0.05
        out.append([Detection(tuple(b), 0.9) for b in boxes[keep]])
    return out


def stats(ms: list[float]) -> str:
    a = np.asarray(ms)
    return f"mean {a.mean():.3f}  median {np.median(a):.3f}  p95 {np.percentile(a, 95):.3f} ms/frame"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=2000)
    ap.add_argument("--vehicles", type=int, default=10)
    ap.add_argument("--particles", type=int, default=100)
    args = ap.parse_args()

    dets = synthetic_detections(args.frames + 100, args.vehicles)
    tracker, state, risk = ParticleTracker(n_particles=args.particles), StateEstimator(CAM), TTCRiskEstimator()
    times = {"tracker": [], "state": [], "risk": []}
    n_tracks, n_states = [], []
    for k, d in enumerate(dets):
        t = k / 30.0
        t0 = time.perf_counter()
        tracks = tracker.update(None, d, t)
        t1 = time.perf_counter()
        states = state.update(tracks, t)
        t2 = time.perf_counter()
        risk.assess(states, t)
        t3 = time.perf_counter()
        if k >= 100:
            times["tracker"].append((t1 - t0) * 1e3)
            times["state"].append((t2 - t1) * 1e3)
            times["risk"].append((t3 - t2) * 1e3)
            n_tracks.append(len(tracks))
            n_states.append(len(states))

    print(f"{args.vehicles} vehicles, {args.particles} particles/track, {args.frames} frames "
          f"(mean {np.mean(n_tracks):.1f} tracks, {np.mean(n_states):.1f} states per frame)")
    for name, ms in times.items():
        print(f"  {name:8s} {stats(ms)}")

    class Replay:  # zero-cost detector: replays the synthetic detections by frame index
        def detect(self, image):
            return dets[int(image[0, 0, 0]) + 256 * int(image[0, 0, 1])]

    def frames(n):
        img = np.zeros((2, 2, 3), np.uint8)
        for k in range(n):
            im = img.copy()
            im[0, 0, 0], im[0, 0, 1] = k % 256, k // 256
            yield Frame(k, k / 30.0, im)

    n = min(1000, len(dets))
    for name, runner in (("run_sync", run_sync), ("run_threaded", run_threaded)):
        pipe = Pipeline(Replay(), ParticleTracker(), StateEstimator(CAM), TTCRiskEstimator())
        t0 = time.perf_counter()
        results = list(runner(pipe, frames(n)))
        wall = (time.perf_counter() - t0) * 1e3 / n
        stage_sum = np.mean([sum(v for k, v in r.timings_ms.items() if k != "total") for r in results])
        print(f"  {name:12s} wall {wall:.3f} ms/frame ({1e3 / wall:.0f} frames/s); stages sum {stage_sum:.3f} ms")


if __name__ == "__main__":
    run_script(main)
