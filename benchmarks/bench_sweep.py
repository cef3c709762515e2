"""End-to-end sweep throughput: simulated frames per second, aggregated over runs (simulate, render,
run the pipeline, score, write), at 640x360, with 1 and 2 local workers (and optionally Ray).

    python benchmarks/bench_sweep.py [--workers 1 2] [--seeds 4] [--frames 60] [--ray] [--cache DIR|off]

Each configuration runs the same sweep (one scenario x N seeds x one variant) into a fresh
directory; the figure is total frames / wall time of the whole `run_sweep` call, which includes
worker start-up, expansion, summary and report. The per-run figure (frames / run wall time,
from run.json) shows the steady state without those fixed costs. The frame cache is off unless
``--cache DIR`` is given (then every configuration after the first reads its frames from it).
Scaling (speed-up, efficiency) and cold/warm cache: ``benchmarks/bench_sweep_scaling.py``.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

import yaml

from harness.bench.script import run_script

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
os.environ.setdefault("PYOPENGL_PLATFORM", "egl")


def add_spec_options(ap: argparse.ArgumentParser) -> None:
    """The options ``write_spec`` reads besides ``--seeds`` and ``--frames``: scenario, detector, tracker."""
    ap.add_argument("--scenario", default="scenarios/highway_cruise.yaml")
    ap.add_argument("--detector", default="oracle")
    ap.add_argument("--tracker", default="particle")


def write_spec(tmp: Path, args: argparse.Namespace, trackers: list[str] | None = None, name: str = "bench") -> Path:
    """A sweep spec: ``args.scenario`` x ``args.seeds`` seeds x one variant per tracker (default ``args.tracker``)."""
    spec = {"name": name, "scenarios": [{"file": str((ROOT / args.scenario).resolve()),
                                         "overrides": {"duration_s": args.frames / 15 + 1, "fps": 15}}],
            "seeds": list(range(1, args.seeds + 1)), "frames": args.frames,
            "overrides": {"camera.width": 640, "camera.height": 360},
            "variants": [{"name": t, "detector": args.detector, "tracker": t} for t in trackers or [args.tracker]]}
    p = tmp / f"{name}.yaml"
    p.write_text(yaml.safe_dump(spec, sort_keys=False))
    return p


def bench(spec: Path, out: Path, executor: str, workers: int, cache: object = None) -> dict:
    """One ``run_sweep`` into ``out``; ``cache``: a :class:`harness.run.frame_cache.FrameCache` or None (off)."""
    from harness.sweep.orchestrate import run_sweep

    t0 = time.perf_counter()
    res = run_sweep(spec, out, executor=executor, workers=workers, progress=False, cache=cache)
    wall = time.perf_counter() - t0
    if res.failed:
        raise SystemExit(f"runs failed: {[r['error'] for r in res.failed]}")
    frames = sum(r["metrics"]["frames"] for r in res.rows)
    run_walls = [json.loads((out / "runs" / r["id"] / "run.json").read_text())["wall_time_s"] for r in res.rows]
    per_run_fps = [r["metrics"]["frames"] / w for r, w in zip(res.rows, run_walls)]
    pipeline_fps = statistics.mean(r["metrics"]["fps"] for r in res.rows)
    return {"executor": executor, "workers": workers, "runs": len(res.rows), "frames": frames, "wall_s": wall,
            "fps": frames / wall, "per_run_fps": statistics.mean(per_run_fps), "pipeline_fps": pipeline_fps,
            "run_walls_s": run_walls}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--seeds", type=int, default=4, help="runs per configuration (one per seed)")
    ap.add_argument("--frames", type=int, default=60, help="frames per run")
    add_spec_options(ap)
    ap.add_argument("--ray", action="store_true", help="also run each worker count on a local Ray instance")
    ap.add_argument("--cache", default="off", metavar="DIR|off", help="frame cache (default off)")
    args = ap.parse_args()
    from harness.run.frame_cache import open_cache

    cache = open_cache(args.cache, None)

    print(f"sweep throughput: {args.scenario} at 640x360, {args.seeds} runs x {args.frames} frames, "
          f"detector {args.detector}, tracker {args.tracker}; {os.cpu_count()} CPUs")
    print(f"{'executor':8s} {'workers':>7s} {'frames':>7s} {'wall s':>8s} {'frames/s':>9s} "
          f"{'per-run f/s':>11s} {'pipeline f/s':>12s}")
    configs = [("local", w) for w in args.workers] + ([("ray", w) for w in args.workers] if args.ray else [])
    with tempfile.TemporaryDirectory(prefix="bench_sweep-") as d:
        tmp = Path(d)
        spec = write_spec(tmp, args)
        for executor, workers in configs:
            r = bench(spec, tmp / f"{executor}{workers}", executor, workers, cache)
            print(f"{r['executor']:8s} {r['workers']:7d} {r['frames']:7d} {r['wall_s']:8.1f} {r['fps']:9.1f} "
                  f"{r['per_run_fps']:11.1f} {r['pipeline_fps']:12.1f}", flush=True)
    print("frames/s: aggregated end to end (simulate + render + pipeline + score + write, incl. worker start-up); "
          "per-run f/s: mean of frames / run wall time; pipeline f/s: the pipeline stages alone (metrics 'fps').")


if __name__ == "__main__":
    run_script(main)
