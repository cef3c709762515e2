"""The public import path of :mod:`monorarp.core.camera` (plug-ins and users write ``monorarp.camera``)."""

from monorarp.core.camera import (  # noqa: F401 - re-exported
    CameraError,
    MAX_PIXELS,
    FILE_KEYS,
    CameraModel,
)

__all__ = ['CameraError', 'MAX_PIXELS', 'FILE_KEYS', 'CameraModel']
