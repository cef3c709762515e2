"""``monorarp bench trackers``: the paper's Table III with accuracy, every tracker on identical frames and detections.

Writes ``DIR/trackers.json`` and ``DIR/trackers.md`` (see :mod:`harness.bench.trackers`).
"""

from __future__ import annotations

import argparse
from pathlib import Path

from harness.commands.cache_args import add_cache_arguments, cache_from_args
from harness.commands.detector_args import add_oracle_arguments, pipeline_config
from harness.commands.look_args import add_look_arguments, apply_look
from monorarp.app.common_options import add_frames_option, add_out_option
from monorarp.app.options import add_pipeline_options
from monorarp.core.errors import UserError


def _split(values: list[str] | None) -> list[str]:
    """``["a,b", "c"]`` -> ``["a", "b", "c"]``."""
    return [v.strip() for item in values or [] for v in item.split(",") if v.strip()]


def parse_seeds(values: list[str] | None) -> list[int] | None:
    """``["3-5", "9,11"]`` -> ``[3, 4, 5, 9, 11]`` (None: not given); a bad item, or more than
    :data:`~harness.bench.defaults.MAX_SEEDS` seeds, is a one-line error."""
    from harness.bench.defaults import MAX_SEEDS

    if values is None:
        return None
    seeds: dict[int, None] = {}                        # ordered, without repeats
    for item in _split(values):
        lo, sep, hi = item.partition("-")
        try:
            a, b = int(lo), int(hi if sep else lo)
        except ValueError:
            a, b = -1, -1
        if a < 0 or b < a:
            raise UserError(f"--seeds: expected non-negative integers or ranges like 3-12, got {item!r}")
        if b - a + 1 > MAX_SEEDS:                    # checked before the range is expanded
            raise UserError(f"--seeds: at most {MAX_SEEDS} seeds, got {item!r} ({b - a + 1} seeds)")
        seeds.update(dict.fromkeys(range(a, b + 1)))
        if len(seeds) > MAX_SEEDS:
            raise UserError(f"--seeds: at most {MAX_SEEDS} seeds in all, got {len(seeds)} by {item!r}")
    if not seeds:
        raise UserError("--seeds: no seed given")
    return list(seeds)


def register(sub: argparse._SubParsersAction) -> None:
    from harness.bench.defaults import DEFAULT_FRAMES, DEFAULT_SCENARIOS, DEFAULT_TRACKERS, MAX_SEEDS

    p = sub.add_parser("bench", help="benchmark component alternatives on identical frames",
                       description="Benchmark component alternatives on identical simulated frames.")
    bench_sub = p.add_subparsers(dest="bench_command", metavar="BENCHMARK")
    t = bench_sub.add_parser(
        "trackers", help="the paper's Table III: tracker runtime, with MOTA/IDF1/ID switches/distance error",
        description="Render each scenario once, run the detector once per frame, then run every tracker (plus the "
                    "same state and risk estimators) over the identical frames and detections and score it. Prints "
                    "the paper's Table III with accuracy added and writes DIR/trackers.json and DIR/trackers.md. With 5 "
                    "or more sequences (scenarios x seeds) it adds 95 % bootstrap intervals of each tracker's MOTA "
                    "and IDF1 and of its gap to the first tracker listed.")
    t.add_argument("--scenarios", nargs="+", default=None, metavar="SCENARIO.yaml",
                   help=f"scenario files, space- or comma-separated, each at most once (default: the shipped "
                        f"{','.join(DEFAULT_SCENARIOS)}, found from any directory)")
    t.add_argument("--trackers", nargs="+", default=None, metavar="NAME",
                   help=f"registered trackers, space- or comma-separated (default: {','.join(DEFAULT_TRACKERS)})")
    t.add_argument("--seeds", nargs="+", default=None, metavar="SEED",
                   help="run each scenario at each of these seeds (integers or ranges such as 3-12, space- or "
                        f"comma-separated; at most {MAX_SEEDS} seeds; one sequence per scenario and seed, all "
                        "pooled; default: each scenario's own)")
    add_pipeline_options(t, stages=("detector",))
    add_oracle_arguments(t)
    add_frames_option(t, help="frames per scenario, 1 <= N <= its duration_s x fps (default: "
                              f"{DEFAULT_FRAMES}, or all of a shorter scenario)")
    add_cache_arguments(t)
    add_look_arguments(t)
    add_out_option(t, default=Path("runs") / "bench-trackers",
                   help="output directory (default: runs/bench-trackers; a previous benchmark there is replaced)")
    t.set_defaults(func=run_trackers)
    p.set_defaults(func=lambda args: (p.print_help(), 2)[1])


def run_trackers(args: argparse.Namespace) -> int:
    from harness.bench.defaults import DEFAULT_FRAMES, DEFAULT_TRACKERS, default_scenarios
    from harness.bench.trackers import BenchConfig, run_bench, stderr_log, table_iii
    from harness.run.frame_cache import check_max_gb

    trackers = _split(args.trackers) if args.trackers is not None else list(DEFAULT_TRACKERS)
    scenarios = _split(args.scenarios) if args.scenarios is not None else default_scenarios()
    check_max_gb(args.cache_max_gb)              # even with --cache off
    seeds = parse_seeds(args.seeds)
    cfg = BenchConfig(scenarios=scenarios, trackers=trackers, pipeline=pipeline_config(args),
                      frames=DEFAULT_FRAMES if args.frames is None else args.frames, cap_frames=args.frames is None,
                      seeds=seeds)
    cfg.cache = lambda: cache_from_args(args)
    cfg.adjust = lambda sc: apply_look(sc, args)
    result = run_bench(cfg, out_dir=args.out, log=stderr_log)
    print(table_iii(result))
    print(f"\nwrote {args.out}/trackers.json and {args.out}/trackers.md")
    return 0
