"""Throughput and figures of ``monorarp eval kitti`` on KITTI-size frames.

Usage: python benchmarks/bench_eval_kitti.py [--frames 150] [--size 1242x375] [--scenario S.yaml]
                                             [--kind kitti|kitti-tracking] [--data DIR] [--detector centernet]

Renders ``--frames`` frames of the scenario at ``--size`` and exports them as a KITTI dataset
(``monorarp export``; not timed; kept in ``--data`` when given and reused when it exists), then
runs the evaluation (:func:`harness.kitti_eval.evaluate.evaluate_kitti`) with the detector and with
the labels as an oracle. Prints frames/s of the whole evaluation (reading labels, PNG decoding,
pipeline, scoring, writing) and of the pipeline alone; the CPU time per frame in all threads and in
the main thread alone (the critical path: images decode on a second thread); the mean ms per
stage; distance/lateral errors, detection precision/recall and Car AP. Wall-clock figures depend
on the machine's load; CPU times much less.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import yaml

from harness.bench.script import run_script

ROOT = Path(__file__).resolve().parents[1]


def export_dataset(scenario: Path, size: tuple[int, int], frames: int, kind: str, out: Path) -> None:
    from harness.export.exporter import export
    from harness.export.source import open_source

    from harness.world.scenario import load_scenario_dict

    data = load_scenario_dict(scenario)             # a missing or malformed file: one line (ScenarioError)
    data["camera"] = {**(data.get("camera") or {}), "width": size[0], "height": size[1]}
    with tempfile.TemporaryDirectory() as tmp:
        scen = Path(tmp) / scenario.name
        scen.write_text(yaml.safe_dump(data, sort_keys=False))
        export(open_source(scen, frames), kind, out, progress=False)


def frame_size(text: str) -> tuple[int, int]:
    """``"1242x375"`` -> (1242, 375); anything else is an argparse error."""
    w, sep, h = text.lower().partition("x")
    if not (sep and w.isdigit() and h.isdigit() and int(w) >= 64 and int(h) >= 64):
        raise argparse.ArgumentTypeError(f"expected WIDTHxHEIGHT in px (each >= 64), got {text!r}")
    return int(w), int(h)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=150)
    ap.add_argument("--size", type=frame_size, default="1242x375", help="WIDTHxHEIGHT (default 1242x375)")
    ap.add_argument("--scenario", type=Path, default=ROOT / "scenarios" / "highway_cruise.yaml")
    ap.add_argument("--kind", default="kitti", choices=("kitti", "kitti-tracking"))
    ap.add_argument("--data", type=Path, default=None, help="keep (or reuse) the exported dataset here")
    ap.add_argument("--detector", default="centernet")
    args = ap.parse_args()
    size = args.size

    from harness.kitti_eval.evaluate import KittiEvalOptions, evaluate_kitti
    from harness.kitti_eval.reader import open_dataset

    with tempfile.TemporaryDirectory() as tmp:
        data = args.data or Path(tmp) / "data"
        if not data.exists():
            t0 = time.perf_counter()
            export_dataset(args.scenario, size, args.frames, args.kind, data)
            print(f"exported {args.frames} frames at {size[0]}x{size[1]} in {time.perf_counter() - t0:.1f} s -> {data}")
        for det in (args.detector, "labels"):
            t0, c0, m0 = time.perf_counter(), time.process_time(), time.thread_time()
            ds = open_dataset(data)
            m = evaluate_kitti(ds, KittiEvalOptions(detector=det), Path(tmp) / f"out-{det}")
            wall, cpu, main_cpu = time.perf_counter() - t0, time.process_time() - c0, time.thread_time() - m0
            rt = m["runtime_ms"]
            d, lat, dd = m["distance"], m["lateral"], m["detection"]
            print(f"\n{det}: {m['frames']} frames ({ds.kind}) in {wall:.2f} s = {m['frames'] / wall:.1f} frames/s "
                  f"overall ({cpu / m['frames'] * 1e3:.1f} ms CPU per frame in all threads, "
                  f"{main_cpu / m['frames'] * 1e3:.1f} ms in the main thread); pipeline {m['fps']:.1f} frames/s "
                  f"(detector {rt['detector']:.2f} ms, state "
                  f"{rt['state']:.3f} ms, tracker {rt['tracker']:.3f} ms, total {rt['total']:.2f} ms per frame)")
            print(f"  distance: {d['count']} pairs, |err| median {d['abs_err_median_m']} m, rel. median "
                  f"{d['rel_err_median']}, p90 {d['rel_err_p90']}; lateral |err| median {lat['abs_err_median_m']} m")
            print(f"  detection @IoU 0.5: precision {dd['precision']}, recall {dd['recall']}")
            for thr in ("0.7", "0.5"):
                a = m["kitti_ap"][f"iou_{thr}"]
                print(f"  Car AP @IoU {thr}: " + ", ".join(
                    f"{k} R40 {v['ap_r40']:.4f} R11 {v['ap_r11']:.4f} (devkit sampling {v['ap_r40_devkit']:.4f} / "
                    f"{v['ap_r11_devkit']:.4f}; {v['valid']} cars)" for k, v in a.items()))
            if m["tracking"]["mota"] is not None:
                t = m["tracking"]
                print(f"  tracking: MOTA {t['mota']}, IDF1 {t['idf1']}, HOTA {t['hota']}")


if __name__ == "__main__":
    run_script(main)
