"""Per-face Lambert shading baked into vertex colours (drawn with pyrender's FLAT shader).

Every surface is flat-shaded, so a face's colour depends only on its normal:
``linear = albedo * (ambient + intensity / pi * max(0, n . -l))``, gamma-encoded
to sRGB (1 / 2.2), as pyrender's own shader treats a directional light of that
intensity (without its specular term). This costs nothing per pixel, which
keeps the colour pass fast on a software rasteriser.
"""

from __future__ import annotations

import math

import numpy as np

#: The clear sky's colour (sRGB 0..1): the background of a daylight frame.
SKY_RGB = (0.62, 0.74, 0.90)
AMBIENT = 0.5


def shade(albedo_srgb: np.ndarray, normals: np.ndarray, light_dir: np.ndarray,
          intensity: float, ambient: float = AMBIENT) -> np.ndarray:
    """(F, 3) sRGB albedo (0..255) and unit normals -> (F, 3) shaded sRGB colours in 0..1.

    ``light_dir`` is the direction the light travels, in the normals' frame.
    """
    lin = (np.asarray(albedo_srgb, dtype=float) / 255.0) ** 2.2
    to_light = -np.asarray(light_dir, dtype=float)
    to_light = to_light / np.linalg.norm(to_light)
    lambert = np.clip(np.asarray(normals, dtype=float) @ to_light, 0.0, None)
    out = lin * (ambient + intensity / math.pi * lambert)[:, None]
    return np.clip(out, 0.0, 1.0) ** (1.0 / 2.2)


def rotate_z(vectors: np.ndarray, angle: float) -> np.ndarray:
    """Rotate (..., 3) vectors by ``angle`` (rad) about +Z (counter-clockwise seen from above)."""
    c, s = math.cos(angle), math.sin(angle)
    v = np.asarray(vectors, dtype=float)
    return np.stack([c * v[..., 0] - s * v[..., 1], s * v[..., 0] + c * v[..., 1], v[..., 2]], axis=-1)
