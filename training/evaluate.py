"""Validation figures of a CenterNet ONNX model on a held-out rendered set.

AP at IoU 0.5 and 0.7 (all-point interpolated, :mod:`training.ap`; vehicles with
visibility below the set's threshold or tiny boxes are *ignored*), the median
absolute error of the box bottom edge (source-image px, detections matched at
IoU 0.5), the F1-optimal score threshold, and the detector's time per frame.

    python -m training.evaluate --model monorarp/models/centernet_vehicle.onnx --data data/val

``--source`` runs the detector as the pipeline does: on the full-resolution frames
(``source.npy``, from ``generate_data --keep-source``) with each frame's camera (so the
foveated second pass runs), ``--refine-bottom on|off`` choosing the sub-pixel bottom-edge
refinement. When the set has ``boxes_fine.npy`` (``--truth-supersample``), the bottom edge
is also scored against that continuous truth (``bottom_edge_fine_*``): the 1x mask's edges
are rounded to pixel boundaries, so even an exact edge scores 0.25 px median against them.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from monorarp.detection.centernet import CenterNetDetector
from monorarp.core.boxes import BORDER_TOL_PX
from training.ap import average_precision, match
from training.data import Dataset


def predict(det: CenterNetDetector, ds: Dataset) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """Boxes (source px) and scores for every image of ``ds`` (images are net-size canvases)."""
    boxes, scores = [], []
    for i in range(len(ds.images)):
        dets = det.detect(np.asarray(ds.images[i]))
        b = np.array([d.box for d in dets], dtype=np.float64).reshape(-1, 4)
        boxes.append(ds.letterbox(i).to_src(b))
        scores.append(np.array([d.score for d in dets]))
    return boxes, scores


def predict_source(det: CenterNetDetector, ds: Dataset) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """Boxes and scores on the full-resolution frames, each with its own camera (fovea placement)."""
    from monorarp.core.camera import CameraModel

    src = np.load(Path(ds.meta["dir"]) / "source.npy", mmap_mode="r")
    boxes, scores = [], []
    for i in range(len(src)):
        det.set_camera(CameraModel.from_dict(ds.meta["images"][i]["camera"]))
        dets = det.detect(np.ascontiguousarray(src[i]))
        boxes.append(np.array([d.box for d in dets], dtype=np.float64).reshape(-1, 4))
        scores.append(np.array([d.score for d in dets]))
    return boxes, scores


def figures(boxes, scores, ds: Dataset) -> dict:
    gts, igns = zip(*(ds.boxes_of(i) for i in range(len(ds.images))))
    out: dict = {"images": len(ds.images), "vehicles": int(sum(len(g) for g in gts))}
    for thr in (0.5, 0.7):
        out["ap50" if thr == 0.5 else "ap70"] = round(average_precision(match(boxes, scores, list(gts), thr, list(igns))), 4)
    ap_by_h = {}
    for lo, hi in ((0, 16), (16, 40), (40, 1e9)):   # required boxes of one height band, the rest ignored
        hs = [g[:, 3] - g[:, 1] for g in gts]
        sel = [(x >= lo) & (x < hi) for x in hs]
        g_in = [g[k] for g, k in zip(gts, sel)]
        i_out = [np.concatenate([ig, g[~k]]) for ig, g, k in zip(igns, gts, sel)]
        key = f"{lo}-{int(hi) if hi < 1e9 else 'inf'}"
        ap_by_h[key] = {"count": int(sum(len(x) for x in g_in)),
                        "ap50": round(average_precision(match(boxes, scores, g_in, 0.5, i_out)), 4),
                        "ap70": round(average_precision(match(boxes, scores, g_in, 0.7, i_out)), 4)}
    out["ap_by_box_height_px"] = ap_by_h
    m = match(boxes, scores, list(gts), 0.5, list(igns))
    err = np.array([boxes[i][d, 3] - gts[i][j, 3] for i, d, j in m.pairs])
    h = np.array([gts[i][j, 3] - gts[i][j, 1] for i, d, j in m.pairs])
    out["bottom_edge_abs_err_median_px"] = round(float(np.median(np.abs(err))), 3) if err.size else None
    out["bottom_edge_err_mean_px"] = round(float(err.mean()), 3) if err.size else None
    out["bottom_edge_abs_err_p90_px"] = round(float(np.percentile(np.abs(err), 90)), 3) if err.size else None
    if ds.fine is not None and m.pairs:
        fine = [ds.fine_of(i) for i in range(len(ds.images))]
        ef_all = np.array([boxes[i][d, 3] - fine[i][j, 3] for i, d, j in m.pairs])
        ef = ef_all[np.isfinite(ef_all)]
        out["bottom_edge_fine_abs_err_median_px"] = round(float(np.median(np.abs(ef))), 3)
        out["bottom_edge_fine_abs_err_p90_px"] = round(float(np.percentile(np.abs(ef), 90)), 3)
        out["bottom_edge_fine_count"] = int(ef.size)
        # boxes cut by the image's bottom border (truth bottom within BORDER_TOL_PX of it) have no
        # visible bottom edge and give no distance; the figure without them is the one that matters
        cut = np.array([fine[i][j, 3] >= ds.src_sizes[i, 1] - 0.5 - BORDER_TOL_PX for i, d, j in m.pairs])
        vis = np.isfinite(ef_all) & ~cut
        out["bottom_edge_fine_abs_err_median_px_uncut"] = round(float(np.median(np.abs(ef_all[vis]))), 3)
        out["bottom_edge_fine_count_uncut"] = int(vis.sum())
    by_h = {}
    for lo, hi in ((0, 16), (16, 40), (40, 100), (100, 1e9)):
        sel = (h >= lo) & (h < hi)
        key = f"{lo}-{int(hi) if hi < 1e9 else 'inf'}"
        by_h[key] = {"count": int(sel.sum()),
                     "abs_err_median_px": round(float(np.median(np.abs(err[sel]))), 3) if sel.any() else None}
    out["bottom_edge_by_box_height_px"] = by_h
    # F1-optimal threshold
    keep = m.outcome >= 0
    tp = np.cumsum(m.outcome[keep] == 1)
    n = np.arange(1, keep.sum() + 1)
    prec, rec = tp / n, tp / max(m.n_gt, 1)
    f1 = 2 * prec * rec / np.maximum(prec + rec, 1e-12)
    k = int(np.argmax(f1)) if f1.size else 0
    out["f1_best"] = {"score_threshold": round(float(m.scores[keep][k]), 3) if f1.size else None,
                      "f1": round(float(f1[k]), 4) if f1.size else 0.0,
                      "precision": round(float(prec[k]), 4) if f1.size else 0.0,
                      "recall": round(float(rec[k]), 4) if f1.size else 0.0}
    return out


def time_per_frame(det: CenterNetDetector, width: int = 640, height: int = 360, n: int = 200,
                   image: np.ndarray | None = None) -> float:
    """Mean wall time (ms) of ``det.detect`` on a ``width`` x ``height`` frame (letterbox + net + decode)."""
    img = image if image is not None else np.random.default_rng(0).integers(0, 255, (height, width, 3), np.uint8)
    for _ in range(10):
        det.detect(img)
    t = time.perf_counter()
    for _ in range(n):
        det.detect(img)
    return (time.perf_counter() - t) / n * 1000.0


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--model", type=Path, default=Path("monorarp/models/centernet_vehicle.onnx"))
    ap.add_argument("--data", type=Path, default=Path("data/val"))
    ap.add_argument("--score-threshold", type=float, default=0.05, help="low, for AP")
    ap.add_argument("--json", type=Path, default=None, help="write the figures here")
    ap.add_argument("--source", action="store_true",
                    help="full-resolution frames with their cameras (needs source.npy), as the pipeline runs")
    ap.add_argument("--refine-bottom", choices=("on", "off"), default="off",
                    help="sub-pixel bottom-edge refinement (default off: the net's own figures)")
    a = ap.parse_args(argv)
    ds = Dataset.load(a.data)
    ds.meta["dir"] = str(a.data)
    det = CenterNetDetector(a.model, score_threshold=a.score_threshold, refine_bottom=a.refine_bottom == "on")
    boxes, scores = predict_source(det, ds) if a.source else predict(det, ds)
    fig = figures(boxes, scores, ds)
    det_rt = CenterNetDetector(a.model, refine_bottom=a.refine_bottom == "on")
    fig["ms_per_frame_640x360_1thread"] = round(time_per_frame(det_rt), 2)
    print(json.dumps(fig, indent=2))
    if a.json:
        a.json.write_text(json.dumps(fig, indent=2))


if __name__ == "__main__":
    main()
