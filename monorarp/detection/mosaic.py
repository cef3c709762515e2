"""Mosaic full view: a wide frame as two overlapping halves stacked in one square net input.

A 1242x375 KITTI frame letterboxed into a 416x416 canvas is seen at scale 0.335 (125 rows of
image, 291 rows of padding): a car 25 px tall is 8 px at the net's input. Cut into a left and a
right tile (each ``tile_w`` columns, all rows; they overlap in the middle) and stacked one above
the other with a ``gap_px`` grey band between them, the same frame fills the canvas at scale
``(net_h - gap_px) / (2 * src_h)`` (0.539 for KITTI) for the price of the same one net run.

Placement (canvas = net input, edge convention: it spans [0, net_w]): the left tile (source
columns ``[0, tile_w)``) at the canvas's top-left corner, the right tile (``[src_w - tile_w,
src_w)``) at its bottom-left corner, both resized to ``new_w x new_h``. A box belongs to the tile
holding its centre; one within ``margin_px`` (canvas px) of its tile's inner side (the left tile's
right side, the right tile's left side: not an image border) is *cut* by the tile. :func:`join`
then keeps whole boxes, drops cut ones that a whole box covers, and joins a vehicle cut by both
tiles (wider than the overlap) into one box.

Source coordinates: continuous pixels (:mod:`monorarp.core.types`: pixel centres at integers, an
image of width W spans [-0.5, W - 0.5]).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from monorarp.core.boxes import as_boxes, intersection


@dataclass(frozen=True)
class Mosaic:
    """Two tiles of a ``src_w`` x ``src_h`` frame in a ``net_w`` x ``net_h`` canvas (module docstring)."""

    src_w: int
    src_h: int
    net_w: int
    net_h: int
    tile_w: int       # source columns per tile
    new_w: int        # a tile's size in the canvas (px)
    new_h: int

    @classmethod
    def plan(cls, src_w: int, src_h: int, net_w: int, net_h: int, gap_px: int = 12, min_gain: float = 1.2,
             min_overlap: float = 0.2) -> "Mosaic | None":
        """The mosaic at the largest scale at which both tiles fit with ``gap_px`` rows between them and
        overlap by at least ``min_overlap`` of the width; None unless that scale is ``min_gain`` x the
        letterbox's ``min(net_w / src_w, net_h / src_h)`` (frames of ordinary aspect: 16:9 never gains)."""
        full = min(net_w / src_w, net_h / src_h)
        scale = min((net_h - gap_px) / (2 * src_h), 2 * net_w / (src_w * (1 + min_overlap)))
        if scale < min_gain * full:
            return None
        tile_w = min(int(net_w / scale), src_w)
        new_w, new_h = min(int(tile_w * scale + 1e-9), net_w), int(src_h * scale + 1e-9)   # 1e-9: 375 * 404 / 750 is 202
        return cls(src_w, src_h, net_w, net_h, tile_w, new_w, new_h)

    @property
    def right_x0(self) -> int:
        """First source column of the right tile."""
        return self.src_w - self.tile_w

    @property
    def bottom_y0(self) -> int:
        """First canvas row of the right tile (the left tile starts at row 0)."""
        return self.net_h - self.new_h

    @property
    def sx(self) -> float:
        return self.new_w / self.tile_w

    @property
    def sy(self) -> float:
        return self.new_h / self.src_h

    def apply(self, image: np.ndarray, pad_value: int = 114, interpolation: int = cv2.INTER_LINEAR) -> np.ndarray:
        """(src_h, src_w, 3) uint8 -> (net_h, net_w, 3) uint8 canvas (``interpolation``: a cv2 ``INTER_*`` flag)."""
        canvas = np.full((self.net_h, self.net_w, image.shape[2]), pad_value, dtype=image.dtype)
        for x0, y0 in ((0, 0), (self.right_x0, self.bottom_y0)):
            tile = cv2.resize(image[:, x0:x0 + self.tile_w], (self.new_w, self.new_h), interpolation=interpolation)
            canvas[y0:y0 + self.new_h, :self.new_w] = tile
        return canvas

    def to_src(self, boxes: np.ndarray, margin_px: float = 8.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(N, 4) canvas boxes (edge convention) -> (source boxes (N, 4), tile (N,), cut (N,)).

        ``tile``: 0 left, 1 right, -1 for a box centred in neither (the gap; its source box is
        meaningless). A box is first clipped to its tile; ``cut``: it reaches within ``margin_px``
        (canvas px) of the tile's inner side.
        """
        b = as_boxes(boxes).copy()
        cx, cy = (b[:, 0] + b[:, 2]) / 2, (b[:, 1] + b[:, 3]) / 2
        tile = np.full(len(b), -1, dtype=np.int64)
        tile[cy < self.new_h] = 0
        tile[cy >= self.bottom_y0] = 1
        tile[(cx < 0) | (cx > self.new_w)] = -1
        top = np.where(tile == 1, self.bottom_y0, 0).astype(np.float64)
        x_off = np.where(tile == 1, self.right_x0, 0).astype(np.float64)
        cut = np.where(tile == 0, b[:, 2] > self.new_w - margin_px, b[:, 0] < margin_px) & (tile >= 0)
        b[:, [0, 2]] = np.clip(b[:, [0, 2]], 0.0, self.new_w)
        b[:, [1, 3]] = np.clip(b[:, [1, 3]] - top[:, None], 0.0, self.new_h)
        src = np.stack([b[:, 0] / self.sx + x_off, b[:, 1] / self.sy,
                        b[:, 2] / self.sx + x_off, b[:, 3] / self.sy], axis=1) - 0.5
        return src, tile, cut


def join(boxes: np.ndarray, scores: np.ndarray, tile: np.ndarray, cut: np.ndarray, cover: float = 0.6,
         pair_iou: float = 0.6) -> tuple[np.ndarray, np.ndarray]:
    """The two tiles' boxes (source px, each tile's own NMS done) as one view: (boxes (K, 4), source index (K,)).

    * whole (uncut) boxes are kept;
    * a cut box with more than ``cover`` of its area inside a whole box is that vehicle's part: dropped;
    * a left-tile cut box and a right-tile cut box that overlap in x and whose row spans overlap by more
      than ``pair_iou`` (1-D IoU) are one vehicle wider than the overlap: their union (greedy by score);
    * other cut boxes are kept as they are.

    ``source index``: the input box each output comes from (for a union, the higher-scoring part), for
    its score and class. No NMS across tiles here: duplicates from the overlap are left to the caller's.
    """
    b = as_boxes(boxes)
    s = np.asarray(scores, dtype=np.float64).reshape(-1)
    tile, cut = np.asarray(tile).reshape(-1), np.asarray(cut, dtype=bool).reshape(-1)
    whole = np.flatnonzero(~cut)
    parts = np.flatnonzero(cut)
    if len(parts) and len(whole):
        area = np.maximum((b[parts, 2] - b[parts, 0]) * (b[parts, 3] - b[parts, 1]), 1e-9)
        inside = intersection(b[parts][:, None, :], b[whole][None, :, :]).max(axis=1) / area
        parts = parts[inside <= cover]
    out_b, out_i = [b[whole]], [whole]
    left = [i for i in parts[np.argsort(-s[parts], kind="stable")] if tile[i] == 0]
    right = [i for i in parts if tile[i] == 1]
    for i in left:
        lo, hi = np.minimum(b[i, 3], b[right, 3]), np.maximum(b[i, 1], b[right, 1])
        span = np.maximum(b[i, 3], b[right, 3]) - np.minimum(b[i, 1], b[right, 1])
        row_iou = np.maximum(lo - hi, 0.0) / np.maximum(span, 1e-9)
        ok = (np.minimum(b[i, 2], b[right, 2]) > np.maximum(b[i, 0], b[right, 0])) & (row_iou > pair_iou)
        if not ok.any():
            out_b.append(b[i][None])
            out_i.append(np.array([i]))
            continue
        j = right[int(np.argmax(np.where(ok, row_iou, -1.0)))]
        right.remove(j)
        u = np.r_[np.minimum(b[i, :2], b[j, :2]), np.maximum(b[i, 2:], b[j, 2:])]
        out_b.append(u[None])
        out_i.append(np.array([i if s[i] >= s[j] else j]))
    for j in right:
        out_b.append(b[j][None])
        out_i.append(np.array([j]))
    return np.concatenate(out_b).reshape(-1, 4), np.concatenate(out_i).astype(np.int64)
