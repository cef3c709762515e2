"""One frame's truth and tracks side by side: the :class:`~harness.scoring.records.ObjectRecord` rows.

Tracks are matched to the frame's ground-truth objects (Hungarian on IoU, :mod:`harness.scoring.match`);
each object gets a record (with its matched track's box and state, if any) and each unmatched track
one of its own, marked ``set_aside`` when the rules do not count it as a false positive.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from harness.scoring.match import match_boxes, split_ignored
from harness.scoring.records import ObjectRecord, as_float
from harness.scoring.rules import EvalConfig, counted_mask, out_of_range
from harness.world.truth import FrameTruth
from monorarp.core.boxes import as_boxes
from monorarp.core.camera import CameraModel
from monorarp.core.types import FrameResult


def frame_records(truth: FrameTruth, result: FrameResult, cfg: EvalConfig,
                  camera: CameraModel | None = None) -> list[ObjectRecord]:
    """Side-by-side records of one frame (see :mod:`harness.scoring.records`)."""
    objects = truth.objects
    counted = counted_mask(objects, cfg)
    tracks = result.tracks
    gt_boxes = as_boxes([o.box for o in objects])
    tr_boxes = as_boxes([t.box for t in tracks])
    match = {g: (e, iou) for g, e, iou in match_boxes(gt_boxes, tr_boxes, cfg.min_iou)}
    _, set_aside = split_ignored(gt_boxes, counted, tr_boxes, cfg.min_iou, cfg.ignore_cover,
                                 out_of_range(tr_boxes, camera, cfg.max_range_m))
    frame, t = truth.frame, truth.t
    recs: list[ObjectRecord] = []
    used = set()
    num = as_float

    def fill_track(r: ObjectRecord, tr) -> None:
        r.track_id, r.coasting = tr.id, tr.coasting
        r.est_x1, r.est_y1, r.est_x2, r.est_y2 = map(float, tr.box)
        st = result.states.get(tr.id)
        if st is not None:
            r.d_y_est, r.d_x_est, r.v_y_est, r.v_x_est = st.d_y, st.d_x, st.v_y, st.v_x
            r.d_y_std, r.d_x_std, r.v_y_std, r.v_x_std = map(num, (st.d_y_std, st.d_x_std, st.v_y_std, st.v_x_std))
            r.a_y_est, r.a_y_std, r.age_s, r.expansion_rate, r.expansion_rate_std = map(
                num, (st.a_y, st.a_y_std, st.age_s, st.expansion_rate, st.expansion_rate_std))
            r.registered_rate, r.registered_rate_std = num(st.registered_rate), num(st.registered_rate_std)
            r.registered_v_x, r.registered_v_x_std = num(st.registered_v_x), num(st.registered_v_x_std)
        r.ttc_est = num(result.risk.ttc.get(tr.id))

    for g, o in enumerate(objects):
        r = ObjectRecord(frame=frame, t=t, gt_id=o.id, counted=bool(counted[g]),
                         visibility=float(o.visibility), d_long_gt=num(o.d_long), d_lat_gt=num(o.d_lat),
                         v_long_gt=num(o.v_long), v_lat_gt=num(o.v_lat), ttc_gt=num(o.ttc))
        r.gt_x1, r.gt_y1, r.gt_x2, r.gt_y2 = map(float, o.box)
        if g in match:
            e, iou = match[g]
            used.add(e)
            r.matched, r.iou = True, iou
            fill_track(r, tracks[e])
        recs.append(r)
    for e, tr in enumerate(tracks):
        if e not in used:
            r = ObjectRecord(frame=frame, t=t, set_aside=bool(set_aside[e]))
            fill_track(r, tr)
            recs.append(r)
    return recs


def scored_pairs(records: Sequence[ObjectRecord]) -> list[ObjectRecord]:
    """The records of counted objects matched to a track (what state and TTC errors are taken over)."""
    return [r for r in records if r.counted and r.matched]


def column(records: Sequence[ObjectRecord], name: str) -> np.ndarray:
    """(N,) float array of one field of ``records``."""
    return np.array([getattr(r, name) for r in records], dtype=float)
