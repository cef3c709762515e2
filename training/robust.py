"""The appearance-randomised variant ``centernet_vehicle_robust`` (detector ``centernet_robust``).

Same net and loss as the shipped model; its data and its start differ:

* data: ``SHARDS``, every frame as full view + fovea crop, a fraction ``CONDITIONS`` of the
  scenarios with random light/weather/lens conditions and a fraction ``APPEARANCE`` with a random
  style of the training family (:mod:`training.appearance`) and wider vehicle sizes;
* start: the shipped model's weights, read back from its ONNX file (:mod:`training.onnx_init`),
  fine-tuned ``EPOCHS`` epochs (one cosine cycle) with BatchNorm frozen (its statistics are folded
  into the exported convs);
* validation, beside the plain set of :mod:`training.reproduce`: ``STYLE_VAL`` rendered three times,
  unstyled (``val_unstyled``), with styles of the training family (``val_style``) and of the held-out
  family (``val_heldout``): the same scenes and frames (with the wider vehicle sizes), only the styles
  differ.

    python -m training.reproduce --variant robust
"""

from __future__ import annotations

from pathlib import Path

from monorarp.detection.centernet import DEFAULT_MODEL, ROBUST_MODEL
from training import generate_data, onnx_init

SHARDS = ((10, 150), (11, 150))          # (seed, scenarios); 10 frames each, full view + fovea crop
CONDITIONS, APPEARANCE = 0.5, 0.7        # fractions of scenarios with conditions / with a style
STYLE_VAL = (200000, 40, 8)              # seed, scenarios, frames; 640x360; in-family and held-out styles
EPOCHS, BATCH, LR, SEED = 1, 16, 1e-3, 2   # one epoch: fine-tuning on 2 shared CPU cores (~7 s a step)
OUT = ROBUST_MODEL


def style_val_dirs(d: Path) -> dict[str, Path]:
    """The ``STYLE_VAL`` scenes unstyled, with training-family styles, with held-out styles."""
    return {"unstyled": d / "val_unstyled", "styled": d / "val_style", "heldout": d / "val_heldout"}


def make_data(d: Path, force: bool) -> list[Path]:
    """Render the training shards and the two styled validation sets; return the training shards."""
    shards = [d / f"robust{seed}f" for seed, _ in SHARDS]
    for (seed, n), out in zip(SHARDS, shards):
        if force or not (out / "meta.json").exists():
            generate_data.main(["--out", str(out), "--scenarios", str(n), "--seed", str(seed), "--fovea",
                                "--conditions", str(CONDITIONS), "--appearance", str(APPEARANCE)])
    vs, vn, vf = STYLE_VAL
    for family, out in zip(("none", "train", "heldout"), style_val_dirs(d).values()):
        if force or not (out / "meta.json").exists():
            generate_data.main(["--out", str(out), "--scenarios", str(vn), "--seed", str(vs), "--frames", str(vf),
                                "--resolutions", "640x360", "--appearance", "1", "--appearance-family", family])
    return shards


def checkpoint(d: Path, force: bool) -> Path:
    """Data, the shipped model's weights as the start, fine-tuning; return the checkpoint."""
    return onnx_init.fine_tune_shipped(d, make_data(d, force), d / "centernet_robust.pt", EPOCHS, BATCH, LR, SEED,
                                       force)


def training_card() -> dict:
    """The ``training`` block of the model's metadata."""
    return {
        "command": "python -m training.reproduce --variant robust",
        "init": f"{DEFAULT_MODEL.name} (the shipped model's weights read back from ONNX, BatchNorm folded; "
                "training.onnx_init), BatchNorm frozen",
        "data": f"{sum(n for _, n in SHARDS)} random harness scenarios (seeds {[s for s, _ in SHARDS]}), 10 frames "
                "each as full view + fovea crop, as the shipped model's data, plus: random light/weather/lens "
                f"conditions on a fraction {CONDITIONS} of the scenarios (dusk, night with lamps, low sun, fog "
                f"40-1000 m, rain, motion blur, JPEG) and a random appearance style on a fraction {APPEARANCE} "
                "(training.appearance: paint hue/saturation/value, ground and sky tones, road texture, camera "
                "white balance, contrast, saturation, gamma, vignetting; wider vehicle sizes)",
        "epochs": EPOCHS, "batch": BATCH, "lr": LR, "seed": SEED,
        "loss": "focal (heatmap) + L1 on edge distances (Gaussian-weighted, each vehicle's weights sum to 1, "
                "bottom edge x2)",
    }
