"""The project's two time-to-collision thresholds (s), in one place, each named by its role.

* :data:`FCW_THRESHOLD_S` is the **alert**: the forward-collision warning stage
  (:class:`monorarp.warning.fcw.ForwardCollisionWarning`) raises a warning episode when an object
  in the ego's path will reach it within this time (docs/warning.md). Every "warning" a user sees
  (the banner, ``warning_active`` in ``per_frame.csv``, the scorecard) is this stage's decision.
* :data:`TTC_CUE_THRESHOLD_S` is the paper's per-object **cue** (Phillips et al. 2019, sect. VI):
  an object whose own constant-velocity TTC is below it is drawn red, and the ``ttc_warnings``
  metric scores "TTC below the cue" per object against the truth. It is a display and scoring
  threshold, not an alert.
"""

from __future__ import annotations

#: The warning stage's default alert threshold (s).
FCW_THRESHOLD_S = 3.0
#: The paper's per-object TTC cue (s): box colour, ``ttc_warnings`` metric, ``--warning-threshold``.
TTC_CUE_THRESHOLD_S = 2.0
