"""The horizon stage's row (px) against the true horizon row of each frame (``horizon`` of ``metrics.json``)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from harness.scoring import algo
from harness.world.truth import FrameTruth
from monorarp.core.camera import CameraModel
from monorarp.core.types import FrameResult

NAN = float("nan")


def horizon_metrics(truths: Sequence[FrameTruth], results: Sequence[FrameResult],
                    camera: CameraModel | None) -> dict | None:
    """The horizon stage's row against the true horizon row of each frame (None without a stage).

    True row: the truth's ``camera.horizon_row`` (a moving camera) or the calibration's.
    ``abs_err_*_px`` over all frames; ``coverage_90``: share of frames whose true row lies in
    ``row +- 1.645 std_px``; ``sources``: frames per reading source; ``calibrated_abs_err_*_px``:
    the calibrated row's error on the same frames (what the stage improves on).
    """
    if not results or all(r.horizon is None for r in results):
        return None
    est, std, true, nominal, sources = [], [], [], [], {}
    for tr, r in zip(truths, results):
        if r.horizon is None:
            continue
        cam_true = tr.camera.horizon_row if tr.camera is not None else None
        if cam_true is None and camera is None:
            continue
        true.append(float(cam_true) if cam_true is not None else camera.horizon_row)
        nominal.append(camera.horizon_row if camera is not None else np.nan)
        est.append(r.horizon.row)
        std.append(r.horizon.std_px)
        sources[r.horizon.source] = sources.get(r.horizon.source, 0) + 1
    est, std, true, nominal = map(np.asarray, (est, std, true, nominal))
    err = np.abs(est - true)
    out = {"count": int(err.size), **algo.summary(err, "abs_err_", "_px"),
           **algo.summary(np.abs(nominal - true), "calibrated_abs_err_", "_px"),
           "coverage_90": float(np.mean(err <= algo.Z90 * std)) if err.size else NAN,
           "std_median_px": float(np.median(std)) if std.size else NAN, "sources": sources}
    return out
