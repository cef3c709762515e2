"""Annotated display of one pipeline frame (the paper's Fig. 2), pure OpenCV on BGR images.

Draws each track's box coloured by its per-object time to collision, the paper's cue
(:data:`~monorarp.warning.thresholds.TTC_CUE_THRESHOLD_S`: red below it, orange below twice it,
yellow for any other TTC within the horizon, green when not on a collision course); a label per
track (id, TTC, ``d_x``/``d_y`` in m; one compact line ``#id y..m TTC ..s`` for small, far boxes);
a vertical risk gauge (risk = max 1/TTC, 1/s) at the right edge; and a header with frame index,
frame time, pipeline time per frame and, when known, the ego speed. The gauge reads
``result.risk.kind``: ``"inverse_ttc"`` (1/s) or ``"probability"`` (0..1).

**Forward-collision warning** (``result.warning``), as a driver sees it: while a warning is active,
a red banner "BRAKE! / COLLISION WARNING" (with the warning stage's TTC when known) at the top
centre, and the object it is for framed thick red with a red marker above it, its box and label red
and the label giving the same TTC as the banner (``FCW TTC 1.1s``: the warning stage's in-path TTC,
not the risk stage's per-object one that the other labels show; docs/warning.md); while inactive
only a small "FCW ready" indicator. Nothing depends on the wall clock (no flashing): the same result
gives the same pixels.

Modules: :mod:`.content` (which text and colour: pure), :mod:`.placement` (rectangles, the greedy
label placement: pure), :mod:`.layout` (:func:`layout_frame`: every rectangle of a frame, drawing
nothing; it measures text through :mod:`.text`, the font's metrics), :mod:`.style` (colours, sizes),
:mod:`.draw` (:func:`draw_frame`: the cv2 drawing). Inputs are never modified unless ``copy=False``.
"""

from monorarp.app.display.draw import draw_frame, draw_risk_gauge
from monorarp.app.display.layout import FrameLayout, Label, layout_frame
from monorarp.app.display.placement import Rect, place_labels, rects_overlap
from monorarp.app.display.style import BANNER_RED, BLACK, GREEN, GREY, ORANGE, RED, WHITE, YELLOW, ttc_colour

__all__ = ["BANNER_RED", "BLACK", "GREEN", "GREY", "ORANGE", "RED", "WHITE", "YELLOW", "FrameLayout", "Label",
           "Rect", "draw_frame", "draw_risk_gauge", "layout_frame", "place_labels", "rects_overlap", "ttc_colour"]
