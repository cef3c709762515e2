"""Train the CenterNet vehicle net on CPU (seeded).

Loss: penalty-reduced focal loss on the heatmap (CenterNet, alpha=2, beta=4,
normalised by the number of vehicles) + L1 on the four edge distances (px / stride,
Gaussian-weighted with each vehicle's weights summing to 1, so small far vehicles
count as much as near ones; bottom edge weighted x2 since the distance estimator reads it).
Augmentation: horizontal flip, brightness/contrast/colour jitter, sensor noise; optionally (``--clutter P``)
procedural foliage and tree shade (:mod:`training.clutter`), and (``--negatives P``) procedural pedestrians,
cyclists and building fronts (:mod:`training.negatives`).

    python -m training.train --data data/train0 data/train1 --out data/ckpt.pt --epochs 30
    python -m training.train ... --init data/ckpt.pt --lr 1e-3   # fine-tune (a second cosine cycle)
    python -m training.train ... --init data/shipped_init.pt --freeze-bn   # from an exported model
                                                                          # (training.onnx_init)
"""

from __future__ import annotations

import argparse
import math
import time
from pathlib import Path

import numpy as np
import torch

from training import clutter, negatives
from training.data import Dataset, gaussian_targets
from training.model import SIZES, n_params, of_size

EDGE_WEIGHTS = (1.0, 1.0, 1.0, 2.0)


def focal_loss(logits: torch.Tensor, target: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
    p = torch.sigmoid(logits).clamp(1e-4, 1 - 1e-4)
    pos = target.eq(1).float()
    neg = (1 - pos) * mask
    pos_loss = -torch.log(p) * (1 - p) ** 2 * pos
    neg_loss = -torch.log(1 - p) * p ** 2 * (1 - target) ** 4 * neg
    n = pos.sum().clamp(min=1.0)
    return (pos_loss.sum() + neg_loss.sum()) / n


def box_loss(pred: torch.Tensor, target: torch.Tensor, weight: torch.Tensor, stride: int) -> torch.Tensor:
    w = weight.unsqueeze(1) * torch.tensor(EDGE_WEIGHTS).view(1, 4, 1, 1)
    return (w * (pred - target).abs()).sum() / (stride * weight.sum().clamp(min=1.0))  # weight sums to #vehicles


def make_batch(ds: Dataset, idx: np.ndarray, rng: np.random.Generator, stride: int, augment: bool,
               clutter_p: float = 0.0, negatives_p: float = 0.0):
    """Images (B,3,H,W) float RGB [0,1], heatmap targets, ltrb targets, weights, loss masks. ``clutter_p``,
    ``negatives_p``: the probability of each of :mod:`training.clutter`'s and :mod:`training.negatives`'
    augmentations (0: none, and no draw from ``rng``)."""
    imgs = np.stack([ds.images[i] for i in idx])
    b, h, w = imgs.shape[:3]
    oh, ow = h // stride, w // stride
    hms = np.zeros((b, 1, oh, ow), np.float32)
    lts = np.zeros((b, 4, oh, ow), np.float32)
    wts = np.zeros((b, oh, ow), np.float32)
    masks = np.ones((b, 1, oh, ow), np.float32)
    x = imgs.astype(np.float32) / 255.0
    for k, i in enumerate(idx):
        req, ign = ds.boxes_of(int(i), net_scale=True)
        if augment and rng.random() < 0.5:
            x[k] = x[k, :, ::-1]
            req = np.stack([w - 1 - req[:, 2], req[:, 1], w - 1 - req[:, 0], req[:, 3]], 1) if len(req) else req
            ign = np.stack([w - 1 - ign[:, 2], ign[:, 1], w - 1 - ign[:, 0], ign[:, 3]], 1) if len(ign) else ign
        if augment and (clutter_p > 0 or negatives_p > 0):   # on the image, not the letterbox's padding (flat)
            lb = ds.letterbox(int(i))
            boxes = np.concatenate([req.reshape(-1, 4), ign.reshape(-1, 4)]) - [lb.pad_x, lb.pad_y] * 2
            view = x[k, lb.pad_y:lb.pad_y + lb.new_h, lb.pad_x:lb.pad_x + lb.new_w]
            if negatives_p > 0:
                negatives.augment(view, boxes, rng, negatives_p)
            if clutter_p > 0:
                clutter.augment(view, boxes, rng, clutter_p)
        hms[k, 0], lts[k], wts[k] = gaussian_targets(req, oh, ow, stride)
        for x1, y1, x2, y2 in ign:   # no penalty for firing on an ignored vehicle's interior
            j1, j2 = int(max((x1 + 0.5) // stride, 0)), int(min((x2 + 0.5) // stride + 1, ow))
            i1, i2 = int(max((y1 + 0.5) // stride, 0)), int(min((y2 + 0.5) // stride + 1, oh))
            masks[k, 0, i1:i2, j1:j2] = 0.0
        if augment:
            gain = rng.uniform(0.7, 1.3) * rng.uniform(0.85, 1.15, size=3).astype(np.float32)
            bias = rng.uniform(-0.1, 0.1)
            x[k] = x[k] * gain + bias
            if rng.random() < 0.3:
                x[k] += rng.normal(0, rng.uniform(0.005, 0.03), size=x[k].shape).astype(np.float32)
    x = np.clip(x, 0, 1)[..., ::-1].transpose(0, 3, 1, 2)   # BGR -> RGB, NCHW
    return (torch.from_numpy(np.ascontiguousarray(x)), torch.from_numpy(hms), torch.from_numpy(lts),
            torch.from_numpy(wts), torch.from_numpy(masks))


def train(data: list[Path], out: Path, epochs: int, batch: int, lr: float, seed: int, threads: int,
          log_every: int = 20, init: Path | None = None, freeze_bn: bool = False, clutter_p: float = 0.0,
          size: str = "small", negatives_p: float = 0.0) -> None:
    """Train (from scratch, or fine-tune from checkpoint ``init``) and save to ``out`` after every epoch.
    ``freeze_bn``: BatchNorm layers use their running statistics (not the batch's) and keep them; needed
    when ``init`` comes from an exported model, whose BatchNorms are folded into the convs. ``clutter_p``,
    ``negatives_p``: see :func:`make_batch`. ``size``: the net's widths (:data:`training.model.SIZES`)."""
    torch.manual_seed(seed)
    torch.set_num_threads(threads)
    rng = np.random.default_rng(seed)
    ds = Dataset.concat(data)
    net = of_size(size)
    if init is not None:
        net.load_state_dict(torch.load(init, map_location="cpu")["model"])
    stride = net.stride
    print(f"{len(ds.images)} images, {int((ds.boxes[:, 5] < 0.5).sum())} boxes, params {n_params(net)}", flush=True)
    opt = torch.optim.AdamW(net.parameters(), lr=lr, weight_decay=1e-4)
    steps_per_epoch = len(ds.images) // batch
    total = epochs * steps_per_epoch
    warm = min(200, total // 10)
    sched = torch.optim.lr_scheduler.LambdaLR(
        opt, lambda s: (s + 1) / warm if s < warm else 0.5 * (1 + math.cos(math.pi * (s - warm) / max(total - warm, 1))))
    t0 = time.time()
    step = 0
    for ep in range(epochs):
        net.train()
        if freeze_bn:
            for m in net.modules():
                if isinstance(m, torch.nn.BatchNorm2d):
                    m.eval()
        perm = rng.permutation(len(ds.images))
        for bi in range(steps_per_epoch):
            x, hm, lt, wt, mk = make_batch(ds, perm[bi * batch:(bi + 1) * batch], rng, stride, True, clutter_p,
                                          negatives_p)
            hm_logits, lt_pred = net(x)
            l_hm = focal_loss(hm_logits, hm, mk)
            l_box = box_loss(lt_pred, lt, wt, stride)
            loss = l_hm + l_box
            opt.zero_grad(set_to_none=True)
            loss.backward()
            torch.nn.utils.clip_grad_norm_(net.parameters(), 10.0)
            opt.step()
            sched.step()
            step += 1
            if step % log_every == 0:
                print(f"ep {ep} step {step}/{total} hm {l_hm.item():.3f} box {l_box.item():.3f} "
                      f"lr {sched.get_last_lr()[0]:.2e} {time.time() - t0:.0f}s", flush=True)
        torch.save({"model": net.state_dict(), "epoch": ep + 1, "seed": seed,
                    "init": None if init is None else str(init), "freeze_bn": freeze_bn, "size": size}, out)
    print(f"done in {time.time() - t0:.0f}s -> {out}", flush=True)


def probability(text: str) -> float:
    """argparse type: a number in [0, 1]."""
    try:
        p = float(text)
    except ValueError:
        p = float("nan")
    if not 0.0 <= p <= 1.0:
        raise argparse.ArgumentTypeError(f"{text!r} is not a probability in [0, 1]")
    return p


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--data", type=Path, nargs="+", default=[Path("data/train0"), Path("data/train1")])
    ap.add_argument("--out", type=Path, default=Path("data/centernet.pt"))
    ap.add_argument("--epochs", type=int, default=30)
    ap.add_argument("--batch", type=int, default=32)
    ap.add_argument("--lr", type=float, default=3e-3)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--init", type=Path, default=None, help="fine-tune from this checkpoint's weights")
    ap.add_argument("--freeze-bn", action="store_true", help="keep BatchNorm statistics fixed (init from ONNX)")
    ap.add_argument("--clutter", type=probability, default=0.0, metavar="P",
                    help="probability of each procedural clutter augmentation (foliage, shade; training.clutter)")
    ap.add_argument("--negatives", type=probability, default=0.0, metavar="P",
                    help="probability of each procedural negative (pedestrians and cyclists, building fronts; "
                         "training.negatives)")
    ap.add_argument("--size", choices=tuple(SIZES), default="small", help="the net's widths (training.model.SIZES)")
    a = ap.parse_args(argv)
    a.out.parent.mkdir(parents=True, exist_ok=True)
    train(a.data, a.out, a.epochs, a.batch, a.lr, a.seed, a.threads, init=a.init, freeze_bn=a.freeze_bn,
          clutter_p=a.clutter, size=a.size, negatives_p=a.negatives)


if __name__ == "__main__":
    main()
