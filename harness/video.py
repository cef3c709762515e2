"""H.264 ``.mp4`` writing (and reading back, for tests and tools).

The implementation lives in :mod:`monorarp.video.writer` (``monorarp video``
writes annotated videos too, and :mod:`monorarp` never imports the harness);
this module re-exports it under its historical name.
"""

from monorarp.video.writer import VideoFrame, VideoWriter, read_video  # noqa: F401  (re-exports)

__all__ = ["VideoFrame", "VideoWriter", "read_video"]
