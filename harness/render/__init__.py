"""Offscreen dashcam renderer (pyrender + trimesh over EGL; no GPU needed): :mod:`.renderer`."""

import os

os.environ.setdefault("PYOPENGL_PLATFORM", "egl")    # before any module of the package imports pyrender
