"""Reproduce the committed detector end to end: data -> training -> ONNX -> validation -> metadata.

Training has two stages: ``EPOCHS`` from scratch on the full-view shards, then ``FT_EPOCHS``
(a second cosine cycle at ``FT_LR``) on those plus a shard whose frames also give the
detector's fovea crop (:mod:`monorarp.detection.fovea`), so the net learns the view its
second pass sees.

    pip install -e '.[train]'
    python -m training.reproduce            # writes monorarp/models/centernet_vehicle.{onnx,json}
    python -m training.reproduce --variant robust   # centernet_vehicle_robust.{onnx,json} (training.robust)
    python -m training.reproduce --variant dense    # centernet_vehicle_dense.{onnx,json} (training.dense)
    python -m training.reproduce --variant realistic  # centernet_vehicle_realistic.{onnx,json} (training.realistic)
    python -m training.reproduce --variant street     # centernet_vehicle_street.{onnx,json} (training.street)

Stages are skipped when their output exists (``--force`` redoes them). Everything is
seeded; the renderer (Mesa llvmpipe) and torch's CPU kernels are deterministic on
one machine, though float results may differ across CPUs/library versions.
"""

from __future__ import annotations

import argparse
import json
import os
from pathlib import Path

import cv2
import numpy as np

from monorarp.core.camera import CameraModel
from training import dense, evaluate, export, generate_data, realistic, robust, street, train
from training.data import Dataset
from training.model import n_params

TRAIN_SHARDS = ((0, 150), (1, 150))       # (seed, scenarios); 10 frames each
FOVEA_SHARDS = ((2, 150),)                 # (seed, scenarios); 10 frames each, full view + fovea crop
VAL = (100000, 40, 8)                      # seed, scenarios, frames; 640x360 only
EPOCHS, BATCH, LR, SEED = 24, 16, 3e-3, 0  # stage 1: from scratch on TRAIN_SHARDS
FT_EPOCHS, FT_LR, FT_SEED = 10, 1e-3, 1    # stage 2: fine-tune on TRAIN_SHARDS + FOVEA_SHARDS


def model_card(name: str, score_threshold: float, model_path: Path, params: int) -> dict:
    """The metadata fields every CenterNet model file carries (input, outputs, decoding, size); ``params``: the
    trained net's parameter count."""
    import onnx

    return {
        "name": name,
        "input": {"width": export.INPUT_W, "height": export.INPUT_H, "layout": "NCHW", "color": "RGB",
                  "scale": "1/255", "resize": "letterbox (aspect kept, centred, pad value 114)"},
        "outputs": {"heatmap": "(1,1,H/4,W/4) sigmoid vehicle-centre probability",
                    "ltrb": "(1,4,H/4,W/4) distances (input px) from cell centre (4j+1.5, 4i+1.5) to the box's "
                            "left, top, right, bottom edges"},
        "stride": 4, "pad_value": 114, "label": "car", "max_detections": 100,
        "score_threshold": round(float(score_threshold), 3),
        "params": params,
        "opset": 17, "onnx_ir_version": onnx.load(str(model_path)).ir_version,
    }


def training_card() -> dict:
    """The ``training`` block of the shipped model's metadata."""
    return {
        "command": "python -m training.reproduce",
        "data": f"{sum(n for _, n in TRAIN_SHARDS + FOVEA_SHARDS)} random harness scenarios (seeds "
                f"{[s for s, _ in TRAIN_SHARDS + FOVEA_SHARDS]}), "
                "10 frames each, resolutions 640x360/960x540/1280x720/640x480/800x450, lanes 2-5, camera "
                "height 1.1-1.8 m, pitch 0-6 deg, hfov 50-90 deg, random palettes, light, noise, blur; "
                "1-4 placed vehicles at 4-70 m (cars and 8-16 m trucks) plus random traffic; required boxes: "
                "visibility >= 0.3 and >= 3 px at 320x192; the seed-"
                f"{[s for s, _ in FOVEA_SHARDS]} scenarios also give each frame's fovea crop (the detector's "
                "second pass around the horizon at 2x the full view's scale) as a training image",
        "epochs": EPOCHS, "batch": BATCH, "lr": LR, "seed": SEED,
        "fine_tune": {"epochs": FT_EPOCHS, "lr": FT_LR, "seed": FT_SEED,
                      "data": "all shards (full views + fovea crops)", "init": "the stage-1 weights"},
        "loss": "focal (heatmap) + L1 on edge distances (Gaussian-weighted, each vehicle's weights sum to 1, "
                "bottom edge x2)",
    }


def shipped_data(d: Path, force: bool) -> list[Path]:
    """Render the shipped model's shards (full views, then full views + fovea crops); return them."""
    for seed, n in TRAIN_SHARDS:
        if force or not (d / f"train{seed}" / "meta.json").exists():
            generate_data.main(["--out", str(d / f"train{seed}"), "--scenarios", str(n), "--seed", str(seed)])
    for seed, n in FOVEA_SHARDS:
        if force or not (d / f"train{seed}f" / "meta.json").exists():
            generate_data.main(["--out", str(d / f"train{seed}f"), "--scenarios", str(n), "--seed", str(seed),
                                "--fovea"])
    return [d / f"train{s}" for s, _ in TRAIN_SHARDS] + [d / f"train{s}f" for s, _ in FOVEA_SHARDS]


def shipped_checkpoint(d: Path, force: bool) -> Path:
    """Data, stage 1 from scratch, stage 2 with fovea crops; return the final checkpoint."""
    shipped_data(d, force)
    ckpt = d / "centernet.pt"
    if force or not ckpt.exists():
        train.main(["--data", *[str(d / f"train{s}") for s, _ in TRAIN_SHARDS], "--out", str(ckpt),
                    "--epochs", str(EPOCHS), "--batch", str(BATCH), "--lr", str(LR), "--seed", str(SEED)])
    ckpt_ft = d / "centernet_fovea.pt"
    if force or not ckpt_ft.exists():
        shards = [str(d / f"train{s}") for s, _ in TRAIN_SHARDS] + [str(d / f"train{s}f") for s, _ in FOVEA_SHARDS]
        train.main(["--data", *shards, "--out", str(ckpt_ft), "--init", str(ckpt), "--epochs", str(FT_EPOCHS),
                    "--batch", str(BATCH), "--lr", str(FT_LR), "--seed", str(FT_SEED)])
    return ckpt_ft


def val_figures(model: Path, data: Path) -> dict:
    """The net's own figures (one pass on the 320x192 canvases, no refinement) on one validation set."""
    ds = Dataset.load(data)
    det = evaluate.CenterNetDetector(model, score_threshold=0.05, refine_bottom=False)
    return evaluate.figures(*evaluate.predict(det, ds), ds)


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--data", type=Path, default=Path("data"))
    ap.add_argument("--variant", choices=("shipped", "robust", "dense", "realistic", "street"), default="shipped",
                    help="shipped: centernet_vehicle; robust: centernet_vehicle_robust (training.robust); "
                         "dense: centernet_vehicle_dense (training.dense); realistic: "
                         "centernet_vehicle_realistic (training.realistic); street: centernet_vehicle_street "
                         "(training.street)")
    ap.add_argument("--out", type=Path, default=None, help="default: the variant's file in monorarp/models/")
    ap.add_argument("--force", action="store_true")
    a = ap.parse_args(argv)
    d = a.data
    robust_variant = a.variant == "robust"
    out = a.out or {"robust": robust.OUT, "dense": dense.OUT, "realistic": realistic.OUT, "street": street.OUT}.get(
        a.variant, Path("monorarp/models/centernet_vehicle.onnx"))
    vs, vn, vf = VAL
    if a.force or not (d / "val" / "meta.json").exists():
        generate_data.main(["--out", str(d / "val"), "--scenarios", str(vn), "--seed", str(vs),
                            "--frames", str(vf), "--resolutions", "640x360"])
    if a.variant == "dense":
        ckpt = dense.checkpoint(d, shipped_data(d, a.force), a.force)
    elif a.variant == "realistic":
        ckpt = realistic.checkpoint(d, a.force)
    elif a.variant == "street":
        ckpt = street.checkpoint(d, a.force)
    else:
        ckpt = robust.checkpoint(d, a.force) if robust_variant else shipped_checkpoint(d, a.force)
    export.export(ckpt, out, d / "val")
    # validation at a low threshold (AP), then the F1-optimal threshold goes into the metadata
    out.with_suffix(".json").unlink(missing_ok=True)
    figs = val_figures(out, d / "val")
    extra = {k: val_figures(out, p) for k, p in robust.style_val_dirs(d).items()} if robust_variant else {}
    if robust_variant:   # threshold: best F1 over the plain and in-family styled sets (never the held-out one)
        ds_thr = Dataset.concat([d / "val", robust.style_val_dirs(d)["styled"]])
        det = evaluate.CenterNetDetector(out, score_threshold=0.05, refine_bottom=False)
        thr = evaluate.figures(*evaluate.predict(det, ds_thr), ds_thr)["f1_best"]["score_threshold"] or 0.3
    elif a.variant == "realistic":   # threshold: best F1 on the held-out realistic renders
        extra_realistic = val_figures(out, realistic.val_dir(d))
        thr = extra_realistic["f1_best"]["score_threshold"] or 0.3
    elif a.variant == "street":      # threshold: best F1 on the held-out realistic motorways and streets together
        extra_realistic = val_figures(out, realistic.val_dir(d, street.BOXES))
        extra_street = val_figures(out, street.val_dir(d))
        ds_thr = Dataset.concat([realistic.val_dir(d, street.BOXES), street.val_dir(d)])
        det = evaluate.CenterNetDetector(out, score_threshold=0.05, refine_bottom=False)
        thr = evaluate.figures(*evaluate.predict(det, ds_thr), ds_thr)["f1_best"]["score_threshold"] or 0.3
    else:
        thr = figs["f1_best"]["score_threshold"] or 0.3
    ds = Dataset.load(d / "val")
    frame = cv2.resize(np.asarray(ds.images[0])[6:186], (640, 360), interpolation=cv2.INTER_LINEAR)
    figs["ms_per_frame_640x360_1thread"] = round(evaluate.time_per_frame(
        evaluate.CenterNetDetector(out, score_threshold=thr, refine_bottom=False), image=frame), 2)
    cam = CameraModel.from_fov(640, 360, 70.0, 1.3)   # a level camera: fovea = the 320x192 px around the horizon
    figs["ms_per_frame_640x360_1thread_foveated"] = round(evaluate.time_per_frame(
        evaluate.CenterNetDetector(out, score_threshold=thr, camera=cam, refine_bottom=False), image=frame), 2)
    figs["timing_note"] = (f"mean of 200 detect() calls on a 640x360 validation frame (letterbox + net + "
                           f"decode), intra_op_num_threads=1, {os.cpu_count()} CPUs shared with other jobs; "
                           "'foveated': with a camera, so the second pass on the fovea crop runs too. AP and "
                           "bottom-edge figures are the net's own (one pass on the 320x192 validation canvases)")
    val_note = (f"{VAL[1]} scenarios (seed {VAL[0]}), {VAL[2]} frames each, 640x360; "
                "required boxes: visibility >= 0.3 and >= 3 px at 320x192 (others ignored)")
    cards = {"robust": robust.training_card, "dense": lambda: dense.training_card(training_card()["data"]),
             "realistic": realistic.training_card, "street": street.training_card}
    meta = model_card(out.stem, thr, out, n_params(export.load_net(ckpt))) | {
        "training": cards.get(a.variant, training_card)(),
        "validation": {"data": val_note, **figs}}
    if a.variant == "dense":
        meta["validation_dense"] = {"data": dense.VAL_NOTE, **val_figures(out, dense.val_dir(d))}
    if a.variant in ("realistic", "street"):
        note = realistic.VAL_NOTE + ("" if a.variant == "realistic" or street.BOXES == "visible"
                                     else f"; {street.BOXES} boxes")
        meta["validation_realistic"] = {"data": note, **extra_realistic}
    if a.variant == "street":
        meta["validation_street"] = {"data": street.VAL_NOTE, **extra_street}
    for k, f in extra.items():
        sv = robust.STYLE_VAL
        style = {"unstyled": "no style", "styled": "a style of the training family",
                 "heldout": "a style of the held-out family"}[k]
        meta[f"validation_{k}"] = {"data": f"{sv[1]} scenarios (seed {sv[0]}), {sv[2]} frames each, 640x360, every "
                                           f"scenario with {style} (training.appearance) and the wider vehicle sizes; "
                                           "the same scenes in the unstyled, styled and held-out sets", **f}
    out.with_suffix(".json").write_text(json.dumps(meta, indent=2) + "\n")
    print(json.dumps({k: v for k, v in meta.items() if k.startswith("validation")}, indent=2))


if __name__ == "__main__":
    main()
