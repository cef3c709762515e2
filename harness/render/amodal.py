"""Amodal boxes: each vehicle's box as if nothing hid it, clipped to the image (KITTI's 2-D box convention).

KITTI's 2-D labels are the projections of the 3-D boxes clipped to the image: a parked car half hidden
by the one in front still gets its whole box (median IoU 0.97 with the projected 3-D box over the
development frames, occluded or not). Training a detector on tight boxes of the *visible* pixels
teaches it to box only the visible part, which is a localisation miss under KITTI's rules.

The renderer already draws every vehicle that may be hidden (by a nearer vehicle, by the roadside, or by
the image border) alone in a sub-window (:mod:`harness.render.visibility`). The tight box of its pixels
there is its unoccluded silhouette's box. With a lens, the silhouette's row ends are mapped onto the
distorted image before boxing. A vehicle that was not drawn alone is unhidden, so its visible box is
already its amodal box.

Coordinates: continuous pixels, pixel centres at integers (a box spans [x0, x1] x [y0, y1] edges).
"""

from __future__ import annotations

import numpy as np

from monorarp.core.boxes import clip_to_image
from monorarp.core.camera import CameraModel


def window_silhouette_boxes(codes: np.ndarray, x0: int, y0: int, scale: int,
                            n_members: int) -> dict[int, np.ndarray]:
    """Member index k -> its silhouette's box in full-resolution (canvas) pixels.

    ``codes``: (h, w) overlay id pass of a sub-window, top row first, member k drawn as bit k (the codes
    OR-ed: a pixel holds the bits of every member covering it); window pixel (r, c) covers
    full-resolution columns ``x0 + scale*c`` .. ``x0 + scale*c + scale - 1`` (and rows alike).
    """
    rows_or = np.bitwise_or.reduce(codes, axis=1)          # (h,) the members in each row
    cols_or = np.bitwise_or.reduce(codes, axis=0)          # (w,) and in each column
    out = {}
    for k in range(n_members):
        rows = np.flatnonzero((rows_or >> k) & 1)
        if not len(rows):
            continue
        cols = np.flatnonzero((cols_or >> k) & 1)
        out[k] = np.array([x0 + scale * cols[0] - 0.5, y0 + scale * rows[0] - 0.5,
                           x0 + scale * (cols[-1] + 1) - 0.5, y0 + scale * (rows[-1] + 1) - 0.5])
    return out


def window_silhouette_outline(codes: np.ndarray, k: int, x0: int, y0: int, scale: int) -> np.ndarray:
    """(M, 2) full-resolution points on member k's silhouette outline (bit k of the overlay ``codes``, as
    for :func:`window_silhouette_boxes`): the outer edges of each row's first and last pixel (pixel
    corners, so the box of the points is the silhouette's box)."""
    mask = ((codes >> k) & 1).astype(bool)
    rows = np.flatnonzero(mask.any(axis=1))
    if not len(rows):
        return np.empty((0, 2))
    sub = mask[rows]
    first = sub.argmax(axis=1)
    last = sub.shape[1] - 1 - sub[:, ::-1].argmax(axis=1)
    left = x0 + scale * first - 0.5
    right = x0 + scale * (last + 1) - 0.5
    top = y0 + scale * rows - 0.5
    bottom = y0 + scale * (rows + 1) - 0.5
    return np.concatenate([np.stack([left, top], 1), np.stack([left, bottom], 1),
                           np.stack([right, top], 1), np.stack([right, bottom], 1)])


def distorted_box(outline_canvas: np.ndarray, canvas_origin: tuple[int, int], camera: CameraModel) -> np.ndarray:
    """The box on ``camera``'s distorted image of outline points given in lens-canvas pixels
    (canvas pixel (u, v) is the ideal pixel (u + x0, v + y0))."""
    ideal = np.asarray(outline_canvas, dtype=float) + np.asarray(canvas_origin, dtype=float)
    uv = camera.distort_pixels(ideal)
    return np.r_[uv.min(axis=0), uv.max(axis=0)]


def clip_box(box: np.ndarray, width: int, height: int) -> np.ndarray | None:
    """``box`` clipped to a ``width`` x ``height`` image; None when nothing of it is inside."""
    b = clip_to_image(box, width, height)
    return b if b[2] > b[0] and b[3] > b[1] else None
