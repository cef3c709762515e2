"""What the annotated display says: the texts and colours of the header, banner, gauge and labels; pure.

A track's label gives its id, its TTC and its position (``d_x``/``d_y``, m). The TTC shown depends on
the object: the one the warning alerts on shows the **warning stage's** in-path TTC (``FCW TTC 1.1s``,
the number of the banner; just ``FCW`` in the hold time, when the stage has none this frame) and is
drawn red, the alert's colour; every other shows the risk stage's **per-object TTC** (``TTC 1.3s``),
coloured by the cue :data:`~monorarp.warning.thresholds.TTC_CUE_THRESHOLD_S`. Why the two differ:
docs/warning.md, "The warning's TTC and the risk stage's".
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from monorarp.app.display.style import RED, Colour, ttc_colour
from monorarp.core.boxes import iou_matrix
from monorarp.core.types import Box, FrameResult, Track, WarningState

MISSED_IOU = 0.3          # a truth box no track overlaps at this IoU or more is "missed"
MISSED_TEXT = "missed"
#: The legend's entries, top to bottom: (sample drawn beside it, text); samples: :func:`..draw._legend`.
LEGEND = (("box", "estimate"), ("thin", "coasting"), ("dashed", "missed truth"), ("warned", "FCW warned"))


def _finite(v: float | None) -> bool:
    return v is not None and bool(np.isfinite(v))


def is_warned(track_id: int, warning: WarningState) -> bool:
    """Whether the (active) warning alerts on track ``track_id``."""
    return warning.active and track_id == warning.track_id


def missed_truth(truth_boxes: Sequence[Box], tracks: Sequence[Track]) -> list[int]:
    """Indices of the truth boxes that no track's box overlaps at IoU >= :data:`MISSED_IOU`."""
    if not len(truth_boxes):
        return []
    if not tracks:
        return list(range(len(truth_boxes)))
    best = iou_matrix(np.asarray(truth_boxes, float), np.asarray([t.box for t in tracks], float)).max(axis=1)
    return [i for i, v in enumerate(best) if v < MISSED_IOU]


def cue_text(warning_s: float) -> str:
    """The legend's colour key of the per-object TTC cue."""
    return f"TTC <{warning_s:g}s orange, <{2 * warning_s:g}s yellow"


def header_lines(result: FrameResult, ego_speed: float | None) -> list[str]:
    """Frame index, frame time and pipeline time per frame; the ego speed when known (``ego_speed`` first)."""
    header = [f"frame {result.index}  t={result.t:.2f}s"]
    total = result.timings_ms.get("total")
    if total is not None:
        header[0] += f"  pipeline {total:.1f} ms" + (f" ({1000 / total:.0f} fps)" if total > 0 else "")
    speed = ego_speed if ego_speed is not None else result.ego_speed
    if speed is not None and np.isfinite(speed):
        header.append(f"ego {speed:.1f} m/s ({speed * 3.6:.0f} km/h)")
    return header


def banner_lines(warning: WarningState) -> tuple[str, str]:
    """The banner's two lines; the second gives the warning stage's TTC of the warned object when it has one."""
    ttc = warning.ttc
    return "BRAKE!", "COLLISION WARNING" + (f"  TTC {ttc:.1f} s" if _finite(ttc) else "")


def gauge_text(risk: float, kind: str) -> str:
    """The gauge's value: ``P=0.42`` for a probability, ``0.42/s`` for an inverse TTC."""
    return f"P={risk:.2f}" if kind == "probability" else f"{risk:.2f}/s"


def ttc_text(track_id: int, result: FrameResult) -> str:
    """The TTC part of a track's label (module docstring): ``FCW TTC 1.1s``, ``FCW``, ``TTC 1.3s`` or none."""
    if is_warned(track_id, result.warning):
        ttc = result.warning.ttc
        return "FCW" + (f" TTC {ttc:.1f}s" if _finite(ttc) else "")
    ttc = result.risk.ttc.get(track_id)
    return f"TTC {ttc:.1f}s" if _finite(ttc) else ""


def label_lines(tr: Track, result: FrameResult, compact: bool) -> tuple[str, ...]:
    """A track's label: ``#id TTC`` and ``x.. y..m``; one line ``#id y..m TTC`` when ``compact`` (small boxes)."""
    ttc_s = ttc_text(tr.id, result)
    st = result.states.get(tr.id)
    if st is None:
        return (f"#{tr.id} {ttc_s}".strip(),)
    if compact:
        return (f"#{tr.id} y{st.d_y:.0f}m {ttc_s}".strip(),)
    return (f"#{tr.id} {ttc_s}".strip(), f"x{st.d_x:+.1f} y{st.d_y:.1f}m")


def label_colour(track_id: int, result: FrameResult, warning_s: float) -> Colour:
    """Colour of a track's box and label: red for the warned object, else by its per-object TTC (cue ``warning_s``)."""
    if is_warned(track_id, result.warning):
        return RED
    return ttc_colour(result.risk.ttc.get(track_id), warning_s)


def label_priority(tr: Track, result: FrameResult) -> tuple:
    """Sort key: the warned object, then lowest per-object TTC, then nearest (d_y, else lowest box bottom)."""
    ttc = result.risk.ttc.get(tr.id)
    st = result.states.get(tr.id)
    return (not is_warned(tr.id, result.warning), ttc if _finite(ttc) else np.inf,
            st.d_y if st is not None else np.inf, -tr.box[3], tr.id)
