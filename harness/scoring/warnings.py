"""Forward-collision warnings scored as episodes against the truth (``warning.*`` of ``metrics.json``).

The pipeline decides (:mod:`monorarp.warning`); the harness only scores: episodes, conflict
frames, false alarms, first-warning TTC (s), lead time (s) and exposure (s, km). Their
definitions: docs/metrics.md (warning episodes).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import asdict, dataclass

import numpy as np

from harness.scoring.match import as_boxes, match_boxes
from harness.truth import FrameTruth, ObjectTruth
from monorarp.types import FrameResult


@dataclass
class Episode:
    index: int
    onset_frame: int
    end_frame: int
    onset_t: float
    end_t: float
    track_id: int | None           # the object warned for at onset
    gt_id: int | None = None       # the truth vehicle that track matches at onset
    true_ttc_at_onset_s: float | None = None
    true_ttc_at_conflict_s: float | None = None   # onset, or the first collision-course frame of an early episode
    conflict: bool = False         # a conflict frame lies within the episode
    false_alarm: bool = False
    why: str = ""

    def to_dict(self) -> dict:
        return asdict(self)


def episodes(results: Sequence[FrameResult]) -> list[Episode]:
    """The warning episodes of a run, in order (frames whose warning is active, grouped by episode index)."""
    out: list[Episode] = []
    for r in results:
        w = r.warning
        if not w.active:
            continue
        key = w.episode if w.episode is not None else -1
        if out and out[-1].index == key and out[-1].end_frame == r.index - 1:
            out[-1].end_frame, out[-1].end_t = r.index, float(r.t)
        else:
            out.append(Episode(index=key, onset_frame=r.index, end_frame=r.index, onset_t=float(r.t),
                               end_t=float(r.t), track_id=w.track_id))
    return out


def conflict_frames(truths: Sequence[FrameTruth], threshold_s: float) -> np.ndarray:
    """Per frame: is there a truth conflict (module docstring)?"""
    return np.array([t.ego.crashed or any(o.ttc is not None and o.ttc < threshold_s for o in t.objects)
                     for t in truths], dtype=bool)


def _matched_truth(truth: FrameTruth, result: FrameResult, track_id: int | None,
                   min_iou: float) -> ObjectTruth | None:
    """The truth object the track ``track_id`` matches in this frame (Hungarian on IoU), or None."""
    objs = truth.objects
    ids = [t.id for t in result.tracks]
    if track_id is None or track_id not in ids or not objs:
        return None
    pairs = match_boxes(as_boxes([o.box for o in objs]), as_boxes([t.box for t in result.tracks]), min_iou)
    e_of = ids.index(track_id)
    return next((objs[g] for g, e, _ in pairs if e == e_of), None)


def _frame_ttc(truth: FrameTruth, result: FrameResult, track_id: int | None,
               min_iou: float) -> tuple[ObjectTruth | None, float | None]:
    """(matched truth object, true TTC) of the warned track in one frame; unmatched: the frame's lowest true TTC."""
    obj = _matched_truth(truth, result, track_id, min_iou)
    if obj is not None:
        return obj, obj.ttc
    return None, truth.min_ttc


def _why(ep: Episode, truth: FrameTruth, result: FrameResult, obj: ObjectTruth | None) -> str:
    """One line saying what the pipeline saw and what was true at the onset of a false alarm."""
    st = result.states.get(ep.track_id) if ep.track_id is not None else None
    est = (f"est d_x {st.d_x:+.1f} m, d_y {st.d_y:.1f} m, v_x {st.v_x:+.1f} m/s, v_y {st.v_y:+.1f} m/s, "
           f"warning TTC {result.warning.ttc:.2f} s" if st is not None and result.warning.ttc is not None
           else "no state")
    if obj is None:
        return f"track {ep.track_id} matches no vehicle (a false or mislocated track); {est}"
    ttc = obj.ttc
    return (f"track {ep.track_id} is vehicle {obj.id} (lane {obj.lane_rel or 0:+d}): {est}; "
            f"true d_lat {obj.d_lat:+.1f} m, d_long {obj.d_long:.1f} m, v_lat {obj.v_lat:+.1f} m/s, "
            f"v_long {obj.v_long:+.1f} m/s, true TTC {'none' if ttc is None else f'{ttc:.2f} s'}")


def warning_metrics(truths: Sequence[FrameTruth], results: Sequence[FrameResult], threshold_s: float,
                    min_iou: float = 0.5) -> dict:
    """``warning.*`` of ``metrics.json`` (module docstring). ``truths[i]`` and ``results[i]`` are the same frame."""
    conflict = conflict_frames(truths, threshold_s)
    by_frame = {r.index: k for k, r in enumerate(results)}
    eps = episodes(results)
    for ep in eps:
        k0, k1 = by_frame[ep.onset_frame], by_frame[ep.end_frame]
        ep.conflict = bool(conflict[k0:k1 + 1].any())
        ep.false_alarm = not ep.conflict
        obj, ep.true_ttc_at_onset_s = _frame_ttc(truths[k0], results[k0], ep.track_id, min_iou)
        if obj is not None:
            ep.gt_id = obj.id
        ep.true_ttc_at_conflict_s = ep.true_ttc_at_onset_s
        for k in range(k0 + 1, k1 + 1) if ep.true_ttc_at_onset_s is None else ():
            _, ttc_k = _frame_ttc(truths[k], results[k], results[k].warning.track_id, min_iou)
            if ttc_k is not None:       # early episode still on when the collision course began
                ep.true_ttc_at_conflict_s = ttc_k
                break
        if ep.false_alarm:
            ep.why = _why(ep, truths[k0], results[k0], obj)
    t = np.array([tr.t for tr in truths], dtype=float)
    dt = float(np.median(np.diff(t))) if t.size > 1 else 0.0
    speeds = np.array([tr.ego.speed for tr in truths], dtype=float)
    crash = [k for k, tr in enumerate(truths) if tr.ego.crashed]
    contact_t = float(t[crash[0]]) if crash else None
    first = eps[0] if eps else None
    conflict_idx = np.flatnonzero(conflict)
    return {
        "threshold_s": float(threshold_s),
        "episodes": len(eps),
        "false_alarms": sum(e.false_alarm for e in eps),
        "first_warning_t_s": None if first is None else first.onset_t,
        "first_warning_ttc_s": None if first is None else first.true_ttc_at_conflict_s,
        "first_warning_early": None if first is None else (first.true_ttc_at_onset_s is None
                                                           and first.true_ttc_at_conflict_s is not None),
        "first_warning_false_alarm": None if first is None else first.false_alarm,
        "first_conflict_t_s": float(t[conflict_idx[0]]) if conflict_idx.size else None,
        "contact_t_s": contact_t,
        "lead_time_s": None if first is None or contact_t is None else contact_t - first.onset_t,
        "conflict_frames": int(conflict.sum()),
        "warning_frames": sum(r.warning.active for r in results),
        "exposure_s": len(truths) * dt,
        "exposure_km": float(speeds.sum() * dt / 1000.0),
        "episode_list": [e.to_dict() for e in eps],
    }
