"""Procedural negatives for training images: things on a real street that are not vehicles, drawn at training time.

On real frames the renders-only detector fires on pedestrians (singly and in groups), cyclists and building
fronts (brick, tiles, windows), none of which the renders contain. Two seeded augmentations of a net-input image
``x`` ((H, W, 3) float BGR in [0, 1], in place), never over a labelled vehicle's box grown by 15 %:

* :func:`people` -- 1-5 standing or walking figures (head, hair, torso, arms, legs; a share of them on bicycles),
  grounded beside a labelled vehicle at a person's height relative to it (1.0-1.4 times the vehicle's box height,
  feet on its bottom row), or anywhere below the middle of the image when there is none;
* :func:`facade` -- a wall of brick or tiles (bond, mortar, per-unit colour jitter) with dark windows and a door,
  over the upper part of the image.

Each figure is anti-aliased (drawn at 4x, area-downsampled) with a vertical shading gradient. No real image is
involved: everything is drawn from ``rng``.
"""

from __future__ import annotations

import cv2
import numpy as np

from training.clutter import keep_out, octave_noise

#: BGR clothes colours (muted: black, greys, navy, denim, olive, beige, white, red, brown)
CLOTHES = np.array([(25, 25, 25), (70, 70, 70), (140, 140, 140), (80, 40, 20), (130, 90, 50), (50, 80, 70),
                    (150, 180, 200), (225, 225, 225), (40, 40, 170), (40, 60, 100)], np.float32) / 255.0
SKIN = np.array([(160, 190, 230), (120, 160, 210), (80, 120, 170), (50, 80, 120)], np.float32) / 255.0
HAIR = np.array([(20, 20, 20), (30, 50, 80), (90, 140, 180), (150, 150, 150)], np.float32) / 255.0
SS = 4   # supersampling of the drawn figures


def _colour(palette: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    return np.clip(palette[rng.integers(len(palette))] * rng.uniform(0.8, 1.15), 0, 1)


def figure(height_px: float, rng: np.random.Generator, cyclist: bool) -> tuple[np.ndarray, np.ndarray]:
    """A person (on a bicycle when ``cyclist``) ``height_px`` tall: (colour (h, w, 3), alpha (h, w)), feet at
    the bottom row, centred."""
    hgt = height_px * SS
    wid = int(hgt * (1.1 if cyclist else 0.6)) + 4
    cv_h = int(hgt) + 4
    col = np.zeros((cv_h, wid, 3), np.float32)
    alpha = np.zeros((cv_h, wid), np.float32)
    cx, base = wid / 2.0, cv_h - 2.0
    top, legs, skin, hair = _colour(CLOTHES, rng), _colour(CLOTHES, rng), _colour(SKIN, rng), _colour(HAIR, rng)

    def poly(pts, c):
        p = np.round(np.array(pts, np.float32)).astype(np.int32)
        cv2.fillPoly(col, [p], tuple(float(v) for v in c))
        cv2.fillPoly(alpha, [p], 1.0)

    def limb(a, b, thick, c):
        a, b = tuple(int(round(v)) for v in a), tuple(int(round(v)) for v in b)
        cv2.line(col, a, b, tuple(float(v) for v in c), max(1, int(thick)))
        cv2.line(alpha, a, b, 1.0, max(1, int(thick)))

    lean = hgt * (0.12 if cyclist else rng.uniform(-0.02, 0.02))      # shoulders ahead of the hips
    hip_y = base - hgt * (0.5 if not cyclist else 0.55)
    sh_y = base - hgt * 0.82
    if cyclist:
        r = hgt * 0.2
        wheel_c = (0.12, 0.12, 0.12)
        for wx in (cx - hgt * 0.32, cx + hgt * 0.32):
            cv2.circle(col, (int(wx), int(base - r)), int(r), wheel_c, max(1, int(hgt * 0.025)))
            cv2.circle(alpha, (int(wx), int(base - r)), int(r), 1.0, max(1, int(hgt * 0.025)))
        frame_c = _colour(CLOTHES, rng)
        for a, b in (((cx - hgt * 0.32, base - r), (cx, base - r)), ((cx, base - r), (cx - hgt * 0.05, hip_y)),
                     ((cx - hgt * 0.05, hip_y), (cx + hgt * 0.22, hip_y)), ((cx + hgt * 0.22, hip_y),
                     (cx + hgt * 0.32, base - r)), ((cx + hgt * 0.22, hip_y), (cx, base - r))):
            limb(a, b, hgt * 0.02, frame_c)
        foot = [(cx + hgt * 0.05, base - r * 0.6), (cx - hgt * 0.08, base - r * 1.3)]
    else:
        stride = hgt * rng.uniform(0.0, 0.18)
        foot = [(cx - stride / 2, base), (cx + stride / 2, base)]
    hip_w, sh_w = hgt * rng.uniform(0.1, 0.14), hgt * rng.uniform(0.12, 0.16)
    for f in foot:                                                    # legs
        limb((cx, hip_y), f, hgt * 0.075, legs)
    poly([(cx - hip_w, hip_y), (cx + hip_w, hip_y), (cx + lean + sh_w, sh_y), (cx + lean - sh_w, sh_y)], top)
    swing = hgt * rng.uniform(-0.08, 0.08)
    for s in (-1, 1):                                                 # arms
        hand = (cx + lean * 2.2, hip_y) if cyclist else (cx + s * sh_w * 1.05 + s * swing, base - hgt * 0.45)
        limb((cx + lean + s * sh_w * 0.9, sh_y + hgt * 0.02), hand, hgt * 0.055, top * 0.9)
    head_r = hgt * rng.uniform(0.06, 0.07)
    hc = (int(cx + lean * 1.1), int(sh_y - head_r * 1.1))
    cv2.circle(col, hc, int(head_r), tuple(float(v) for v in skin), -1)
    cv2.circle(alpha, hc, int(head_r), 1.0, -1)
    cv2.ellipse(col, hc, (int(head_r * 1.05), int(head_r)), 0, 180, 360, tuple(float(v) for v in hair), -1)
    if rng.random() < 0.3:                                            # a bag
        bx = cx + lean + sh_w * (1 if rng.random() < 0.5 else -1)
        poly([(bx - hgt * 0.05, hip_y - hgt * 0.15), (bx + hgt * 0.05, hip_y - hgt * 0.15),
              (bx + hgt * 0.05, hip_y + hgt * 0.02), (bx - hgt * 0.05, hip_y + hgt * 0.02)], _colour(CLOTHES, rng))
    shading = np.linspace(1.15, 0.75, cv_h, dtype=np.float32)[:, None, None]     # lit from above
    col *= shading
    h, w = max(1, int(round(cv_h / SS))), max(1, int(round(wid / SS)))
    return cv2.resize(col, (w, h), interpolation=cv2.INTER_AREA), cv2.resize(alpha, (w, h), interpolation=cv2.INTER_AREA)


def _paste(x: np.ndarray, allowed: np.ndarray, col: np.ndarray, alpha: np.ndarray, left: int, bottom: int) -> bool:
    """Blend a figure with its bottom-left at (``left``, ``bottom``), cut by the image's edges, unless it would
    cover a pixel where ``allowed`` is 0 (a vehicle); return whether it was drawn."""
    h, w = alpha.shape
    i1, i2, j1, j2 = bottom - h, bottom, left, left + w
    a1, a2, b1, b2 = max(0, -i1), h - max(0, i2 - x.shape[0]), max(0, -j1), w - max(0, j2 - x.shape[1])
    if a2 - a1 < h // 2 or b2 - b1 < w // 2:             # mostly outside the image
        return False
    a = alpha[a1:a2, b1:b2]
    i1, j1 = i1 + a1, j1 + b1
    region = allowed[i1:i1 + a.shape[0], j1:j1 + a.shape[1]]
    if (region[a > 0.05] <= 0.0).any():
        return False
    win = x[i1:i1 + a.shape[0], j1:j1 + a.shape[1]]
    win *= 1.0 - a[..., None]
    win += a[..., None] * col[a1:a2, b1:b2]
    return True


def people(x: np.ndarray, boxes: np.ndarray, rng: np.random.Generator) -> None:
    """Draw 1-5 pedestrians or cyclists on ``x`` outside ``boxes`` (K, 4, net-input px; in place)."""
    h, w = x.shape[:2]
    allowed = keep_out(h, w, boxes)
    n = int(rng.integers(1, 6))
    if len(boxes) and rng.random() < 0.8:                 # beside a vehicle, at its scale
        x1, y1, x2, y2 = boxes[rng.integers(len(boxes))]
        height, bottom = (y2 - y1) * rng.uniform(1.0, 1.4), y2 + (y2 - y1) * rng.uniform(-0.1, 0.05)
        cx = rng.uniform(x1 - (x2 - x1), x2 + (x2 - x1))
    else:
        bottom = rng.uniform(0.55, 1.0) * h
        height = (bottom - 0.45 * h) * rng.uniform(0.5, 1.5)
        cx = rng.uniform(0, w)
    if height < 6:
        return
    for _ in range(n):
        col, alpha = figure(height * rng.uniform(0.9, 1.1), rng, cyclist=rng.random() < 0.25)
        if rng.random() < 0.5:
            col, alpha = col[:, ::-1], alpha[:, ::-1]
        fh, fw = alpha.shape
        feet = int(bottom + rng.normal(0, height * 0.03))
        free = allowed[max(0, feet - fh):max(1, min(h, feet))].min(axis=0) > 0      # columns clear of vehicles
        run = np.convolve(free.astype(np.int32), np.ones(fw, np.int32), "valid") == fw
        lefts = np.flatnonzero(run)
        if not len(lefts):
            continue
        left = int(lefts[np.argmin(np.abs(lefts + fw / 2 - cx - rng.normal(0, height * 0.4)))])
        _paste(x, allowed, col, alpha, left, feet)


def facade(x: np.ndarray, boxes: np.ndarray, rng: np.random.Generator) -> None:
    """Paint a brick or tile wall with windows and a door over part of ``x``, outside ``boxes`` (in place)."""
    h, w = x.shape[:2]
    allowed = keep_out(h, w, boxes)
    ww = int(rng.uniform(0.15, 0.5) * w)                 # on one side of the street, from above to near the ground
    j1 = 0 if rng.random() < 0.5 else w - ww
    j1 = int(np.clip(j1 + rng.normal(0, 0.1 * w), 0, w - ww))
    i1, i2 = int(rng.uniform(0, 0.3) * h), int(rng.uniform(0.45, 0.75) * h)
    j2 = j1 + ww
    ph, pw = i2 - i1, j2 - j1
    if ph < 8 or pw < 8:
        return
    unit_w = rng.uniform(3, 12)
    unit_h = unit_w * (rng.uniform(0.3, 0.45) if rng.random() < 0.6 else rng.uniform(0.8, 1.2))   # brick, tile
    base = _colour(np.array([(40, 60, 140), (60, 90, 170), (150, 150, 150), (170, 120, 60), (80, 80, 90),
                             (180, 190, 200)], np.float32) / 255.0, rng)
    mortar = np.clip(base * rng.uniform(0.5, 1.6), 0, 1)
    yy, xx = np.mgrid[0:ph, 0:pw].astype(np.float32)
    row = np.floor(yy / unit_h)
    shift = (row % 2) * unit_w * 0.5
    col_i = np.floor((xx + shift) / unit_w)
    jitter = np.random.default_rng(int(rng.integers(1 << 31))).uniform(0.8, 1.2, (int(row.max()) + 1, int(col_i.max()) + 2))
    tex = base * jitter[row.astype(int), col_i.astype(int)][..., None]
    line = max(0.6, unit_w * 0.08)
    is_mortar = ((yy % unit_h) < line) | (((xx + shift) % unit_w) < line)
    wall = np.where(is_mortar[..., None], mortar, tex) * (0.85 + 0.3 * octave_noise(ph, pw, rng, 2.0, 3))[..., None]
    win_w, win_h = rng.uniform(0.06, 0.15) * w, rng.uniform(0.08, 0.2) * h
    glass = rng.uniform(0.05, 0.35) * np.array([1.1, 1.0, 0.9], np.float32)
    frame = np.clip(rng.uniform(0.2, 0.9) * np.ones(3, np.float32), 0, 1)
    gap_x, gap_y = win_w * rng.uniform(1.4, 2.5), win_h * rng.uniform(1.5, 2.5)
    for wy in np.arange(rng.uniform(0, gap_y * 0.5), ph - win_h, gap_y):
        for wx in np.arange(rng.uniform(0, gap_x * 0.5), pw - win_w, gap_x):
            a, b, c, d = int(wy), int(wy + win_h), int(wx), int(wx + win_w)
            wall[a:b, c:d] = frame
            fw = max(1, int(win_w * 0.08))
            wall[a + fw:b - fw, c + fw:d - fw] = glass * rng.uniform(0.7, 1.3)
    if rng.random() < 0.5:                                # a door on the wall's bottom row
        dw, dh = int(win_w * 1.2), int(min(ph, win_h * 2.2))
        dc = int(rng.uniform(0, max(1, pw - dw)))
        wall[ph - dh:, dc:dc + dw] = _colour(CLOTHES, rng) * 0.7
    a = allowed[i1:i2, j1:j2, None] * rng.uniform(0.8, 1.0)
    win = x[i1:i2, j1:j2]
    win *= 1.0 - a
    win += a * wall


def augment(x: np.ndarray, boxes: np.ndarray, rng: np.random.Generator, p: float) -> None:
    """With probability ``p`` each: :func:`facade`, then :func:`people`, outside ``boxes`` (in place)."""
    if rng.random() < p:
        facade(x, boxes, rng)
    if rng.random() < p:
        people(x, boxes, rng)
