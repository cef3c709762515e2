"""Optional sensor effects on the colour image: Gaussian blur (optics), then Gaussian noise."""

from __future__ import annotations

import cv2
import numpy as np


def apply_sensor(image: np.ndarray, noise_std: float, blur_px: float, seed: int, frame: int) -> np.ndarray:
    """Blur with sigma ``blur_px`` (px), then add noise of ``noise_std`` 8-bit levels.

    The noise is seeded from (``seed``, ``frame``), so a frame is reproducible.
    Returns ``image`` itself when both effects are off.
    """
    out = image
    if blur_px > 0:
        out = cv2.GaussianBlur(out, (0, 0), sigmaX=float(blur_px), sigmaY=float(blur_px),
                               borderType=cv2.BORDER_REFLECT101)
    if noise_std > 0:
        rng = np.random.default_rng([int(seed) & 0xFFFFFFFF, int(frame) & 0xFFFFFFFF, 0x5E5])
        noisy = out.astype(np.float32) + np.float32(noise_std) * rng.standard_normal(out.shape, dtype=np.float32)
        out = np.clip(np.rint(noisy), 0, 255).astype(np.uint8)
    return out
