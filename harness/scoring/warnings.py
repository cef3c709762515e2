"""Forward-collision warnings scored as episodes against the truth (``warning.*`` of ``metrics.json``).

The pipeline decides (:mod:`monorarp.warning.fcw`); the harness only scores: episodes, conflict
frames, false alarms, first-warning TTC (s), lead time (s) and exposure (s, km); and, for a
diagnosis of each episode, the warned vehicle's true TTC had it kept its braking (s). Their
definitions: docs/metrics.md (warning episodes).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass

import numpy as np

from harness.scoring.match import as_boxes, match_boxes
from harness.world.truth import FrameTruth, ObjectTruth
from monorarp.risk.ttc import closing_time
from monorarp.core.types import FrameResult

BRAKING_DIFF_S = 0.1        # the truth's acceleration: central difference of its speeds over +- this (s)
BRAKING_MAX_LATERAL_MPS = 0.5   # the braking TTC is asked only of a vehicle keeping its lane (|v_lat|, m/s)


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
    true_braking_ttc_s: float | None = None   # lowest in the episode of the warned vehicle's braking TTC (braking_ttc)
    true_accel_mps2: float | None = None      # its true relative longitudinal acceleration then (m/s^2)
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


def true_accelerations(truths: Sequence[FrameTruth], k: int, diff_s: float = BRAKING_DIFF_S) -> dict[int, float]:
    """Per vehicle id in frame ``k``, its true relative longitudinal acceleration (m/s^2, negative: closing
    faster): the central difference of ``v_long`` over the frames ``diff_s`` before and after (one-sided at
    the run's ends, or where the vehicle is not in one of them)."""
    times = [t.t for t in truths[max(0, k - 3):k + 4]]
    if not truths[k].objects or len(times) < 2:
        return {}
    dt = float(np.median(np.diff(times)))
    m = max(1, int(round(diff_s / dt))) if dt > 0 else 1
    lo, hi = truths[max(0, k - m)], truths[min(len(truths) - 1, k + m)]
    v_lo = {o.id: o.v_long for o in lo.objects}
    v_hi = {o.id: o.v_long for o in hi.objects}
    out = {}
    for o in truths[k].objects:
        a, b = v_lo.get(o.id), v_hi.get(o.id)
        (t0, v0), (t1, v1) = ((lo.t, a) if a is not None else (truths[k].t, o.v_long),
                              (hi.t, b) if b is not None else (truths[k].t, o.v_long))
        if o.v_long is not None and v0 is not None and v1 is not None and t1 > t0:
            out[o.id] = (v1 - v0) / (t1 - t0)
    return out


def braking_ttc(obj: ObjectTruth, accel_mps2: float) -> float | None:
    """The true TTC (s) of a vehicle on a collision course (``obj.ttc``) had its relative longitudinal
    acceleration ``accel_mps2`` been held: the gap its constant-velocity TTC implies, ``ttc x -v_long``, closed
    at ``v_long`` and that acceleration (:func:`monorarp.risk.ttc.closing_time`). None for a vehicle on no course, or
    moving sideways (|v_lat| over 0.5 m/s: its course is not the gap's alone)."""
    if obj.ttc is None or obj.v_long is None or obj.v_long >= 0 or abs(obj.v_lat or 0.0) > BRAKING_MAX_LATERAL_MPS:
        return None
    return float(closing_time(obj.ttc * -obj.v_long, obj.v_long, accel_mps2))


def braking_alarm(episode: Mapping, threshold_s: float) -> bool:
    """A false alarm (an episode's dict) for a vehicle truly braking so hard that, had it kept braking, its TTC
    fell under the threshold (s)."""
    ttc = episode.get("true_braking_ttc_s")
    return bool(episode.get("false_alarm")) and ttc is not None and ttc < threshold_s


def _episode_braking(truths: Sequence[FrameTruth], k0: int, k1: int, gt_id: int) -> tuple[float | None, float | None]:
    """(lowest braking TTC, the acceleration at that frame) of vehicle ``gt_id`` over frames ``k0..k1``."""
    best: tuple[float | None, float | None] = (None, None)
    for k in range(k0, k1 + 1):
        obj = next((o for o in truths[k].objects if o.id == gt_id), None)
        a = true_accelerations(truths, k).get(gt_id) if obj is not None else None
        ttc = None if a is None else braking_ttc(obj, a)
        if ttc is not None and (best[0] is None or ttc < best[0]):
            best = (ttc, a)
    return best


def _why(ep: Episode, truth: FrameTruth, result: FrameResult, obj: ObjectTruth | None) -> str:
    """One line saying what the pipeline saw and what was true at the onset of a false alarm."""
    st = result.states.get(ep.track_id) if ep.track_id is not None else None
    est = (f"est d_x {st.d_x:+.1f} m, d_y {st.d_y:.1f} m, v_x {st.v_x:+.1f} m/s, v_y {st.v_y:+.1f} m/s, "
           f"warning TTC {result.warning.ttc:.2f} s" if st is not None and result.warning.ttc is not None
           else "no state")
    if obj is None:
        return f"track {ep.track_id} matches no vehicle (a false or mislocated track); {est}"
    ttc = obj.ttc
    braking = "" if ep.true_braking_ttc_s is None else (
        f"; braking held ({ep.true_accel_mps2:+.1f} m/s^2): true TTC {ep.true_braking_ttc_s:.2f} s at the lowest")
    return (f"track {ep.track_id} is vehicle {obj.id} (lane {obj.lane_rel or 0:+d}): {est}; "
            f"true d_lat {obj.d_lat:+.1f} m, d_long {obj.d_long:.1f} m, v_lat {obj.v_lat:+.1f} m/s, "
            f"v_long {obj.v_long:+.1f} m/s, true TTC {'none' if ttc is None else f'{ttc:.2f} s'}{braking}")


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
            ep.true_braking_ttc_s, ep.true_accel_mps2 = _episode_braking(truths, k0, k1, obj.id)
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
        "braking_false_alarms": sum(braking_alarm(e.to_dict(), threshold_s) for e in eps),
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
