"""Dark-channel-prior dehazing (monorarp/detection/dehaze.py) against Koschmieder's model:
a scene J with a dark pixel in every patch, hazed as I = J t + A (1 - t), is recovered."""

from __future__ import annotations

import numpy as np

from monorarp.detection.dehaze import dehaze

A = np.array([0.80, 0.82, 0.85])


def _scene(h=180, w=320, seed=0):
    rng = np.random.default_rng(seed)
    j = rng.uniform(0.1, 0.9, (h, w, 3))
    j[::6, ::6] = 0.0                       # a black pixel in every 15 x 15 window: dark channel 0
    j[:40] = A                              # a sky band: the brightest dark channel, gives the airlight
    return j


def test_recovers_radiance_under_uniform_haze():
    j = _scene()
    for t in (0.3, 0.6):
        hazy = np.rint(255 * (j * t + A * (1 - t))).astype(np.uint8)
        out = dehaze(hazy, patch=15, omega=1.0, t_min=0.1).astype(float)
        interior = (slice(70, 170), slice(20, 300))           # away from the sky edge and the border
        err = np.abs(out[interior] - 255 * j[interior])
        assert np.median(err) <= 1.0 and err.max() <= 3.0 / t, (t, np.median(err), err.max())
        before = np.abs(hazy[interior].astype(float) - 255 * j[interior])
        assert np.median(before) > 10


def test_haze_free_image_nearly_unchanged_and_deterministic():
    j = _scene(seed=1)
    img = np.rint(255 * j).astype(np.uint8)
    out = dehaze(img)
    assert np.array_equal(out, dehaze(img))
    assert np.median(np.abs(out.astype(int) - img.astype(int))[60:]) <= 1
