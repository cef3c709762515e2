"""Foveated second pass: where the crop goes and how its detections merge with the full view's.

A fixed-size net sees a 640x360 frame at half resolution, so a vehicle 60 m away
(~10 px tall) is ~5 px tall at the net's input and its bottom edge -- the distance
estimator's input, ``d_y^2 / (h_c F)`` m per px -- is coarse. Far vehicles sit near
the horizon at the image's centre column, so a second pass over a crop around
``(c_x, horizon_row)`` at ``zoom`` times the full view's scale (at most the source's
own resolution) gives them ``zoom`` times the pixels for the price of one more run.

Coordinates: continuous source pixels (:mod:`monorarp.core.types`: pixel centres at
integers, an image of width W spans [-0.5, W - 0.5]).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from monorarp.core.boxes import iou_matrix

if TYPE_CHECKING:
    from monorarp.core.camera import CameraModel
    from monorarp.detection.letterbox import Letterbox


@dataclass(frozen=True)
class Fovea:
    """A crop ``[x0, x0 + w) x [y0, y0 + h)`` (integer source pixel indices) of a ``src_w`` x ``src_h`` image."""

    x0: int
    y0: int
    w: int
    h: int
    src_w: int
    src_h: int

    @classmethod
    def place(cls, src_w: int, src_h: int, net_w: int, net_h: int, centre_col: float, horizon_row: float,
              zoom: float = 2.0, below: float = 0.25) -> "Fovea | None":
        """The crop the net sees at ``zoom`` x the full view's letterbox scale (capped at 1 = source pixels).

        Its size is the net input's divided by that scale (so no padding); it is centred on
        ``centre_col``, its centre row is ``horizon_row + below * h`` (vehicles lie mostly below the
        horizon: with ``below=0.25`` the horizon is a quarter of the way down the crop), and it is
        shifted to lie inside the image.
        None when the crop would not add resolution (scale gain < 1.2) or would cover the whole image.
        """
        full = min(net_w / src_w, net_h / src_h)
        scale = min(zoom * full, 1.0)
        if scale < 1.2 * full:
            return None
        w, h = int(round(net_w / scale)), int(round(net_h / scale))
        if w >= src_w and h >= src_h:
            return None
        w, h = min(w, src_w), min(h, src_h)
        x0 = int(round(centre_col + 0.5 - w / 2))
        y0 = int(round(horizon_row + below * h + 0.5 - h / 2))
        x0 = min(max(x0, 0), src_w - w)
        y0 = min(max(y0, 0), src_h - h)
        return cls(x0, y0, w, h, src_w, src_h)

    @classmethod
    def for_camera(cls, camera: "CameraModel | None", src_w: int, src_h: int, net_w: int, net_h: int,
                   zoom: float = 2.0, below: float = 0.25) -> "Fovea | None":
        """:meth:`place` centred on the camera's principal column and around its horizon row (the camera
        scaled to the image's size); without a camera, on the image centre."""
        cam = camera
        if cam is not None and (cam.width, cam.height) != (src_w, src_h):
            cam = cam.scaled(src_w, src_h)
        col = cam.cx if cam is not None else (src_w - 1) / 2
        row = cam.horizon_row if cam is not None else (src_h - 1) / 2
        return cls.place(src_w, src_h, net_w, net_h, col, row, zoom, below)

    def cut(self, image: np.ndarray) -> np.ndarray:
        return image[self.y0:self.y0 + self.h, self.x0:self.x0 + self.w]

    def to_src(self, boxes: np.ndarray) -> np.ndarray:
        """(N, 4) boxes in crop pixels -> source pixels."""
        return np.asarray(boxes, dtype=np.float64).reshape(-1, 4) + np.array([self.x0, self.y0, self.x0, self.y0])

    def interior(self, boxes: np.ndarray, margin_px: float) -> np.ndarray:
        """(N,) True where a source-pixel box keeps ``margin_px`` from every crop edge that is not an image edge.

        A box reaching a crop edge inside the image is cut by the crop: the full view sees it whole.
        """
        b = np.asarray(boxes, dtype=np.float64).reshape(-1, 4)
        lo_x, hi_x = self.x0 - 0.5, self.x0 + self.w - 0.5
        lo_y, hi_y = self.y0 - 0.5, self.y0 + self.h - 0.5
        ok = np.ones(len(b), dtype=bool)
        if self.x0 > 0:
            ok &= b[:, 0] >= lo_x + margin_px
        if self.x0 + self.w < self.src_w:
            ok &= b[:, 2] <= hi_x - margin_px
        if self.y0 > 0:
            ok &= b[:, 1] >= lo_y + margin_px
        if self.y0 + self.h < self.src_h:
            ok &= b[:, 3] <= hi_y - margin_px
        return ok


def merge(full_boxes: np.ndarray, full_scores: np.ndarray, fov_boxes: np.ndarray, fov_scores: np.ndarray,
          fovea: Fovea, score_threshold: float, support: float | None = None, margin_px: float = 2.0,
          dup_iou: float = 0.3, box: str = "auto", max_height: float = 0.35,
          mean_above: float = 0.15) -> tuple[np.ndarray, np.ndarray]:
    """Union of the two passes; inside the crop the fovea (the finer view) has the last word.

    ``full_*``: the full view's detections at ``score_threshold``; ``fov_*``: the fovea's, decoded
    down to ``support`` (<= ``score_threshold``), all in source pixels. Only fovea boxes in the crop's
    interior (:meth:`Fovea.interior`) and at most ``max_height`` of the crop's height tall count:
    the fovea is for far, small vehicles (without the road's context a close-up of the crop's lower
    part can look like a vehicle); a taller full-view box is treated as outside the crop. Then:

    * a fovea box scoring >= ``score_threshold`` is a detection;
    * a full-view box overlapping a fovea box (IoU > ``dup_iou``) is the same vehicle, output once with
      the higher of the two scores, even when the fovea's score lies only between ``support`` and
      ``score_threshold``; its box is the fovea's (``box="fovea"``: twice the pixels), the mean of the
      two (``box="mean"``: two nearly independent readings of each edge), or (``"auto"``) the fovea's
      for boxes up to ``mean_above`` of the crop's height and the mean for taller ones (on rendered
      640x360 frames the fovea's bottom edge is the better one below ~30 px, the mean above);
    * a full-view box in the crop's interior that no fovea box (>= ``support``) confirms is dropped
      when ``support`` is given (the fovea saw the region at higher resolution and found nothing);
      with ``support=None`` it is kept (plain union);
    * other full-view boxes (outside or cut by the crop) are kept.

    Returns (boxes (K, 4), scores (K,)) sorted by score.
    """
    fb, fs = np.asarray(full_boxes, float).reshape(-1, 4), np.asarray(full_scores, float).reshape(-1)
    cb, cs = np.asarray(fov_boxes, float).reshape(-1, 4), np.asarray(fov_scores, float).reshape(-1)
    tall = max_height * fovea.h
    inside = fovea.interior(cb, margin_px) & (cb[:, 3] - cb[:, 1] <= tall)
    if support is None:
        inside &= cs >= score_threshold
    cb, cs = cb[inside], cs[inside]
    out_c = cs >= score_threshold                   # fovea boxes output on their own
    out_s = cs.copy()
    drop_f = np.zeros(len(fb), dtype=bool)
    if len(cb) and len(fb):
        iou = iou_matrix(fb, cb)                      # (F, C)
        best = iou.argmax(axis=1)
        dup = iou[np.arange(len(fb)), best] > dup_iou
        cb = cb.copy()
        for f in np.flatnonzero(dup):                 # full-view box confirmed by the fovea: fused
            c = best[f]
            out_c[c] = True
            out_s[c] = max(out_s[c], fs[f])
            if box == "mean" or (box == "auto" and cb[c, 3] - cb[c, 1] > mean_above * fovea.h):
                cb[c] = (cb[c] + fb[f]) / 2
        drop_f |= dup
    if support is not None:
        drop_f |= fovea.interior(fb, margin_px) & (fb[:, 3] - fb[:, 1] <= tall)
    boxes = np.concatenate([fb[~drop_f], cb[out_c]])
    scores = np.concatenate([fs[~drop_f], out_s[out_c]])
    order = np.argsort(-scores, kind="stable")
    return boxes[order], scores[order]


class FoveaPass:
    """The second pass's crop of a detector, cached per image size: :meth:`Fovea.for_camera` when
    ``foveate`` (None otherwise) and the letterbox the detector's net sees it through
    (:meth:`fovea_letterbox`). Needs ``camera``, ``foveate``, ``input_w``, ``input_h``, ``fovea_zoom``,
    ``fovea_below`` and ``_fovea`` (None until the first call) on the detector."""

    def fovea_letterbox(self, w: int, h: int) -> "Letterbox":
        raise NotImplementedError

    def fovea(self, width: int, height: int) -> "tuple[Fovea | None, Letterbox | None]":
        """The second-pass crop for a ``width`` x ``height`` image (None: no second pass) and its letterbox.

        Centred on the camera's principal column, around its horizon row (the camera is scaled
        to the image's size); without a camera, the image centre.
        """
        if self._fovea is not None and self._fovea[0] == (width, height):
            return self._fovea[1], self._fovea[2]
        fov = (Fovea.for_camera(self.camera, width, height, self.input_w, self.input_h, self.fovea_zoom,
                                self.fovea_below) if self.foveate else None)
        lb = None if fov is None else self.fovea_letterbox(fov.w, fov.h)
        self._fovea = ((width, height), fov, lb)
        return fov, lb
