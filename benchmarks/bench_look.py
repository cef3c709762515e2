"""Realism of the renders, measured: detectors scored on renders as on real KITTI frames, per look.

Usage: python benchmarks/bench_look.py [--real DIR] [--looks simple realistic:train realistic:heldout]
                                       [--seeds N] [--frames N] [--detectors yolox centernet] [--fleet mixed]
                                       [--scene motorway|street]

For each look it renders ``scenarios/looks/kitti_camera.yaml`` (KITTI's camera over three-lane traffic; with
``--scene street`` ``scenarios/looks/street.yaml``: the same camera in an urban street with parked cars) at
``--seeds`` seeds (each seed its own traffic and, for the realistic look, its own draw of the look from the
family), ``--frames`` frames each (0.2 s apart), exports them as one KITTI object dataset
(:mod:`harness.export`) and runs ``monorarp eval kitti`` on it with each detector
(:func:`harness.kitti_eval.evaluate.evaluate_kitti`). With ``--real`` (a labelled KITTI dataset, e.g.
``../shared/real/kitti_object_dev``) the same detectors are scored on the real frames too, so a row of
renders stands beside the real one: Car AP_R40 easy/moderate/hard at IoU 0.5 and 0.7 (easy counts boxes
>= 40 px tall, moderate and hard >= 25 px: the difficulties match box sizes) and precision/recall at 0.5.
The realism target (issue 43): the real-world detector's moderate AP on the realistic renders within
+-0.10 of its AP on the real frames, judged on the gap's 95 % interval from image-bootstrap resamples of
both sets (met: the whole interval within +-0.10). Also prints the renders' frames/s per look.
"""

from __future__ import annotations

import argparse
import shutil
import tempfile
import time
from pathlib import Path

import numpy as np

from harness.bench.script import run_script
from monorarp.core.errors import UserError

ROOT = Path(__file__).resolve().parent.parent
SCENES = {"motorway": ROOT / "scenarios" / "looks" / "kitti_camera.yaml",
          "street": ROOT / "scenarios" / "looks" / "street.yaml"}
KITTI_HEIGHT_M = 1.65
DIFFICULTIES = ("easy", "moderate", "hard")


def parse_look(text: str) -> tuple[str, str]:
    look, _, family = text.partition(":")
    if look not in ("simple", "realistic") or family not in ("", "train", "heldout"):
        raise UserError(f"--looks: expected simple, realistic:train or realistic:heldout, got {text!r}")
    return look, family or "train"


def render_dataset(look: str, family: str, seeds: int, frames: int, out: Path, fleet: str | None = None,
                   scene: str = "motorway") -> float:
    """Export ``seeds`` x ``frames`` renders of the scene in one KITTI object dataset at ``out``; frames/s."""
    from harness.export.exporter import export
    from harness.export.source import open_source

    out.mkdir(parents=True)
    n_done, seconds = 0, 0.0
    for seed in range(seeds):
        def adjust(sc, seed=seed):
            render = sc.render.model_copy(update={"look": look, "look_family": family, "look_seed": seed})
            traffic = sc.traffic if fleet is None else sc.traffic.model_copy(update={"fleet": fleet})
            return sc.model_copy(update={"seed": seed, "render": render, "traffic": traffic})

        part = out.parent / f"{out.name}-part{seed}"
        t0 = time.perf_counter()
        export(open_source(SCENES[scene], frames, adjust), "kitti", part, progress=False)
        seconds += time.perf_counter() - t0
        for sub in ("image_2", "label_2", "calib"):
            (out / sub).mkdir(exist_ok=True)
            for f in sorted((part / sub).iterdir()):     # KITTI names: 6 digits, seed then frame
                shutil.copy(f, out / sub / f"{seed:02d}{int(f.stem):04d}{f.suffix}")
        if seed == 0:
            shutil.copy(part / "export.json", out / "export.json")
        shutil.rmtree(part)
        n_done += frames
    return n_done / seconds


def score(data: Path, detector: str, out: Path, height: float | None) -> dict:
    from harness.kitti_eval.evaluate import KittiEvalOptions, evaluate_kitti
    from harness.kitti_eval.reader import open_dataset

    m = evaluate_kitti(open_dataset(data), KittiEvalOptions(detector=detector, camera_height_m=height), out)
    ap = {thr: [m["kitti_ap"][f"iou_{thr}"][d]["ap_r40"] for d in DIFFICULTIES] for thr in ("0.5", "0.7")}
    boot = m["kitti_ap"]["bootstrap"]["moderate_iou_0.5"]
    return {"frames": m["frames"], "ap": ap, "precision": m["detection"]["precision"],
            "recall": m["detection"]["recall"], "interval": boot["interval_95"],
            "samples": np.array([np.nan if v is None else v for v in boot["samples"]], float)}


def gap_interval(renders: np.ndarray, real: np.ndarray) -> tuple[float, float]:
    """95 % interval of the moderate AP@0.5 gap renders - real: the two sets' image-bootstrap resamples,
    paired at random (independent sets), differenced."""
    n = min(len(renders), len(real))
    d = np.random.default_rng(1).permutation(renders)[:n] - real[:n]
    d = d[np.isfinite(d)]
    return tuple(float(v) for v in np.percentile(d, [2.5, 97.5]))


def table(rows: list[tuple[str, str, dict]]) -> str:
    lines = ["| frames | detector | n | AP@0.5 easy/mod/hard | AP@0.7 easy/mod/hard | precision / recall @0.5 |",
             "|---|---|---|---|---|---|"]
    for where, det, r in rows:
        f = lambda v: " / ".join(f"{x:.3f}" for x in v)  # noqa: E731
        lines.append(f"| {where} | {det} | {r['frames']} | {f(r['ap']['0.5'])} | {f(r['ap']['0.7'])} | "
                     f"{r['precision']:.3f} / {r['recall']:.3f} |")
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--real", type=Path, default=None, metavar="DIR", help="a labelled KITTI dataset (real frames)")
    ap.add_argument("--looks", nargs="+", default=["simple", "realistic:train", "realistic:heldout"])
    ap.add_argument("--seeds", type=int, default=6)
    ap.add_argument("--frames", type=int, default=10)
    ap.add_argument("--detectors", nargs="+", default=["yolox", "centernet"])
    ap.add_argument("--fleet", choices=("none", "mixed"), default=None,
                    help="the traffic fleet (traffic.fleet; mixed: harness.world.fleet body types); default: the "
                         "scene's (motorway: none, street: mixed)")
    ap.add_argument("--scene", choices=tuple(SCENES), default="motorway",
                    help="motorway: scenarios/looks/kitti_camera.yaml; street: scenarios/looks/street.yaml")
    ap.add_argument("--keep", type=Path, default=None, metavar="DIR", help="keep the rendered datasets here")
    args = ap.parse_args()
    looks = [parse_look(t) for t in args.looks]
    if args.seeds < 1 or args.frames < 1:
        raise UserError("--seeds and --frames must be positive")
    rows, speeds = [], {}
    with tempfile.TemporaryDirectory() as tmp:
        base = Path(tmp) if args.keep is None else args.keep
        if args.real is not None:
            for det in args.detectors:
                rows.append(("real", det, score(args.real, det, Path(tmp) / f"real-{det}", KITTI_HEIGHT_M)))
        for look, family in looks:
            name = look if look == "simple" else f"{look}:{family}"
            data = base / name.replace(":", "-")
            if data.exists():
                shutil.rmtree(data)
            speeds[name] = render_dataset(look, family, args.seeds, args.frames, data, args.fleet, args.scene)
            for det in args.detectors:
                rows.append((f"renders, {name}", det, score(data, det, Path(tmp) / f"{name}-{det}", None)))
    print(table(rows))
    print("\nexport frames/s (simulation + render + truth + writing, 1242x375): "
          + ", ".join(f"{k} {v:.1f}" for k, v in speeds.items()))
    real = {det: r for where, det, r in rows if where == "real"}
    for where, det, r in rows:
        if where.startswith("renders, realistic") and det in real:
            gap = r["ap"]["0.5"][1] - real[det]["ap"]["0.5"][1]
            lo, hi = gap_interval(r["samples"], real[det]["samples"])
            verdict = "met" if -0.10 <= lo and hi <= 0.10 else "missed" if hi < -0.10 or lo > 0.10 else "not shown"
            print(f"{det} on {where[9:]}: moderate AP@0.5 {r['ap']['0.5'][1]:.3f} "
                  f"(95 % {r['interval'][0]:.3f}-{r['interval'][1]:.3f}) vs real {real[det]['ap']['0.5'][1]:.3f} "
                  f"({real[det]['interval'][0]:.3f}-{real[det]['interval'][1]:.3f}): gap {gap:+.3f}, 95 % "
                  f"{lo:+.3f} to {hi:+.3f} (target within +-0.10: {verdict})")


if __name__ == "__main__":
    run_script(main)
