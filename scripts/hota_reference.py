"""Reference numbers for ``harness/scoring/hota.py`` from TrackEval itself (tests/data/hota_trackeval.json).

TrackEval (PyPI ``trackeval``) pulls ``opencv-python``, which would overwrite the project's
contrib OpenCV, so it runs in a separate, throwaway environment. Two steps:

1. in the project's environment, export MOT sequences and make tracker outputs for them::

       python scripts/hota_reference.py inputs /tmp/hota_work

   (renders ``highway_cruise`` and ``cut_in`` at 320x180 for 30 frames each with
   ``monorarp export --format mot``; trackers: ``sort`` and ``bytetrack`` on the exported
   ``det/det.txt``, and a seeded perturbation of the truth with misses, jitter, identity
   swaps and false positives; plus a KITTI-tracking export of ``cut_in`` and synthetic
   per-frame similarity cases, edge cases included);

2. in an environment with TrackEval (``python3 -m venv /tmp/te_venv && /tmp/te_venv/bin/pip
   install trackeval``)::

       /tmp/te_venv/bin/python scripts/hota_reference.py reference /tmp/hota_work \\
           --out tests/data/hota_trackeval.json

   runs TrackEval's evaluator on the files (``MotChallenge2DBox`` with ``BENCHMARK: MOT15``:
   no pedestrian-only preprocessing, ``conf`` 0 rows left out of the truth; ``Kitti2DBox``
   on the KITTI-tracking export with its own labels as the tracker) and its ``HOTA`` metric
   class on the synthetic cases, and writes their inputs and TrackEval's numbers to one
   JSON file. Step 2 imports nothing from this project.
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
SCENARIOS = ("scenarios/highway_cruise.yaml", "scenarios/cut_in.yaml")
FRAMES = 30
SIZE = (320, 180)
TRACKERS = ("sort", "bytetrack", "perturbed")
SUMMARY = ("HOTA", "DetA", "AssA", "LocA", "DetRe", "DetPr", "AssRe", "AssPr", "OWTA")


# ------------------------------------------------------------------------- step 1: inputs
def _small_scenario(path: Path, out: Path) -> Path:
    import yaml

    data = yaml.safe_load(path.read_text())
    cam = dict(data.get("camera") or {})
    scale = SIZE[0] / cam.get("width", 640)
    if cam.get("focal_px") is not None:
        cam["focal_px"] = cam["focal_px"] * scale
    cam.update(width=SIZE[0], height=SIZE[1])
    data["camera"] = cam
    dst = out / path.name
    dst.write_text(yaml.safe_dump(data, sort_keys=False))
    return dst


def _read_mot(path: Path) -> np.ndarray:
    rows = [[float(v) for v in line.split(",")] for line in path.read_text().splitlines() if line.strip()]
    return np.array(rows, dtype=float).reshape(-1, max((len(r) for r in rows), default=10))


def _run_tracker(name: str, det: np.ndarray, n_frames: int, camera) -> list[str]:
    from harness.export.mot import box_to_mot, mot_to_box
    from monorarp.pipeline.registry import build
    from monorarp.core.types import Detection

    trk = build("tracker", name, {}, camera)
    lines = []
    for f in range(1, n_frames + 1):
        dets = [Detection(box=mot_to_box(*r[2:6]), score=float(r[6])) for r in det[det[:, 0] == f]]
        for t in trk.update(None, dets, (f - 1) / 15.0):
            left, top, w, h = box_to_mot(t.box)
            lines.append(f"{f},{t.id},{left:.2f},{top:.2f},{w:.2f},{h:.2f},1,-1,-1,-1")
    return lines


def _perturbed(gt: np.ndarray, n_frames: int, seed: int, width: int, height: int) -> list[str]:
    """The truth with 15 % misses, 1.5 px jitter, id swaps and ~0.5 false positives a frame."""
    rng = np.random.default_rng(seed)
    ids = sorted({int(i) for i in gt[:, 1]})
    remap = {i: 100 + k for k, i in enumerate(ids)}
    lines = []
    for f in range(1, n_frames + 1):
        if f == n_frames // 2 and len(ids) >= 2:                 # two identities swap half-way
            a, b = ids[0], ids[1]
            remap[a], remap[b] = remap[b], remap[a]
        if f == 2 * n_frames // 3 and ids:                       # one track is re-born with a new id
            remap[ids[-1]] = 900 + f
        for r in gt[gt[:, 0] == f]:
            if rng.random() < 0.15:
                continue
            left, top, w, h = r[2:6] + rng.normal(0.0, 1.5, 4) * np.array([1, 1, 0.5, 0.5])
            lines.append(f"{f},{remap[int(r[1])]},{left:.2f},{top:.2f},{max(w, 1):.2f},{max(h, 1):.2f},1,-1,-1,-1")
        for k in range(rng.poisson(0.5)):
            w, h = rng.uniform(5, 40), rng.uniform(4, 25)
            lines.append(f"{f},{500 + f * 10 + k},{rng.uniform(1, width - w):.2f},{rng.uniform(1, height - h):.2f},"
                         f"{w:.2f},{h:.2f},1,-1,-1,-1")
    return lines


def _synthetic_cases(seed: int = 7) -> list[dict]:
    """Per-frame (gt ids, tracker ids, similarity) cases for TrackEval's HOTA class directly."""
    rng = np.random.default_rng(seed)
    cases = []

    def add(name, frames):
        cases.append({"name": name, "frames": [{"gt": [int(v) for v in g], "tr": [int(v) for v in t],
                                                "sim": np.round(np.asarray(s, float).reshape(len(g), len(t)), 4).tolist()}
                                               for g, t, s in frames]})

    for k in range(6):                                          # random sequences with sparse overlaps
        n_f = int(rng.integers(5, 25))
        frames = []
        for _ in range(n_f):
            g = rng.choice(12, size=int(rng.integers(0, 7)), replace=False)
            t = rng.choice(15, size=int(rng.integers(0, 8)), replace=False)
            s = rng.uniform(0, 1, (len(g), len(t))) * (rng.random((len(g), len(t))) < 0.4)
            frames.append((g, t, s))
        add(f"random_{k}", frames)
    add("perfect", [([1, 2], [7, 8], [[1.0, 0.0], [0.0, 1.0]])] * 5)
    add("id_swap", [([1, 2], [7, 8], [[0.9, 0.0], [0.0, 0.8]])] * 4 + [([1, 2], [7, 8], [[0.0, 0.85], [0.7, 0.0]])] * 4)
    add("ties", [([1, 2], [3, 4], [[0.6, 0.6], [0.6, 0.6]])] * 3)
    add("empty_frames", [([], [], []), ([1], [], []), ([], [5], []), ([1], [5], [[0.55]])])
    add("no_tracker", [([1, 2], [], []), ([1], [], [])])
    add("no_gt", [([], [4], []), ([], [4, 6], [])])
    add("threshold_edges", [([1, 2, 3], [4, 5, 6], [[0.05, 0, 0], [0, 0.5, 0], [0, 0, 0.95]])] * 2)
    return cases


def make_inputs(work: Path) -> None:
    import os

    os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
    from monorarp.pipeline.detectors import build_detector
    from harness.export.exporter import export
    from harness.export.source import open_source
    from monorarp.pipeline.config import ComponentConfig

    if work.exists():
        shutil.rmtree(work)
    (work / "scen").mkdir(parents=True)
    for s in SCENARIOS:
        scen = _small_scenario(ROOT / s, work / "scen")
        src = open_source(scen, FRAMES)
        det = build_detector(ComponentConfig(name="centernet"), src.camera)
        out = work / "mot_export" / src.name
        export(src, "mot", out, detector=det, detector_name="centernet")
        seq_dir = out / src.name
        gt_root = work / "mot" / src.name
        gt_root.mkdir(parents=True)
        shutil.copytree(seq_dir / "gt", gt_root / "gt")
        shutil.copy(seq_dir / "seqinfo.ini", gt_root / "seqinfo.ini")
        gt = _read_mot(seq_dir / "gt" / "gt.txt")
        dets = _read_mot(seq_dir / "det" / "det.txt")
        for name in TRACKERS:
            lines = (_perturbed(gt, FRAMES, seed=len(src.name), width=SIZE[0], height=SIZE[1]) if name == "perturbed"
                     else _run_tracker(name, dets, FRAMES, src.camera))
            d = work / "trackers" / name / "data"
            d.mkdir(parents=True, exist_ok=True)
            (d / f"{src.name}.txt").write_text("".join(line + "\n" for line in lines))
        if s.endswith("cut_in.yaml"):                           # the KITTI-tracking reader check
            export(open_source(scen, FRAMES), "kitti-tracking", work / "kitti")
            d = work / "kitti_trackers" / "labels" / "data"
            d.mkdir(parents=True)
            labels = (work / "kitti" / "label_02" / "0000.txt").read_text().splitlines()
            (d / "0000.txt").write_text("".join(line + " 1.0\n" for line in labels))
    (work / "synthetic.json").write_text(json.dumps(_synthetic_cases()))
    print(f"inputs written to {work}")


# ---------------------------------------------------------------------- step 2: TrackEval
def _summary(res: dict) -> dict:
    out = {k: float(np.mean(res[k])) for k in SUMMARY}
    out.update({"HOTA(0)": float(res["HOTA(0)"]), "LocA(0)": float(res["LocA(0)"]),
                "HOTA_alpha": [float(v) for v in res["HOTA"]],
                "HOTA_TP": [int(v) for v in res["HOTA_TP"]], "HOTA_FN": [int(v) for v in res["HOTA_FN"]],
                "HOTA_FP": [int(v) for v in res["HOTA_FP"]]})
    return out


def _rows(path: Path, cols: int) -> list[list[float]]:
    return [[float(v) for v in line.split(",")[:cols]] for line in path.read_text().splitlines() if line.strip()]


def reference(work: Path, out: Path) -> None:
    import trackeval

    eval_cfg = {"USE_PARALLEL": False, "PRINT_RESULTS": False, "PRINT_CONFIG": False, "TIME_PROGRESS": False,
                "OUTPUT_SUMMARY": False, "OUTPUT_DETAILED": False, "PLOT_CURVES": False, "OUTPUT_EMPTY_CLASSES": False,
                "DISPLAY_LESS_PROGRESS": True, "PRINT_ONLY_COMBINED": True}
    seqs = sorted(p.name for p in (work / "mot").iterdir())
    ds_cfg = {"GT_FOLDER": str(work / "mot"), "TRACKERS_FOLDER": str(work / "trackers"), "BENCHMARK": "MOT15",
              "SKIP_SPLIT_FOL": True, "SEQ_INFO": {s: None for s in seqs}, "TRACKERS_TO_EVAL": list(TRACKERS),
              "PRINT_CONFIG": False, "OUTPUT_FOLDER": str(work / "te_out")}
    evaluator = trackeval.Evaluator(eval_cfg)
    metrics = [trackeval.metrics.HOTA(), trackeval.metrics.CLEAR({"PRINT_CONFIG": False}),
               trackeval.metrics.Identity({"PRINT_CONFIG": False})]
    res, _ = evaluator.evaluate([trackeval.datasets.MotChallenge2DBox(ds_cfg)], metrics)
    mot = res["MotChallenge2DBox"]
    sequences = {}
    for s in seqs:
        sequences[s] = {"gt": _rows(work / "mot" / s / "gt" / "gt.txt", 7),
                        "trackers": {t: _rows(work / "trackers" / t / "data" / f"{s}.txt", 6) for t in TRACKERS}}
    results = {t: {seq: _summary(mot[t][seq]["pedestrian"]["HOTA"]) for seq in [*seqs, "COMBINED_SEQ"]}
               for t in TRACKERS}
    clear = {t: {seq: {"MOTA": float(mot[t][seq]["pedestrian"]["CLEAR"]["MOTA"]),
                       "IDF1": float(mot[t][seq]["pedestrian"]["Identity"]["IDF1"])} for seq in seqs} for t in TRACKERS}

    # KITTI tracking export read by TrackEval's own KITTI reader, its labels as the tracker.
    kitti_cfg = {"GT_FOLDER": str(work / "kitti"), "TRACKERS_FOLDER": str(work / "kitti_trackers"),
                 "CLASSES_TO_EVAL": ["car"], "PRINT_CONFIG": False, "OUTPUT_FOLDER": str(work / "te_kitti_out")}
    kres, _ = trackeval.Evaluator(eval_cfg).evaluate([trackeval.datasets.Kitti2DBox(kitti_cfg)],
                                                     [trackeval.metrics.HOTA(), trackeval.metrics.CLEAR({"PRINT_CONFIG": False})])
    k = kres["Kitti2DBox"]["labels"]["0000"]["car"]
    kitti = {"HOTA": float(np.mean(k["HOTA"]["HOTA"])), "MOTA": float(k["CLEAR"]["MOTA"]),
             "gt_dets_counted": int(k["CLEAR"]["CLR_TP"] + k["CLEAR"]["CLR_FN"]),
             "label_lines": len((work / "kitti" / "label_02" / "0000.txt").read_text().splitlines())}

    synthetic = json.loads((work / "synthetic.json").read_text())
    hota_metric = trackeval.metrics.HOTA()
    for case in synthetic:
        gt_all = sorted({i for f in case["frames"] for i in f["gt"]})
        tr_all = sorted({i for f in case["frames"] for i in f["tr"]})
        data = {"num_gt_ids": len(gt_all), "num_tracker_ids": len(tr_all),
                "num_gt_dets": sum(len(f["gt"]) for f in case["frames"]),
                "num_tracker_dets": sum(len(f["tr"]) for f in case["frames"]),
                "gt_ids": [np.array([gt_all.index(i) for i in f["gt"]], dtype=int) for f in case["frames"]],
                "tracker_ids": [np.array([tr_all.index(i) for i in f["tr"]], dtype=int) for f in case["frames"]],
                "similarity_scores": [np.array(f["sim"], dtype=float).reshape(len(f["gt"]), len(f["tr"]))
                                      for f in case["frames"]]}
        case["trackeval"] = _summary(hota_metric.eval_sequence(data))

    fixture = {"trackeval_version": getattr(trackeval, "__version__", "unknown"),
               "made_by": "scripts/hota_reference.py (see its docstring)",
               "mot": {"benchmark": "MOT15 (no preprocessing; gt rows with conf 0 left out)",
                       "columns_gt": "frame,id,bb_left,bb_top,bb_width,bb_height,conf",
                       "columns_tracker": "frame,id,bb_left,bb_top,bb_width,bb_height",
                       "frames": {s: int(FRAMES) for s in seqs},
                       "sequences": sequences, "hota": results, "clear_identity": clear},
               "kitti_tracking_reader": kitti,
               "synthetic": synthetic}
    out.write_text(json.dumps(fixture, separators=(",", ":")) + "\n")
    print(f"wrote {out}: {len(seqs)} sequences x {len(TRACKERS)} trackers, {len(synthetic)} synthetic cases; "
          f"KITTI reader: HOTA {kitti['HOTA']:.4f}")
    for t in TRACKERS:
        c = results[t]["COMBINED_SEQ"]
        print(f"  {t:<10} HOTA {c['HOTA']:.4f} DetA {c['DetA']:.4f} AssA {c['AssA']:.4f} LocA {c['LocA']:.4f}")


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = p.add_subparsers(dest="step", required=True)
    a = sub.add_parser("inputs", help="step 1 (project environment): export sequences, run trackers")
    a.add_argument("work", type=Path)
    b = sub.add_parser("reference", help="step 2 (TrackEval environment): TrackEval's numbers -> fixture")
    b.add_argument("work", type=Path)
    b.add_argument("--out", type=Path, default=ROOT / "tests" / "data" / "hota_trackeval.json")
    args = p.parse_args(argv)
    if args.step == "inputs":
        make_inputs(args.work)
    else:
        reference(args.work, args.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
