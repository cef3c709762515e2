"""The dense-traffic tracking target, measured: prints target vs measured for the shipped pipeline.

    python benchmarks/bench_tracking.py [--detector NAME] [--tracker NAME] [--seeds 3-12] [--frames 300]
        [--no-cache] [--out DIR]

Target (issue "collision-warning scorecard", item 8): ``dense_traffic`` with the shipped detector and
the particle tracker at MOTA >= 0.95 and IDF1 >= 0.95, without losing what ``highway_cruise`` and
``cut_in`` have (MOTA and IDF1 1.000). Prints three kinds of row:

* each scenario as written, whole (what ``monorarp run SCENARIO`` scores: ``dense_traffic`` is seed 2);
* ``dense_traffic`` at other seeds (default 3-12, ``--frames`` each), pooled as ``monorarp bench
  trackers --seeds`` pools them, with the 95 % sequence-bootstrap interval of the pooled MOTA and
  IDF1 (:mod:`harness.scoring.bootstrap`): the held-out figure and how far another draw of
  sequences could move it;
* the wall time.

Frames come from the frame cache (``harness.run.frame_cache``; the outputs are identical with
``--no-cache``). ``--out DIR`` keeps each whole run's files and the pooled benchmark's
``trackers.json``. Nothing is asserted; the figures are printed.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from harness.bench.script import run_script
from harness.bench.targets import target_table
from harness.bench.trackers import BenchConfig, run_bench
from harness.commands.bench import parse_seeds
from harness.run.frame_cache import FrameCache, default_dir
from harness.run.runner import run_scenario
from harness.world.scenario import load_scenario
from monorarp.pipeline.config import ComponentConfig, PipelineConfig

SCENARIOS = Path(__file__).resolve().parents[1] / "scenarios"
#: scenario -> MOTA and IDF1 it must reach (dense_traffic: the target; the others: what they have)
WHOLE_RUNS = {"dense_traffic": 0.95, "highway_cruise": 1.0, "cut_in": 1.0}
TARGET = 0.95


def _fmt(v) -> str:
    return "–" if v is None or v != v else f"{v:.3f}"


def _scores(t) -> str:
    """MOTA / IDF1 and the error counts of a ``tracking`` section (one run's, or pooled)."""
    return (f"{_fmt(t['mota'])} / {_fmt(t['idf1'])}  (misses {t['misses']}, FP {t['false_positives']}, "
            f"id switches {t['id_switches']} of {t['objects']})")


def whole_run_row(name: str, required: float, cfg: PipelineConfig, cache: FrameCache | None,
                  out: Path | None) -> tuple[str, str, str]:
    """(row label, required, measured) of ``monorarp run scenarios/NAME.yaml``."""
    scenario = load_scenario(SCENARIOS / f"{name}.yaml")
    metrics = run_scenario(scenario, cfg, out_dir=None if out is None else out / name, annotate=False,
                           write_frames=False, cache=cache)
    return f"{name} seed {scenario.seed}, whole run, MOTA / IDF1", f">= {required:.2f} each", _scores(metrics["tracking"])


def pooled_rows(seeds: list[int], frames: int, cfg: PipelineConfig, cache: FrameCache | None,
                out: Path | None) -> list[tuple[str, str, str]]:
    """Rows of the pooled ``dense_traffic`` benchmark at ``seeds`` (point and 95 % interval)."""
    tracker = cfg.tracker.name
    result = run_bench(BenchConfig(scenarios=[SCENARIOS / "dense_traffic.yaml"], trackers=[tracker], frames=frames,
                                   seeds=seeds, pipeline=cfg, cache=cache),
                       out_dir=None if out is None else out / "dense_traffic_pooled")
    label = f"dense_traffic seeds {_seed_text(seeds)}, {frames} frames each, pooled"
    rows = [(f"{label}, MOTA / IDF1", f">= {TARGET:.2f} each", _scores(result["trackers"][tracker]))]
    boot = result["bootstrap"]
    if boot:
        b = boot["trackers"][tracker]
        rows.append((f"  its {100 * boot['level']:.0f} % interval over sequences, MOTA / IDF1",
                     "(information)",
                     f"{_fmt(b['mota'][0])}-{_fmt(b['mota'][1])} / {_fmt(b['idf1'][0])}-{_fmt(b['idf1'][1])}"))
    return rows


def _seed_text(seeds: list[int]) -> str:
    contiguous = seeds == list(range(seeds[0], seeds[0] + len(seeds)))
    return f"{seeds[0]}-{seeds[-1]}" if contiguous and len(seeds) > 2 else ",".join(map(str, seeds))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--detector", default="centernet", help="detector name or ONNX file (default: centernet)")
    ap.add_argument("--tracker", default="particle", help="tracker name (default: particle)")
    ap.add_argument("--seeds", nargs="+", default=["3-12"],
                    help="dense_traffic seeds pooled, e.g. 3-12 or 1,4-6 (default 3-12; its own seed 2 is the whole run)")
    ap.add_argument("--frames", type=int, default=300, help="frames per pooled sequence (default 300, the whole 20 s)")
    ap.add_argument("--no-cache", action="store_true", help="render every frame (no frame cache)")
    ap.add_argument("--out", type=Path, default=None, help="keep the runs' files here")
    args = ap.parse_args()
    if args.frames <= 0:
        ap.error(f"--frames: must be a positive integer, got {args.frames}")
    seeds = parse_seeds(args.seeds)     # a bad item: one line, exit 2 (run_script)
    cfg = PipelineConfig(detector=ComponentConfig(name=args.detector), tracker=ComponentConfig(name=args.tracker))
    cfg.validate_names()                # an unknown name: one line, before anything renders
    cache = None if args.no_cache else FrameCache(default_dir())
    t0 = time.perf_counter()
    rows = [whole_run_row(name, req, cfg, cache, args.out) for name, req in WHOLE_RUNS.items()]
    rows += pooled_rows(seeds, args.frames, cfg, cache, args.out)
    rows.append(("wall time", "", f"{time.perf_counter() - t0:.0f} s"))
    print(target_table(f"tracking targets — detector {args.detector}, tracker {args.tracker}", rows))


if __name__ == "__main__":
    run_script(main)
