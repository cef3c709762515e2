"""Training data on disk and CenterNet targets.

A dataset directory holds

* ``images.npy`` -- (N, H, W, 3) uint8 BGR, already letterboxed to the net's input size;
* ``boxes.npy`` -- (M, 7) float: image index, x1, y1, x2, y2 (*source*-image pixels,
  continuous convention of :mod:`monorarp.core.types`), ignore flag (1 = too occluded/small:
  neither required nor penalised);
* ``boxes_fine.npy`` (optional, ``generate_data --truth-supersample``) -- (M, 4) the same boxes
  from an id mask rendered at N x the resolution (continuous edges to 1/N px; NaN: none);
* ``source.npy`` (optional, ``generate_data --keep-source``) -- (N, src_h, src_w, 3) the
  full-resolution frames, each image's camera in ``meta.json``;
* ``meta.json`` -- per image the source size (``src_w``, ``src_h``) and the scenario
  parameters, plus how the set was generated.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from monorarp.detection.letterbox import Letterbox


@dataclass
class Dataset:
    images: np.ndarray          # (N, H, W, 3) uint8 BGR, net input size
    boxes: np.ndarray           # (M, 6): img, x1, y1, x2, y2, ignore (source px)
    src_sizes: np.ndarray       # (N, 2) int: src_w, src_h
    meta: dict
    fine: np.ndarray | None = None      # (M, 4) supersampled-truth boxes aligned with ``boxes``

    @classmethod
    def load(cls, d: str | Path) -> "Dataset":
        d = Path(d)
        meta = json.loads((d / "meta.json").read_text())
        src = np.array([[m["src_w"], m["src_h"]] for m in meta["images"]], dtype=np.int64)
        fine = np.load(d / "boxes_fine.npy") if (d / "boxes_fine.npy").is_file() else None
        return cls(np.load(d / "images.npy", mmap_mode="r"), np.load(d / "boxes.npy"), src, meta, fine)

    @classmethod
    def concat(cls, dirs: list[str | Path]) -> "Dataset":
        """Several generated shards as one in-memory dataset (image indices renumbered)."""
        parts = [cls.load(d) for d in dirs]
        offsets = np.cumsum([0] + [len(p.images) for p in parts])[:-1]
        boxes = np.concatenate([p.boxes + np.array([o, 0, 0, 0, 0, 0]) for p, o in zip(parts, offsets)])
        meta = {"shards": [p.meta | {"images": len(p.meta["images"])} for p in parts]}
        return cls(np.concatenate([np.asarray(p.images) for p in parts]), boxes,
                   np.concatenate([p.src_sizes for p in parts]), meta)

    def letterbox(self, i: int) -> Letterbox:
        h, w = self.images.shape[1:3]
        return Letterbox.fit(int(self.src_sizes[i, 0]), int(self.src_sizes[i, 1]), w, h)

    def boxes_of(self, i: int, net_scale: bool = False) -> tuple[np.ndarray, np.ndarray]:
        """(required boxes (K, 4), ignored boxes (L, 4)) of image i, source px or net-input px."""
        b = self.boxes[self.boxes[:, 0] == i]
        xy = b[:, 1:5]
        if net_scale:
            xy = self.letterbox(i).to_dst(xy)
        ign = b[:, 5] > 0.5
        return xy[~ign], xy[ign]

    def fine_of(self, i: int) -> np.ndarray | None:
        """Supersampled-truth boxes (K, 4, source px) of image i's required boxes, in ``boxes_of`` order."""
        if self.fine is None:
            return None
        sel = self.boxes[:, 0] == i
        return self.fine[sel][self.boxes[sel, 5] <= 0.5]


def gaussian_targets(boxes: np.ndarray, out_h: int, out_w: int, stride: int, alpha: float = 0.54,
                     reg_min: float = 0.3) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """CenterNet/TTFNet targets for one image from (K, 4) boxes in net-input px.

    Returns heatmap (out_h, out_w) in [0, 1] (1 at each box's centre cell, elliptic
    Gaussian with sigma = alpha * size / 6 in cells), ltrb (4, out_h, out_w): distances
    from each cell centre ``stride * j + (stride - 1) / 2`` to the edges of the box it
    regresses, and regression weights (out_h, out_w) (the Gaussian value where >= reg_min,
    normalised to sum 1 per vehicle so that small, far vehicles weigh as much as near ones;
    smaller boxes take precedence where boxes overlap).
    """
    hm = np.zeros((out_h, out_w), np.float32)
    ltrb = np.zeros((4, out_h, out_w), np.float32)
    wt = np.zeros((out_h, out_w), np.float32)
    if len(boxes) == 0:
        return hm, ltrb, wt
    jj = np.arange(out_w)[None, :]
    ii = np.arange(out_h)[:, None]
    cxs = stride * jj + (stride - 1) / 2.0
    cys = stride * ii + (stride - 1) / 2.0
    areas = (boxes[:, 2] - boxes[:, 0]) * (boxes[:, 3] - boxes[:, 1])
    for k in np.argsort(-areas):          # large first; small ones overwrite the regression
        x1, y1, x2, y2 = boxes[k]
        cx, cy = (x1 + x2) / 2, (y1 + y2) / 2
        cj = int(np.clip(np.floor((cx + 0.5) / stride), 0, out_w - 1))
        ci = int(np.clip(np.floor((cy + 0.5) / stride), 0, out_h - 1))
        sx = max(alpha * (x2 - x1) / stride / 6, 0.35)
        sy = max(alpha * (y2 - y1) / stride / 6, 0.35)
        g = np.exp(-((jj - cj) ** 2) / (2 * sx * sx) - ((ii - ci) ** 2) / (2 * sy * sy)).astype(np.float32)
        np.maximum(hm, g, out=hm)
        hm[ci, cj] = 1.0
        reg = g >= reg_min
        reg[ci, cj] = True
        ltrb[0][reg] = (cxs - x1).repeat(out_h, 0)[reg]
        ltrb[1][reg] = (cys - y1).repeat(out_w, 1)[reg]
        ltrb[2][reg] = (x2 - cxs).repeat(out_h, 0)[reg]
        ltrb[3][reg] = (y2 - cys).repeat(out_w, 1)[reg]
        wt[reg] = g[reg] / g[reg].sum()     # every vehicle weighs the same, whatever its size
    return hm, ltrb, wt
