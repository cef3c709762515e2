"""The dense-traffic variant ``centernet_vehicle_dense`` (detector ``centernet_dense``).

Same net and loss as the shipped model; its data and its start differ:

* data: the shipped model's shards (:data:`training.reproduce.TRAIN_SHARDS` and ``FOVEA_SHARDS``) plus
  ``DENSE_SHARDS``: scenarios made dense occluding traffic (:func:`training.generate_data.densify`:
  pairs of cars in adjacent lanes 20-70 m ahead, the far one partly hidden by the near one), every
  frame as full view + fovea crop;
* start: the shipped model's weights, read back from its ONNX file (:mod:`training.onnx_init`),
  fine-tuned ``EPOCHS`` epochs (one cosine cycle) with BatchNorm frozen;
* validation: the plain set of :mod:`training.reproduce` (its best-F1 threshold is the model's) and
  ``DENSE_VAL``, densified scenes.

    python -m training.reproduce --variant dense
"""

from __future__ import annotations

from pathlib import Path

from monorarp.detection.centernet import DEFAULT_MODEL, DENSE_MODEL
from training import generate_data, onnx_init

DENSE_SHARDS = ((20, 200),)              # (seed, scenarios); 10 frames each, full view + fovea crop, all dense
DENSE_VAL = (100020, 40, 8)              # seed, scenarios, frames; 640x360; all dense
VAL_NOTE = (f"{DENSE_VAL[1]} scenarios (seed {DENSE_VAL[0]}), {DENSE_VAL[2]} frames each, 640x360, every scenario "
            "dense occluding traffic (training.generate_data --dense); required boxes as above")
EPOCHS, BATCH, LR, SEED = 6, 16, 1e-3, 3
OUT = DENSE_MODEL


def val_dir(d: Path) -> Path:
    return d / "val_dense"


def make_data(d: Path, force: bool) -> list[Path]:
    """Render the dense shards and the dense validation set; return the dense shards."""
    shards = [d / f"dense{seed}f" for seed, _ in DENSE_SHARDS]
    for (seed, n), out in zip(DENSE_SHARDS, shards):
        if force or not (out / "meta.json").exists():
            generate_data.main(["--out", str(out), "--scenarios", str(n), "--seed", str(seed), "--fovea",
                                "--dense", "1"])
    vs, vn, vf = DENSE_VAL
    if force or not (val_dir(d) / "meta.json").exists():
        generate_data.main(["--out", str(val_dir(d)), "--scenarios", str(vn), "--seed", str(vs), "--frames", str(vf),
                            "--resolutions", "640x360", "--dense", "1"])
    return shards


def checkpoint(d: Path, shipped_shards: list[Path], force: bool) -> Path:
    """The shipped model's weights as the start, fine-tuned on ``shipped_shards`` + the dense shards."""
    return onnx_init.fine_tune_shipped(d, shipped_shards + make_data(d, force), d / "centernet_dense.pt", EPOCHS,
                                       BATCH, LR, SEED, force)


def training_card(shipped_data: str) -> dict:
    """The ``training`` block of the model's metadata."""
    return {
        "command": "python -m training.reproduce --variant dense",
        "init": f"{DEFAULT_MODEL.name} (the shipped model's weights read back from ONNX, BatchNorm folded; "
                "training.onnx_init), BatchNorm frozen",
        "data": f"the shipped model's data ({shipped_data}) plus {sum(n for _, n in DENSE_SHARDS)} scenarios "
                f"(seeds {[s for s, _ in DENSE_SHARDS]}) of dense occluding traffic (training.generate_data "
                "--dense: 3-5 lanes, 25-50 vehicles at density 2-3.5, 1-3 pairs of cars in adjacent lanes "
                "20-70 m ahead, the far one 2-12 m behind the near one), 10 frames each as full view + fovea crop",
        "epochs": EPOCHS, "batch": BATCH, "lr": LR, "seed": SEED,
        "loss": "focal (heatmap) + L1 on edge distances (Gaussian-weighted, each vehicle's weights sum to 1, "
                "bottom edge x2)",
    }
