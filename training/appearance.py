"""Appearance randomisation of rendered training frames: a seeded style applied as a post-process.

A :class:`Style` recolours a rendered frame by region (from the renderer's exact id mask and the
camera's horizon row: vehicles, ground below the horizon, sky above it), then passes it through a
random camera response. Boxes are unchanged (they come from the id pass). The knobs, each small:

* ``body_hue_deg`` / ``body_sat`` / ``body_val``: per vehicle, a hue rotation drawn in
  +-``body_hue_deg`` and saturation / value gains drawn in the given (lo, hi) ranges (paint
  families: muted, vivid, dark, pale); tyres, glass and trim are near-grey, so only the paint moves;
* ``ground_gain`` (B, G, R gains) and ``ground_texture`` (amplitude of a smooth multiplicative
  noise field, about 12 px grain at 640x360): road and verge tone and wear;
* ``sky_gain`` (B, G, R gains): sky / background tone;
* camera response, in this order: ``white_balance`` (B, G, R gains), ``grade_mix`` (strength of a
  cross-channel colour-grading matrix, teal shadows / orange highlights; 0 = none), ``contrast``
  (about mid-grey), ``saturation`` (towards the luma), ``gamma`` (``out = in ** (1 / gamma)``),
  ``vignette`` (darkening at the corners, ``1 - v r^2`` with r = 1 at the corner).

Two samplers draw styles from disjoint families: :func:`sample_training` (what the training
renders see) and :func:`sample_heldout` (a held-out family for validation only: strong colour
grading, a flat lifted response, vivid paints, a red-brown ground and a yellow-green sky, each
outside the training ranges). :func:`is_heldout` tells them apart; a test checks that no training
draw falls in the held-out family.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import cv2
import numpy as np

Gains = tuple[float, float, float]

# training ranges (the held-out family lies outside each of the bounds marked *)
TRAIN_GAMMA = (0.75, 1.35)          # * held-out >= HELDOUT_GAMMA_MIN
TRAIN_CONTRAST = (0.75, 1.25)
TRAIN_SATURATION = (0.5, 1.4)
TRAIN_WB = 0.12                     # |log gain| per channel
TRAIN_VIGNETTE = (0.0, 0.35)
TRAIN_BODY_HUE_DEG = 60.0
TRAIN_BODY_SAT = (0.3, 1.4)         # * held-out paints >= HELDOUT_BODY_SAT_MIN
TRAIN_BODY_VAL = (0.55, 1.3)
TRAIN_GROUND = 0.15                 # * |log gain| per channel; held-out ground tint >= HELDOUT_TINT_MIN
TRAIN_GROUND_LEVEL = (0.7, 1.3)     # common brightness of the ground
TRAIN_TEXTURE = (0.0, 0.15)
TRAIN_SKY = 0.15                    # * |log gain| per channel
TRAIN_SKY_LEVEL = (0.8, 1.15)

HELDOUT_GAMMA_MIN = 1.45
HELDOUT_GRADE_MIN = 0.3
HELDOUT_BODY_SAT_MIN = 1.8
HELDOUT_TINT_MIN = 0.25             # |log gain| of the strongest channel of ground and sky tints


@dataclass(frozen=True)
class Style:
    """One frame style (a scenario keeps it for all its frames). ``seed`` draws per-vehicle paint and the
    texture field. Gains are (B, G, R), matching OpenCV images."""

    seed: int
    gamma: float = 1.0
    contrast: float = 1.0
    saturation: float = 1.0
    white_balance: Gains = (1.0, 1.0, 1.0)
    grade_mix: float = 0.0
    vignette: float = 0.0
    body_hue_deg: float = 0.0
    body_sat: tuple[float, float] = (1.0, 1.0)
    body_val: tuple[float, float] = (1.0, 1.0)
    ground_gain: Gains = (1.0, 1.0, 1.0)
    ground_texture: float = 0.0
    sky_gain: Gains = (1.0, 1.0, 1.0)

    def to_dict(self) -> dict:
        return asdict(self)


def _gains(rng: np.random.Generator, spread: float, level: tuple[float, float] = (1.0, 1.0)) -> Gains:
    g = np.exp(rng.uniform(-spread, spread, 3)) * rng.uniform(*level)
    return tuple(round(float(v), 4) for v in g)


def _r(x: float) -> float:
    return round(float(x), 4)


def sample_training(rng: np.random.Generator) -> Style:
    """A style of the training family."""
    lo_s = rng.uniform(*TRAIN_BODY_SAT)
    lo_v = rng.uniform(*TRAIN_BODY_VAL)
    return Style(
        seed=int(rng.integers(0, 2**31 - 1)),
        gamma=_r(rng.uniform(*TRAIN_GAMMA)), contrast=_r(rng.uniform(*TRAIN_CONTRAST)),
        saturation=_r(rng.uniform(*TRAIN_SATURATION)), white_balance=_gains(rng, TRAIN_WB),
        grade_mix=0.0, vignette=_r(rng.uniform(*TRAIN_VIGNETTE)),
        body_hue_deg=_r(rng.uniform(0.0, TRAIN_BODY_HUE_DEG)),
        body_sat=(_r(lo_s), _r(rng.uniform(lo_s, TRAIN_BODY_SAT[1]))),
        body_val=(_r(lo_v), _r(rng.uniform(lo_v, TRAIN_BODY_VAL[1]))),
        ground_gain=_gains(rng, TRAIN_GROUND, TRAIN_GROUND_LEVEL), ground_texture=_r(rng.uniform(*TRAIN_TEXTURE)),
        sky_gain=_gains(rng, TRAIN_SKY, TRAIN_SKY_LEVEL))


def sample_heldout(rng: np.random.Generator) -> Style:
    """A style of the held-out family (never drawn by :func:`sample_training`)."""
    red_brown = np.log([0.72, 0.9, 1.35])        # B, G, R: dusty red-brown ground
    yellow_green = np.log([0.65, 1.15, 1.05])     # B, G, R: yellow-green sky
    jit = lambda: np.exp(rng.uniform(-0.04, 0.04, 3))  # noqa: E731
    s_lo = rng.uniform(HELDOUT_BODY_SAT_MIN, 2.1)
    return Style(
        seed=int(rng.integers(0, 2**31 - 1)),
        gamma=_r(rng.uniform(HELDOUT_GAMMA_MIN, 1.7)), contrast=_r(rng.uniform(0.9, 1.1)),
        saturation=_r(rng.uniform(0.9, 1.2)), white_balance=(1.0, 1.0, 1.0),
        grade_mix=_r(rng.uniform(HELDOUT_GRADE_MIN, 0.5)), vignette=_r(rng.uniform(0.0, 0.3)),
        body_hue_deg=_r(rng.uniform(0.0, 30.0)), body_sat=(_r(s_lo), _r(s_lo + 0.4)), body_val=(1.0, 1.2),
        ground_gain=tuple(_r(v) for v in np.exp(red_brown) * jit()), ground_texture=_r(rng.uniform(0.05, 0.15)),
        sky_gain=tuple(_r(v) for v in np.exp(yellow_green) * jit()))


def _tint(g: Gains) -> float:
    """Strength of a tint: the largest |log| of the gains relative to their geometric mean."""
    lg = np.log(np.asarray(g, float))
    return float(np.abs(lg - lg.mean()).max())


def is_heldout(s: Style) -> bool:
    """Whether ``s`` lies in the held-out family (any of its marks)."""
    return (s.gamma >= HELDOUT_GAMMA_MIN or s.grade_mix >= HELDOUT_GRADE_MIN or s.body_sat[0] >= HELDOUT_BODY_SAT_MIN
            or min(_tint(s.ground_gain), _tint(s.sky_gain)) >= HELDOUT_TINT_MIN)


# teal-orange grade: shadows pushed to teal, highlights to orange (rows: out B, G, R; cols: in B, G, R)
GRADE = np.array([[0.75, 0.35, -0.10],
                  [0.05, 0.95, 0.00],
                  [-0.15, 0.10, 1.05]], np.float32)


def _smooth_noise(h: int, w: int, rng: np.random.Generator, grain_px: float) -> np.ndarray:
    """Zero-mean, unit-std smooth noise (h, w): white noise on a coarse grid, bicubically upsampled."""
    gh, gw = max(2, int(round(h / grain_px))), max(2, int(round(w / grain_px)))
    n = rng.standard_normal((gh, gw)).astype(np.float32)
    up = cv2.resize(n, (w, h), interpolation=cv2.INTER_CUBIC)
    return (up - up.mean()) / max(float(up.std()), 1e-6)


def apply(style: Style, image: np.ndarray, id_mask: np.ndarray, horizon_row: float) -> np.ndarray:
    """The styled frame (uint8 BGR, same shape). ``id_mask``: vehicle id per pixel (-1 none);
    ``horizon_row``: image row (px) of the horizon, the sky lies above it."""
    h, w = image.shape[:2]
    rng = np.random.default_rng([style.seed & 0x7FFFFFFF, 0xA77])
    x = image.astype(np.float32) / 255.0
    veh = id_mask >= 0
    sky = (~veh) & (np.arange(h)[:, None] < horizon_row)
    ground = ~(veh | sky)
    # ground: tint and texture
    field = 1.0 + style.ground_texture * _smooth_noise(h, w, rng, 12.0 * w / 640.0)
    x[ground] *= np.asarray(style.ground_gain, np.float32) * np.clip(field[ground], 0.5, 1.5)[:, None]
    x[sky] *= np.asarray(style.sky_gain, np.float32)
    # vehicles: per-id paint (hue rotation, saturation and value gains)
    if veh.any():
        ids = id_mask[veh]
        n = int(ids.max()) + 1
        prng = np.random.default_rng([style.seed & 0x7FFFFFFF, 0xB0D])
        dh = prng.uniform(-style.body_hue_deg, style.body_hue_deg, n).astype(np.float32)
        ds = prng.uniform(*style.body_sat, n).astype(np.float32)
        dv = prng.uniform(*style.body_val, n).astype(np.float32)
        hsv = cv2.cvtColor(np.clip(x, 0, 1)[veh][None], cv2.COLOR_BGR2HSV)[0]   # H degrees, S, V in [0, 1]
        hsv[:, 0] = np.mod(hsv[:, 0] + dh[ids], 360.0)
        hsv[:, 1] = np.clip(hsv[:, 1] * ds[ids], 0, 1)
        hsv[:, 2] = np.clip(hsv[:, 2] * dv[ids], 0, 1)
        x[veh] = cv2.cvtColor(hsv[None], cv2.COLOR_HSV2BGR)[0]
    # camera response
    x *= np.asarray(style.white_balance, np.float32)
    if style.grade_mix:
        m = (1 - style.grade_mix) * np.eye(3, dtype=np.float32) + style.grade_mix * GRADE
        x = x @ m.T
    x = (x - 0.5) * style.contrast + 0.5
    luma = x @ np.array([0.114, 0.587, 0.299], np.float32)
    x = luma[..., None] + style.saturation * (x - luma[..., None])
    x = np.clip(x, 0, 1) ** (1.0 / style.gamma)
    if style.vignette:
        yy, xx = np.mgrid[0:h, 0:w].astype(np.float32)
        r2 = ((xx - (w - 1) / 2) ** 2 + (yy - (h - 1) / 2) ** 2) / (((w - 1) / 2) ** 2 + ((h - 1) / 2) ** 2)
        x *= (1.0 - style.vignette * r2)[..., None]
    return np.clip(np.round(x * 255.0), 0, 255).astype(np.uint8)
