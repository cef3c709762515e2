"""Single-image haze removal by the dark channel prior (He, Sun and Tang, CVPR 2009).

A hazy image follows Koschmieder's model ``I = J t + A (1 - t)`` (J the scene radiance,
t the transmittance, A the airlight). In haze-free outdoor patches some channel of some
pixel is nearly black (the *dark channel* ``min_c min_patch J_c / A_c ~ 0``), so
``t ~ 1 - omega * min_c min_patch I_c / A_c``; A is taken as the brightest value (per
channel) among the 0.1 % pixels with the highest dark channel. The estimate of t is
smoothed (Gaussian, instead of the paper's soft matting), floored at ``t_min`` and the
radiance restored as ``J = (I - A) / max(t, t_min) + A``. Works on any frames (simulated
or a dashcam's); used as an optional pre-processing step of a detector (``dehaze: true``).
Intensities are taken as they come (no gamma handling), as in the paper.
"""

from __future__ import annotations

import cv2
import numpy as np


def dark_channel(img01: np.ndarray, patch: int) -> np.ndarray:
    """(H, W) minimum over the channels and a ``patch`` x ``patch`` window of an (H, W, 3) float image."""
    return cv2.erode(img01.min(axis=2), np.ones((patch, patch), np.uint8), borderType=cv2.BORDER_REPLICATE)


def airlight(img01: np.ndarray, dark: np.ndarray, top_fraction: float = 0.001) -> np.ndarray:
    """(3,) airlight: per-channel maximum over the ``top_fraction`` pixels with the highest dark channel."""
    n = max(1, int(dark.size * top_fraction))
    idx = np.argpartition(dark.ravel(), -n)[-n:]
    return img01.reshape(-1, 3)[idx].max(axis=0)


def dehaze(image: np.ndarray, patch: int | None = None, omega: float = 0.9, t_min: float = 0.25,
           smooth_px: float | None = None) -> np.ndarray:
    """(H, W, 3) uint8 hazy image -> uint8 image with the haze removed (same channel order).

    ``patch``: dark-channel window (px; default 15 px per 640 px of width, odd); ``omega``:
    fraction of the haze removed (the paper's 0.95 keeps a little for depth perception; 0.9
    here); ``t_min``: floor of the transmittance (limits noise amplification);
    ``smooth_px``: Gaussian sigma of the transmittance map (default patch / 4).
    """
    h, w = image.shape[:2]
    if patch is None:
        patch = max(3, int(round(15 * w / 640)) | 1)
    img = image.astype(np.float32) * np.float32(1 / 255)
    a = np.maximum(airlight(img, dark_channel(img, patch)), np.float32(1e-3)).astype(np.float32)
    t = np.float32(1.0) - np.float32(omega) * dark_channel(img / a, patch)
    t = cv2.GaussianBlur(t, (0, 0), smooth_px if smooth_px is not None else patch / 4)
    t = np.maximum(t, np.float32(t_min))
    out = (img - a) / cv2.merge([t, t, t]) + a
    return (np.clip(out, 0.0, 1.0) * np.float32(255) + np.float32(0.5)).astype(np.uint8)
