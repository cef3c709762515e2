"""Procedural shade and clutter for training images: texture the renders lack, drawn at training time.

The realistic renders are smooth where real streets are busy: dappled tree shade over road and cars, foliage,
brickwork. Two seeded augmentations of a net-input image ``x`` ((H, W, 3) float BGR in [0, 1], in place):

* :func:`shade` -- a dappled shadow field (smooth noise, thresholded with a soft edge) darkening everything
  under it below a random top row (ground, vehicles, frontage; not the sky), vehicles included, by a depth
  of 0.3-0.7 and a little bluer in the shade (sky light);
* :func:`foliage` -- irregular patches of multi-octave noise texture (a random palette of greens, browns,
  greys) painted over, or modulating, the background, never within any labelled vehicle's box grown by 15 %:
  high-frequency clutter that is not a vehicle.

No real image is involved: everything is noise drawn from ``rng``.
"""

from __future__ import annotations

import cv2
import numpy as np

#: BGR palettes of clutter (dark, light): foliage greens, olive, bark and soil browns, stone and render greys
PALETTES = np.array([[(20, 60, 30), (90, 170, 120)], [(15, 45, 45), (70, 150, 140)], [(20, 35, 55), (90, 120, 150)],
                     [(50, 55, 60), (170, 175, 180)], [(30, 40, 70), (110, 140, 190)], [(10, 30, 15), (60, 120, 60)]],
                    np.float32) / 255.0
GROW = 0.15


def smooth_noise(h: int, w: int, cell_px: float, rng: np.random.Generator) -> np.ndarray:
    """(h, w) float32 noise in [0, 1] with features about ``cell_px`` pixels across (bicubic-upsampled)."""
    gh, gw = max(2, int(round(h / cell_px)) + 1), max(2, int(round(w / cell_px)) + 1)
    return np.clip(cv2.resize(rng.random((gh, gw), dtype=np.float32), (w, h), interpolation=cv2.INTER_CUBIC), 0, 1)


def octave_noise(h: int, w: int, rng: np.random.Generator, finest_px: float, octaves: int = 4) -> np.ndarray:
    """(h, w) float32 fractal noise in [0, 1] (contrast-stretched): ``octaves`` smooth-noise layers from
    ``finest_px`` up, each twice the size and 0.7 times the weight of the one before (a busy, fine texture)."""
    acc = np.zeros((h, w), np.float32)
    total = 0.0
    for k in range(octaves):
        wgt = 0.7 ** k
        acc += wgt * smooth_noise(h, w, finest_px * 2 ** k, rng)
        total += wgt
    acc /= total
    lo, hi = np.percentile(acc, (2, 98))
    return np.clip((acc - lo) / max(hi - lo, 1e-6), 0, 1)


def shade(x: np.ndarray, rng: np.random.Generator) -> None:
    """Dapple ``x`` with tree shade (in place)."""
    h, w = x.shape[:2]
    n = smooth_noise(h, w, rng.uniform(6, 30), rng) * 0.7 + smooth_noise(h, w, rng.uniform(2, 6), rng) * 0.3
    level = np.quantile(n, 1 - rng.uniform(0.2, 0.7))          # share of the image in shade
    soft = rng.uniform(0.01, 0.05)
    m = 1.0 / (1.0 + np.exp(-(n - level) / soft))
    top = rng.uniform(0.15, 0.5) * h                          # falls on the ground, vehicles and frontage
    m *= np.clip((np.arange(h, dtype=np.float32) - top) / (0.1 * h) + 0.5, 0, 1)[:, None]
    depth = rng.uniform(0.3, 0.7)
    tint = np.array([0.8, 1.0, 1.1], np.float32)              # shade keeps more blue (B, G, R)
    x *= 1.0 - depth * m[..., None] * tint


def keep_out(h: int, w: int, boxes: np.ndarray) -> np.ndarray:
    """(h, w) float32: 0 within any box of ``boxes`` (K, 4, px) grown by ``GROW`` each side, else 1."""
    allowed = np.ones((h, w), np.float32)
    for x1, y1, x2, y2 in boxes:
        gx, gy = GROW * (x2 - x1), GROW * (y2 - y1)
        j1, j2 = int(max(x1 - gx, 0)), int(min(np.ceil(x2 + gx), w))
        i1, i2 = int(max(y1 - gy, 0)), int(min(np.ceil(y2 + gy), h))
        allowed[i1:i2, j1:j2] = 0.0
    return allowed


def foliage(x: np.ndarray, boxes: np.ndarray, rng: np.random.Generator, patches: tuple[int, int] = (1, 4)) -> None:
    """Paint patches of clutter texture on ``x`` outside ``boxes`` (K, 4, net-input px; in place)."""
    h, w = x.shape[:2]
    allowed = keep_out(h, w, boxes)
    for _ in range(int(rng.integers(patches[0], patches[1] + 1))):
        cx, cy = rng.uniform(0, w), rng.uniform(0, 0.75 * h)
        rx, ry = rng.uniform(0.05, 0.3) * w, rng.uniform(0.08, 0.4) * h
        j1, j2 = int(max(cx - 1.3 * rx, 0)), int(min(cx + 1.3 * rx + 1, w))
        i1, i2 = int(max(cy - 1.3 * ry, 0)), int(min(cy + 1.3 * ry + 1, h))
        ph, pw = i2 - i1, j2 - j1
        if ph < 2 or pw < 2:
            continue
        yy, xx = np.mgrid[i1:i2, j1:j2].astype(np.float32)
        r = ((xx - cx) / rx) ** 2 + ((yy - cy) / ry) ** 2
        edge = smooth_noise(ph, pw, rng.uniform(3, 12), rng)
        blob = np.clip((1.0 - r + 0.6 * (edge - 0.5)) * 6.0, 0, 1) * allowed[i1:i2, j1:j2]
        if not blob.any():
            continue
        tex = octave_noise(ph, pw, rng, rng.uniform(0.7, 3.0))
        win = x[i1:i2, j1:j2]
        if rng.random() < 0.6:    # paint: the clutter replaces what was there
            dark, light = PALETTES[rng.integers(len(PALETTES))] * rng.uniform(0.6, 1.3)
            a = (blob * rng.uniform(0.7, 1.0))[..., None]
            win *= 1.0 - a
            win += a * (dark + (light - dark) * tex[..., None])
        else:                      # modulate: the scene keeps its shapes and gains a busy surface
            win *= 1.0 + (blob * rng.uniform(0.3, 0.8) * (tex - 0.5))[..., None]


def augment(x: np.ndarray, boxes: np.ndarray, rng: np.random.Generator, p: float) -> None:
    """With probability ``p`` each: :func:`foliage` outside ``boxes`` (every labelled vehicle), then
    :func:`shade` (in place)."""
    if rng.random() < p:
        foliage(x, boxes, rng)
    if rng.random() < p:
        shade(x, rng)
