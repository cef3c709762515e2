"""The variant trained on the realistic look only: ``centernet_vehicle_realistic`` (detector ``centernet_realistic``).

Same net and loss as the shipped model; its images differ, and it starts from scratch:

* data: ``SHARDS``, every scenario rendered with the realistic look (:mod:`harness.render.look`: textured
  road, roadside, sky, sun shadows, detailed vehicles, sensor model) of the *training* family, the traffic
  and the placed vehicles a real motorway fleet (:mod:`harness.world.fleet`: nine body types), a fraction
  ``DENSE`` made dense occluding traffic; resolutions ``RESOLUTIONS`` (KITTI's wide 1242x375 twice as
  often as each 16:9 / 4:3 one), the second shard also giving each frame's fovea crop;
* validation (what chooses the score threshold): ``VAL``, realistic renders of the *held-out* family.
  No real image is in its training, and none chooses a checkpoint or threshold: the KITTI figures in
  docs/looks.md are measured after the fact.

    python -m training.reproduce --variant realistic
"""

from __future__ import annotations

from pathlib import Path

from monorarp.detection.centernet import REALISTIC_MODEL
from training import generate_data, train

SHARDS = ((10, 200, False), (11, 150, True))   # (seed, scenarios, fovea); 10 frames each
RESOLUTIONS = "1242x375,1242x375,640x360,960x540,1280x720,800x450"
DENSE = 0.3
VAL = (100010, 40, 8)                           # seed, scenarios, frames; 640x360 and 1242x375; held-out family
EPOCHS, BATCH, LR, SEED = 12, 16, 3e-3, 4
OUT = REALISTIC_MODEL
VAL_NOTE = (f"{VAL[1]} scenarios (seed {VAL[0]}), {VAL[2]} frames each, 640x360 and 1242x375, realistic look of the "
            "held-out family, mixed fleet; required boxes: visibility >= 0.3 and >= 3 px at 320x192 (others ignored)")


LOSS = ("focal (heatmap) + L1 on edge distances (Gaussian-weighted, each vehicle's weights sum to 1, "
        "bottom edge x2)")


def suffix(boxes: str) -> str:
    """Data directory suffix of a label box kind (``generate_data --boxes``): none for the visible boxes."""
    return "" if boxes == "visible" else f"_{boxes}"


def val_dir(d: Path, boxes: str = "visible") -> Path:
    return d / f"val_realistic{suffix(boxes)}"


def make_data(d: Path, force: bool, boxes: str = "visible") -> list[Path]:
    """Render the realistic shards and the held-out validation set with label boxes ``boxes``; return the
    shards."""
    shards = []
    for seed, n, fovea in SHARDS:
        out = d / f"realistic{seed}{'f' if fovea else ''}{suffix(boxes)}"
        shards.append(out)
        if force or not (out / "meta.json").exists():
            generate_data.main(["--out", str(out), "--scenarios", str(n), "--seed", str(seed), "--look", "realistic",
                                "--fleet", "mixed", "--dense", str(DENSE), "--resolutions", RESOLUTIONS,
                                "--boxes", boxes] + (["--fovea"] if fovea else []))
    vs, vn, vf = VAL
    if force or not (val_dir(d, boxes) / "meta.json").exists():
        generate_data.main(["--out", str(val_dir(d, boxes)), "--scenarios", str(vn), "--seed", str(vs),
                            "--frames", str(vf), "--look", "realistic", "--look-family", "heldout", "--fleet", "mixed",
                            "--resolutions", "640x360,1242x375", "--boxes", boxes])
    return shards


def from_scratch(shards: list[Path], ckpt: Path, force: bool, epochs: int = EPOCHS, batch: int = BATCH,
                 lr: float = LR, seed: int = SEED, clutter: float = 0.0, size: str = "small",
                 negatives: float = 0.0) -> Path:
    """Train the net from scratch on ``shards`` into ``ckpt`` (skipped when it exists, unless ``force``);
    ``clutter``: ``train --clutter`` (:mod:`training.clutter`; 0: none); ``size``: ``train --size``;
    ``negatives``: ``train --negatives`` (:mod:`training.negatives`; 0: none)."""
    if force or not ckpt.exists():
        train.main(["--data", *map(str, shards), "--out", str(ckpt), "--epochs", str(epochs), "--batch", str(batch),
                    "--lr", str(lr), "--seed", str(seed)] + (["--clutter", str(clutter)] if clutter > 0 else [])
                   + (["--size", size] if size != "small" else [])
                   + (["--negatives", str(negatives)] if negatives > 0 else []))
    return ckpt


def checkpoint(d: Path, force: bool) -> Path:
    """Data, then training from scratch; return the checkpoint."""
    return from_scratch(make_data(d, force), d / "centernet_realistic.pt", force)


def training_card() -> dict:
    """The ``training`` block of the model's metadata."""
    return {
        "command": "python -m training.reproduce --variant realistic",
        "init": "from scratch",
        "data": f"{sum(n for _, n, _ in SHARDS)} random harness scenarios (seeds {[s for s, _, _ in SHARDS]}), 10 "
                "frames each, rendered with the realistic look of the training family (textured road, roadside, "
                "sky, sun shadows, detailed vehicles, sensor model; harness.render.look), a mixed motorway fleet "
                "(harness.world.fleet: nine body types, traffic and placed vehicles), a fraction "
                f"{DENSE} dense occluding traffic, resolutions {RESOLUTIONS}; the seed-{SHARDS[1][0]} scenarios also "
                "give each frame's fovea crop; no real image",
        "epochs": EPOCHS, "batch": BATCH, "lr": LR, "seed": SEED, "loss": LOSS,
    }
