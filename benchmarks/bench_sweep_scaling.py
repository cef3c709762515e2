"""Sweep scaling and the frame cache, measured end to end (simulate, render, pipeline, score, write).

    python benchmarks/bench_sweep_scaling.py [--workers 1 2 4] [--seeds 8] [--frames 30] [--ray]
                                             [--variants particle sort bytetrack] [--cache-seeds 4]
                                             [--model-workers 1 2 4 8 16] [--skip-scaling] [--skip-cache]

1. **Scaling**: one sweep (``--scenario`` at 640x360, ``--seeds`` runs, one variant, so every run
   renders its own instance; frame cache off) with each worker count, on the local process pool and
   (``--ray``) on a local Ray instance started by the sweep. Prints wall time of the whole
   ``run_sweep`` call (worker or Ray start-up, expansion, summary and report included), simulated
   frames/s (frames of all runs / wall time), speed-up over 1 worker of the same executor and
   efficiency = speed-up / workers.
2. **Render once**: a sweep with several variants per scenario instance (``--variants``, one
   tracker each, same detector) with ``--cache off`` (every variant renders), a cold cache (each
   instance renders once) and the warm cache (nothing renders), at 1 worker and at the largest
   ``--workers``. Results are identical in all three (``tests/test_render_cache.py``).
3. **Scheduler model** (not a measurement): ``--model-runs`` runs cycling the per-run wall times
   measured in part 1 at 1 worker, list-scheduled in order on ``--model-workers`` idle workers,
   plus the measured fixed cost (sweep wall time minus the sum of run times) and a per-worker
   warm-up (the first run's excess over the median: imports, EGL start): what a machine with that
   many idle cores could reach at best. It ignores memory-bandwidth and Mesa contention.

The load average of the machine is printed before and after each part: on a shared machine the
figures are only as good as the idle cores behind them.
"""

from __future__ import annotations

import argparse
import heapq
import os
import statistics
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_sweep import add_spec_options, bench, write_spec  # noqa: E402  (sets sys.path for the repository and PYOPENGL_PLATFORM)

from harness.bench.script import run_script


def load() -> str:
    a, b, c = os.getloadavg()
    return f"load average {a:.2f} {b:.2f} {c:.2f}"


def makespan(times: list[float], workers: int) -> float:
    """Finish time (s) of ``times`` handed out in order to the first free of ``workers`` workers."""
    free = [0.0] * workers
    for t in times:
        heapq.heappush(free, heapq.heappop(free) + t)
    return max(free)


def scaling(tmp: Path, args: argparse.Namespace) -> list[dict]:
    spec = write_spec(tmp, args, name="scaling")
    runs = args.seeds
    print(f"\n1. scaling: {args.scenario} 640x360, {runs} runs x {args.frames} frames, one variant "
          f"(detector {args.detector}, tracker {args.tracker}), frame cache off; {os.cpu_count()} CPUs; {load()}")
    print(f"{'executor':8s} {'workers':>7s} {'wall s':>8s} {'frames/s':>9s} {'speed-up':>8s} {'efficiency':>10s} "
          f"{'mean run s':>10s}")
    rows = []
    for executor in ("local", "ray") if args.ray else ("local",):
        for w in args.workers:
            r = bench(spec, tmp / f"scale-{executor}{w}", executor, w)
            rows.append(r)
            one = next((x["wall_s"] for x in rows if x["executor"] == executor and x["workers"] == 1), None)
            r["speedup"] = one / r["wall_s"] if one else float("nan")
            r["efficiency"] = r["speedup"] / w
            print(f"{executor:8s} {w:7d} {r['wall_s']:8.1f} {r['fps']:9.1f} {r['speedup']:8.2f} "
                  f"{100 * r['efficiency']:9.0f}% {sum(r['run_walls_s']) / len(r['run_walls_s']):10.2f}", flush=True)
    print(f"({load()})")
    return rows


def cache_part(tmp: Path, args: argparse.Namespace) -> None:
    from harness.run.frame_cache import FrameCache

    sub = argparse.Namespace(**{**vars(args), "seeds": args.cache_seeds})
    spec = write_spec(tmp, sub, trackers=args.variants, name="variants")
    n_runs, n_inst = args.cache_seeds * len(args.variants), args.cache_seeds
    print(f"\n2. render once: {n_inst} scenario instances x {len(args.variants)} variants ({', '.join(args.variants)}) "
          f"= {n_runs} runs x {args.frames} frames; {load()}")
    print(f"{'workers':>7s} {'cache':6s} {'new entries':>11s} {'wall s':>8s} {'frames/s':>9s} {'vs off':>7s}")
    for w in sorted({1, max(args.workers)}):
        cache = FrameCache(tmp / f"cache{w}", max_bytes=None)
        off = None
        for label, c in (("off", None), ("cold", cache), ("warm", cache)):
            before = len(cache.entries())
            r = bench(spec, tmp / f"variants-{label}{w}", "local", w, c)
            off = off or r["wall_s"]
            new = "-" if c is None else str(len(cache.entries()) - before)
            print(f"{w:7d} {label:6s} {new:>11s} {r['wall_s']:8.1f} {r['fps']:9.1f} {off / r['wall_s']:6.2f}x",
                  flush=True)
    print(f"({load()})")


def model(rows: list[dict], workers: list[int], n_runs: int) -> None:
    """Part 3: list scheduling of the measured 1-worker run times (see the module docstring)."""
    one = next((r for r in rows if r["executor"] == "local" and r["workers"] == 1), None)
    if one is None:
        return
    times = one["run_walls_s"]
    steady = statistics.median(times)
    warm_up = max(0.0, times[0] - steady)          # the first run in a process also imports and starts EGL
    fixed = max(0.0, one["wall_s"] - sum(times))   # expansion, summary, report
    runs = [steady if i == 0 else t for i, t in enumerate(times)]
    runs = (runs * (n_runs // len(runs) + 1))[:n_runs]
    t1 = fixed + warm_up + sum(runs)
    print(f"\n3. scheduler model (NOT measured): {n_runs} runs cycling the {len(times)} measured 1-worker run times "
          f"(median {steady:.2f} s), + {warm_up:.1f} s process warm-up per worker + {fixed:.1f} s fixed; idle workers, "
          f"no contention")
    print(f"{'workers':>7s} {'wall s':>8s} {'speed-up':>8s} {'efficiency':>10s}")
    for w in workers:
        tw = fixed + warm_up + makespan(runs, w)
        print(f"{w:7d} {tw:8.1f} {t1 / tw:8.2f} {100 * t1 / tw / w:9.0f}%")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    cpus = os.cpu_count() or 1
    ap.add_argument("--workers", type=int, nargs="+",
                    default=[w for w in (1, 2, 4, 8, 16, 32, 64) if w <= max(2, cpus)])
    ap.add_argument("--seeds", type=int, default=8, help="runs of the scaling sweep (one per seed)")
    ap.add_argument("--frames", type=int, default=30, help="frames per run")
    add_spec_options(ap)
    ap.add_argument("--ray", action="store_true", help="also run each worker count on a local Ray instance")
    ap.add_argument("--variants", nargs="+", default=["particle", "sort", "bytetrack"],
                    help="trackers of the render-once sweep, one variant each")
    ap.add_argument("--cache-seeds", type=int, default=4, help="scenario instances of the render-once sweep")
    ap.add_argument("--model-workers", type=int, nargs="+", default=[1, 2, 4, 8, 16])
    ap.add_argument("--model-runs", type=int, default=128, help="runs of the modelled sweep")
    ap.add_argument("--skip-scaling", action="store_true")
    ap.add_argument("--skip-cache", action="store_true")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory(prefix="bench_scaling-") as d:
        tmp = Path(d)
        rows = [] if args.skip_scaling else scaling(tmp, args)
        if not args.skip_cache:
            cache_part(tmp, args)
        model(rows, args.model_workers, args.model_runs)


if __name__ == "__main__":
    run_script(main)
