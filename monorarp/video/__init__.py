"""The pipeline on real video: frame sources, the ``monorarp video`` run, horizon calibration, mp4 writing.

* :mod:`.source` -- :class:`VideoSource`: frames and container timestamps from a file, or a webcam;
* :mod:`.run` -- :func:`run_video`: pipeline over a source -> ``predictions.jsonl``, ``annotated.mp4``;
* :mod:`.horizon` -- :func:`estimate_horizon`: horizon row / pitch from the lane lines' vanishing point;
* :mod:`.writer` -- :class:`VideoWriter` (H.264 mp4) and :func:`read_video`;
* :mod:`.cli` -- the ``video`` and ``calibrate-horizon`` sub-commands.

Names are imported lazily so that ``import monorarp.video.writer`` stays light.
"""

from __future__ import annotations

from importlib import import_module
from typing import Any

_EXPORTS = {
    "VideoSource": "source", "VideoSourceError": "source", "VideoInfo": "source",
    "run_video": "run", "VideoRunOptions": "run", "VideoRunSummary": "run",
    "estimate_horizon": "horizon", "HorizonEstimate": "horizon", "HorizonError": "horizon",
    "VideoWriter": "writer", "read_video": "writer",
}

__all__ = sorted(_EXPORTS)


def __getattr__(name: str) -> Any:
    if name in _EXPORTS:
        return getattr(import_module(f"monorarp.video.{_EXPORTS[name]}"), name)
    raise AttributeError(f"module 'monorarp.video' has no attribute {name!r}")
