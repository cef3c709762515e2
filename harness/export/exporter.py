"""Orchestration of ``monorarp export``: source -> (detector) -> format writer, atomically.

The output directory is built in a temporary directory beside ``out`` and moved into
place only when every frame has been written (:func:`monorarp.app.io.atomic_output_dir`):
an error or Ctrl-C leaves ``out`` as it was. Beside the format's own files the export
writes ``export.json``: format, source, frames, sequence name, fps, the camera
(``camera.json``'s layout) and the detector of ``det/det.txt``.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path
from typing import Any

from harness.export.kitti import KittiObjectWriter, KittiTrackingWriter
from harness.export.mot import MotWriter, sequence_name
from harness.export.source import ExportSource

FORMATS = ("kitti", "kitti-tracking", "mot")
MANIFEST_NAME = "export.json"


def owned_names(fmt: str, name: str) -> tuple[str, ...]:
    """Top-level names an export of ``fmt`` writes (a previous export of any format may be replaced)."""
    return (MANIFEST_NAME, *KittiObjectWriter.names, *KittiTrackingWriter.names, sequence_name(name))


def export(source: ExportSource, fmt: str, out: str | Path, detector: Any = None, detector_name: str | None = None,
           progress: bool | None = None) -> dict:
    """Write ``source`` to ``out`` in ``fmt``; ``detector`` (``detect(image)``) fills MOT's ``det/det.txt``.

    Returns summary figures: frames, objects (label lines), detections, seconds.
    """
    from tqdm import tqdm

    from monorarp.app.io import atomic_output_dir, write_json_atomic

    if fmt not in FORMATS:
        raise ValueError(f"unknown format {fmt!r}")
    if progress is None:
        progress = sys.stderr.isatty()
    start = time.perf_counter()
    set_truth = getattr(detector, "set_truth", None)     # the oracle detector reads the truth
    if detector is not None and hasattr(detector, "reset"):
        detector.reset()
    with atomic_output_dir(out, owned_names=owned_names(fmt, source.name)) as tmp:
        if fmt == "kitti":
            writer = KittiObjectWriter(tmp, source.camera)
        elif fmt == "kitti-tracking":
            writer = KittiTrackingWriter(tmp, source.camera)
        else:
            writer = MotWriter(tmp, source.camera, source.name, source.fps, with_detections=detector is not None)
        try:
            bar = tqdm(source.frames, total=source.n_frames, unit="frame", desc=f"export {fmt}", file=sys.stderr,
                       disable=not progress, dynamic_ncols=True)
            with bar:
                for frame, truth in bar:
                    dets = None
                    if detector is not None:
                        if set_truth is not None:
                            set_truth(truth, frame.image)
                        dets = list(detector.detect(frame.image))
                    writer.add(frame.index, frame.image, truth, dets)
        finally:
            writer.close()
        write_json_atomic(tmp / MANIFEST_NAME, {
            "format": fmt, "source": source.origin, "sequence": source.name, "frames": writer.frames,
            "fps": source.fps, "camera": source.camera.to_dict(),
            "detector": detector_name if fmt == "mot" and detector is not None else None,
            "conventions": "camera frame = the pitched camera's own (OpenCV axes); R0_rect = I; "
                           "Tr_velo_to_cam = levelled frame at the camera -> camera (holds the pitch); "
                           "see harness/export/geometry.py"})
    return {"frames": writer.frames, "objects": writer.objects, "detections": getattr(writer, "detections", 0),
            "seconds": time.perf_counter() - start}
