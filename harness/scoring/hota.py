"""HOTA (Luiten et al., IJCV 2021: "HOTA: A Higher Order Metric for Evaluating Multi-Object
Tracking"), computed as TrackEval computes it, in numpy.

Input per frame: the ids of the ground-truth objects and of the tracks that take part, and their
(n_gt, n_tracks) similarity matrix (IoU for boxes); outputs (fractions 0..1) are means over the
localisation thresholds :data:`ALPHAS`, and sequences combine as in TrackEval (:func:`combine`).
Matching, definitions and the check against TrackEval 1.3.0: docs/metrics.md (HOTA).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import linear_sum_assignment

#: Localisation thresholds, exactly TrackEval's ``np.arange(0.05, 0.99, 0.05)``.
ALPHAS = np.arange(0.05, 0.99, 0.05)
_EPS = np.finfo(float).eps

#: The per-threshold statistics that suffice to combine sequences (``metrics.json``'s
#: ``tracking.hota_by_alpha``).
STAT_FIELDS = ("tp", "fn", "fp", "ass_a", "ass_re", "ass_pr", "loc_a")


@dataclass
class HotaResult:
    """HOTA statistics per threshold (arrays over :data:`ALPHAS`)."""

    tp: np.ndarray
    fn: np.ndarray
    fp: np.ndarray
    ass_a: np.ndarray
    ass_re: np.ndarray
    ass_pr: np.ndarray
    loc_a: np.ndarray
    alphas: np.ndarray = field(default_factory=lambda: ALPHAS.copy())

    @property
    def det_re(self) -> np.ndarray:
        return self.tp / np.maximum(1, self.tp + self.fn)

    @property
    def det_pr(self) -> np.ndarray:
        return self.tp / np.maximum(1, self.tp + self.fp)

    @property
    def det_a(self) -> np.ndarray:
        return self.tp / np.maximum(1, self.tp + self.fn + self.fp)

    @property
    def hota(self) -> np.ndarray:
        return np.sqrt(self.det_a * self.ass_a)

    @property
    def owta(self) -> np.ndarray:
        return np.sqrt(self.det_re * self.ass_a)

    def summary(self) -> dict[str, float]:
        """Means over the thresholds (TrackEval's summary values), plus ``hota0``/``loca0`` at alpha = 0.05."""
        return {"hota": float(np.mean(self.hota)), "deta": float(np.mean(self.det_a)),
                "assa": float(np.mean(self.ass_a)), "loca": float(np.mean(self.loc_a)),
                "detre": float(np.mean(self.det_re)), "detpr": float(np.mean(self.det_pr)),
                "assre": float(np.mean(self.ass_re)), "asspr": float(np.mean(self.ass_pr)),
                "owta": float(np.mean(self.owta)),
                "hota0": float(self.hota[0]), "loca0": float(self.loc_a[0])}

    def to_dict(self) -> dict[str, list[float]]:
        """JSON-ready per-threshold statistics (enough to :func:`combine` later)."""
        return {"alpha": [round(float(a), 2) for a in self.alphas],
                **{k: [float(v) for v in getattr(self, k)] for k in STAT_FIELDS}}

    @classmethod
    def from_dict(cls, d: Mapping) -> "HotaResult":
        arrays = {k: np.asarray(d[k], dtype=float) for k in STAT_FIELDS}
        return cls(**arrays, alphas=np.asarray(d.get("alpha", ALPHAS), dtype=float))


def _empty_result(n_gt: int, n_tr: int) -> HotaResult:
    z = np.zeros(len(ALPHAS))
    return HotaResult(tp=z.copy(), fn=np.full(len(ALPHAS), float(n_gt)), fp=np.full(len(ALPHAS), float(n_tr)),
                      ass_a=z.copy(), ass_re=z.copy(), ass_pr=z.copy(), loc_a=np.ones(len(ALPHAS)))


def _dense_ids(frames: Sequence[np.ndarray]) -> tuple[list[np.ndarray], int]:
    """Per-frame id arrays relabelled to 0..n-1 (sorted order of the distinct ids), and n."""
    arrays = [np.asarray(f, dtype=np.int64).reshape(-1) for f in frames]
    allv = np.concatenate(arrays) if arrays else np.empty(0, np.int64)
    uniq = np.unique(allv)
    return [np.searchsorted(uniq, a) for a in arrays], int(uniq.size)


def hota(gt_ids: Sequence[Sequence[int]], tracker_ids: Sequence[Sequence[int]],
         similarity: Sequence[np.ndarray]) -> HotaResult:
    """HOTA of one sequence. Per frame ``k``: ``gt_ids[k]`` (n_g,), ``tracker_ids[k]`` (n_t,) and
    ``similarity[k]`` (n_g, n_t) in [0, 1]. Ids must be unique within a frame."""
    if not len(gt_ids) == len(tracker_ids) == len(similarity):
        raise ValueError("gt_ids, tracker_ids and similarity must have one entry per frame")
    g_frames, n_gid = _dense_ids(gt_ids)
    t_frames, n_tid = _dense_ids(tracker_ids)
    sims = [np.asarray(s, dtype=float).reshape(len(g), len(t)) for s, g, t in zip(similarity, g_frames, t_frames)]
    for k, (g, t) in enumerate(zip(g_frames, t_frames)):
        if np.unique(g).size != g.size or np.unique(t).size != t.size:
            raise ValueError(f"frame {k}: an id occurs twice")
    n_gt_dets = sum(g.size for g in g_frames)
    n_tr_dets = sum(t.size for t in t_frames)
    if n_tr_dets == 0 or n_gt_dets == 0:
        return _empty_result(n_gt_dets, n_tr_dets)

    gt_count = np.bincount(np.concatenate(g_frames), minlength=n_gid).astype(float)
    tr_count = np.bincount(np.concatenate(t_frames), minlength=n_tid).astype(float)

    # Global alignment A(g, t), kept sparse: only the pairs that ever share a frame.
    codes, shares, sizes = [], [], []
    for g, t, s in zip(g_frames, t_frames, sims):
        denom = s.sum(0)[None, :] + s.sum(1)[:, None] - s
        share = np.zeros_like(s)
        ok = denom > 0 + _EPS
        share[ok] = s[ok] / denom[ok]
        codes.append((g[:, None] * n_tid + t[None, :]).ravel())
        shares.append(share.ravel())
        sizes.append(s.size)
    code_all = np.concatenate(codes)
    pair, inverse = np.unique(code_all, return_inverse=True)
    potential = np.bincount(inverse, weights=np.concatenate(shares), minlength=pair.size)
    pg, pt = np.divmod(pair, n_tid)
    alignment = potential / (gt_count[pg] + tr_count[pt] - potential)
    align_all = alignment[inverse]
    offsets = np.concatenate([[0], np.cumsum(sizes)])

    n_a = len(ALPHAS)
    tp, fn, fp, loc = np.zeros(n_a), np.zeros(n_a), np.zeros(n_a), np.zeros(n_a)
    matched_codes, matched_masks = [], []
    for k, (g, t, s) in enumerate(zip(g_frames, t_frames, sims)):
        if g.size == 0 or t.size == 0:
            fp += t.size
            fn += g.size
            continue
        score = align_all[offsets[k]:offsets[k + 1]].reshape(s.shape) * s
        rows, cols = linear_sum_assignment(-score)
        msim = s[rows, cols]
        hit = msim[:, None] >= ALPHAS[None, :] - _EPS                  # (matches, alphas)
        n_hit = hit.sum(axis=0)
        tp += n_hit
        fn += g.size - n_hit
        fp += t.size - n_hit
        loc += np.where(hit, msim[:, None], 0.0).sum(axis=0)
        matched_codes.append(g[rows] * n_tid + t[cols])
        matched_masks.append(hit)

    ass_a, ass_re, ass_pr = np.zeros(n_a), np.zeros(n_a), np.zeros(n_a)
    if matched_codes:
        mcode = np.concatenate(matched_codes)
        mhit = np.concatenate(matched_masks).astype(float)
        upair, uinv = np.unique(mcode, return_inverse=True)
        m = np.zeros((upair.size, n_a))
        np.add.at(m, uinv, mhit)                                        # TP count of each id pair, per alpha
        ug, ut = np.divmod(upair, n_tid)
        gc, tc = gt_count[ug][:, None], tr_count[ut][:, None]
        denom_tp = np.maximum(1, tp)
        ass_a = np.sum(m * (m / np.maximum(1, gc + tc - m)), axis=0) / denom_tp
        ass_re = np.sum(m * (m / np.maximum(1, gc)), axis=0) / denom_tp
        ass_pr = np.sum(m * (m / np.maximum(1, tc)), axis=0) / denom_tp
    loc_a = np.maximum(1e-10, loc) / np.maximum(1e-10, tp)
    return HotaResult(tp=tp, fn=fn, fp=fp, ass_a=ass_a, ass_re=ass_re, ass_pr=ass_pr, loc_a=loc_a)


def combine(results: Sequence[HotaResult]) -> HotaResult:
    """Several sequences as one score (TrackEval's ``combine_sequences``)."""
    if not results:
        return _empty_result(0, 0)
    tp = sum(r.tp for r in results)
    fn = sum(r.fn for r in results)
    fp = sum(r.fp for r in results)
    w = np.maximum(1.0, tp)
    loc_sum = sum(r.loc_a * r.tp for r in results)
    return HotaResult(tp=tp, fn=fn, fp=fp,
                      ass_a=sum(r.ass_a * r.tp for r in results) / w,
                      ass_re=sum(r.ass_re * r.tp for r in results) / w,
                      ass_pr=sum(r.ass_pr * r.tp for r in results) / w,
                      loc_a=np.maximum(1e-10, loc_sum) / np.maximum(1e-10, tp))


class HotaAccumulator:
    """Collects frames (ids + similarity) and computes :func:`hota` at the end."""

    def __init__(self) -> None:
        self.gt_ids: list[np.ndarray] = []
        self.tracker_ids: list[np.ndarray] = []
        self.similarity: list[np.ndarray] = []

    def update(self, gt_ids: Sequence[int], tracker_ids: Sequence[int], similarity: np.ndarray) -> None:
        g = np.asarray(gt_ids, dtype=np.int64).reshape(-1)
        t = np.asarray(tracker_ids, dtype=np.int64).reshape(-1)
        self.gt_ids.append(g)
        self.tracker_ids.append(t)
        self.similarity.append(np.asarray(similarity, dtype=float).reshape(g.size, t.size))

    def compute(self) -> HotaResult:
        return hota(self.gt_ids, self.tracker_ids, self.similarity)
