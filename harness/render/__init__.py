"""Offscreen dashcam renderer (pyrender + trimesh over EGL; no GPU needed)."""

import os

os.environ.setdefault("PYOPENGL_PLATFORM", "egl")

from harness.render.renderer import RenderedFrame, Renderer  # noqa: E402

__all__ = ["Renderer", "RenderedFrame"]
